//! `fogline bench perturb`: per-family cost of the perturbation engine on a synthetic frame,
//! one thread, next to the memory floor (a copy) and, with `peers`, next to the Python
//! libraries (numpy, OpenCV, albumentations, imagecorruptions) run on the same frame.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use fogline_perturb::rng::WyRand;
use fogline_perturb::{DepthMap, Frame, FrameInput, FrameKey, ObjectBox, Perturbation, Prepared};
use serde::{Deserialize, Serialize};

/// What `fogline bench perturb` runs.
#[derive(Debug, Clone)]
pub struct PerturbBench {
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// Timed runs per family (the median is reported), after one warm-up.
    pub runs: usize,
    /// Only conditions whose name contains this.
    pub filter: Option<String>,
    /// Also time the Python peers on the same frame.
    pub peers: bool,
    /// Python interpreter for the peers (default: `$FOGLINE_PYTHON`, else
    /// `target/perturb-peers-venv/bin/python` when it exists, else `python3`).
    pub python: Option<PathBuf>,
    /// The peers script (default: the one shipped in the binary).
    pub peers_script: Option<PathBuf>,
    /// Print JSON instead of the table.
    pub json: bool,
}

/// The conditions timed, with `@depth` (Koschmieder, with the synthetic depth map) and
/// `@boxes` (the 10 synthetic boxes) marking what they are given.
const BENCH_CONDITIONS: [&str; 30] = [
    "noise_10",
    "noise_30",
    "noise_50",
    "noise_70",
    "dark",
    "bright",
    "fog_03",
    "fog_07",
    "fog_07@depth",
    "visibility_150@depth",
    "shot_4",
    "impulse_0.03",
    "contrast_0.4",
    "saturation_0.2",
    "quantize_3",
    "glare_0.8",
    "defocus_3",
    "motion_15",
    "pixelate_8",
    "jpeg_25",
    "dead_0.001",
    "dirt_5",
    "mask_all@boxes",
    "noise_30+fog_03",
    "noise_20.4",
    "noise_30.6",
    "noise_66.3",
    "shot_4.25",
    "dark+noise_10+jpeg_25",
    "clean",
];

struct Bench {
    frame: Frame,
    depth: DepthMap,
    boxes: Vec<ObjectBox>,
    out: Frame,
    flush: Vec<u8>,
    runs: usize,
}

impl Bench {
    /// Evicts the caches: one write per 64-byte line of a 64 MiB buffer.
    fn flush(&mut self) {
        for (i, b) in self.flush.iter_mut().enumerate().step_by(64) {
            *b = b.wrapping_add(i as u8);
        }
        std::hint::black_box(&self.flush);
    }

    /// Median and minimum ms of `runs` timed calls after one warm-up, caches flushed before
    /// each.
    fn time(&mut self, mut f: impl FnMut(&mut Self) -> Result<()>) -> Result<Timing> {
        f(self)?;
        let mut ms = Vec::with_capacity(self.runs);
        for _ in 0..self.runs {
            self.flush();
            let t = Instant::now();
            f(self)?;
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(&self.out);
        }
        ms.sort_by(f64::total_cmp);
        Ok(Timing {
            median_ms: ms[ms.len() / 2],
            min_ms: ms[0],
        })
    }

    fn copy(&mut self) -> Result<Timing> {
        self.time(|b| {
            b.out.clone_from(&b.frame);
            Ok(())
        })
    }

    fn condition(&mut self, spec: &str) -> Result<(Timing, Prepared)> {
        let (name, extra) = spec.split_once('@').unwrap_or((spec, ""));
        let p = Perturbation::parse(name)?.prepare(0)?;
        let ms = self.time(|b| {
            let input = FrameInput {
                frame: b.frame.view(),
                key: FrameKey::new(1, 0, 0),
                depth: (extra == "depth").then_some(&b.depth),
                boxes: if extra == "boxes" { &b.boxes } else { &[] },
            };
            p.apply_into(&input, &mut b.out)?;
            Ok(())
        })?;
        Ok((ms, p))
    }
}

