//! `fogline rco replay` and its errors.

use std::process::Command;

fn data() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../rco/tests/data/observations.jsonl")
}

#[test]
fn replay_prints_one_decision_per_tick_and_a_summary() {
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(["rco", "replay"])
        .arg(data())
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("80 ticks:"), "{out}");
    let ticks = out
        .lines()
        .filter(|l| {
            let mut w = l.split_whitespace();
            w.next().is_some_and(|t| t.parse::<u32>().is_ok()) && w.next() != Some("ticks:")
        })
        .count();
    assert_eq!(ticks, 80, "{out}");
    // The ablation without the verifier never refuses a condition.
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(["rco", "replay"])
        .arg(data())
        .args(["--modules", "hi,st,sc", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(!text.contains("\"refused\":{"), "no refusals without AV");
}

#[test]
fn a_bad_observation_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("obs.jsonl");
    std::fs::write(&f, "{\"not\": \"an observation\"}\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(["rco", "replay"])
        .arg(&f)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("obs.jsonl"), "{err}");
}

#[test]
fn a_replay_where_every_tick_fell_back_exits_1_and_a_malformed_url_fails_at_start_up() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("obs.jsonl");
    let head: String = std::fs::read_to_string(data())
        .unwrap()
        .lines()
        .take(4)
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&f, head).unwrap();
    // A closed port on loopback: every call fails, every tick falls back.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let url = format!("http://127.0.0.1:{port}");
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(["rco", "replay"])
        .arg(&f)
        .args(["--backend", "openai", "--url", &url, "--timeout-ms", "500"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("all 4 ticks fell back"), "{err}");
    // The rules backend on the same file: no fallback, exit 0.
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(["rco", "replay"])
        .arg(&f)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    for bad in ["http://[::1", "http://host:port", "http://a b"] {
        let sim_out = dir.path().join("sim");
        for cmd in [
            vec!["rco", "replay", f.to_str().unwrap()],
            vec!["sim", "run", "--quick", "--out", sim_out.to_str().unwrap()],
        ] {
            let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
                .args(&cmd)
                .args(["--backend", "openai", "--url", bad])
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{cmd:?} {bad}: {err}");
            assert!(
                err.contains("--url") && err.contains(bad),
                "{cmd:?} {bad}: {err}"
            );
        }
    }
}

#[test]
fn dataset_deficit_then_rco_eval_run_as_documented() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("deficit");
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args([
            "-q",
            "dataset",
            "deficit",
            "--samples",
            "8",
            "--seed",
            "7",
            "--out",
        ])
        .arg(&data)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        out.contains("8 samples in") && out.contains("samples/s"),
        "{out}"
    );
    assert!(out.contains("dataset_info.json"), "{out}");
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args([
            "-q",
            "rco",
            "eval",
            "--backend",
            "rules",
            "--split",
            "all",
            "--data",
        ])
        .arg(&data)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("| pedestrian | 2 |"), "{out}");
    assert!(out.contains("## Planning prompt"), "{out}");
    assert!(data.join("eval/eval.json").is_file());
    // report.html: the figure-6 tables and the gallery (8 samples: at most 8 shown, 15
    // frames each).
    let html = std::fs::read_to_string(data.join("eval/report.html")).unwrap();
    assert!(html.contains("id=\"table-deficit-class\""), "{html}");
    let shown = html.matches("<img src=\"data:image/png;base64,").count();
    assert!(
        shown >= 15 && shown.is_multiple_of(15) && shown <= 8 * 15,
        "{shown}"
    );
    // A directory without a data set: exit 2, the file named.
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(["rco", "eval", "--data"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("manifest.json"), "{err}");
}
