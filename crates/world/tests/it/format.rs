//! The on-disk clip format: exact round trips, deterministic bytes, atomic replacement, and an
//! error naming the file and the problem for every kind of bad input.

use std::path::{Path, PathBuf};

use fogline_perturb::frame::{DepthMap, Frame, ObjectBox};
use fogline_types::clip::{
    CameraCalib, CameraId, Decision, EgoPose, FRAMES, HISTORY, HORIZON, Trajectory,
};
use fogline_world::format::{
    BOXES_JSON, CLIP_JSON, ClipMeta, cm_to_depth, depth_to_cm, read_meta, validate_clip,
};
use fogline_world::{
    CameraClip, CameraFrame, Clip, SceneInfo, WorldError, list_clips, read_clip, write_clip,
};
use image::ImageEncoder as _;
use serde_json::{Value, json};

const W: u32 = 32;
const H: u32 = 24;

fn pixels(w: u32, h: u32, salt: u32) -> Vec<u8> {
    (0..w * h * 3)
        .map(|i| ((i * 31 + salt * 17 + i / 97) % 256) as u8)
        .collect()
}

/// Sky (+inf) in the top quarter, then distances from 0 m up to beyond the 655.34 m limit.
fn depth(w: u32, h: u32, salt: u32) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let y = i / w;
            if y < h / 4 {
                f32::INFINITY
            } else {
                match (i + salt) % 7 {
                    0 => 0.0,
                    1 => 700.0,
                    _ => ((i * 13 + salt) % 20_000) as f32 * 0.0317,
                }
            }
        })
        .collect()
}

fn boxes(k: usize, cam: usize) -> Vec<ObjectBox> {
    (0..(k + cam) % 3)
        .map(|i| ObjectBox {
            class: if i == 0 { "car" } else { "pedestrian" }.into(),
            track_id: (i == 0).then_some(7 + cam as u64),
            x_px: 1.5 + i as f64 * 4.0,
            y_px: 2.25,
            width_px: 10.0 / 3.0,
            height_px: f64::from(H) - 2.25,
        })
        .collect()
}

/// A clip of the four standard cameras, 32×24, synthetic pixels, depth and boxes.
fn sample_clip(id: &str, with_depth: bool) -> Clip {
    let cameras = CameraId::ALL
        .iter()
        .enumerate()
        .map(|(c, &id)| CameraClip {
            calib: CameraCalib::standard(id, W, H),
            frames: (0..FRAMES)
                .map(|k| {
                    let salt = (c * FRAMES + k) as u32;
                    CameraFrame {
                        t_s: [-0.3, -0.2, -0.1, 0.0][k],
                        image: Frame::new(W, H, pixels(W, H, salt)).unwrap(),
                        depth: with_depth.then(|| DepthMap::new(W, H, depth(W, H, salt)).unwrap()),
                        boxes: boxes(k, c),
                    }
                })
                .collect(),
        })
        .collect();
    let mut facts = serde_json::Map::new();
    facts.insert("time_of_day".into(), json!("dusk"));
    facts.insert("lead_gap_m".into(), json!(23.5));
    Clip {
        id: id.into(),
        scenario: "STOP_SIGNAL".into(),
        cameras,
        ego_history: (0..HISTORY)
            .map(|i| {
                let t = -0.1 * (HISTORY - 1 - i) as f64;
                EgoPose {
                    t_s: t,
                    x_m: 8.3 * t,
                    y_m: 0.01 * t * t,
                    yaw_rad: -0.002 * t,
                    speed_mps: 8.3 + 0.1 * t,
                }
            })
            .collect(),
        ground_truth: Trajectory {
            xy: (0..HORIZON)
                .map(|i| {
                    let t = 0.1 * (i + 1) as f64;
                    [8.3 * t - 0.6 * t * t, 0.013 * t]
                })
                .collect(),
        },
        scene: SceneInfo {
            decision: Some(Decision::StopForSign),
            facts,
        },
    }
}

