//! `fogline clips import physicalai-av`: a tiny PhysicalAI-AV-shaped tree made here (MP4s
//! encoded by ffmpeg from world frames, egomotion from the world's trajectory and from an
//! analytic 3-D path, the metadata as pandas writes it), imported by the binary, compared
//! with the world it came from and with what the dataset's own devkit (the PyPI package
//! `physical-ai-av`, installed by `scripts/python-peers.sh`) reads from the same tree; then a
//! campaign runs on the imported clips.

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;

use arrow_array::{ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray};
use arrow_schema::{DataType, Field, Schema};
use fogline_types::clip::CameraId;

use crate::{fogline, text};

/// The ffmpeg the import uses (`FOGLINE_FFMPEG`, PATH, or target/pyenv's imageio-ffmpeg).
pub fn ffmpeg() -> PathBuf {
    match fogline_import::Ffmpeg::locate(None) {
        Ok(f) => f.path().to_path_buf(),
        Err(e) => panic!("{e}"),
    }
}

/// Encodes RGB frames (`w × h`) as an H.264 MP4 at 30 fps; `faststart` puts the index first.
pub fn encode_mp4(ff: &Path, frames: &[Vec<u8>], w: u32, h: u32, faststart: bool) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v.mp4");
    let mut cmd = Command::new(ff);
    cmd.args(["-y", "-hide_banner", "-loglevel", "error", "-f", "rawvideo"])
        .args(["-pix_fmt", "rgb24", "-s", &format!("{w}x{h}"), "-r", "30"])
        .args(["-i", "pipe:0", "-c:v", "libx264", "-preset", "veryfast"])
        .args(["-crf", "12", "-pix_fmt", "yuv420p", "-threads", "1"]);
    if faststart {
        cmd.args(["-movflags", "+faststart"]);
    }
    let mut child = cmd
        .arg(&out)
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    for f in frames {
        stdin.write_all(f).unwrap();
    }
    drop(stdin);
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(out).unwrap()
}

