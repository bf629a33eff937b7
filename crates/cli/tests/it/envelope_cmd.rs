//! `fogline envelope` and `fogline demo` as a user runs them.

use std::path::Path;
use std::process::{Command, Output};

fn fogline(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(args)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .expect("the binary runs")
}

fn write_pairs(dir: &Path, n_clips: usize) -> std::path::PathBuf {
    let path = dir.join("pairs.csv");
    let mut f = std::fs::File::create(&path).unwrap();
    fogline_envelope::synthetic::write_csv(
        &fogline_envelope::synthetic::SyntheticParams { n_clips, seed: 4 },
        &mut f,
    )
    .unwrap();
    path
}

const QUICK: [&str; 6] = ["--bootstrap", "300", "--restarts", "3", "--k-max", "6"];

/// Runs `fogline envelope PAIRS --out OUT <extra> <QUICK>`.
fn envelope_quick(pairs: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "envelope",
        pairs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    args.extend(QUICK);
    fogline(&args)
}

#[test]
fn envelope_writes_the_three_files_and_prints_their_paths() {
    let dir = tempfile::tempdir().unwrap();
    let pairs = write_pairs(dir.path(), 400);
    let out = dir.path().join("out");
    let o = envelope_quick(&pairs, &out, &[]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8(o.stdout).unwrap();
    for f in ["envelope.json", "envelope.md", "odd.json", "report.html"] {
        assert!(out.join(f).is_file(), "{f}");
        assert!(stdout.contains(f), "{stdout}");
    }
    assert!(stdout.contains("STOP_SIGNAL"), "{stdout}");
    // Logs go to stderr, not stdout.
    assert!(!stdout.contains("[INFO"));
    assert!(String::from_utf8_lossy(&o.stderr).contains("analysed"));

    // The schema the issue promises.
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("envelope.json")).unwrap()).unwrap();
    assert_eq!(v["schema_version"], 1);
    let th = &v["thresholds"][0];
    for k in [
        "scenario",
        "budget",
        "rule",
        "n_clips",
        "sigma_star",
        "right_censored",
        "ci95",
        "bootstrap_share",
        "vs_aggregate",
        "pilot",
    ] {
        assert!(th.get(k).is_some(), "thresholds[].{k}");
    }
    assert!(v["dose_response"].as_array().is_some_and(|a| !a.is_empty()));
    let sev = &v["severity"];
    for k in ["n_changed", "bic", "chosen_k", "cv_loglik", "bands"] {
        assert!(sev.get(k).is_some(), "severity.{k}");
    }
    for k in ["k", "min", "per_seed", "chosen_count"] {
        assert!(sev["bic"][0].get(k).is_some(), "severity.bic[].{k}");
    }
    for k in ["name", "mean_m", "std_m", "weight", "share"] {
        assert!(sev["bands"][0].get(k).is_some(), "severity.bands[].{k}");
    }
    assert!(
        v["high_severity"]["by_scenario"].is_array()
            && v["high_severity"]["by_condition"].is_array()
    );
    assert!(v["odd"].as_array().is_some_and(|a| a.len() == 7));
    let st = &v["statistics"];
    for k in [
        "point_biserial_r",
        "cohens_d",
        "l2_ratio",
        "jaccard_l2_pearson",
        "jaccard_l2_spearman",
        "mwu",
        "bimodality_coefficient",
        "chi2",
        "cramers_v",
        "icc",
        "never_flip_share",
        "always_flip_share",
    ] {
        assert!(st.get(k).is_some_and(|x| !x.is_null()), "statistics.{k}");
    }
    for k in ["u", "p_value", "cohens_d"] {
        assert!(st["mwu"].get(k).is_some(), "mwu.{k}");
    }
    for k in ["statistic", "dof", "p_value"] {
        assert!(st["chi2"].get(k).is_some(), "chi2.{k}");
    }
    for k in ["icc2_1", "icc3_1"] {
        assert!(st["icc"].get(k).is_some(), "icc.{k}");
    }
    assert!(v["transitions"]["counts"].is_array());
    let odd: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("odd.json")).unwrap()).unwrap();
    assert_eq!(odd["kind"], "fogline.odd");
    let e = &odd["entries"][0];
    for k in [
        "scenario",
        "sigma_star",
        "ci95",
        "p_high",
        "quadrant",
        "accepted",
    ] {
        assert!(e.get(k).is_some(), "odd.entries[].{k}");
    }
    let md = std::fs::read_to_string(out.join("envelope.md")).unwrap();
    for t in [
        "Table 1",
        "Table 2",
        "Table 3",
        "Table 4",
        "Table 5",
        "Statistics",
        "Action transitions",
    ] {
        assert!(md.contains(t), "{t}");
    }
}

#[test]
fn json_summary_on_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let pairs = write_pairs(dir.path(), 120);
    let out = dir.path().join("o");
    let o = envelope_quick(&pairs, &out, &["--json"]);
    assert_eq!(o.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    assert_eq!(v["n_pairs"], 960);
}

