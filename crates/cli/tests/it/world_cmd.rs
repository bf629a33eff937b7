//! `fogline world show` and `fogline world generate` as a user runs them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use image::ImageEncoder as _;

fn fogline(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(args)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .expect("the binary runs")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write_png(path: &Path, w: u32, h: u32, data: &[u8], color: image::ExtendedColorType) {
    let f = std::fs::File::create(path).unwrap();
    image::codecs::png::PngEncoder::new(f)
        .write_image(data, w, h, color)
        .unwrap();
}

/// A clip directory made by hand, the way a user converts their own data: the clip.json of
/// docs/clip-format.md (one camera, 32×24), four PNG frames, no depth, one box.
fn hand_made_clip(root: &Path) -> PathBuf {
    let dir = root.join("my_clip_001");
    let cam = dir.join("camera_front_wide_120fov");
    std::fs::create_dir_all(&cam).unwrap();
    let ego: Vec<String> = (0..16)
        .map(|i| {
            let t = -0.1 * f64::from(15 - i);
            format!(
                r#"{{"t_s": {t:.1}, "x_m": {:.2}, "y_m": 0.0, "yaw_rad": 0.0, "speed_mps": 10.0}}"#,
                10.0 * t
            )
        })
        .collect();
    let gt: Vec<String> = (1..=64).map(|i| format!("[{i}.0, 0.0]")).collect();
    let json = format!(
        r#"{{
  "format": "fogline-clip",
  "version": 1,
  "clip_id": "my_clip_001",
  "scenario": "LANE_KEEPING",
  "frames_t_s": [-0.3, -0.2, -0.1, 0.0],
  "cameras": [
    {{"id": "front_wide", "width": 32, "height": 24,
      "fx": 9.2376, "fy": 9.2376, "cx": 16.0, "cy": 12.0,
      "x_m": 1.8, "y_m": 0.0, "z_m": 1.6, "yaw_rad": 0.0, "pitch_rad": 0.0}}
  ],
  "ego_history": [{}],
  "ground_truth": [{}],
  "scene": {{"decision": "keep_lane", "facts": {{"source": "hand-made"}}}}
}}
"#,
        ego.join(",\n    "),
        gt.join(", ")
    );
    std::fs::write(dir.join("clip.json"), json).unwrap();
    for k in 0..4u32 {
        let data: Vec<u8> = (0..32 * 24 * 3)
            .map(|i| ((i * 7 + k * 40) % 256) as u8)
            .collect();
        write_png(
            &cam.join(format!("frame_{k}.png")),
            32,
            24,
            &data,
            image::ExtendedColorType::Rgb8,
        );
    }
    std::fs::write(
        cam.join("boxes.json"),
        r#"[[], [], [], [{"class": "car", "track_id": 1, "x_px": 10, "y_px": 8, "width_px": 6, "height_px": 4}]]"#,
    )
    .unwrap();
    dir
}

fn show(dir: &Path) -> Output {
    fogline(&["world", "show", dir.to_str().unwrap()])
}

#[test]
fn world_show_summarises_a_hand_made_clip() {
    let tmp = tempfile::tempdir().unwrap();
    let clip = hand_made_clip(tmp.path());
    let o = show(&clip);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    for want in [
        "my_clip_001",
        "scenario      LANE_KEEPING",
        "4 per camera at t = -0.3, -0.2, -0.1, 0 s",
        "camera_front_wide_120fov",
        "32x24",
        "0 0 0 1",
        "16 poses",
        "first (1.00, 0.00) m, last (64.00, 0.00) m",
        "decision      keep_lane",
        "source=hand-made",
    ] {
        assert!(out.contains(want), "{want:?} missing from:\n{out}");
    }
}

