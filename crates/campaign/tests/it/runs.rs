//! Runs against the built-in planner and against misbehaving in-process planners.

use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use fogline_campaign::runner::Silent;
use fogline_campaign::store::Outcome;
use fogline_campaign::{
    BuiltinPlanner, Campaign, CampaignConfig, RunOptions, Shard, Store, merge, run, run_options,
};
use fogline_remote::{FailureKind, PlanFailure, PlanRequest, Planner};
use fogline_types::clip::{PlannerOutput, Trajectory};

fn config(extra: &str) -> CampaignConfig {
    CampaignConfig::from_toml(&format!(
        "[clips]\ncount = 6\nseed = 3\nwidth = 192\nheight = 108\n\
         [conditions]\nnames = [\"noise_30\", \"fog_07\", \"dark\"]\n{extra}"
    ))
    .unwrap()
}

fn with_conditions(names: &[&str], seeds: &[u64]) -> CampaignConfig {
    CampaignConfig {
        conditions: fogline_campaign::config::ConditionsConfig {
            names: names.iter().map(|s| s.to_string()).collect(),
            seeds: seeds.to_vec(),
        },
        ..config("")
    }
}

fn run_into(cfg: &CampaignConfig, store: &Path, shard: Shard, workers: usize) -> usize {
    let campaign = Campaign::new(cfg.clone()).unwrap();
    let mut s = if store.exists() {
        Store::resume(store, &campaign.store_meta(shard)).unwrap()
    } else {
        Store::create(store, &campaign.store_meta(shard)).unwrap()
    };
    let mut opts = run_options(cfg, shard);
    opts.concurrency = workers;
    let summary = run(&campaign, &mut s, &BuiltinPlanner::new(), &opts, &Silent).unwrap();
    summary.ran
}

fn exported(store: &Path, dir: &Path) -> Vec<(String, Vec<u8>)> {
    let runs = Store::open(store).unwrap().runs().unwrap();
    crate::export_all(&runs, dir)
        .files
        .iter()
        .map(|f| {
            (
                f.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(f).unwrap(),
            )
        })
        .collect()
}

#[test]
fn a_campaign_is_complete_deterministic_and_independent_of_workers() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config("");
    let a = dir.path().join("a.sqlite");
    let b = dir.path().join("b.sqlite");
    assert_eq!(run_into(&cfg, &a, Shard::ALL, 1), 6 * 4);
    assert_eq!(run_into(&cfg, &b, Shard::ALL, 3), 6 * 4);
    let ea = exported(&a, &dir.path().join("ea"));
    let eb = exported(&b, &dir.path().join("eb"));
    assert_eq!(ea.len(), 4, "runs and pairs, csv and parquet");
    assert_eq!(ea, eb, "1 and 3 workers export the same bytes");
    // The pairs table: 6 clips × 3 perturbed conditions, in the envelope's column contract.
    let pairs =
        String::from_utf8(ea.iter().find(|(n, _)| n == "pairs.csv").unwrap().1.clone()).unwrap();
    let mut lines = pairs.lines();
    let header = lines.next().unwrap();
    for col in [
        "clip_id",
        "scenario",
        "condition",
        "ade_clean",
        "ade_attacked",
        "l2",
        "coc_clean",
        "coc_attacked",
    ] {
        assert!(header.split(',').any(|h| h == col), "{col} in {header}");
    }
    assert_eq!(lines.count(), 18);
    // Every stored run has a finite ADE and 64 waypoints.
    let runs = Store::open(&a).unwrap().runs().unwrap();
    for r in &runs {
        let Outcome::Ok {
            trajectory, ade_m, ..
        } = &r.outcome
        else {
            panic!("{r:?}");
        };
        assert_eq!(trajectory.len(), 64);
        assert!(ade_m.is_finite());
    }
}

#[test]
fn resume_does_not_redo_finished_runs_and_a_changed_config_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config("");
    let store = dir.path().join("s.sqlite");
    assert_eq!(run_into(&cfg, &store, Shard::ALL, 2), 24);
    assert_eq!(
        run_into(&cfg, &store, Shard::ALL, 2),
        0,
        "nothing left to do"
    );
    // Creating over an existing store is refused.
    let campaign = Campaign::new(cfg.clone()).unwrap();
    let e = Store::create(&store, &campaign.store_meta(Shard::ALL))
        .unwrap_err()
        .to_string();
    assert!(e.contains("--resume"), "{e}");
    // A different configuration is refused, naming what changed.
    let mut other = cfg.clone();
    other.clips.count = Some(7);
    let c2 = Campaign::new(other).unwrap();
    let e = Store::resume(&store, &c2.store_meta(Shard::ALL))
        .unwrap_err()
        .to_string();
    assert!(e.contains("clips.count 6 → 7"), "{e}");
    // Another shard of the same configuration too.
    let e = Store::resume(&store, &campaign.store_meta(Shard::parse("1/2").unwrap()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("shard"), "{e}");
    // Settings that do not change results do not change the hash.
    let mut faster = cfg.clone();
    faster.run.concurrency = 9;
    assert_eq!(run_into(&faster, &store, Shard::ALL, 2), 0);
}

