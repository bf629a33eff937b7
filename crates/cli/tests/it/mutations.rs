//! Mutation tests of the input formats fogline reads (docs/security.md): random byte flips,
//! insertions, deletions, truncations, duplicated chunks and huge numbers applied to valid
//! inputs — a campaign configuration (TOML), a sim suite (JSON and TOML), recorded
//! observations (JSON Lines, then driven through the controller), LLM answers of every task,
//! frames given to `fogline perturb` (JPEG and PNG), a clip on disk (its JSON metadata and
//! PNG frames), and the PhysicalAI-AV import's readers: MP4 videos decoded through ffmpeg
//! (index first and last), egomotion and timestamp Parquet, `features.csv`, the scenario
//! labels, chunk zips, and whole imports from a mutated zip. Each mutant must give a clear
//! error or a valid result: never a panic.
//! Deterministic (fixed seeds) and bounded: a few thousand mutants in all. The envelope
//! readers (CSV, Parquet, JSONL) have their own mutation properties in `fogline-envelope`, the
//! servers theirs (mutated requests sent to live servers, in `fogline-remote`).

use std::panic::{AssertUnwindSafe, catch_unwind};

use fogline_types::clip::CameraId;

/// SplitMix64: the mutants are random yet reproducible.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// One to three random edits of `input`.
fn mutate(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut v = input.to_vec();
    for _ in 0..1 + rng.below(3) {
        let at = rng.below(v.len() + 1);
        match rng.below(6) {
            0 if !v.is_empty() => {
                let i = at.min(v.len() - 1);
                v[i] = rng.next() as u8;
            }
            1 => {
                let n = 1 + rng.below(8);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                v.splice(at..at, bytes);
            }
            2 => {
                let end = (at + 1 + rng.below(16)).min(v.len());
                v.drain(at.min(end)..end);
            }
            3 => v.truncate(at),
            4 if !v.is_empty() => {
                let start = rng.below(v.len());
                let end = (start + 1 + rng.below(32)).min(v.len());
                let chunk = v[start..end].to_vec();
                v.splice(at..at, chunk);
            }
            _ => {
                let huge: &[u8] =
                    [&b"1e308"[..], b"-9999999999999999999", b"NaN", b"\xff\xfe"][rng.below(4)];
                v.splice(at..at, huge.iter().copied());
            }
        }
    }
    v
}

/// Runs `check` on `n` mutants of `input`; a panic fails the test naming the mutant.
fn survive(what: &str, input: &[u8], n: usize, seed: u64, check: impl Fn(&[u8])) {
    let mut rng = Rng(seed);
    for i in 0..n {
        let m = mutate(input, &mut rng);
        if catch_unwind(AssertUnwindSafe(|| check(&m))).is_err() {
            panic!(
                "{what}: mutant {i} panicked: {:?}",
                String::from_utf8_lossy(&m[..m.len().min(400)])
            );
        }
    }
}

#[test]
fn campaign_configurations_and_sim_suites() {
    let template = fogline_campaign::config::TEMPLATE.as_bytes();
    survive("campaign TOML", template, 600, 1, |m| {
        let _ = fogline_campaign::CampaignConfig::from_toml(&String::from_utf8_lossy(m));
    });
    let dir = tempfile::tempdir().unwrap();
    let suite = serde_json::to_vec_pretty(&fogline_sim::suite::SuiteParams::quick()).unwrap();
    for (ext, seed) in [("json", 2), ("toml", 3)] {
        let path = dir.path().join(format!("suite.{ext}"));
        let input = if ext == "json" {
            suite.clone()
        } else {
            // The same suite as TOML: what `docs/sim.md` shows users.
            b"towns = 2\nroutes_per_town = 2\n".to_vec()
        };
        survive(&format!("suite {ext}"), &input, 300, seed, |m| {
            std::fs::write(&path, m).unwrap();
            let _ = fogline_sim::suite::SuiteParams::read(&path);
        });
    }
}