/// `clip` with its depth as it comes back from disk (whole centimetres).
fn quantised(mut clip: Clip) -> Clip {
    for cam in &mut clip.cameras {
        for f in &mut cam.frames {
            if let Some(d) = &f.depth {
                let q = d
                    .depth_m()
                    .iter()
                    .map(|&v| cm_to_depth(depth_to_cm(v)))
                    .collect();
                f.depth = Some(DepthMap::new(d.width(), d.height(), q).unwrap());
            }
        }
    }
    clip
}

/// `a == b`, reporting the first difference briefly (a clip's Debug output is huge).
fn assert_same(a: &Clip, b: &Clip) {
    if a == b {
        return;
    }
    assert_eq!((&a.id, &a.scenario), (&b.id, &b.scenario));
    assert_eq!(a.ego_history, b.ego_history);
    assert_eq!(a.ground_truth, b.ground_truth);
    assert_eq!(a.scene, b.scene);
    assert_eq!(a.cameras.len(), b.cameras.len());
    for (ca, cb) in a.cameras.iter().zip(&b.cameras) {
        assert_eq!(ca.calib, cb.calib);
        assert_eq!(ca.frames.len(), cb.frames.len());
        for (k, (fa, fb)) in ca.frames.iter().zip(&cb.frames).enumerate() {
            let what = format!("{} frame {k}", ca.calib.id);
            assert_eq!(fa.t_s, fb.t_s, "{what}");
            assert!(fa.image == fb.image, "{what}: images differ");
            assert!(fa.depth == fb.depth, "{what}: depth maps differ");
            assert_eq!(fa.boxes, fb.boxes, "{what}");
        }
    }
    panic!("the clips differ");
}