#[test]
fn three_shards_merged_equal_one_unsharded_run() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = with_conditions(&["noise_50", "bright"], &[0, 5]);
    let whole = dir.path().join("whole.sqlite");
    run_into(&cfg, &whole, Shard::ALL, 2);
    let mut parts = Vec::new();
    for i in 0..3 {
        let p = dir.path().join(format!("part{i}.sqlite"));
        run_into(&cfg, &p, Shard { index: i, count: 3 }, 2);
        parts.push(p);
    }
    // Two shards are not the campaign; a shard twice is refused.
    let partial = merge::merge(&dir.path().join("partial.sqlite"), &parts[..2]).unwrap();
    assert!(!partial.complete());
    let e = merge::merge(
        &dir.path().join("dup.sqlite"),
        &[parts[0].clone(), parts[0].clone()],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("also in"), "{e}");
    let merged = dir.path().join("merged.sqlite");
    let m = merge::merge(&merged, &parts).unwrap();
    assert!(m.complete());
    assert_eq!(m.runs, 6 * 3 * 2);
    let a = exported(&whole, &dir.path().join("e1"));
    let b = exported(&merged, &dir.path().join("e2"));
    assert_eq!(
        a.len(),
        6,
        "runs + pairs for each of 2 seeds, csv and parquet"
    );
    assert_eq!(a, b);
    // The merged store is a whole campaign: resuming it finds nothing to do.
    assert_eq!(run_into(&cfg, &merged, Shard::ALL, 2), 0);
    // A store of another campaign does not merge.
    let mut cfg2 = config("");
    cfg2.clips.seed = 4;
    let foreign = dir.path().join("foreign.sqlite");
    run_into(&cfg2, &foreign, Shard { index: 2, count: 3 }, 1);
    let e = merge::merge(&dir.path().join("x.sqlite"), &[parts[0].clone(), foreign])
        .unwrap_err()
        .to_string();
    assert!(e.contains("different campaign configuration"), "{e}");
}

/// A planner that misbehaves by scene: errors, NaN, wrong waypoint counts, and transient
/// failures that succeed on a retry.
struct Flaky {
    calls: AtomicUsize,
    seen: Mutex<std::collections::HashMap<String, usize>>,
}

impl Planner for Flaky {
    fn describe(&self) -> String {
        "flaky".into()
    }
    fn plan(&self, r: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        self.calls.fetch_add(1, Ordering::Relaxed);
        let key = {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            r.input.cameras[0].frames[0].hash(&mut h);
            format!("{}/{}", r.scene_id, h.finish())
        };
        let n = {
            let mut seen = self.seen.lock().unwrap();
            let e = seen.entry(key).or_default();
            *e += 1;
            *e
        };
        let ok = |n: usize, v: f64| PlannerOutput {
            trajectory: Trajectory {
                xy: (1..=n).map(|i| [v * i as f64, 0.0]).collect(),
            },
            explanation: "Keep lane.".into(),
            decision: None,
        };
        let idx: usize = r.scene_id.rsplit('_').next().unwrap().parse().unwrap();
        match idx % 6 {
            0 => Ok(ok(64, 0.5)),
            1 => Err(PlanFailure::new(FailureKind::Remote, "status 500: boom")),
            2 => Ok(ok(64, f64::NAN)),
            3 => Ok(ok(10, 0.5)),
            4 if n == 1 => Err(PlanFailure::new(
                FailureKind::Unavailable,
                "connection reset",
            )),
            4 => Ok(ok(64, 0.4)),
            _ => Err(PlanFailure::new(
                FailureKind::InvalidAnswer,
                "garbage bytes",
            )),
        }
    }
}