#[test]
fn observations_and_llm_answers() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../rco/tests/data/observations.jsonl");
    let text = std::fs::read(&data).unwrap();
    // A few lines, so each mutant is cheap to drive through the controller.
    let head: Vec<u8> = text
        .split_inclusive(|&b| b == b'\n')
        .take(2)
        .flatten()
        .copied()
        .collect();
    let driven = std::cell::Cell::new(0);
    survive("observations", &head, 1500, 4, |m| {
        if let Ok(obs) = fogline_rco::replay::read_observations(m) {
            driven.set(driven.get() + 1);
            let mut rco = fogline_rco::Rco::with_rules(fogline_rco::RcoParams::default()).unwrap();
            for o in &obs {
                let d = rco.step(o);
                assert!(d.control.in_range(), "{:?}", d.control);
            }
        }
    });
    // Some mutants stay valid (a digit changed, a chunk repeated) and reach the controller.
    assert!(
        driven.get() >= 10,
        "only {} mutants were valid",
        driven.get()
    );
    let views = [
        CameraId::CrossLeft,
        CameraId::FrontWide,
        CameraId::CrossRight,
    ];
    let conds = r#"{"cross_left": "no_immediate_hazard", "front_wide": "maybe", "cross_right": "immediate_hazard"}"#;
    let answers = [
        r#"{"hazards": [{"camera": "front_wide", "object": "pedestrian", "motion": "crossing"}], "strategy": "stop-observe-move", "rationale": "x"}"#.to_string(),
        format!(r#"{{"steps": [{{"conditions": {conds}, "behavior": "move_forward", "speed": "constant_speed"}}], "rationale": "x"}}"#),
        format!(r#"{{"wait_steps": 3, "move_trigger": {conds}, "rationale": "x"}}"#),
        r#"{"max_speed_kmh": 40, "min_following_distance_s": 3, "max_acceleration_mps2": 1.5, "max_deceleration_mps2": 3, "max_yaw_rate_dps": 10, "min_braking_distance_m": 20}"#.to_string(),
    ];
    for (k, a) in answers.iter().enumerate() {
        survive("LLM answer", a.as_bytes(), 400, 10 + k as u64, |m| {
            let t = String::from_utf8_lossy(m);
            use fogline_rco::backend::answer;
            let _ = answer::parse_hazard(&t, &views);
            let _ = answer::parse_move(&t, &views, 5);
            let _ = answer::parse_som(&t, &views, 20);
            if let Ok(sc) = answer::parse_constraints(&t) {
                assert!(sc.validate().is_ok(), "{sc:?}");
            }
        });
    }
}

#[test]
fn clips_on_disk() {
    let cfg = fogline_world::WorldConfig {
        width: 96,
        height: 64,
        depth: false,
        ..fogline_world::WorldConfig::default()
    };
    let clip = fogline_world::generate_clip(&cfg, 2).unwrap();
    let dir = tempfile::tempdir().unwrap();
    fogline_world::write_clip(dir.path(), &clip).unwrap();
    let clip_dir = dir.path().join(&clip.id);
    assert!(fogline_world::read_clip(&clip_dir).is_ok());
    let mut files: Vec<std::path::PathBuf> = Vec::new();
    let mut stack = vec![clip_dir.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                files.push(p);
            }
        }
    }
    files.sort();
    // The metadata and a handful of frames, each mutated in place and restored.
    let chosen: Vec<_> = files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .chain(
            files
                .iter()
                .filter(|p| p.extension().is_some_and(|e| e == "png"))
                .take(3),
        )
        .cloned()
        .collect();
    assert!(chosen.len() >= 2, "{files:?}");
    for (k, f) in chosen.iter().enumerate() {
        let original = std::fs::read(f).unwrap();
        survive(
            &f.display().to_string(),
            &original,
            120,
            20 + k as u64,
            |m| {
                std::fs::write(f, m).unwrap();
                let _ = fogline_world::read_clip(&clip_dir);
            },
        );
        std::fs::write(f, &original).unwrap();
    }
    if let Err(e) = fogline_world::read_clip(&clip_dir) {
        panic!("the restored clip does not read: {e}");
    }
}

#[test]
fn frames_perturbed_from_disk() {
    // `fogline perturb` on a directory holding one JPEG and one PNG frame, each mutated in
    // turn: a clear error naming the file, or perturbed frames.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir_all(&input).unwrap();
    let rgb: Vec<u8> = (0..64 * 48 * 3).map(|i| (i * 7 % 251) as u8).collect();
    let jpeg =
        fogline_io::encode(&rgb, 64, 48, fogline_io::ImageFormat::Jpeg { quality: 85 }).unwrap();
    let png = fogline_io::encode(&rgb, 64, 48, fogline_io::ImageFormat::Png).unwrap();
    for (name, bytes, seed) in [("a.jpg", &jpeg, 40u64), ("b.png", &png, 41)] {
        let other = if name == "a.jpg" {
            ("b.png", &png)
        } else {
            ("a.jpg", &jpeg)
        };
        std::fs::write(input.join(other.0), other.1).unwrap();
        let target = input.join(name);
        survive(name, bytes, 150, seed, |m| {
            std::fs::write(&target, m).unwrap();
            let job = fogline_api::perturb_dir::PerturbDir {
                input: input.clone(),
                output: dir.path().join("out"),
                condition: "noise_30+fog_03".into(),
                ..Default::default()
            };
            if let Err(e) = fogline_api::perturb_dir::run(&job) {
                let text = format!("{e:#}");
                assert!(text.contains(name) || text.contains("in/"), "{text}");
            }
        });
        std::fs::write(&target, bytes).unwrap();
    }
}

