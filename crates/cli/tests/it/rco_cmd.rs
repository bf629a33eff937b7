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