fn written(dir: &Path, clip: &Clip) -> PathBuf {
    write_clip(dir, clip).unwrap();
    dir.join(&clip.id)
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Every file under `root`: (path relative to `root`, bytes), sorted.
fn all_files(root: &Path) -> Vec<(String, Vec<u8>)> {
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

fn write_png(path: &Path, w: u32, h: u32, data: &[u8], color: image::ExtendedColorType) {
    let f = std::fs::File::create(path).unwrap();
    image::codecs::png::PngEncoder::new(f)
        .write_image(data, w, h, color)
        .unwrap();
}

fn edit_json(path: &Path, f: impl FnOnce(&mut Value)) {
    let mut v: Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(path, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
}

/// Writes a good clip, lets `break_it` damage it, reads it back and returns the error text
/// (after checking that it names `file`) and the clip directory.
fn broken(file: &str, break_it: impl FnOnce(&Path)) -> String {
    let dir = tempfile::tempdir().unwrap();
    let clip = written(dir.path(), &sample_clip("c0001", true));
    break_it(&clip);
    let e = read_clip(&clip).expect_err("a broken clip must not read");
    let msg = e.to_string();
    assert!(msg.contains(file), "error does not name {file}: {msg}");
    assert!(
        matches!(e, WorldError::ClipFile { .. } | WorldError::Io { .. }),
        "{e:?}"
    );
    msg
}

fn assert_has(msg: &str, words: &[&str]) {
    for w in words {
        assert!(msg.contains(w), "{w:?} missing from: {msg}");
    }
}

const FRONT: &str = "camera_front_wide_120fov";

// ---------------------------------------------------------------------------------------------
// Round trips
// ---------------------------------------------------------------------------------------------

#[test]
fn round_trip_is_exact_for_frames_boxes_and_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let clip = sample_clip("c0001", true);
    let back = read_clip(&written(dir.path(), &clip)).unwrap();
    assert_eq!(back.id, clip.id);
    assert_eq!(back.scenario, clip.scenario);
    assert_eq!(back.ego_history, clip.ego_history);
    assert_eq!(back.ground_truth, clip.ground_truth);
    assert_eq!(back.scene, clip.scene);
    assert_eq!(back.cameras.len(), 4);
    for (a, b) in back.cameras.iter().zip(&clip.cameras) {
        assert_eq!(a.calib, b.calib);
        assert_eq!(a.frames.len(), FRAMES);
        for (fa, fb) in a.frames.iter().zip(&b.frames) {
            assert_eq!(fa.t_s, fb.t_s);
            assert_eq!(fa.image, fb.image);
            assert_eq!(fa.boxes, fb.boxes);
            // Depth to the centimetre; beyond 655.34 m clamped; +inf stays +inf.
            let (da, db) = (fa.depth.as_ref().unwrap(), fb.depth.as_ref().unwrap());
            for (&x, &y) in da.depth_m().iter().zip(db.depth_m()) {
                if y.is_infinite() {
                    assert_eq!(x, f32::INFINITY);
                } else if y > 655.34 {
                    assert_eq!(x, 655.34);
                } else {
                    assert!((x - y).abs() <= 0.005 + 1e-4, "{x} vs {y}");
                }
            }
        }
    }
    // With depth already on the centimetre grid the whole clip comes back equal.
    assert_same(&back, &quantised(clip));
}

#[test]
fn clips_without_depth_or_scene_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let mut clip = sample_clip("plain", false);
    clip.scene = SceneInfo::default();
    let path = written(dir.path(), &clip);
    assert!(!path.join(FRONT).join("depth_0.png").exists());
    let text = std::fs::read_to_string(path.join(CLIP_JSON)).unwrap();
    assert!(!text.contains("\"scene\""), "{text}");
    assert_same(&read_clip(&path).unwrap(), &clip);
}

#[test]
fn identical_clips_give_identical_bytes_and_rewriting_is_stable() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let clip = sample_clip("c0001", true);
    let pa = written(a.path(), &clip);
    let pb = written(b.path(), &clip.clone());
    let files = all_files(&pa);
    assert_eq!(files, all_files(&pb));
    let expected: Vec<String> = {
        let mut v = vec![CLIP_JSON.to_string()];
        for c in CameraId::ALL {
            for k in 0..FRAMES {
                v.push(format!("{}/frame_{k}.png", c.name()));
                v.push(format!("{}/depth_{k}.png", c.name()));
            }
            v.push(format!("{}/{BOXES_JSON}", c.name()));
        }
        v.sort();
        v
    };
    assert_eq!(
        files.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>(),
        expected
    );
    // Reading and writing again changes nothing.
    let back = read_clip(&pa).unwrap();
    let c = tempfile::tempdir().unwrap();
    assert_eq!(all_files(&written(c.path(), &back)), files);
}

#[test]
fn clip_json_has_the_documented_fields_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = written(dir.path(), &sample_clip("c0001", false));
    let text = std::fs::read_to_string(path.join(CLIP_JSON)).unwrap();
    let keys = [
        "\"format\": \"fogline-clip\"",
        "\"version\": 1",
        "\"clip_id\": \"c0001\"",
        "\"scenario\": \"STOP_SIGNAL\"",
        "\"frames_t_s\"",
        "\"cameras\"",
        "\"ego_history\"",
        "\"ground_truth\"",
        "\"scene\"",
    ];
    let pos: Vec<usize> = keys.iter().map(|k| text.find(k).unwrap()).collect();
    assert!(pos.windows(2).all(|w| w[0] < w[1]), "{text}");
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["frames_t_s"], json!([-0.3, -0.2, -0.1, 0.0]));
    assert_eq!(v["cameras"][1]["id"], "front_wide");
    assert_eq!(v["ground_truth"].as_array().unwrap().len(), HORIZON);
    assert_eq!(v["scene"]["decision"], "stop_for_sign");
    let meta: ClipMeta = read_meta(&path).unwrap();
    assert_eq!(meta.frames_t_s, [-0.3, -0.2, -0.1, 0.0]);
}