/// The synthetic scene: sky above the horizon (depth +inf), a textured ground plane below
/// (depth `1.5 m · H / (y − H/2 + ½)`), coloured boxes standing in for cars.
fn synthetic(w: u32, h: u32) -> Result<(Frame, DepthMap, Vec<ObjectBox>)> {
    let mut rng = WyRand::new(0);
    let mut data = Vec::with_capacity((w * h * 3) as usize);
    let mut depth = Vec::with_capacity((w * h) as usize);
    let horizon = h / 2;
    for y in 0..h {
        for x in 0..w {
            let r = rng.next_u64();
            let tex = (r & 31) as u32;
            let px = if y < horizon {
                let t = 120 * y / horizon.max(1);
                [
                    (90 + t / 2 + tex / 4) as u8,
                    (130 + t / 2) as u8,
                    (200 + tex / 8) as u8,
                ]
            } else {
                let lane = (x * 16 / w).is_multiple_of(4) && ((y - horizon) / 8).is_multiple_of(2);
                let g = if lane { 220 } else { 70 + tex * 3 };
                [g as u8, g as u8, (g + 5).min(255) as u8]
            };
            data.extend_from_slice(&px);
            depth.push(if y < horizon {
                f32::INFINITY
            } else {
                1.5 * h as f32 / ((y - horizon) as f32 + 0.5)
            });
        }
    }
    let mut frame = Frame::new(w, h, data)?;
    let boxes: Vec<ObjectBox> = (0..10u32)
        .map(|i| ObjectBox {
            class: if i % 3 == 0 { "pedestrian" } else { "car" }.into(),
            track_id: Some(u64::from(i)),
            x_px: f64::from(w * (5 + 8 * i) / 100),
            y_px: f64::from(h * 46 / 100),
            width_px: f64::from((w * 4 / 100).max(1)),
            height_px: f64::from((h * 11 / 100).max(1)),
        })
        .collect();
    // Paint the objects so that masking has something to hide.
    let stride = w as usize * 3;
    for (i, b) in boxes.iter().enumerate() {
        let r = b.pixel_rect();
        let colour = [[200, 30, 30], [30, 30, 200], [230, 230, 230]][i % 3];
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let o = y as usize * stride + x as usize * 3;
                frame.data_mut()[o..o + 3].copy_from_slice(&colour);
            }
        }
    }
    Ok((frame, DepthMap::new(w, h, depth)?, boxes))
}

/// Median and minimum of a benchmark's runs.
#[derive(Clone, Copy)]
struct Timing {
    median_ms: f64,
    min_ms: f64,
}

#[derive(Serialize)]
struct BenchRow {
    condition: String,
    family: String,
    /// Median ms/frame.
    ms: f64,
    min_ms: f64,
    vs_copy: f64,
}

#[derive(Serialize, Deserialize)]
struct PeerRow {
    op: String,
    peer: String,
    fogline: String,
    ms: f64,
    #[serde(default)]
    min_ms: f64,
    runs: usize,
    #[serde(default)]
    note: String,
}

#[derive(Serialize, Deserialize)]
struct PeerSkip {
    peer: String,
    why: String,
}

#[derive(Deserialize)]
struct PeerReport {
    python: String,
    versions: BTreeMap<String, String>,
    results: Vec<PeerRow>,
    skipped: Vec<PeerSkip>,
}

/// The source tree this binary was built from (for the peers script and its venv).
/// The peers script, shipped inside the binary (written next to the frame when run), so an
/// installed `fogline` needs no source tree.
const PEERS_SCRIPT: &str = include_str!("../../../scripts/perturb_peers.py");

