//! Samples from a user's own logs.

use fogline_dataset::sample::read_samples;
use fogline_dataset::{ImportParams, import};
use fogline_rco::Strategy;
use fogline_rco::deficit_eval::{HiddenClass, MotionLabel};
use fogline_types::clip::{CameraCalib, CameraId};
use serde_json::json;

fn write_log(dir: &std::path::Path, motion: Option<&str>) {
    let log = dir.join("town-a");
    std::fs::create_dir_all(&log).unwrap();
    let cams = [
        CameraId::CrossLeft,
        CameraId::FrontWide,
        CameraId::CrossRight,
    ];
    let calibs: Vec<CameraCalib> = cams
        .iter()
        .map(|&c| CameraCalib::standard(c, 48, 36))
        .collect();
    let grey = fogline_io::encode(
        &vec![120u8; 48 * 36 * 3],
        48,
        36,
        fogline_io::ImageFormat::Png,
    )
    .unwrap();
    let mut frames = Vec::new();
    for k in 0..6 {
        let mut images = serde_json::Map::new();
        for c in cams {
            let name = format!("{}_{k}.png", c.short());
            std::fs::write(log.join(&name), &grey).unwrap();
            images.insert(c.short().into(), json!(name));
        }
        let x = 10.0 + k as f64;
        frames.push(json!({
            "t_s": k as f64, "ego_speed_mps": 4.0, "brake": k == 4,
            "images": images,
            "objects": [
                {"camera": "front_wide", "class": "pedestrian", "track_id": 7,
                 "bbox": [x, 8.0, x + 6.0, 24.0], "motion": motion},
                {"camera": "front_wide", "class": "car", "track_id": 8, "bbox": [30.0, 14.0, 44.0, 24.0]}
            ]
        }));
    }
    let doc =
        json!({"format": "fogline-deficit-log", "version": 1, "cameras": calibs, "frames": frames});
    std::fs::write(log.join("log.json"), serde_json::to_vec(&doc).unwrap()).unwrap();
}

#[test]
fn a_log_becomes_masked_labelled_samples() {
    let logs = tempfile::tempdir().unwrap();
    write_log(logs.path(), Some("crossing"));
    let out = tempfile::tempdir().unwrap();
    let built = import(&ImportParams::default(), logs.path(), out.path()).unwrap();
    assert_eq!(
        built.samples, 1,
        "one window of five frames, one tracked pedestrian"
    );
    let s = &read_samples(out.path()).unwrap()[0];
    assert_eq!(s.class, HiddenClass::Pedestrian);
    assert_eq!(s.motion, MotionLabel::Crossing);
    assert_eq!(
        s.strategy,
        Strategy::StopObserveMove,
        "the expert brakes at the last frame"
    );
    let front = &s.frames[4].views[1];
    assert_eq!(front.deficits, vec![[14, 8, 20, 24]]);
    assert_eq!(front.objects.len(), 1, "the car stays visible");
    let img =
        fogline_io::decode_rgb(&std::fs::read(out.path().join(&front.image)).unwrap()).unwrap();
    let px = |x: usize, y: usize| &img.rgb[(y * 48 + x) * 3..(y * 48 + x) * 3 + 3];
    assert_eq!(px(17, 16), &[0, 0, 0], "black fill");
    assert_eq!(px(14, 16), &[255, 0, 0], "red outline");
    assert_eq!(px(2, 2), &[120, 120, 120], "the rest untouched");
}

#[test]
fn a_log_without_motion_is_named_in_the_error() {
    let logs = tempfile::tempdir().unwrap();
    write_log(logs.path(), None);
    let out = tempfile::tempdir().unwrap();
    let e = import(&ImportParams::default(), logs.path(), out.path()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("log.json") && msg.contains("frames[0].objects[0].motion"),
        "{msg}"
    );
}