#[test]
fn missing_boxes_json_means_no_boxes_and_jpeg_frames_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let clip = sample_clip("c0001", false);
    let path = written(dir.path(), &clip);
    let cam = path.join(FRONT);
    std::fs::remove_file(cam.join(BOXES_JSON)).unwrap();
    std::fs::remove_file(cam.join("frame_2.png")).unwrap();
    let f = std::fs::File::create(cam.join("frame_2.jpg")).unwrap();
    image::codecs::jpeg::JpegEncoder::new_with_quality(f, 95)
        .write_image(
            clip.cameras[1].frames[2].image.data(),
            W,
            H,
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
    let back = read_clip(&path).unwrap();
    let front = &back.cameras[1];
    assert!(front.frames.iter().all(|f| f.boxes.is_empty()));
    assert!(back.cameras[0] == clip.cameras[0]);
    let jpeg = &front.frames[2].image;
    assert_eq!((jpeg.width(), jpeg.height()), (W, H));
    let mean_err = jpeg
        .data()
        .iter()
        .zip(clip.cameras[1].frames[2].image.data())
        .map(|(a, b)| f64::from(a.abs_diff(*b)))
        .sum::<f64>()
        / jpeg.data().len() as f64;
    assert!(mean_err < 40.0, "{mean_err}");
}

#[test]
fn a_subset_of_cameras_in_any_order_is_a_clip() {
    let dir = tempfile::tempdir().unwrap();
    let mut clip = sample_clip("c0002", true);
    clip.cameras = vec![clip.cameras[3].clone(), clip.cameras[1].clone()];
    let path = written(dir.path(), &clip);
    assert_eq!(names(&path), ["camera_front_tele_30fov", FRONT, CLIP_JSON]);
    let back = read_clip(&path).unwrap();
    assert_same(&back, &quantised(clip));
}

// ---------------------------------------------------------------------------------------------
// Atomic writes and listing
// ---------------------------------------------------------------------------------------------

#[test]
fn writing_replaces_a_clip_of_the_same_id_and_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let first = sample_clip("c0001", true);
    written(dir.path(), &first);
    let mut second = sample_clip("c0001", false);
    second.scenario = "LANE_KEEPING".into();
    second.cameras.truncate(2);
    let path = written(dir.path(), &second);
    assert_same(&read_clip(&path).unwrap(), &second);
    assert_eq!(names(dir.path()), ["c0001"]);
    // The old clip's cameras are gone, not merged.
    assert_eq!(names(&path).len(), 3);
}

#[test]
fn a_refused_write_keeps_the_previous_clip() {
    let dir = tempfile::tempdir().unwrap();
    let good = sample_clip("c0001", false);
    let path = written(dir.path(), &good);
    let mut bad = good.clone();
    bad.cameras[2].frames[1].boxes.push(ObjectBox {
        class: "car".into(),
        track_id: None,
        x_px: 30.0,
        y_px: 0.0,
        width_px: 5.0,
        height_px: 1.0,
    });
    let e = write_clip(dir.path(), &bad).unwrap_err();
    assert!(matches!(e, WorldError::InvalidClip { .. }), "{e:?}");
    assert_has(
        &e.to_string(),
        &["c0001", "camera_cross_right_120fov", "frame 1", "outside"],
    );
    assert_same(&read_clip(&path).unwrap(), &good);
    assert_eq!(names(dir.path()), ["c0001"]);
}

#[test]
fn a_directory_that_is_not_a_clip_is_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let other = dir.path().join("c0001");
    std::fs::create_dir(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "keep me").unwrap();
    let e = write_clip(dir.path(), &sample_clip("c0001", false)).unwrap_err();
    assert_has(&e.to_string(), &["c0001", "not a clip directory"]);
    assert_eq!(names(&other), ["notes.txt"]);
    assert_eq!(names(dir.path()), ["c0001"]);
}

