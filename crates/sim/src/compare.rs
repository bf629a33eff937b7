//! Two sets of runs of the same suite, compared configuration by configuration: what a
//! change to the agent, the override or the world did to each configuration's runs.
//!
//! The closed loop is chaotic: a change anywhere moves every encounter after it, so a
//! change meant for one configuration also re-draws the collisions of the others. Pairing
//! each configuration's runs by seed and route, before against after, shows how far the
//! driving score moves for a configuration whose rules did not change — the scale against
//! which an RCO-against-no-RCO difference is read — and whether a change that should not
//! alter results (a faster implementation) left every record as it was.
//!
//! ```
//! use fogline_sim::compare::compare;
//!
//! // No records: nothing to compare.
//! let c = compare(&[], &[]);
//! assert!(c.configs.is_empty());
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::experiment::{BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED, paired_bootstrap};
use crate::run::RouteRecord;
use crate::score::{collisions_per_km, infractions_per_km};

/// One configuration's runs, before against after.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConfigChange {
    /// The configuration's name.
    pub config: String,
    /// Runs present in both sets (same seed and route).
    pub pairs: usize,
    /// Pairs whose records are equal in everything the run computes (wall-clock times, the
    /// measured LLM latency and the system time built on it aside).
    pub identical: usize,
    /// Pairs whose driving score differs.
    pub ds_changed: usize,
    /// Mean driving score over the pairs: before, after.
    pub ds: [f64; 2],
    /// Mean of the per-run differences, after minus before (DS points).
    pub delta: f64,
    /// Its 95 % percentile bootstrap interval (resampling the pairs, as `fogline sim run`'s
    /// RCO-against-no-RCO interval does).
    pub ci95: [f64; 2],
    /// Collisions (vehicles, pedestrians, layout) per km over the pairs: before, after.
    pub collisions_per_km: [f64; 2],
}

/// Two sets of runs compared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    /// Per configuration present in both, in the order of the first set.
    pub configs: Vec<ConfigChange>,
    /// Runs found in only one set: before, after.
    pub unpaired: [usize; 2],
}

impl Comparison {
    /// Whether every run is in both sets and every pair is identical.
    pub fn all_identical(&self) -> bool {
        self.unpaired == [0, 0] && self.configs.iter().all(|c| c.identical == c.pairs)
    }

    /// The comparison as a Markdown table (what `fogline sim compare` prints).
    pub fn markdown(&self) -> String {
        let mut s = String::from(
            "| Configuration | Pairs | Identical | DS changed | DS before → after | ΔDS | 95 % CI | Collisions per km |\n|---|---|---|---|---|---|---|---|\n",
        );
        for k in &self.configs {
            s += &format!(
                "| {} | {} | {} | {} | {:.2} → {:.2} | {:+.2} | [{:+.2}, {:+.2}] | {:.2} → {:.2} |\n",
                k.config,
                k.pairs,
                k.identical,
                k.ds_changed,
                k.ds[0],
                k.ds[1],
                k.delta,
                k.ci95[0],
                k.ci95[1],
                k.collisions_per_km[0],
                k.collisions_per_km[1]
            );
        }
        if self.unpaired != [0, 0] {
            s += &format!(
                "\n{} run(s) only before, {} only after (not compared).\n",
                self.unpaired[0], self.unpaired[1]
            );
        }
        s
    }
}

/// A record with what is not computed by the run (wall-clock times, measured latency) set
/// to zero, so that equal runs compare equal.
fn computed_part(r: &RouteRecord) -> RouteRecord {
    let mut r = r.clone();
    r.wall_s = 0.0;
    r.wall_parts_s = [0.0; 4];
    r.system_time_s = 0.0;
    for p in &mut r.timeline {
        p[3] = 0.0;
    }
    if let Some(s) = r.rco.as_mut() {
        s.llm_latency_ms = 0.0;
    }
    r
}