#[test]
fn bad_input_exits_2_with_the_error_chain_and_keeps_previous_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let pairs = write_pairs(dir.path(), 60);
    let out = dir.path().join("out");
    assert_eq!(envelope_quick(&pairs, &out, &[]).status.code(), Some(0));
    let before = std::fs::read(out.join("envelope.json")).unwrap();

    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\nc,PASSING,noise_10,1,oops,1,a,a\n").unwrap();
    let o = fogline(&[
        "envelope",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("error:") && err.contains("bad.csv: row 2, column `ade_attacked`"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(out.join("envelope.json")).unwrap(),
        before,
        "a failed run must not touch outputs"
    );
    // No temporary files are left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty());

    // One file of the set cannot be written (a directory is where report.html goes): none
    // of the four is replaced, and the error names it.
    let kept: Vec<_> = ["envelope.json", "envelope.md", "odd.json"]
        .map(|f| std::fs::read(out.join(f)).unwrap())
        .into();
    std::fs::remove_file(out.join("report.html")).unwrap();
    std::fs::create_dir_all(out.join("report.html/x")).unwrap();
    let o = envelope_quick(&pairs, &out, &["--seed", "9"]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("report.html") && err.contains("directory"),
        "{err}"
    );
    let now: Vec<_> = ["envelope.json", "envelope.md", "odd.json"]
        .map(|f| std::fs::read(out.join(f)).unwrap())
        .into();
    assert!(now == kept, "a failed set must leave every previous file");
    let names: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(names.is_empty(), "temporaries left: {names:?}");
    std::fs::remove_dir_all(out.join("report.html")).unwrap();
    // With the obstacle gone the same run replaces all four.
    assert_eq!(
        envelope_quick(&pairs, &out, &["--seed", "9"]).status.code(),
        Some(0)
    );
    assert_ne!(std::fs::read(out.join("envelope.json")).unwrap(), kept[0]);
    assert!(out.join("report.html").is_file());

    let o = fogline(&[
        "envelope",
        "/nonexistent/pairs.csv",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("cannot read /nonexistent/pairs.csv: No such file"),
        "{err}"
    );

    let o = fogline(&[
        "envelope",
        pairs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--headline",
        "0.3",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("headline_budget"));

    let o = fogline(&[
        "envelope",
        pairs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--bands",
        "six",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr)
            .contains("--bands <BANDS>': expected `auto` or a whole number, got \"six\"")
    );
}

#[test]
fn a_failed_acceptance_gate_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let pairs = write_pairs(dir.path(), 400);
    let out = dir.path().join("out");
    let o = envelope_quick(&pairs, &out, &["--pi-star", "0"]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("REJECTED"));
    assert!(
        out.join("odd.json").is_file(),
        "outputs are written before the gate"
    );
    assert_eq!(
        envelope_quick(&pairs, &out, &["--pi-star", "1", "--sigma-op", "10"])
            .status
            .code(),
        Some(0)
    );
}

#[test]
fn help_lists_the_commands_with_examples() {
    let o = fogline(&["--help"]);
    assert_eq!(o.status.code(), Some(0));
    let s = String::from_utf8(o.stdout).unwrap();
    assert!(s.contains("envelope") && s.contains("demo") && s.contains("Examples:"));
    let o = fogline(&["envelope", "--help"]);
    let s = String::from_utf8(o.stdout).unwrap();
    for flag in [
        "--budgets",
        "--rule",
        "--bootstrap",
        "--seed",
        "--k-max",
        "--restarts",
        "--n-init",
        "--bands",
        "--high-bands",
        "--pi-star",
        "--min-clips",
        "--l2",
    ] {
        assert!(s.contains(flag), "{flag}");
    }
    let o = fogline(&["envelope"]);
    assert_eq!(o.status.code(), Some(2), "usage errors exit 2");
}

#[test]
fn demo_runs_offline_and_prints_its_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let o = fogline(&["demo", "--clips", "60", "--out", out.to_str().unwrap()]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let s = String::from_utf8(o.stdout).unwrap();
    // The campaign ran on the world: 60 clips × 9 conditions, the pairs exported, the
    // analysis and the report written, and their paths printed.
    assert!(s.contains("ran 540 runs"), "{s}");
    assert!(s.contains("pairs (seed 0): 480"), "{s}");
    assert!(
        s.contains("envelope.md") && s.contains("report.html"),
        "{s}"
    );
    for f in [
        "campaign.toml",
        "campaign.sqlite",
        "runs.csv",
        "pairs.csv",
        "pairs.parquet",
        "envelope.json",
        "report.html",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // The quick closed loop ran the condition ramps too, and the report shows the guarded run.
    assert!(
        s.contains("ramps/guard") && s.contains("ramps/oracle"),
        "{s}"
    );
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        report.contains("ramps/guard"),
        "the report shows the guarded run"
    );
    assert!(
        report.contains("kept the car in override"),
        "and the guard's note"
    );
    // Made in a staging directory and committed as one set: nothing of it is left, and the
    // envelope names the table where it now is.
    assert!(!out.join(".fogline-demo.staging").exists());
    let env: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("envelope.json")).unwrap()).unwrap();
    assert_eq!(
        env["input"]["path"].as_str(),
        out.join("pairs.csv").to_str(),
        "{}",
        env["input"]
    );
}