#[test]
fn invalid_clips_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let base = sample_clip("c0001", true);
    type Mutation = Box<dyn Fn(&mut Clip)>;
    let cases: Vec<(Mutation, &[&str])> = vec![
        (Box::new(|c| c.id = "a/../b".into()), &["clip_id", "'/'"]),
        (Box::new(|c| c.id = ".hidden".into()), &["clip_id"]),
        (Box::new(|c| c.scenario = " ".into()), &["scenario"]),
        (
            Box::new(|c| c.cameras[0].calib.fx = f64::NAN),
            &["cameras[0]", "finite"],
        ),
        (
            Box::new(|c| c.cameras[1].calib.width = 31),
            &["camera_front_wide_120fov frame 0", "32x24", "31x24"],
        ),
        (
            Box::new(|c| c.cameras[2].frames[3].t_s = 0.05),
            &["camera_cross_right_120fov", "frame times"],
        ),
        (
            Box::new(|c| c.cameras[0].frames[1].depth = None),
            &["camera_cross_left_120fov", "3 of 4 frames have depth"],
        ),
        (
            Box::new(|c| {
                for cam in &mut c.cameras {
                    cam.frames.pop();
                }
            }),
            &["frames_t_s has 3 entries"],
        ),
        (Box::new(|c| c.cameras.clear()), &["cameras has 0 entries"]),
        (
            Box::new(|c| {
                c.cameras[3] = c.cameras[0].clone();
            }),
            &["listed twice"],
        ),
        (
            Box::new(|c| {
                c.ego_history.pop();
            }),
            &["ego_history has 15 poses"],
        ),
        (
            Box::new(|c| c.ego_history[3].speed_mps = f64::INFINITY),
            &["ego_history[3]", "non-finite"],
        ),
        (
            Box::new(|c| c.ground_truth.xy[9][1] = f64::NAN),
            &["ground_truth", "waypoint 9"],
        ),
        (
            Box::new(|c| c.ground_truth.xy.truncate(10)),
            &["ground_truth", "64 waypoints"],
        ),
    ];
    for (i, (mutate, words)) in cases.iter().enumerate() {
        let mut c = base.clone();
        mutate(&mut c);
        let e = validate_clip(&c).unwrap_err();
        assert_has(&e.to_string(), words);
        let e = write_clip(dir.path(), &c).unwrap_err();
        assert!(
            matches!(e, WorldError::InvalidClip { .. }),
            "case {i}: {e:?}"
        );
    }
    assert!(names(dir.path()).is_empty());
}

#[test]
fn list_clips_finds_clip_directories_in_order() {
    let dir = tempfile::tempdir().unwrap();
    for id in ["b", "a", "c10", "c9"] {
        written(dir.path(), &sample_clip(id, false));
    }
    std::fs::create_dir(dir.path().join("not_a_clip")).unwrap();
    std::fs::create_dir(dir.path().join(".hidden")).unwrap();
    std::fs::write(dir.path().join(".hidden").join(CLIP_JSON), "{}").unwrap();
    std::fs::write(dir.path().join("corpus.json"), "{}").unwrap();
    let found: Vec<String> = list_clips(dir.path())
        .unwrap()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(found, ["a", "b", "c10", "c9"]);
    let e = list_clips(&dir.path().join("nope")).unwrap_err();
    assert!(e.to_string().contains("nope"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// clip.json errors
// ---------------------------------------------------------------------------------------------

#[test]
fn missing_clip_json_or_directory() {
    let m = broken(CLIP_JSON, |c| {
        std::fs::remove_file(c.join(CLIP_JSON)).unwrap()
    });
    assert_has(&m, &["missing"]);
    let e = read_clip(Path::new("/nonexistent/clip_x")).unwrap_err();
    assert_has(&e.to_string(), &["clip_x", "does not exist"]);
}

#[test]
fn json_syntax_errors_give_the_line() {
    let m = broken(CLIP_JSON, |c| {
        let p = c.join(CLIP_JSON);
        let text = std::fs::read_to_string(&p).unwrap();
        std::fs::write(&p, text.replacen("\"scenario\":", "\"scenario\" ", 1)).unwrap();
    });
    assert_has(&m, &["invalid JSON", "line 5"]);
}

#[test]
fn schema_errors_give_the_field_path_and_line() {
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["cameras"][1]["fx"] = json!("wide")
        });
    });
    assert_has(&m, &["cameras[1].fx", "line", "expected f64"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["cameras"][0]["id"] = json!("front_left")
        });
    });
    assert_has(
        &m,
        &[
            "cameras[0].id",
            "unknown variant `front_left`",
            "front_wide",
        ],
    );
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v.as_object_mut().unwrap().remove("ego_history");
        });
    });
    assert_has(&m, &["missing field `ego_history`"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| v["ground_thruth"] = json!([]));
    });
    assert_has(&m, &["unknown field `ground_thruth`"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| v["ground_truth"][5] = Value::Null);
    });
    assert_has(&m, &["ground_truth[5]"]);
}