#[test]
fn physicalai_av_readers() {
    use crate::import_cmd::{egomotion_analytic, egomotion_parquet, encode_mp4, ffmpeg};
    use fogline_import::egomotion::Egomotion;
    use fogline_import::table::Table;

    // The video reader: mutated MP4s through ffmpeg, a clear error naming the video or
    // the frames asked for at the size asked for.
    let ff = fogline_import::Ffmpeg::at(&ffmpeg()).unwrap();
    let (w, h) = (64u32, 48u32);
    let frames: Vec<Vec<u8>> = (0..12)
        .map(|k| {
            (0..w * h * 3)
                .map(|i| ((i as usize * 7 + k * 13) % 251) as u8)
                .collect()
        })
        .collect();
    let decoded = std::cell::Cell::new(0);
    for (index_first, seed) in [(true, 60u64), (false, 61)] {
        let mp4 = encode_mp4(ff.path(), &frames, w, h, index_first);
        assert_eq!(
            ff.decode("v.mp4", &mp4, &[2, 5, 11], w, h).unwrap().len(),
            3
        );
        survive("mp4", &mp4, 80, seed, |m| {
            match ff.decode("v.mp4", m, &[2, 5, 11], w, h) {
                Ok(f) => {
                    decoded.set(decoded.get() + 1);
                    assert!(f.len() == 3 && f.iter().all(|f| f.len() == (w * h * 3) as usize));
                }
                Err(e) => assert!(e.to_string().starts_with("v.mp4: "), "{e}"),
            }
        });
    }
    assert!(decoded.get() >= 5, "only {} mutants decoded", decoded.get());

    // Egomotion and frame timestamps (Parquet), down to the trajectory at t0.
    let ego = egomotion_parquet(&egomotion_analytic(0, 8_000_000));
    survive("egomotion parquet", &ego, 400, 62, |m| {
        if let Ok(t) = Table::read("e.parquet", m.to_vec())
            && let Ok(e) = Egomotion::from_table(&t)
            && let Ok(ip) = e.interpolator()
            && let Ok(win) = ip.window(5_100_000)
        {
            assert!(win.ground_truth.validate().is_ok());
        }
    });
    let ts = crate::import_cmd::timestamps_parquet(&[0, 33_333, 66_667, 100_000]);
    survive("timestamps parquet", &ts, 200, 63, |m| {
        if let Ok(t) = Table::read("t.parquet", m.to_vec()) {
            let _ = t.i64_column("timestamp");
        }
    });

    // A whole tree: features.csv, the labels, the egomotion zip and the camera zip mutated
    // in turn, each imported with the rest intact.
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("root");
    let (video, stamps) = crate::import_cmd::video_around(&frames[..4], 5_100_000);
    let clip = crate::import_cmd::TreeClip {
        clip_id: "c-1".into(),
        chunk: 0,
        valid: true,
        videos: vec![(CameraId::FrontWide, video, stamps, false)],
        egomotion: egomotion_analytic(0, 12_000_000),
    };
    crate::import_cmd::write_tree(&root, ff.path(), &[clip], w, h);
    let labels = dir.path().join("labels.csv");
    std::fs::write(&labels, "clip_id,scenario\nc-1,STOP_SIGNAL\nc-2,OTHER\n").unwrap();
    let params = fogline_import::ImportParams {
        root: root.clone(),
        out: dir.path().join("out"),
        cameras: vec![CameraId::FrontWide],
        width: w,
        height: h,
        labels: Some(labels.clone()),
        ffmpeg: Some(ff.path().to_path_buf()),
        jobs: Some(1),
        ..Default::default()
    };
    let s = fogline_import::import_physicalai_av(&params).unwrap();
    assert_eq!(s.n_clips, 1);
    let targets = [
        (root.join("features.csv"), 120, 64u64),
        (labels, 80, 65),
        (
            root.join("labels/egomotion/egomotion.chunk_0000.zip"),
            60,
            66,
        ),
        (
            root.join("camera/camera_front_wide_120fov/camera_front_wide_120fov.chunk_0000.zip"),
            40,
            67,
        ),
    ];
    for (file, n, seed) in targets {
        let original = std::fs::read(&file).unwrap();
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        survive(&name, &original, n, seed, |m| {
            std::fs::write(&file, m).unwrap();
            if let Err(e) = fogline_import::import_physicalai_av(&params) {
                let text = e.to_string();
                assert!(!text.is_empty());
            }
        });
        std::fs::write(&file, &original).unwrap();
    }
    assert!(fogline_import::import_physicalai_av(&params).is_ok());
}