#[test]
fn world_show_names_the_broken_file_and_exits_2() {
    type Break = fn(&Path);
    let cases: [(Break, &str, &str); 6] = [
        (
            |c| std::fs::remove_file(c.join("camera_front_wide_120fov/frame_3.png")).unwrap(),
            "frame_3.png",
            "missing",
        ),
        (
            |c| {
                let p = c.join("clip.json");
                let t = std::fs::read_to_string(&p).unwrap();
                std::fs::write(&p, t.replace("\"fy\": 9.2376", "\"fy\": \"wide\"")).unwrap();
            },
            "clip.json",
            "cameras[0].fy",
        ),
        (
            |c| {
                let p = c.join("clip.json");
                let t = std::fs::read_to_string(&p).unwrap();
                std::fs::write(&p, t.replace("\"version\": 1", "\"version\": 7")).unwrap();
            },
            "clip.json",
            "unsupported format version 7",
        ),
        (
            |c| {
                let data = vec![9u8; 32 * 24 * 4];
                write_png(
                    &c.join("camera_front_wide_120fov/frame_1.png"),
                    32,
                    24,
                    &data,
                    image::ExtendedColorType::Rgba8,
                );
            },
            "frame_1.png",
            "RGBA",
        ),
        (
            |c| {
                std::fs::write(
                    c.join("camera_front_wide_120fov/boxes.json"),
                    r#"[[], [], [], [{"class": "car", "x_px": 30, "y_px": 8, "width_px": 6, "height_px": 4}]]"#,
                )
                .unwrap();
            },
            "boxes.json",
            "outside",
        ),
        (
            |c| std::fs::rename(c, c.with_file_name("renamed")).unwrap(),
            "my_clip_001",
            "does not exist",
        ),
    ];
    for (break_it, file, problem) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let clip = hand_made_clip(tmp.path());
        break_it(&clip);
        let o = show(&clip);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{file}: {err}");
        assert!(
            err.contains(file) && err.contains(problem),
            "{file} / {problem} missing from: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn world_generate_refuses_bad_parameters_before_writing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("corpus");
    let o_s = out.to_str().unwrap();
    let cases: [(&[&str], &[&str]); 6] = [
        (&["--width", "5000"], &["width", "5000", "16..=1920"]),
        (&["--height", "8"], &["height", "8", "16..=1080"]),
        (
            &["--scenario", "PARKING"],
            &["PARKING", "LANE_KEEPING", "STOP_SIGNAL"],
        ),
        (&["--clips", "0"], &["--clips must be at least 1"]),
        (&["--jobs", "0"], &["--jobs must be at least 1"]),
        (
            &["--scenario", "STOP_SIGNAL", "--mix", "uniform"],
            &["cannot be used with"],
        ),
    ];
    for (extra, words) in cases {
        let mut args = vec!["world", "generate", "--out", o_s];
        args.extend(extra);
        let o = fogline(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        for w in words {
            assert!(err.contains(w), "{w:?} missing from: {err}");
        }
        assert!(!out.exists(), "{extra:?} wrote {}", out.display());
    }
}

/// Every file under `root`: (relative path, bytes), sorted.
fn tree(root: &Path) -> Vec<(String, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(String, Vec<u8>)>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().display().to_string();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    let mut out = Vec::new();
    walk(root, root, &mut out);
    out.sort();
    out
}

#[test]
fn world_generate_writes_a_corpus_that_world_show_reads() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("corpus");
    let o = fogline(&[
        "world",
        "generate",
        "--out",
        out.to_str().unwrap(),
        "--clips",
        "8",
        "--width",
        "64",
        "--height",
        "48",
        "--seed",
        "5",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains("8 clips (seed 5, 64x48, with depth)"),
        "{text}"
    );
    assert!(text.contains("STOP_SIGNAL"), "{text}");
    assert!(text.contains("corpus.json"), "{text}");
    let corpus: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("corpus.json")).unwrap()).unwrap();
    assert_eq!(corpus["format"], "fogline-corpus");
    assert_eq!(corpus["n_clips"], 8);
    assert_eq!(corpus["config"]["seed"], 5);
    let clips = corpus["clips"].as_array().unwrap();
    assert_eq!(clips.len(), 8);
    for c in clips {
        let dir = out.join(c["id"].as_str().unwrap());
        let o = show(&dir);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let s = stdout(&o);
        assert!(s.contains(c["scenario"].as_str().unwrap()), "{s}");
        assert!(s.contains("64x48"), "{s}");
        assert!(dir.join("camera_front_tele_30fov/depth_3.png").is_file());
    }
}

#[test]
fn world_generate_does_not_depend_on_jobs_and_honours_no_depth() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |name: &str, jobs: &str, extra: &[&str]| {
        let out = tmp.path().join(name);
        let mut args = vec![
            "world",
            "generate",
            "--out",
            out.to_str().unwrap(),
            "--clips",
            "5",
            "--width",
            "48",
            "--height",
            "32",
            "--jobs",
            jobs,
        ];
        args.extend(extra);
        let o = fogline(&args);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        out
    };
    let one = run("one", "1", &["--mix", "uniform"]);
    let two = run("two", "2", &["--mix", "uniform"]);
    let a = tree(&one);
    assert_eq!(a.len(), 5 * (1 + 4 * (4 + 4 + 1)) + 1);
    assert!(a == tree(&two), "the corpus depends on --jobs");
    let flat = run("flat", "2", &["--no-depth", "--scenario", "OTHER"]);
    let files = tree(&flat);
    assert!(files.iter().all(|(p, _)| !p.contains("depth_")));
    assert!(files.iter().any(|(p, _)| p.starts_with("other_00004")));
}