#[test]
fn format_and_version_are_checked_first() {
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| v["version"] = json!(2));
    });
    assert_has(&m, &["unsupported format version 2", "version 1"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["format"] = json!("other");
            v["cameras"] = json!("garbage");
        });
    });
    assert_has(&m, &["format is \"other\"", "fogline-clip"]);
    let m = broken(CLIP_JSON, |c| {
        std::fs::write(c.join(CLIP_JSON), "[1, 2]").unwrap()
    });
    assert_has(&m, &["JSON object"]);
}

#[test]
fn wrong_counts_are_named() {
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["frames_t_s"] = json!([-0.2, -0.1, 0.0])
        });
    });
    assert_has(&m, &["frames_t_s has 3 entries", "4 frames"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["frames_t_s"] = json!([-0.3, -0.1, -0.2, 0.0]);
        });
    });
    assert_has(&m, &["frames_t_s must increase"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["ego_history"].as_array_mut().unwrap().remove(0);
        });
    });
    assert_has(&m, &["ego_history has 15 poses", "expected 16"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["ground_truth"].as_array_mut().unwrap().pop();
        });
    });
    assert_has(&m, &["ground_truth", "64 waypoints, found 63"]);
}

#[test]
fn bad_calibrations_are_named() {
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| v["cameras"][2]["fy"] = json!(-5.0));
    });
    assert_has(&m, &["cameras[2]", "focal lengths must be positive"]);
    let m = broken(CLIP_JSON, |c| {
        let p = c.join(CLIP_JSON);
        let text = std::fs::read_to_string(&p).unwrap();
        let fx = text.find("\"fx\": ").unwrap() + 6;
        let end = fx + text[fx..].find(',').unwrap();
        std::fs::write(&p, format!("{}1e999{}", &text[..fx], &text[end..])).unwrap();
    });
    assert_has(&m, &["line"]);
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["cameras"][3] = v["cameras"][0].clone();
        });
    });
    assert_has(&m, &["cameras[3]", "listed twice"]);
}

#[test]
fn the_clip_id_must_match_the_directory() {
    let m = broken(CLIP_JSON, |c| {
        edit_json(&c.join(CLIP_JSON), |v| v["clip_id"] = json!("c0002"));
    });
    assert_has(&m, &["\"c0002\"", "\"c0001\"", "must match"]);
}

// ---------------------------------------------------------------------------------------------
// Camera directory errors
// ---------------------------------------------------------------------------------------------

#[test]
fn missing_and_unlisted_camera_directories() {
    let m = broken(FRONT, |c| std::fs::remove_dir_all(c.join(FRONT)).unwrap());
    assert_has(&m, &["missing camera directory", "front_wide"]);
    let m = broken("camera_front_tele_30fov", |c| {
        edit_json(&c.join(CLIP_JSON), |v| {
            v["cameras"].as_array_mut().unwrap().pop();
        });
    });
    assert_has(&m, &["without a calibration", "front_tele"]);
}