#[test]
fn failures_are_recorded_with_reasons_retried_when_transient_and_excluded_from_pairs() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = with_conditions(&["noise_30"], &[0]);
    let campaign = Campaign::new(cfg.clone()).unwrap();
    let path = dir.path().join("f.sqlite");
    let mut store = Store::create(&path, &campaign.store_meta(Shard::ALL)).unwrap();
    let opts = RunOptions {
        retries: 2,
        backoff: std::time::Duration::from_millis(1),
        per_clip: false,
        ..run_options(&cfg, Shard::ALL)
    };
    let planner = Flaky {
        calls: AtomicUsize::new(0),
        seen: Mutex::new(Default::default()),
    };
    let s = run(&campaign, &mut store, &planner, &opts, &Silent).unwrap();
    assert_eq!(s.ran, 12, "every run is recorded");
    let runs = store.runs().unwrap();
    let kind_of = |clip: usize| -> Vec<(String, u32)> {
        runs.iter()
            .filter(|r| r.clip_index as usize == clip)
            .map(|r| match &r.outcome {
                Outcome::Ok { .. } => ("ok".to_string(), r.attempts),
                Outcome::Failed { kind, .. } => (kind.clone(), r.attempts),
            })
            .collect()
    };
    assert_eq!(kind_of(0), vec![("ok".into(), 1); 2]);
    assert_eq!(
        kind_of(1),
        vec![("remote_error".into(), 3); 2],
        "retried twice"
    );
    assert_eq!(
        kind_of(2),
        vec![("invalid_answer".into(), 1); 2],
        "NaN is not retried"
    );
    assert_eq!(
        kind_of(3),
        vec![("invalid_answer".into(), 1); 2],
        "10 waypoints"
    );
    assert_eq!(
        kind_of(4),
        vec![("ok".into(), 2); 2],
        "a transient failure retried"
    );
    assert_eq!(kind_of(5), vec![("invalid_answer".into(), 1); 2]);
    let nan = runs.iter().find(|r| r.clip_index == 2).unwrap();
    let Outcome::Failed { reason, .. } = &nan.outcome else {
        panic!()
    };
    assert!(
        reason.contains("finite") || reason.contains("NaN"),
        "{reason}"
    );
    assert_eq!(planner.calls.load(Ordering::Relaxed), 2 + 6 + 2 + 2 + 4 + 2);
    // Pairs: clips 0 and 4 only; the rest are counted as excluded.
    let (t, counts) = fogline_campaign::export::pairs_table(&runs, 0);
    assert_eq!(t.rows(), 2);
    assert_eq!(counts.pairs, 2);
    assert_eq!(counts.attacked_failed, 4);
    // Retrying failed runs: delete them and run again.
    assert_eq!(store.delete_failed().unwrap(), 8);
    let s = run(&campaign, &mut store, &planner, &opts, &Silent).unwrap();
    assert_eq!((s.skipped, s.ran), (4, 8));
}

#[test]
fn the_builtin_planner_answers_the_same_from_only_the_cameras_it_uses() {
    let cfg = config("");
    let campaign = Campaign::new(cfg).unwrap();
    let planner = BuiltinPlanner::new();
    let used = planner.cameras().unwrap();
    for i in 0..3 {
        let full = campaign.clips.load(i, None).unwrap();
        let part = campaign.clips.load(i, Some(&used)).unwrap();
        assert_eq!(full.cameras.len(), 4);
        assert_eq!(part.cameras.len(), 2);
        for p in ["clean", "noise_30"] {
            let prepared = fogline_perturb::Perturbation::parse(p)
                .unwrap()
                .prepare(0)
                .unwrap();
            let answer = |clip: &fogline_world::Clip| {
                let frames =
                    fogline_campaign::runner::condition_frames(clip, i as u64, &prepared).unwrap();
                let input = fogline_campaign::runner::planner_input(clip, &frames);
                let req = PlanRequest {
                    scene_id: &clip.id,
                    seed: 0,
                    input,
                };
                Planner::plan(&planner, &req).unwrap()
            };
            assert_eq!(answer(&full), answer(&part), "clip {i}, {p}");
        }
    }
}

#[test]
fn clips_read_from_a_directory_run_like_the_generated_ones() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config("");
    let world = Campaign::new(cfg.clone()).unwrap();
    let clips = dir.path().join("clips");
    for i in 0..world.clips.len() {
        fogline_world::write_clip(&clips, &world.clips.load(i, None).unwrap()).unwrap();
    }
    std::fs::write(
        dir.path().join("dir.toml"),
        "[clips]\nsource = \"dir\"\npath = \"clips\"\n\
         [conditions]\nnames = [\"noise_30\"]\n",
    )
    .unwrap();
    let dcfg = CampaignConfig::from_file(&dir.path().join("dir.toml")).unwrap();
    let from_dir = dir.path().join("dir.sqlite");
    assert_eq!(run_into(&dcfg, &from_dir, Shard::ALL, 2), 6 * 2);
    let generated = dir.path().join("gen.sqlite");
    run_into(&cfg, &generated, Shard::ALL, 2);
    // Clean runs need no random draw: the same clip gives the same answer from either source.
    let clean = |p: &Path| {
        let mut v: Vec<_> = Store::open(p)
            .unwrap()
            .runs()
            .unwrap()
            .into_iter()
            .filter(|r| r.condition == "clean")
            .map(|r| (r.clip_id.clone(), r.scenario.clone(), r.outcome.clone()))
            .collect();
        v.sort_by(|a, b| a.0.cmp(&b.0));
        v
    };
    assert_eq!(clean(&from_dir), clean(&generated));
    // The directory's clip list is part of the identity: a new clip changes the campaign.
    let c1 = Campaign::new(dcfg.clone()).unwrap();
    let extra = world.clips.load(0, None).unwrap();
    let extra = fogline_world::Clip {
        id: "zz_extra".into(),
        ..extra
    };
    fogline_world::write_clip(&clips, &extra).unwrap();
    let c2 = Campaign::new(dcfg).unwrap();
    assert_ne!(c1.hash, c2.hash);
    assert_eq!(c2.clips.len(), 7);
    // An empty directory is a clear error.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let e = Campaign::new(
        CampaignConfig::from_toml(&format!(
            "[clips]\nsource = \"dir\"\npath = {:?}\n",
            empty.display().to_string()
        ))
        .unwrap(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("holds no clip directories"), "{e}");
}