/// A Parquet file of `columns`, with pandas' metadata naming `index` the DataFrame's index
/// (as pandas writes a frame indexed by clip id).
pub fn parquet(columns: Vec<(&str, ArrayRef)>, index: Option<&str>) -> Vec<u8> {
    let fields: Vec<Field> = columns
        .iter()
        .map(|(n, a)| Field::new(*n, a.data_type().clone(), false))
        .collect();
    let mut schema = Schema::new(fields);
    if let Some(index) = index {
        let cols: Vec<serde_json::Value> = columns
            .iter()
            .map(|(n, a)| {
                let (pandas, numpy) = match a.data_type() {
                    DataType::Int64 => ("int64", "int64"),
                    DataType::Boolean => ("bool", "bool"),
                    _ => ("unicode", "object"),
                };
                serde_json::json!({"name": n, "field_name": n, "pandas_type": pandas,
                                   "numpy_type": numpy, "metadata": null})
            })
            .collect();
        let meta = serde_json::json!({
            "index_columns": [index],
            "column_indexes": [{"name": null, "field_name": null, "pandas_type": "unicode",
                                "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
            "columns": cols,
            "creator": {"library": "fogline-tests", "version": "0"},
            "pandas_version": "2.2.3",
        });
        schema = schema.with_metadata(std::collections::HashMap::from([(
            "pandas".to_string(),
            meta.to_string(),
        )]));
    }
    let batch = RecordBatch::try_new(
        Arc::new(schema),
        columns.into_iter().map(|(_, a)| a).collect(),
    )
    .unwrap();
    let mut out = Vec::new();
    let mut w = parquet::arrow::ArrowWriter::try_new(&mut out, batch.schema(), None).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
    out
}

/// Writes a zip of `members` (Parquet deflated, the rest stored, as the dataset's videos).
pub fn write_zip(path: &Path, members: &[(String, Vec<u8>)]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let mut w = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    for (name, bytes) in members {
        let method = if name.ends_with(".parquet") {
            zip::CompressionMethod::Deflated
        } else {
            zip::CompressionMethod::Stored
        };
        let opts = zip::write::SimpleFileOptions::default().compression_method(method);
        w.start_file(name.as_str(), opts).unwrap();
        w.write_all(bytes).unwrap();
    }
    w.finish().unwrap();
}

/// One egomotion sample in the clip's fixed frame.
#[derive(Clone, Copy, Debug)]
pub struct EgoRow {
    pub t_us: i64,
    pub xyz: [f64; 3],
    pub quat: [f64; 4],
    pub v: [f64; 3],
}

pub fn egomotion_parquet(rows: &[EgoRow]) -> Vec<u8> {
    let f = |g: &dyn Fn(&EgoRow) -> f64| {
        Arc::new(Float64Array::from_iter_values(rows.iter().map(g))) as ArrayRef
    };
    parquet(
        vec![
            (
                "timestamp",
                Arc::new(Int64Array::from_iter_values(rows.iter().map(|r| r.t_us))) as ArrayRef,
            ),
            ("x", f(&|r| r.xyz[0])),
            ("y", f(&|r| r.xyz[1])),
            ("z", f(&|r| r.xyz[2])),
            ("qx", f(&|r| r.quat[0])),
            ("qy", f(&|r| r.quat[1])),
            ("qz", f(&|r| r.quat[2])),
            ("qw", f(&|r| r.quat[3])),
            ("vx", f(&|r| r.v[0])),
            ("vy", f(&|r| r.v[1])),
            ("vz", f(&|r| r.v[2])),
            ("ax", f(&|_| 0.0)),
            ("ay", f(&|_| 0.0)),
            ("az", f(&|_| 0.0)),
            ("curvature", f(&|_| 0.0)),
        ],
        None,
    )
}

pub fn timestamps_parquet(ts: &[i64]) -> Vec<u8> {
    parquet(
        vec![(
            "timestamp",
            Arc::new(Int64Array::from(ts.to_vec())) as ArrayRef,
        )],
        None,
    )
}

/// One camera's video of a tree clip: camera, RGB frames, their timestamps (µs), index first.
pub type TreeVideo = (CameraId, Vec<Vec<u8>>, Vec<i64>, bool);

/// A clip of the tree: its video frames per camera (with their timestamps) and egomotion.
pub struct TreeClip {
    pub clip_id: String,
    pub chunk: i64,
    pub valid: bool,
    /// Per camera: frames (RGB, `w × h`), timestamps (µs), whether the MP4's index is first.
    pub videos: Vec<TreeVideo>,
    pub egomotion: Vec<EgoRow>,
}

/// Writes a PhysicalAI-AV tree: features.csv, clip_index.parquet, metadata/, and the chunk
/// zips of the clips that have data (clips without videos are indexed only).
pub fn write_tree(root: &Path, ff: &Path, clips: &[TreeClip], w: u32, h: u32) {
    std::fs::create_dir_all(root.join("metadata")).unwrap();
    let mut csv = String::from("feature,directory,chunk_path,clip_files_in_zip\n");
    for cam in CameraId::ALL {
        let c = cam.name();
        csv.push_str(&format!(
            "{c},camera,camera/{c}/{c}.chunk_{{chunk_id:04d}}.zip,\"{{\"\"video\"\": \"\"{{clip_id}}.{c}.mp4\"\", \"\"frame_timestamps\"\": \"\"{{clip_id}}.{c}.timestamps.parquet\"\"}}\"\n"
        ));
    }
    csv.push_str("egomotion,labels,labels/egomotion/egomotion.chunk_{chunk_id:04d}.zip,\"{\"\"egomotion\"\": \"\"{clip_id}.egomotion.parquet\"\"}\"\n");
    std::fs::write(root.join("features.csv"), csv).unwrap();
    let ids: Vec<&str> = clips.iter().map(|c| c.clip_id.as_str()).collect();
    let idx = || Arc::new(StringArray::from(ids.clone())) as ArrayRef;
    std::fs::write(
        root.join("clip_index.parquet"),
        parquet(
            vec![
                (
                    "chunk",
                    Arc::new(Int64Array::from_iter_values(clips.iter().map(|c| c.chunk)))
                        as ArrayRef,
                ),
                (
                    "split",
                    Arc::new(StringArray::from_iter_values(clips.iter().map(|_| "train"))),
                ),
                (
                    "clip_is_valid",
                    Arc::new(BooleanArray::from(
                        clips.iter().map(|c| c.valid).collect::<Vec<_>>(),
                    )),
                ),
                ("clip_id", idx()),
            ],
            Some("clip_id"),
        ),
    )
    .unwrap();
    let mut presence: Vec<(&str, ArrayRef)> = CameraId::ALL
        .iter()
        .map(|c| {
            (
                c.name(),
                Arc::new(BooleanArray::from(vec![true; clips.len()])) as ArrayRef,
            )
        })
        .collect();
    presence.push((
        "egomotion",
        Arc::new(BooleanArray::from(vec![true; clips.len()])),
    ));
    presence.push(("clip_id", idx()));
    std::fs::write(
        root.join("metadata/feature_presence.parquet"),
        parquet(presence, Some("clip_id")),
    )
    .unwrap();
    std::fs::write(
        root.join("metadata/data_collection.parquet"),
        parquet(
            vec![
                (
                    "country",
                    Arc::new(StringArray::from_iter_values(
                        clips.iter().map(|_| "nowhere"),
                    )) as ArrayRef,
                ),
                ("clip_id", idx()),
            ],
            Some("clip_id"),
        ),
    )
    .unwrap();
    let mut zips: BTreeMap<PathBuf, Vec<(String, Vec<u8>)>> = BTreeMap::new();
    for c in clips.iter().filter(|c| !c.videos.is_empty()) {
        let chunk = format!("chunk_{:04}", c.chunk);
        for (cam, frames, ts, faststart) in &c.videos {
            let n = cam.name();
            let zip = root.join(format!("camera/{n}/{n}.{chunk}.zip"));
            let e = zips.entry(zip).or_default();
            e.push((
                format!("{}.{n}.mp4", c.clip_id),
                encode_mp4(ff, frames, w, h, *faststart),
            ));
            e.push((
                format!("{}.{n}.timestamps.parquet", c.clip_id),
                timestamps_parquet(ts),
            ));
        }
        zips.entry(root.join(format!("labels/egomotion/egomotion.{chunk}.zip")))
            .or_default()
            .push((
                format!("{}.egomotion.parquet", c.clip_id),
                egomotion_parquet(&c.egomotion),
            ));
    }
    for (path, members) in zips {
        write_zip(&path, &members);
    }
}

/// The video of one camera around `t0`: 30 fps from `t0 − 0.5 s` to `t0 + 0.2 s` (frame
/// timestamps 7 µs early, so each time the import asks for falls just after a frame); the
/// frames at `t0 − 0.3 … t0` (numbers 6, 9, 12, 15) are the world's four, every other frame
/// the colour negative of the nearest of them, so that a wrong choice shows.
pub fn video_around(world: &[Vec<u8>], t0_us: i64) -> (Vec<Vec<u8>>, Vec<i64>) {
    let mut frames = Vec::new();
    let mut ts = Vec::new();
    for i in 0..22i64 {
        ts.push(t0_us - 500_000 + (i * 1_000_000 + 15) / 30 - 7);
        let k = ((i - 6) as f64 / 3.0).round().clamp(0.0, 3.0) as usize;
        if i >= 6 && (i - 6) % 3 == 0 && i <= 15 {
            frames.push(world[k].clone());
        } else {
            frames.push(world[k].iter().map(|v| 255 - v).collect());
        }
    }
    (frames, ts)
}

fn yaw_quat(yaw: f64) -> [f64; 4] {
    [0.0, 0.0, (yaw / 2.0).sin(), (yaw / 2.0).cos()]
}

/// The anchor of clip A's fixed frame: the rig at `t0` sits at `ANCHOR_XY` heading `ANCHOR_YAW`.
const ANCHOR_XY: [f64; 2] = [1234.5, -987.25];
const ANCHOR_YAW: f64 = 0.7;

/// Egomotion at 10 Hz from a world clip's history and ground truth, in a fixed frame rotated
/// and shifted from the rig frame at `t0`; one extra waypoint (extrapolated) so that a second
/// `t0` 0.1 s later is covered.
pub fn egomotion_from_world(clip: &fogline_world::Clip, t0_us: i64) -> Vec<EgoRow> {
    let (s, c) = ANCHOR_YAW.sin_cos();
    let to_world = |x: f64, y: f64| {
        [
            ANCHOR_XY[0] + c * x - s * y,
            ANCHOR_XY[1] + s * x + c * y,
            3.0,
        ]
    };
    let mut rows = Vec::new();
    for p in &clip.ego_history {
        let yaw = ANCHOR_YAW + p.yaw_rad;
        rows.push(EgoRow {
            t_us: t0_us + (p.t_s * 10.0).round() as i64 * 100_000,
            xyz: to_world(p.x_m, p.y_m),
            quat: yaw_quat(yaw),
            v: [p.speed_mps * yaw.cos(), p.speed_mps * yaw.sin(), 0.0],
        });
    }
    let mut gt = clip.ground_truth.xy.clone();
    let (a, b) = (gt[62], gt[63]);
    gt.push([2.0 * b[0] - a[0], 2.0 * b[1] - a[1]]);
    for k in 0..gt.len() {
        let prev = if k == 0 { [0.0, 0.0] } else { gt[k - 1] };
        let (dx, dy) = (gt[k][0] - prev[0], gt[k][1] - prev[1]);
        let yaw = ANCHOR_YAW
            + if dx.hypot(dy) > 1e-6 {
                dy.atan2(dx)
            } else {
                0.0
            };
        let speed = dx.hypot(dy) / 0.1;
        rows.push(EgoRow {
            t_us: t0_us + (k as i64 + 1) * 100_000,
            xyz: to_world(gt[k][0], gt[k][1]),
            quat: yaw_quat(yaw),
            v: [speed * yaw.cos(), speed * yaw.sin(), 0.0],
        });
    }
    rows
}

/// A 3-D path at about 100 Hz (jittered sample times): a left curve of radius 40 m climbing
/// a 2 % grade, speeding up from 8 m/s at 0.5 m/s², with a little pitch and roll.
pub fn egomotion_analytic(start_us: i64, end_us: i64) -> Vec<EgoRow> {
    let mut rows = Vec::new();
    let mut t = start_us;
    let mut i = 0u64;
    while t <= end_us {
        rows.push(analytic(t));
        i += 1;
        t = start_us + i as i64 * 10_000 + ((i * 7919) % 13) as i64 * 100;
    }
    rows
}

/// The analytic path at `t_us` (µs).
pub fn analytic(t_us: i64) -> EgoRow {
    let t = t_us as f64 * 1e-6;
    let (v0, acc, r) = (8.0, 0.5, 40.0);
    let s = v0 * t + 0.5 * acc * t * t;
    let v = v0 + acc * t;
    let heading = s / r;
    let xyz = [r * heading.sin(), r * (1.0 - heading.cos()), 0.02 * s];
    let (pitch, roll) = (-0.02 + 0.01 * (0.5 * t).sin(), 0.015 * (0.3 * t).cos());
    // Z-Y-X: yaw, then pitch, then roll (as quaternions composed yaw · pitch · roll).
    let qz = yaw_quat(heading);
    let qy = [0.0, (pitch / 2.0).sin(), 0.0, (pitch / 2.0).cos()];
    let qx = [(roll / 2.0).sin(), 0.0, 0.0, (roll / 2.0).cos()];
    let quat = fogline_import::spline::compose(fogline_import::spline::compose(qz, qy), qx);
    EgoRow {
        t_us,
        xyz,
        quat,
        v: [v * heading.cos(), v * heading.sin(), 0.02 * v],
    }
}

/// Peak signal-to-noise ratio of two RGB8 buffers, dB.
pub fn psnr(a: &[u8], b: &[u8]) -> f64 {
    let mse = a
        .iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        / a.len() as f64;
    10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10()
}

const A: &str = "0a1b2c3d-0000-4000-8000-00000000000a";
const B: &str = "0a1b2c3d-0000-4000-8000-00000000000b";
const T0: i64 = 5_100_000;

#[test]
fn physicalai_av_clips_import_as_the_world_made_them_and_as_the_devkit_reads_them() {
    let ff = ffmpeg();
    let python = crate::interop::python();
    let cfg = fogline_world::WorldConfig {
        depth: false,
        ..fogline_world::WorldConfig::default()
    };
    let (w, h) = (cfg.width, cfg.height);
    let worlds: Vec<fogline_world::Clip> = (0..2)
        .map(|i| fogline_world::generate_clip(&cfg, i).unwrap())
        .collect();
    let videos = |world: &fogline_world::Clip| {
        world
            .cameras
            .iter()
            .map(|cam| {
                let frames: Vec<Vec<u8>> =
                    cam.frames.iter().map(|f| f.image.data().to_vec()).collect();
                let (v, ts) = video_around(&frames, T0);
                // front_wide's index first (piped to ffmpeg), the others' at the end.
                (cam.calib.id, v, ts, cam.calib.id == CameraId::FrontWide)
            })
            .collect::<Vec<_>>()
    };
    let tree_clips = vec![
        TreeClip {
            clip_id: A.into(),
            chunk: 0,
            valid: true,
            videos: videos(&worlds[0]),
            egomotion: egomotion_from_world(&worlds[0], T0),
        },
        TreeClip {
            clip_id: B.into(),
            chunk: 0,
            valid: true,
            videos: videos(&worlds[1]),
            egomotion: egomotion_analytic(0, 12_000_000),
        },
        // Marked invalid; and in a chunk that is not downloaded.
        TreeClip {
            clip_id: "invalid-clip".into(),
            chunk: 0,
            valid: false,
            videos: vec![],
            egomotion: vec![],
        },
        TreeClip {
            clip_id: "elsewhere".into(),
            chunk: 1,
            valid: true,
            videos: vec![],
            egomotion: vec![],
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("PhysicalAI-Autonomous-Vehicles");
    write_tree(&root, &ff, &tree_clips, w, h);
    let labels = dir.path().join("labels.csv");
    std::fs::write(
        &labels,
        format!("clip_id,scenario\n{A},{}\n", worlds[0].scenario),
    )
    .unwrap();

    // The import, at t0 and 0.1 s later.
    let out = dir.path().join("clips");
    let t0s = format!("{T0},{}", T0 + 100_000);
    let o = fogline(&[
        "clips",
        "import",
        "physicalai-av",
        root.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--labels",
        labels.to_str().unwrap(),
        "--t0-us",
        &t0s,
        "--ffmpeg",
        ff.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("4 clips from 2 PhysicalAI-AV clips"), "{t}");
    assert!(
        t.contains("left out: 1 marked invalid, 1 in chunks not downloaded"),
        "{t}"
    );
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("import.json")).unwrap()).unwrap();
    assert_eq!(manifest["n_clips"], 4);
    assert_eq!(manifest["features_csv"], true);
    let read = |id: &str, t0: i64| {
        fogline_world::read_clip(&out.join(fogline_import::import::clip_name(id, t0))).unwrap()
    };

    // Clip A against the world it came from: frames within the codec's error, the
    // trajectory within rounding.
    let a = read(A, T0);
    assert_eq!(a.scenario, worlds[0].scenario);
    assert_eq!(read(B, T0).scenario, "OTHER");
    for (cam, src) in a.cameras.iter().zip(&worlds[0].cameras) {
        assert_eq!(cam.calib.id, src.calib.id);
        for (f, s) in cam.frames.iter().zip(&src.frames) {
            let p = psnr(f.image.data(), s.image.data());
            assert!(p > 30.0, "{:?} t {}: PSNR {p:.1} dB", cam.calib.id, f.t_s);
        }
    }
    let gt_err = a
        .ground_truth
        .xy
        .iter()
        .zip(&worlds[0].ground_truth.xy)
        .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
        .fold(0.0, f64::max);
    assert!(gt_err < 1e-9, "ground truth off by {gt_err} m");
    for (p, q) in a.ego_history.iter().zip(&worlds[0].ego_history) {
        assert_eq!(p.t_s, q.t_s);
        assert!(
            (p.x_m - q.x_m).abs() < 1e-9 && (p.y_m - q.y_m).abs() < 1e-9,
            "{p:?} {q:?}"
        );
        assert!((p.yaw_rad - q.yaw_rad).abs() < 1e-9, "{p:?} {q:?}");
        assert!((p.speed_mps - q.speed_mps).abs() < 1e-9, "{p:?} {q:?}");
    }
    // Clip B against its analytic path: the spline's interpolation error only.
    let b = read(B, T0);
    let p0 = analytic(T0);
    let inv = fogline_import::spline::to_matrix(fogline_import::spline::inverse(p0.quat));
    for (k, p) in b.ground_truth.xy.iter().enumerate() {
        let q = analytic(T0 + (k as i64 + 1) * 100_000);
        let d = [
            q.xyz[0] - p0.xyz[0],
            q.xyz[1] - p0.xyz[1],
            q.xyz[2] - p0.xyz[2],
        ];
        let want: Vec<f64> = (0..2)
            .map(|r| inv[r][0] * d[0] + inv[r][1] * d[1] + inv[r][2] * d[2])
            .collect();
        assert!(
            (p[0] - want[0]).hypot(p[1] - want[1]) < 1e-4,
            "waypoint {k}: {p:?} vs {want:?}"
        );
    }
    // The second t0 reuses three of the first's frames.
    let a2 = read(A, T0 + 100_000);
    for (c1, c2) in a.cameras.iter().zip(&a2.cameras) {
        for k in 0..3 {
            assert_eq!(c1.frames[k + 1].image, c2.frames[k].image);
        }
    }

    // The devkit on the same tree.
    let dk = dir.path().join("devkit");
    std::fs::create_dir_all(&dk).unwrap();
    let spec = serde_json::json!({
        "clips": [A, B],
        "t0_us": [T0, T0 + 100_000],
        "cameras": CameraId::ALL.iter().map(|c| c.name()).collect::<Vec<_>>(),
    });
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/it/physicalai_devkit.py");
    let o = Command::new(&python)
        .arg(&script)
        .arg(&root)
        .arg(&dk)
        .arg(spec.to_string())
        .output()
        .unwrap();
    assert!(o.status.success(), "the devkit failed: {}", text(&o));
    let devkit: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dk.join("devkit.json")).unwrap()).unwrap();
    let mut worst_traj = 0.0f64;
    let mut worst_pixel = 0u8;
    for id in [A, B] {
        for t0 in [T0, T0 + 100_000] {
            let clip = read(id, t0);
            let d = &devkit[format!("{id}@{t0}")];
            for (k, p) in clip.ground_truth.xy.iter().enumerate() {
                let q = &d["future"][k];
                let e = (p[0] - q[0].as_f64().unwrap()).hypot(p[1] - q[1].as_f64().unwrap());
                worst_traj = worst_traj.max(e);
            }
            for (k, p) in clip.ego_history.iter().enumerate() {
                let q: Vec<f64> = d["history"][k]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect();
                worst_traj = worst_traj
                    .max((p.x_m - q[0]).hypot(p.y_m - q[1]))
                    .max((p.yaw_rad - q[2]).abs())
                    .max((p.speed_mps - q[3]).abs());
            }
            let facts = &clip.scene.facts["frame_timestamps_us"];
            for cam in &clip.cameras {
                let f = &d["frames"][cam.calib.id.name()];
                assert_eq!(
                    facts[cam.calib.id.short()],
                    f["timestamps"],
                    "{id} {t0} {:?}",
                    cam.calib.id
                );
                let raw = std::fs::read(dk.join(f["file"].as_str().unwrap())).unwrap();
                assert_eq!(f["shape"], serde_json::json!([4, h, w, 3]));
                let n = (w * h * 3) as usize;
                for (k, frame) in cam.frames.iter().enumerate() {
                    let theirs = &raw[k * n..(k + 1) * n];
                    let diff = frame
                        .image
                        .data()
                        .iter()
                        .zip(theirs)
                        .map(|(x, y)| x.abs_diff(*y))
                        .max()
                        .unwrap();
                    worst_pixel = worst_pixel.max(diff);
                }
            }
        }
    }
    eprintln!(
        "fogline vs the devkit: trajectories within {worst_traj:.2e} (m, rad, m/s), pixels within {worst_pixel}"
    );
    assert!(
        worst_traj < 1e-9,
        "trajectories differ from the devkit's by {worst_traj}"
    );
    assert!(
        worst_pixel <= 2,
        "frames differ from the devkit's by up to {worst_pixel} levels"
    );

    // A campaign runs on the imported clips.
    let cfg_path = dir.path().join("campaign.toml");
    std::fs::write(
        &cfg_path,
        "[clips]\nsource = \"dir\"\npath = \"clips\"\n[conditions]\nnames = [\"noise_30\"]\n[run]\nconcurrency = 2\n",
    )
    .unwrap();
    let export = dir.path().join("export");
    let o = fogline(&[
        "campaign",
        "run",
        cfg_path.to_str().unwrap(),
        "--export",
        export.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("ran 8 runs"), "{}", text(&o));
    let pairs = std::fs::read_to_string(export.join("pairs.csv")).unwrap();
    assert_eq!(pairs.lines().count(), 5, "{pairs}");
    assert!(
        pairs.contains(&format!("{A}_t5.1s")) && pairs.contains("OTHER"),
        "{pairs}"
    );
}

#[test]
fn import_errors_name_the_file_and_leave_no_manifest() {
    let ff = ffmpeg();
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("root");
    let (w, h) = (64, 48);
    let frames: Vec<Vec<u8>> = (0..4)
        .map(|k| vec![40 * k as u8; (w * h * 3) as usize])
        .collect();
    let (video, ts) = video_around(&frames, T0);
    let clip = |id: &str| TreeClip {
        clip_id: id.into(),
        chunk: 0,
        valid: true,
        videos: vec![(CameraId::FrontWide, video.clone(), ts.clone(), false)],
        egomotion: egomotion_analytic(0, 12_000_000),
    };
    write_tree(&root, &ff, &[clip(A), clip(B)], w, h);
    let out = dir.path().join("out");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "clips",
            "import",
            "physicalai-av",
            root.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--cameras",
            "front_wide",
            "--width",
            "64",
            "--height",
            "48",
            "--ffmpeg",
            ff.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        fogline(&args)
    };
    let o = run(&[]);
    assert!(o.status.success(), "{}", text(&o));
    // Clip B's video truncated in its zip: the member is named, the first clip stays whole,
    // and no manifest claims a complete run.
    let zip = root.join("camera/camera_front_wide_120fov/camera_front_wide_120fov.chunk_0000.zip");
    let mut members = Vec::new();
    {
        let mut a = zip::ZipArchive::new(std::fs::File::open(&zip).unwrap()).unwrap();
        for i in 0..a.len() {
            let mut f = a.by_index(i).unwrap();
            let mut b = Vec::new();
            std::io::Read::read_to_end(&mut f, &mut b).unwrap();
            let name = f.name().unwrap().to_string();
            if name.starts_with(B) && name.ends_with(".mp4") {
                b.truncate(b.len() / 2);
            }
            members.push((name, b));
        }
    }
    write_zip(&zip, &members);
    let o = run(&[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let t = text(&o);
    assert!(
        t.contains(&format!(
            "camera_front_wide_120fov.chunk_0000.zip: {B}.camera_front_wide_120fov.mp4"
        )),
        "{t}"
    );
    assert!(t.contains("truncated MP4"), "{t}");
    assert!(!out.join("import.json").exists());
    assert!(fogline_world::read_clip(&out.join(format!("{A}_t5.1s"))).is_ok());
    // With --keep-going the failure is recorded and the rest imported.
    let o = run(&["--keep-going"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("failed: 1 clips"), "{}", text(&o));
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("import.json")).unwrap()).unwrap();
    assert_eq!(m["failed"][0]["source_clip_id"], B);
    assert!(
        m["failed"][0]["error"]
            .as_str()
            .unwrap()
            .contains("truncated MP4")
    );
    // A t0 the egomotion does not cover, a clip the index lacks, a missing ffmpeg.
    let o = run(&["--t0-us", "11000000"]);
    assert!(text(&o).contains("needs 9.5 … 17.4 s"), "{}", text(&o));
    let o = run(&["--clip", "nope"]);
    assert!(
        text(&o).contains("clip_index.parquet: no clip nope in the index"),
        "{}",
        text(&o)
    );
    let o = fogline(&[
        "clips",
        "import",
        "physicalai-av",
        root.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--ffmpeg",
        "/nonexistent/ffmpeg",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("scripts/python-peers.sh"), "{}", text(&o));
}
