//! Building: determinism across thread counts, splits without leakage, the exports'
//! structure.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use fogline_dataset::sample::{Manifest, read_samples};
use fogline_dataset::{BuildParams, Split, build};
use serde_json::Value;

use crate::small_set;

/// Every file under `dir` (relative path → bytes).
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

#[test]
fn the_same_seed_gives_the_same_bytes_on_any_thread_count() {
    let (a, b, c) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    let p = |threads, seed| BuildParams {
        samples: 8,
        seed,
        threads,
        ..BuildParams::default()
    };
    build(&p(1, 3), a.path()).unwrap();
    build(&p(2, 3), b.path()).unwrap();
    build(&p(2, 4), c.path()).unwrap();
    let (fa, fb, fc) = (files(a.path()), files(b.path()), files(c.path()));
    assert!(fa.len() > 8 * 15, "{} files", fa.len());
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    for (k, v) in &fa {
        assert!(fb[k] == *v, "{k} differs between 1 and 2 threads");
    }
    assert_ne!(
        fa["samples.jsonl"], fc["samples.jsonl"],
        "another seed, other samples"
    );
    // No staging directory is left behind.
    assert!(!fa.keys().any(|k| k.contains("staging")));
}

#[test]
fn no_clip_or_town_is_in_two_splits_and_classes_are_balanced() {
    let dir = small_set();
    let samples = read_samples(dir).unwrap();
    assert_eq!(samples.len(), 32);
    let mut ids = BTreeSet::new();
    let mut town_split: BTreeMap<u64, Split> = BTreeMap::new();
    for s in &samples {
        assert!(ids.insert(s.id.clone()), "{} twice", s.id);
        let prev = town_split.insert(s.town, s.split);
        assert!(
            prev.is_none_or(|p| p == s.split),
            "town {} in two splits",
            s.town
        );
        // Every image of the clip is its own.
        for f in &s.frames {
            for v in &f.views {
                assert!(v.image.starts_with(&format!("images/{}/", s.id)));
            }
        }
        assert_eq!(s.frames.len(), 5);
        assert!(!s.frames[4].views.iter().all(|v| v.deficits.is_empty()));
    }
    let per_split: BTreeMap<Split, usize> = samples.iter().fold(BTreeMap::new(), |mut m, s| {
        *m.entry(s.split).or_default() += 1;
        m
    });
    // 8 towns of 4 clips at 0.5 / 0.25 / 0.25: exactly 16 / 8 / 8.
    assert_eq!(per_split[&Split::Train], 16);
    assert_eq!(per_split[&Split::Val], 8);
    assert_eq!(per_split[&Split::Test], 8);
    let m = Manifest::read(dir).unwrap();
    for class in ["traffic_light", "traffic_sign", "pedestrian", "bicycle"] {
        let c = &m.counts["all"].by_class[class];
        assert_eq!(c.samples, 8, "{class}");
        assert_eq!(c.move_ + c.stop_observe_move, 8);
    }
    let balance = std::fs::read_to_string(dir.join("balance.md")).unwrap();
    assert!(balance.contains("| pedestrian | 8 |"), "{balance}");
}

#[test]
fn sharegpt_files_follow_llama_factory_structure() {
    let dir = small_set();
    let info: Value =
        serde_json::from_slice(&std::fs::read(dir.join("dataset_info.json")).unwrap()).unwrap();
    let entries = info.as_object().unwrap();
    assert_eq!(entries.len(), 12, "3 splits x 4 tasks");
    for (name, e) in entries {
        assert_eq!(e["formatting"], "sharegpt", "{name}");
        assert_eq!(e["columns"]["messages"], "messages");
        assert_eq!(e["columns"]["images"], "images");
        let file = dir.join(e["file_name"].as_str().unwrap());
        let records: Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
        let records = records.as_array().unwrap();
        assert!(!records.is_empty(), "{name}");
        for r in records {
            let msgs = r["messages"].as_array().unwrap();
            assert_eq!(msgs.len(), 2);
            assert_eq!(msgs[0]["role"], "user");
            assert_eq!(msgs[1]["role"], "assistant");
            let images = r["images"].as_array().unwrap();
            assert_eq!(images.len(), 15, "three views x five frames");
            let tokens = msgs[0]["content"]
                .as_str()
                .unwrap()
                .matches("<image>")
                .count();
            assert_eq!(tokens, images.len(), "{name}: <image> tokens = images");
            assert_eq!(
                msgs[1]["content"]
                    .as_str()
                    .unwrap()
                    .matches("<image>")
                    .count(),
                0
            );
            for i in images {
                assert!(dir.join(i.as_str().unwrap()).is_file(), "{i}");
            }
        }
        if name.ends_with("_joint") {
            // The joint answer is valid for the controller's own parser.
            let a = records[0]["messages"][1]["content"].as_str().unwrap();
            fogline_rco::backend::answer::parse_hazard(a, &fogline_dataset::observe::VIEWS)
                .unwrap();
        }
    }
    let qa: Value =
        serde_json::from_slice(&std::fs::read(dir.join("drivelm_qa.json")).unwrap()).unwrap();
    let first = qa.as_object().unwrap().values().next().unwrap();
    assert!(
        first["QA"]["planning"][0]["Q"]
            .as_str()
            .unwrap()
            .contains("brake")
    );
    assert!(!first["key_object_infos"].as_object().unwrap().is_empty());
}

#[test]
fn bad_parameters_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let e = build(
        &BuildParams {
            split_fractions: [0.5, 0.5, 0.5],
            ..BuildParams::default()
        },
        dir.path(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("split fractions"), "{e}");
    let e = Manifest::read(dir.path()).unwrap_err();
    assert!(e.to_string().contains("manifest.json"), "{e}");
}