#[test]
fn missing_extra_and_duplicate_frames() {
    let m = broken("frame_2.png", |c| {
        std::fs::remove_file(c.join(FRONT).join("frame_2.png")).unwrap();
    });
    assert_has(&m, &["missing", "frame 2 of 4"]);
    let m = broken("frame_4.png", |c| {
        let cam = c.join(FRONT);
        std::fs::copy(cam.join("frame_0.png"), cam.join("frame_4.png")).unwrap();
    });
    assert_has(&m, &["more frames than clip.json lists"]);
    let m = broken("frame_1", |c| {
        let cam = c.join(FRONT);
        std::fs::copy(cam.join("frame_1.png"), cam.join("frame_1.jpg")).unwrap();
    });
    assert_has(&m, &["given twice"]);
}

#[test]
fn corrupt_and_truncated_images() {
    let m = broken("frame_1.png", |c| {
        let p = c.join(FRONT).join("frame_1.png");
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    });
    assert_has(&m, &["corrupt or truncated"]);
    let m = broken("frame_3.png", |c| {
        std::fs::write(c.join(FRONT).join("frame_3.png"), b"not an image at all").unwrap();
    });
    assert_has(&m, &["cannot decode"]);
    let m = broken("depth_0.png", |c| {
        std::fs::write(c.join(FRONT).join("depth_0.png"), [0x89, b'P', b'N', b'G']).unwrap();
    });
    assert_has(&m, &["cannot decode"]);
}

#[test]
fn frames_must_be_rgb8_of_the_calibrated_size() {
    use image::ExtendedColorType as C;
    let cases: [(C, usize, &str); 4] = [
        (C::Rgb16, 6, "16-bit RGB"),
        (C::L8, 1, "8-bit greyscale"),
        (C::Rgba8, 4, "RGBA"),
        (C::L16, 2, "16-bit greyscale"),
    ];
    for (color, bytes, word) in cases {
        let m = broken("frame_0.png", |c| {
            let data = vec![100u8; (W * H) as usize * bytes];
            write_png(&c.join(FRONT).join("frame_0.png"), W, H, &data, color);
        });
        assert_has(&m, &[word, "8-bit RGB"]);
    }
    let m = broken("frame_0.png", |c| {
        let data = pixels(W - 1, H, 0);
        write_png(&c.join(FRONT).join("frame_0.png"), W - 1, H, &data, C::Rgb8);
    });
    assert_has(&m, &["31x24", "32x24", "front_wide"]);
}

#[test]
fn depth_maps_must_be_16_bit_complete_and_of_the_right_size() {
    use image::ExtendedColorType as C;
    let m = broken("depth_1.png", |c| {
        let data = vec![7u8; (W * H) as usize];
        write_png(&c.join(FRONT).join("depth_1.png"), W, H, &data, C::L8);
    });
    assert_has(&m, &["8-bit greyscale", "16-bit greyscale PNG"]);
    let m = broken("depth_1.png", |c| {
        let data = vec![7u8; (W * H * 3) as usize];
        write_png(&c.join(FRONT).join("depth_1.png"), W, H, &data, C::Rgb8);
    });
    assert_has(&m, &["8-bit RGB image", "depth map"]);
    let m = broken("depth_2.png", |c| {
        let data = vec![7u8; (16 * H * 2) as usize];
        write_png(&c.join(FRONT).join("depth_2.png"), 16, H, &data, C::L16);
    });
    assert_has(&m, &["depth map is 16x24", "32x24"]);
    let m = broken("depth_3.png", |c| {
        std::fs::remove_file(c.join(FRONT).join("depth_3.png")).unwrap();
    });
    assert_has(&m, &["missing", "depth for 3 of its 4 frames"]);
}

