//! `fogline planner eval` and `fogline bench world` as a user runs them.

use std::process::{Command, Output};

use serde_json::Value;

fn fogline(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(args)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A share in [0, 1], or null.
fn check_share(v: &Value, what: &str) {
    if let Some(x) = v.as_f64() {
        assert!((0.0..=1.0).contains(&x), "{what} = {x}");
    } else {
        assert!(v.is_null(), "{what} = {v}");
    }
}

fn check_row(row: &Value, reference: bool) {
    let n = row["n"].as_u64().unwrap();
    let answered = row["answered"].as_u64().unwrap();
    assert_eq!(answered + row["failed"].as_u64().unwrap(), n, "{row}");
    for key in ["ade_median_m", "ade_mean_m"] {
        if answered > 0 {
            let ade = row[key].as_f64().unwrap();
            assert!(ade.is_finite() && ade >= 0.0, "{key} = {ade}");
        } else {
            assert!(row[key].is_null());
        }
    }
    check_share(&row["agreement"], "agreement");
    if answered > 0 {
        assert!(row["agreement"].is_f64(), "{row}");
    }
    check_share(&row["explanation_changed"], "explanation_changed");
    let l2 = &row["l2_vs_clean_mean_m"];
    if reference {
        assert!(
            l2.is_null() && row["explanation_changed"].is_null(),
            "{row}"
        );
    } else if let Some(l2) = l2.as_f64() {
        assert!(l2.is_finite() && l2 >= 0.0, "{row}");
    }
}

#[test]
fn eval_writes_every_figure() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("eval.json");
    let o = fogline(&[
        "planner",
        "eval",
        "--clips",
        "16",
        "--conditions",
        "clean,noise_70",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("condition clean (reference)"), "{out}");
    assert!(out.contains("condition noise_70"), "{out}");
    assert!(out.contains("decisions, clean"), "{out}");
    assert!(out.contains("all scenarios, by condition"), "{out}");

    let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v["kind"], "fogline.planner_eval");
    assert_eq!(v["schema_version"], 1);
    assert_eq!(v["clips"], 16);
    let mix: Vec<&str> = v["mix"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["scenario"].as_str().unwrap())
        .collect();
    assert_eq!(mix.len(), 8, "the paper mix has every scenario at 16 clips");
    let conditions = v["conditions"].as_array().unwrap();
    let names: Vec<&str> = conditions
        .iter()
        .map(|c| c["condition"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["clean", "noise_70"]);
    for c in conditions {
        let reference = c["reference"].as_bool().unwrap();
        let rows = c["scenarios"].as_array().unwrap();
        let scen: Vec<&str> = rows
            .iter()
            .map(|r| r["scenario"].as_str().unwrap())
            .collect();
        assert_eq!(scen, mix, "rows follow the mix order");
        let total: u64 = rows.iter().map(|r| r["n"].as_u64().unwrap()).sum();
        assert_eq!(total, 16);
        for r in rows {
            check_row(r, reference);
        }
        assert_eq!(c["overall"]["scenario"], "ALL");
        assert_eq!(c["overall"]["n"], 16);
        check_row(&c["overall"], reference);
        let median = &c["plan_time"]["median_ms"];
        assert!(median.as_f64().is_some_and(|m| m.is_finite() && m >= 0.0));
        let failed = failed_clips(c);
        assert_eq!(failed, c["overall"]["failed"].as_u64().unwrap());
    }
    // The reference planner answers on the clean clips.
    assert!(
        conditions[0]["overall"]["answered"].as_u64().unwrap() > 0,
        "{}",
        conditions[0]["failures"]
    );
    let cells: u64 = v["clean_confusion"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["clips"].as_u64().unwrap())
        .sum();
    assert_eq!(cells, 16);
}

#[test]
fn eval_figures_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let run = |threads: &str| {
        let json = dir.path().join(format!("eval-{threads}.json"));
        let o = fogline(&[
            "--threads",
            threads,
            "planner",
            "eval",
            "--clips",
            "4",
            "--conditions",
            "noise_30",
            "--json",
            json.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let mut v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        // Timings and the thread count are the only things allowed to differ.
        for c in v["conditions"].as_array_mut().unwrap() {
            c["plan_time"] = Value::Null;
        }
        v["wall_s"] = Value::Null;
        v["threads"] = Value::Null;
        v
    };
    assert_eq!(run("1"), run("2"));
}

#[test]
fn eval_refuses_bad_input() {
    let o = fogline(&["planner", "eval", "--clips", "4", "--conditions", "bogus_1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("--conditions") && e.contains("bogus_1") && e.contains("unknown condition"),
        "{e}"
    );

    let o = fogline(&["planner", "eval", "--clips", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--clips must be at least 1"),
        "{}",
        stderr(&o)
    );

    let o = fogline(&[
        "planner",
        "eval",
        "--clips",
        "4",
        "--conditions",
        "dark,dark",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("listed twice"), "{}", stderr(&o));
}

#[test]
fn bench_world_prints_parsable_figures() {
    let o = fogline(&["bench", "world", "--clips", "8", "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    let w = &v["world"];
    assert_eq!(w["clips"], 8);
    assert_eq!(
        (w["width"].as_u64(), w["height"].as_u64()),
        (Some(576), Some(320))
    );
    for key in [
        "wall_s",
        "clips_per_s",
        "ms_per_clip",
        "projected_1996_clips_s",
    ] {
        let x = w[key].as_f64().unwrap();
        assert!(x.is_finite() && x > 0.0, "{key} = {x}");
    }
    assert_eq!(w["goal_s"], 60.0);
    assert!(w["met"].is_boolean());
    // The planner is timed clean and under the default noise_30, in that order.
    let rows = v["planner"].as_array().unwrap();
    let names: Vec<&str> = rows
        .iter()
        .map(|p| p["condition"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["clean", "noise_30"]);
    for p in rows {
        assert_eq!(p["clips"], 8);
        assert_eq!(p["threads"], 1);
        assert_eq!(p["goal_ms"], 5.0);
        let answered = p["answered"].as_u64().unwrap();
        if answered > 0 {
            let (median, p95) = (
                p["median_ms"].as_f64().unwrap(),
                p["p95_ms"].as_f64().unwrap(),
            );
            assert!(median > 0.0 && median <= p95 && p95.is_finite());
        }
        assert_eq!(answered + failed_clips(p), 8);
    }

    let o = fogline(&["bench", "world", "--clips", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// The clips counted in a report row's `failures` list.
fn failed_clips(row: &Value) -> u64 {
    row["failures"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["clips"].as_u64().unwrap())
        .sum()
}