/// Compares two sets of runs configuration by configuration, pairing runs by seed and
/// route.
pub fn compare(before: &[RouteRecord], after: &[RouteRecord]) -> Comparison {
    let index = |rs: &'_ [RouteRecord]| -> BTreeMap<(String, u64, usize), usize> {
        rs.iter()
            .enumerate()
            .map(|(i, r)| ((r.config.clone(), r.seed, r.route), i))
            .collect()
    };
    let (ib, ia) = (index(before), index(after));
    let mut order: Vec<&str> = Vec::new();
    for r in before {
        if !order.contains(&r.config.as_str()) {
            order.push(&r.config);
        }
    }
    let mut configs = Vec::new();
    for name in order {
        let pairs: Vec<(&RouteRecord, &RouteRecord)> = ib
            .iter()
            .filter(|((c, _, _), _)| c == name)
            .filter_map(|(k, &i)| ia.get(k).map(|&j| (&before[i], &after[j])))
            .collect();
        if pairs.is_empty() {
            continue;
        }
        let n = pairs.len();
        let d: Vec<f64> = pairs
            .iter()
            .map(|(b, a)| a.score.driving_score - b.score.driving_score)
            .collect();
        let Some((delta, ci95)) = paired_bootstrap(&d, BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED) else {
            continue;
        };
        let mean = |f: &dyn Fn(&(&RouteRecord, &RouteRecord)) -> f64| {
            pairs.iter().map(f).sum::<f64>() / n as f64
        };
        let collisions = |after: bool| {
            let routes: Vec<_> = pairs
                .iter()
                .map(|&(b, a)| {
                    let r = if after { a } else { b };
                    (r.events.as_slice(), r.score.route_completion, r.length_m)
                })
                .collect();
            collisions_per_km(&infractions_per_km(&routes))
        };
        configs.push(ConfigChange {
            config: name.to_string(),
            pairs: n,
            identical: pairs
                .iter()
                .filter(|(b, a)| computed_part(b) == computed_part(a))
                .count(),
            ds_changed: d.iter().filter(|x| x.abs() > 1e-9).count(),
            ds: [
                mean(&|(b, _)| b.score.driving_score),
                mean(&|(_, a)| a.score.driving_score),
            ],
            delta,
            ci95,
            collisions_per_km: [collisions(false), collisions(true)],
        });
    }
    let missing = |from: &BTreeMap<(String, u64, usize), usize>,
                   other: &BTreeMap<(String, u64, usize), usize>| {
        from.keys().filter(|k| !other.contains_key(*k)).count()
    };
    Comparison {
        configs,
        unpaired: [missing(&ib, &ia), missing(&ia, &ib)],
    }
}

