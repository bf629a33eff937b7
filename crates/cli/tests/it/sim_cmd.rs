//! `fogline sim compare`: two sets of runs, paired by seed and route; `fogline sim run`'s
//! bad input.

use crate::fogline;

#[test]
fn sim_compare_finds_runs_identical_across_thread_counts_and_names_a_changed_one() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (out, threads) in [(&a, "1"), (&b, "2")] {
        let o = fogline(&[
            "-q",
            "sim",
            "run",
            "--quick",
            "--deficits",
            "none",
            "--routes",
            "0,1",
            "--threads",
            threads,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // The same runs on one thread and on two: identical, wall-clock times aside.
    let o = fogline(&[
        "sim",
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--require-identical",
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("| no_deficit | 2 | 2 | 0 |"), "{out}");
    // One run's score changed after the fact: no longer identical, and its change shown.
    let path = b.join("records.jsonl");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let ds = lines[0]["score"]["driving_score"].as_f64().unwrap();
    lines[0]["score"]["driving_score"] = serde_json::json!(ds - 50.0);
    let text: String = lines.iter().map(|v| format!("{v}\n")).collect();
    std::fs::write(&path, text).unwrap();
    let o = fogline(&[
        "sim",
        "compare",
        a.to_str().unwrap(),
        path.to_str().unwrap(),
        "--json",
        "--require-identical",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let nd = &c["configs"][0];
    assert_eq!(nd["identical"], 1);
    assert_eq!(nd["ds_changed"], 1);
    assert_eq!(nd["delta"].as_f64().unwrap(), -25.0);
    // A file that is not a records file is named, with its line.
    let bad = dir.path().join("bad.jsonl");
    std::fs::write(&bad, "{\"config\": 1}\n").unwrap();
    let o = fogline(&["sim", "compare", a.to_str().unwrap(), bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("bad.jsonl") && err.contains("line 1"), "{err}");
}

#[test]
fn sim_run_ramps_names_a_bad_envelope_and_a_bad_set() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("odd.json");
    std::fs::write(&bad, "{\"kind\": \"something.else\"}").unwrap();
    // A valid envelope without the situations the ramps look up.
    let mut spec: fogline_types::odd::OddSpec =
        fogline_types::odd::OddSpec::from_json(fogline_sim::ramp::REFERENCE_ODD).unwrap();
    spec.entries.retain(|e| e.scenario != "INTERSECTION");
    let partial = dir.path().join("partial.json");
    std::fs::write(&partial, spec.to_json()).unwrap();
    for (args, expect) in [
        (
            vec!["--configs", "ramps", "--odd", bad.to_str().unwrap()],
            "--odd",
        ),
        (
            vec!["--configs", "ramps", "--odd", "/nonexistent/odd.json"],
            "/nonexistent/odd.json",
        ),
        (
            vec!["--configs", "ramps", "--odd", partial.to_str().unwrap()],
            "no entry for INTERSECTION",
        ),
        (vec!["--configs", "ramp"], "main, ablation, sweep or ramps"),
    ] {
        let mut all = vec![
            "sim",
            "run",
            "--quick",
            "--out",
            dir.path().to_str().unwrap(),
        ];
        all.extend(args);
        let o = fogline(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(expect), "{err}");
    }
}