#[test]
fn boxes_are_checked_against_the_frame() {
    let boxes_of = |c: &Path| c.join(FRONT).join(BOXES_JSON);
    let m = broken(BOXES_JSON, |c| {
        edit_json(&boxes_of(c), |v| {
            v[2] = json!([{"class": "car", "x_px": 20.0, "y_px": 1.0, "width_px": 20.0, "height_px": 3.0}]);
        });
    });
    assert_has(&m, &["frame 2", "box 0 (car)", "outside", "32×24"]);
    let m = broken(BOXES_JSON, |c| {
        edit_json(&boxes_of(c), |v| {
            v[0] = json!([{"class": "bus", "x_px": 1.0, "y_px": 1.0, "width_px": -2.0, "height_px": 3.0}]);
        });
    });
    assert_has(&m, &["frame 0", "bus", "invalid"]);
    let m = broken(BOXES_JSON, |c| {
        edit_json(&boxes_of(c), |v| {
            v.as_array_mut().unwrap().pop();
        });
    });
    assert_has(&m, &["3 lists of boxes", "one per frame (4)"]);
    let m = broken(BOXES_JSON, |c| {
        edit_json(&boxes_of(c), |v| {
            v[1] = json!([{"class": "car", "x_px": "left", "y_px": 1.0, "width_px": 2.0, "height_px": 3.0}]);
        });
    });
    assert_has(&m, &["[1][0].x_px", "line"]);
    let m = broken(BOXES_JSON, |c| {
        std::fs::write(boxes_of(c), "[[], [").unwrap()
    });
    assert_has(&m, &["invalid JSON", "line 1"]);
}

// ---------------------------------------------------------------------------------------------
// Robustness: damaged files give errors, never panics
// ---------------------------------------------------------------------------------------------

#[test]
fn truncated_or_bit_flipped_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let clip = written(dir.path(), &sample_clip("c0001", true));
    let json_path = clip.join(CLIP_JSON);
    let json = std::fs::read(&json_path).unwrap();
    for cut in (0..json.len() - 2).step_by(53) {
        std::fs::write(&json_path, &json[..cut]).unwrap();
        let e = read_clip(&clip).unwrap_err();
        assert!(e.to_string().contains(CLIP_JSON), "{e}");
    }
    std::fs::write(&json_path, &json).unwrap();
    for name in ["frame_0.png", "depth_0.png", BOXES_JSON] {
        let p = clip.join(FRONT).join(name);
        let bytes = std::fs::read(&p).unwrap();
        for i in (0..bytes.len()).step_by(bytes.len() / 40 + 1) {
            let mut b = bytes.clone();
            b[i] ^= 0x5a;
            std::fs::write(&p, &b).unwrap();
            // Some flips land in ignored bytes (a CRC, an unused chunk): Ok or Err, no panic.
            if let Err(e) = read_clip(&clip) {
                assert!(e.to_string().contains(name), "{e}");
            }
            if i < bytes.len() * 9 / 10 {
                std::fs::write(&p, &bytes[..i]).unwrap();
                let e = read_clip(&clip).unwrap_err();
                assert!(e.to_string().contains(name), "{e}");
            }
        }
        std::fs::write(&p, &bytes).unwrap();
    }
    assert!(read_clip(&clip).is_ok());
}

// ---------------------------------------------------------------------------------------------
// Generated clips
// ---------------------------------------------------------------------------------------------

#[test]
fn generated_clips_of_every_scenario_are_valid_and_round_trip() {
    let config = fogline_world::WorldConfig {
        width: 64,
        height: 48,
        mix: fogline_world::ScenarioMix::uniform(1),
        ..fogline_world::WorldConfig::default()
    };
    let dir = tempfile::tempdir().unwrap();
    for i in 0..config.mix.total() {
        let clip = fogline_world::generate_clip(&config, i).unwrap();
        validate_clip(&clip).unwrap();
        let back = read_clip(&written(dir.path(), &clip)).unwrap();
        assert_same(&back, &quantised(clip));
    }
    assert_eq!(list_clips(dir.path()).unwrap().len(), config.mix.total());
}