/// Reads the runs of `fogline sim run --out DIR`: `path` is that directory or its
/// `records.jsonl`. A line that is not a run record is an error naming the file and line.
pub fn read_records(path: &Path) -> Result<Vec<RouteRecord>, SimError> {
    let file = if path.is_dir() {
        path.join("records.jsonl")
    } else {
        path.to_path_buf()
    };
    let text = std::fs::read_to_string(&file).map_err(|source| SimError::Read {
        path: file.display().to_string(),
        source,
    })?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let r: RouteRecord = serde_json::from_str(line).map_err(|e| SimError::Records {
            file: file.display().to_string(),
            line: i + 1,
            message: e.to_string(),
        })?;
        out.push(r);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::score::{Event, EventKind, RouteScore, ScoringParams};

    fn record(config: &str, seed: u64, route: usize, events: Vec<Event>) -> RouteRecord {
        let line = format!(
            r#"{{"config":"{config}","route":{route},"town":0,"seed":{seed},"length_m":1000.0,
            "weather":"cloudy","daylight":"noon",
            "score":{{"route_completion":100.0,"infraction_score":1.0,"driving_score":100.0}},
            "termination":"completed","game_time_s":300.0,"system_time_s":300.0,
            "avg_speed_mps":3.3,"odometer_m":1000.0,"events":[],
            "signals":{{"approaches":0,"red_encounters":0,"stopped_at_red":0,"crossed_on_red":0}},
            "deficit_s":0.0,"takeover_s":0.0,"rco":null,"unstick":0,"plans":10,
            "crossing_events":0,"timeline":[[0.5,1.0,0.0,0.0]],"wall_s":1.0,
            "wall_parts_s":[0.5,0.3,0.1,0.1]}}"#
        );
        let mut r: RouteRecord = serde_json::from_str(&line).expect("a valid record");
        r.score = RouteScore::of(100.0, &events, &ScoringParams::default());
        r.events = events;
        r
    }

    #[test]
    fn runs_are_paired_by_seed_and_route_and_wall_clock_times_do_not_count() {
        let hit = |t| vec![Event::new(EventKind::CollisionPedestrian, t, 0.0, 0.0)];
        let before = vec![
            record("no_deficit", 0, 0, vec![]),
            record("no_deficit", 0, 1, hit(10.0)),
            record("no_deficit", 1, 0, vec![]),
            record("pedestrian/rco", 0, 0, vec![]),
            record("pedestrian/rco", 0, 1, vec![]),
        ];
        let mut after = before.clone();
        // The same runs, timed differently: identical.
        for r in &mut after {
            r.wall_s = 9.0;
            r.wall_parts_s = [1.0; 4];
            r.timeline[0][3] = 55.0;
        }
        // No-deficit route 1 now misses its walker; route 0 of seed 1 did not run; a
        // pedestrian-deficit run hits one and another differs only in its game time.
        after[1] = record("no_deficit", 0, 1, vec![]);
        after.remove(2);
        after[2].events = hit(20.0);
        after[2].score = RouteScore::of(100.0, &after[2].events, &ScoringParams::default());
        after[3].game_time_s = 301.0;
        after.push(record("bicycle/rco", 0, 0, vec![]));
        let c = compare(&before, &after);
        assert_eq!(c.unpaired, [1, 1]);
        assert!(!c.all_identical());
        let nd = &c.configs[0];
        assert_eq!(
            (nd.config.as_str(), nd.pairs, nd.identical),
            ("no_deficit", 2, 1)
        );
        assert_eq!(nd.ds_changed, 1);
        assert_eq!(nd.ds, [75.0, 100.0]);
        assert!((nd.delta - 25.0).abs() < 1e-12);
        assert!(nd.ci95[0] >= 0.0 && nd.ci95[1] <= 50.0 && nd.ci95[0] < nd.ci95[1]);
        // One collision over 2 km before, none after.
        assert_eq!(nd.collisions_per_km, [0.5, 0.0]);
        let ped = &c.configs[1];
        assert_eq!((ped.pairs, ped.identical, ped.ds_changed), (2, 0, 1));
        assert_eq!(ped.ds, [100.0, 75.0]);
        assert_eq!(ped.collisions_per_km, [0.0, 0.5]);
        // Only the first set's configurations, in its order.
        assert_eq!(c.configs.len(), 2);
        let md = c.markdown();
        assert!(
            md.contains("| no_deficit | 2 | 1 | 1 | 75.00 → 100.00 | +25.00 |"),
            "{md}"
        );
        assert!(md.contains("1 run(s) only before, 1 only after"), "{md}");
        // A set against itself, re-timed, is identical throughout.
        let mut again = before.clone();
        again[0].wall_s = 3.0;
        assert!(compare(&before, &again).all_identical());
    }

    #[test]
    fn a_bad_records_line_is_named_by_file_and_line() {
        let dir = std::env::temp_dir().join(format!("fogline-compare-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let good = serde_json::to_string(&record("no_deficit", 0, 0, vec![])).expect("json");
        std::fs::write(
            dir.join("records.jsonl"),
            format!("{good}\n\n{{\"config\":3}}\n"),
        )
        .expect("write");
        let err = read_records(&dir)
            .expect_err("line 3 is no record")
            .to_string();
        assert!(
            err.contains("records.jsonl") && err.contains("line 3"),
            "{err}"
        );
        std::fs::write(dir.join("records.jsonl"), format!("{good}\n")).expect("write");
        assert_eq!(read_records(&dir).expect("reads").len(), 1);
        let missing = read_records(&dir.join("nope.jsonl")).expect_err("no such file");
        assert!(missing.to_string().contains("nope.jsonl"), "{missing}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