/// Runs the benchmark, writing its report (or its JSON with `json`) to `out`.
pub fn run(a: &PerturbBench, out: &mut dyn Write) -> Result<()> {
    if a.width < 16 || a.height < 16 || a.width > 16_384 || a.height > 16_384 {
        bail!("--width and --height must be in [16, 16384]");
    }
    if a.runs == 0 {
        bail!("--runs must be at least 1");
    }
    let (frame, depth, boxes) = synthetic(a.width, a.height)?;
    let mut b = Bench {
        out: frame.clone(),
        frame,
        depth,
        boxes,
        flush: vec![0u8; 64 << 20],
        runs: a.runs,
    };
    let mb = f64::from(a.width) * f64::from(a.height) * 3.0 / 1e6;
    log::info!(
        "bench perturb: {}×{} RGB ({mb:.1} MB), one thread, median of {} runs, caches flushed before each",
        a.width,
        a.height,
        a.runs
    );
    // Let the clock and the caches settle before the first measurement (the first family
    // timed would otherwise pay for it): ~0.3 s of the kind of work measured.
    let settle = Instant::now();
    let warm = Perturbation::parse("noise_30")?.prepare(0)?;
    while settle.elapsed() < Duration::from_millis(300) {
        warm.apply_into(&FrameInput::new(&b.frame, FrameKey::default()), &mut b.out)?;
        b.flush();
    }
    let copy = b.copy()?;
    let copy_ms = copy.median_ms;
    let mut rows: Vec<BenchRow> = Vec::new();
    let mut measured: BTreeMap<String, f64> = BTreeMap::new();
    measured.insert("copy".into(), copy_ms);
    for spec in BENCH_CONDITIONS {
        if a.filter.as_deref().is_some_and(|f| !spec.contains(f)) {
            continue;
        }
        let (t, p) = b.condition(spec)?;
        log::debug!("{spec}: {:.3} ms", t.median_ms);
        rows.push(BenchRow {
            condition: spec.to_string(),
            family: family_of(p.perturbation()),
            ms: t.median_ms,
            min_ms: t.min_ms,
            vs_copy: t.median_ms / copy_ms,
        });
        measured.insert(spec.to_string(), t.median_ms);
    }

    let peers = if a.peers {
        let report = run_peers(a, &b)?;
        // Time any fogline condition a peer compares with that the list above lacks.
        for r in &report.results {
            if !measured.contains_key(&r.fogline) {
                let (t, _) = b.condition(&r.fogline)?;
                measured.insert(r.fogline.clone(), t.median_ms);
            }
        }
        Some(report)
    } else {
        None
    };

    let get = |name: &str| measured.get(name).copied();
    let max_of = |names: &[&str]| {
        names
            .iter()
            .filter_map(|n| get(n))
            .fold(None, |acc: Option<f64>, v| {
                Some(acc.map_or(v, |a| a.max(v)))
            })
    };
    // The millisecond goals are for 1080p frames.
    let full_hd = (a.width, a.height) == (1920, 1080);
    let noise_ms = max_of(&["noise_10", "noise_30", "noise_50", "noise_70"]).filter(|_| full_hd);
    let lut_ms = max_of(&["dark", "bright", "fog_03", "fog_07"]);
    let depth_ms = get("fog_07@depth").filter(|_| full_hd);
    let ratio_min = |peer: &str| -> Option<f64> {
        peers.as_ref().and_then(|p| {
            p.results
                .iter()
                .filter(|r| r.peer.starts_with(peer) && r.fogline.starts_with("noise_"))
                .filter_map(|r| get(&r.fogline).map(|f| r.ms / f))
                .fold(None, |acc: Option<f64>, v| {
                    Some(acc.map_or(v, |a| a.min(v)))
                })
        })
    };
    let numpy_ratio = ratio_min("numpy default_rng");
    let albu_ratio = ratio_min("albumentations GaussNoise");
    let goals = [
        ("gaussian noise <= 3 ms/frame", noise_ms, 3.0, false, "ms"),
        (
            "gain and uniform fog <= 1.5x copy",
            lut_ms.map(|v| v / copy_ms),
            1.5,
            false,
            "x copy",
        ),
        ("depth fog <= 3 ms/frame", depth_ms, 3.0, false, "ms"),
        ("noise >= 25x numpy", numpy_ratio, 25.0, true, "x"),
        ("noise >= 13x albumentations", albu_ratio, 13.0, true, "x"),
    ];

    if a.json {
        let peer_rows: Vec<serde_json::Value> = peers
            .iter()
            .flat_map(|p| &p.results)
            .map(|r| {
                let f = get(&r.fogline);
                serde_json::json!({
                    "op": r.op, "peer": r.peer, "peer_ms": r.ms, "peer_min_ms": r.min_ms,
                    "peer_runs": r.runs,
                    "fogline": r.fogline, "fogline_ms": f, "ratio": f.map(|f| r.ms / f),
                    "note": r.note,
                })
            })
            .collect();
        let v = serde_json::json!({
            "width": a.width,
            "height": a.height,
            "runs": a.runs,
            "threads": 1,
            "caches": "flushed (64 MiB sweep) before every timed run",
            "gaussian_kernel": fogline_perturb::noise::GaussianTable::kernel_name(),
            "copy_ms": copy_ms,
            "copy_min_ms": copy.min_ms,
            "families": rows,
            "goals": goals.iter().map(|(name, v, target, at_least, _)| serde_json::json!({
                "goal": name, "value": v, "target": target,
                "met": v.map(|v| if *at_least { v >= *target } else { v <= *target }),
            })).collect::<Vec<_>>(),
            "peers": peers.as_ref().map(|p| serde_json::json!({
                "python": p.python, "versions": p.versions, "threads": 1,
                "results": peer_rows, "skipped": p.skipped,
            })),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(());
    }
    writeln!(
        out,
        "fogline bench perturb: {}x{} RGB frame ({mb:.1} MB), one thread, median of {} runs, caches flushed before each run; Gaussian-noise kernel: {}",
        a.width,
        a.height,
        a.runs,
        fogline_perturb::noise::GaussianTable::kernel_name()
    )?;
    writeln!(
        out,
        "{:<16} {:<24} {:>10} {:>8} {:>8}",
        "family", "condition", "ms/frame", "min", "x copy"
    )?;
    writeln!(
        out,
        "{:<16} {:<24} {:>10.3} {:>8.3} {:>8.2}",
        "copy floor", "(memcpy)", copy_ms, copy.min_ms, 1.0
    )?;
    for r in &rows {
        writeln!(
            out,
            "{:<16} {:<24} {:>10.3} {:>8.3} {:>8.2}",
            r.family, r.condition, r.ms, r.min_ms, r.vs_copy
        )?;
    }
    for (name, v, target, at_least, unit) in &goals {
        if let Some(v) = v {
            let met = if *at_least { v >= target } else { v <= target };
            writeln!(
                out,
                "goal  {name:<36} {v:>8.2} {unit:<7} {}",
                if met { "met" } else { "NOT met" }
            )?;
        }
    }
    if let Some(p) = &peers {
        let versions: Vec<String> = p.versions.iter().map(|(k, v)| format!("{k} {v}")).collect();
        writeln!(
            out,
            "peers: python {} ({}), one thread, same frame, median of up to {} runs",
            p.python,
            versions.join(", "),
            a.runs
        )?;
        writeln!(
            out,
            "{:<30} {:<48} {:>10} {:<22} {:>10} {:>9}",
            "operation", "peer", "peer ms", "fogline", "fogline ms", "ratio"
        )?;
        for r in &p.results {
            let f = get(&r.fogline);
            writeln!(
                out,
                "{:<30} {:<48} {:>10.2} {:<22} {:>10.3} {:>9}{}",
                r.op,
                r.peer,
                r.ms,
                r.fogline,
                f.unwrap_or(f64::NAN),
                f.map_or("-".into(), |f| format!("{:.1}x", r.ms / f)),
                if r.note.is_empty() {
                    String::new()
                } else {
                    format!("  ({})", r.note)
                }
            )?;
        }
        for s in &p.skipped {
            writeln!(out, "peer skipped: {}: {}", s.peer, s.why)?;
        }
    }
    Ok(())
}

fn family_of(p: &Perturbation) -> String {
    match p.steps.as_slice() {
        [] => "identity".into(),
        [s] => s.family().into(),
        _ => "composite".into(),
    }
}

/// Writes the frame, depth and boxes to a temporary directory, runs the peers script on them
/// and reads its JSON report.
fn run_peers(a: &PerturbBench, b: &Bench) -> Result<PeerReport> {
    let python = a
        .python
        .clone()
        .or_else(|| std::env::var_os("FOGLINE_PYTHON").map(PathBuf::from))
        .unwrap_or_else(|| {
            let venv = PathBuf::from("target/perturb-peers-venv/bin/python");
            if venv.exists() {
                venv
            } else {
                PathBuf::from("python3")
            }
        });
    let dir = std::env::temp_dir().join(format!("fogline-bench-perturb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let result = (|| -> Result<PeerReport> {
        let script = match &a.peers_script {
            Some(s) => s.clone(),
            None => {
                let s = dir.join("perturb_peers.py");
                std::fs::write(&s, PEERS_SCRIPT)?;
                s
            }
        };
        let frame_path = dir.join("frame.rgb");
        let depth_path = dir.join("depth.f32");
        let boxes_path = dir.join("boxes.json");
        std::fs::write(&frame_path, b.frame.data())?;
        let depth_bytes: Vec<u8> = b
            .depth
            .depth_m()
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect();
        std::fs::write(&depth_path, depth_bytes)?;
        let boxes: Vec<[u32; 4]> = b
            .boxes
            .iter()
            .map(|o| {
                let r = o.pixel_rect();
                [r.x0, r.y0, r.x1 - r.x0, r.y1 - r.y0]
            })
            .collect();
        std::fs::write(&boxes_path, serde_json::to_vec(&boxes)?)?;
        log::info!(
            "running the Python peers: {} {}",
            python.display(),
            script.display()
        );
        let o = std::process::Command::new(&python)
            .arg(&script)
            .args(["--width", &a.width.to_string()])
            .args(["--height", &a.height.to_string()])
            .args(["--runs", &a.runs.to_string()])
            .arg("--frame")
            .arg(&frame_path)
            .arg("--depth")
            .arg(&depth_path)
            .arg("--boxes")
            .arg(&boxes_path)
            .env("OMP_NUM_THREADS", "1")
            .env("OPENBLAS_NUM_THREADS", "1")
            .env("MKL_NUM_THREADS", "1")
            .output()
            .with_context(|| {
                format!(
                    "cannot run {} (install the peers with scripts/perturb-peers.sh)",
                    python.display()
                )
            })?;
        if !o.status.success() {
            let err = String::from_utf8_lossy(&o.stderr);
            let tail: Vec<&str> = err.lines().rev().take(5).collect();
            bail!(
                "the peers script failed ({}): {}",
                o.status,
                tail.into_iter().rev().collect::<Vec<_>>().join("\n")
            );
        }
        serde_json::from_slice(&o.stdout).context("the peers script printed no JSON report")
    })();
    let _ = std::fs::remove_dir_all(&dir);
    result
}
