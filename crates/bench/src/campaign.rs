//! `fogline bench campaign`: (a) the paper-size campaign with the built-in planner, timed
//! end to end into a fresh store; (b) the runner's overhead per remote call — the same request
//! answered by a trivial planner in-process, over egodriver gRPC and over HTTP on loopback.

use std::io::Write;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use fogline_campaign::runner::{condition_frames, planner_input};
use fogline_campaign::{Campaign, CampaignConfig, Shard, Store};
use fogline_remote::{ImageFormat, PlanFailure, PlanRequest, Planner};
use fogline_types::clip::{HORIZON, PlannerOutput, Trajectory};

/// What `fogline bench campaign` runs.
#[derive(Debug, Clone)]
pub struct CampaignBench {
    /// Clips of the timed campaign (0 skips it; the paper's corpus has 1,996).
    pub clips: usize,
    /// Remote calls timed per protocol and image format (0 skips the overhead part).
    pub calls: usize,
    /// Runs of `calls` calls each: the figure is the median of the runs' medians.
    pub runs: usize,
    /// Print JSON after the report.
    pub json: bool,
}

/// A planner that answers at once: what remains of a remote call's time is the runner's.
struct Instant64;

impl Planner for Instant64 {
    fn describe(&self) -> String {
        "trivial planner (answers at once)".into()
    }
    fn plan(&self, _: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        Ok(PlannerOutput {
            trajectory: Trajectory {
                xy: (1..=HORIZON).map(|i| [0.5 * i as f64, 0.0]).collect(),
            },
            explanation: "Keep lane.".into(),
            decision: None,
        })
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[v.len() / 2]
}

fn time_calls(planner: &dyn Planner, req: &PlanRequest<'_>, n: usize) -> Result<Vec<f64>> {
    planner.plan(req).map_err(anyhow::Error::msg)?; // warm-up (connection, buffers)
    (0..n)
        .map(|_| {
            let t = Instant::now();
            planner.plan(req).map_err(anyhow::Error::msg)?;
            Ok(t.elapsed().as_secs_f64() * 1e3)
        })
        .collect()
}

/// Runs the benchmark, writing its report to `out` (JSON at the end with `json`).
pub fn run(a: &CampaignBench, out: &mut dyn Write) -> Result<()> {
    let mut json = serde_json::Map::new();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if a.clips > 0 {
        let cfg = CampaignConfig::from_toml(&format!("[clips]\ncount = {}\n", a.clips))?;
        let tmp = crate::TempDir::new("campaign")?;
        let dir = tmp.path().to_path_buf();
        let store_path = dir.join("bench.sqlite");
        let campaign = Campaign::new(cfg.clone())?;
        let mut store = Store::create(&store_path, &campaign.store_meta(Shard::ALL))?;
        let opts = fogline_campaign::run_options(&cfg, Shard::ALL);
        let planner = fogline_campaign::BuiltinPlanner::new();
        let progress = fogline_io::Progress::new(0, "runs");
        let s = fogline_campaign::run(&campaign, &mut store, &planner, &opts, &progress)?;
        progress.finish();
        let runs = store.runs()?;
        let t = Instant::now();
        let exported = fogline_campaign::export::export(
            &runs,
            &dir.join("export"),
            fogline_campaign::export::Formats {
                csv: true,
                parquet: true,
                codec: fogline_campaign::export::ParquetCodec::default(),
            },
            false,
        )?;
        let export_s = t.elapsed().as_secs_f64();
        drop(store);
        drop(tmp);
        let goal = 180.0;
        writeln!(
            out,
            "campaign: {} clips × {} conditions = {} runs, built-in planner, {} workers",
            a.clips,
            campaign.conditions.len(),
            s.ran,
            opts.concurrency
        )?;
        writeln!(
            out,
            "  run      {:>8.1} s  ({:.1} runs/s, {:.1} ms per clip on {cores} cores)   goal ≤ {goal:.0} s for 1,996 clips: {}",
            s.seconds,
            s.ran as f64 / s.seconds,
            s.seconds * 1e3 / a.clips as f64,
            if a.clips == 1996 {
                if s.seconds <= goal { "met" } else { "NOT met" }
            } else {
                "(not the paper size)"
            }
        )?;
        writeln!(
            out,
            "  export   {export_s:>8.2} s  ({} files, {} pairs)",
            exported.files.len(),
            exported.pairs.iter().map(|p| p.1.pairs).sum::<usize>()
        )?;
        json.insert(
            "campaign".into(),
            serde_json::json!({
                "clips": a.clips, "runs": s.ran, "failed": s.failed, "workers": opts.concurrency,
                "cores": cores, "seconds": s.seconds, "export_seconds": export_s, "goal_seconds": goal,
            }),
        );
    }
    if a.calls > 0 {
        let mut rows = Vec::new();
        for condition in ["clean", "noise_30"] {
            rows.push(remote_overhead(a, condition, out)?);
        }
        json.insert("remote_overhead".into(), serde_json::Value::Array(rows));
    }
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&json)?)?;
    }
    Ok(())
}

/// Goals of issue 22 for the overhead per call, ms: PNG, JPEG 95.
const GOAL_MS: [f64; 2] = [10.0, 20.0];

/// The jpeg-encoder crate's time to encode `frames` on one thread at `quality`, 4:4:4 (the
/// median of five rounds, ms), and its bytes.
fn peer_jpeg(frames: &[(&[u8], u32, u32)], quality: u8) -> Result<(f64, usize)> {
    let mut times = Vec::new();
    let mut bytes = 0;
    for _ in 0..5 {
        let t = Instant::now();
        bytes = 0;
        for &(f, w, h) in frames {
            let mut out = Vec::with_capacity(f.len() / 8);
            let mut enc = jpeg_encoder::Encoder::new(&mut out, quality);
            enc.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
            enc.encode(f, w as u16, h as u16, jpeg_encoder::ColorType::Rgb)
                .context("the jpeg-encoder crate")?;
            bytes += out.len();
        }
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok((median(times), bytes))
}

/// Part (b) under one condition: the frames' encode and decode on one thread, then the same
/// request answered by a trivial planner in-process, over egodriver gRPC and over HTTP on
/// loopback, PNG and JPEG 95, `a.runs` runs of `a.calls` calls each.
fn remote_overhead(
    a: &CampaignBench,
    condition: &str,
    out: &mut dyn Write,
) -> Result<serde_json::Value> {
    // One clip of the default size, every camera.
    let cfg = CampaignConfig::from_toml("[clips]\ncount = 1\n")?;
    let campaign = Campaign::new(cfg)?;
    let clip = campaign.clips.load(0, None).map_err(anyhow::Error::msg)?;
    let perturbation = fogline_perturb::Perturbation::parse(condition)?.prepare(0)?;
    let frames = condition_frames(&clip, 0, &perturbation).map_err(anyhow::Error::msg)?;
    let req = PlanRequest {
        scene_id: &clip.id,
        seed: 0,
        input: planner_input(&clip, &frames),
    };
    let runs = a.runs.max(1);
    let cams = req.input.cameras.len();
    let per = req.input.cameras.first().map_or(0, |c| c.frames.len());
    let (w, h) = req
        .input
        .cameras
        .first()
        .map_or((0, 0), |c| (c.calib.width, c.calib.height));
    let formats = [
        (ImageFormat::Png, "png", GOAL_MS[0]),
        (ImageFormat::Jpeg { quality: 95 }, "jpeg95", GOAL_MS[1]),
    ];
    writeln!(
        out,
        "remote call overhead, {condition} frames: {cams} cameras × {per} frames of {w}×{h}, trivial planner, loopback; the median of {runs} runs of {} calls each",
        a.calls
    )?;
    writeln!(
        out,
        "  on {} ({} cores); frames encoded in parallel, egodriver frames sent as they are encoded, camera by camera at once; PNG by the {}, JPEG by {}",
        crate::embed::cpu_name(),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        fogline_io::encoder_name(ImageFormat::Png, fogline_io::PngSpeed::Wire),
        fogline_io::encoder_name(
            ImageFormat::Jpeg { quality: 95 },
            fogline_io::PngSpeed::Wire
        )
    )?;
    // What a call is made of: every frame encoded and decoded once, on one thread.
    let all: Vec<(&[u8], u32, u32)> = req
        .input
        .cameras
        .iter()
        .flat_map(|c| c.frames.iter().map(|f| (*f, c.calib.width, c.calib.height)))
        .collect();
    let raw: usize = all.iter().map(|f| f.0.len()).sum();
    let mut codec = Vec::new();
    for (format, fname, _) in formats {
        use rayon::prelude::*;
        let encode = |&(f, w, h): &(&[u8], u32, u32)| {
            fogline_io::encode_with(f, w, h, format, fogline_io::PngSpeed::Wire)
                .map_err(anyhow::Error::msg)
        };
        let decode = |e: &Vec<u8>| {
            fogline_remote::decode_frame(e, u64::MAX)
                .map(|_| ())
                .map_err(anyhow::Error::msg)
        };
        // Median encode and decode times of five rounds (ms) and the bytes on the wire: on
        // one thread, or on every core (one frame per task: what a call costs at the least
        // here, the client's encode and the server's decode sharing the machine).
        let timed = |all_cores: bool| -> Result<(f64, f64, usize)> {
            let (mut enc, mut dec, mut bytes) = (Vec::new(), Vec::new(), 0);
            for _ in 0..5 {
                let t = Instant::now();
                let encoded: Vec<Vec<u8>> = if all_cores {
                    all.par_iter().map(encode).collect::<Result<_>>()?
                } else {
                    all.iter().map(encode).collect::<Result<_>>()?
                };
                enc.push(t.elapsed().as_secs_f64() * 1e3);
                let t = Instant::now();
                if all_cores {
                    encoded
                        .par_iter()
                        .map(decode)
                        .collect::<Result<Vec<()>>>()?;
                } else {
                    encoded.iter().map(decode).collect::<Result<Vec<()>>>()?;
                }
                dec.push(t.elapsed().as_secs_f64() * 1e3);
                bytes = encoded.iter().map(Vec::len).sum();
            }
            Ok((median(enc), median(dec), bytes))
        };
        let (enc, dec, bytes) = timed(false)?;
        let (par_enc, par_dec, _) = timed(true)?;
        writeln!(
            out,
            "  {fname:<7} {} frames on one thread: encode {enc:.2} ms, decode {dec:.2} ms; {:.0} kB on the wire ({:.0} % of the pixels' bytes)",
            all.len(),
            bytes as f64 / 1e3,
            100.0 * bytes as f64 / raw.max(1) as f64
        )?;
        writeln!(
            out,
            "  {:<7} on all {} cores: encode {par_enc:.2} ms, decode {par_dec:.2} ms; {:.2} ms together, the least a call can cost here",
            "",
            rayon::current_num_threads(),
            par_enc + par_dec
        )?;
        // The peer: the jpeg-encoder crate (AVX2 where the CPU has it) at the same setting.
        let peer = match format {
            ImageFormat::Jpeg { quality } => {
                let (ms, peer_bytes) = peer_jpeg(&all, quality)?;
                writeln!(
                    out,
                    "  {:<7} the jpeg-encoder crate, same setting, one thread: encode {ms:.2} ms, {:.0} kB — fogline's encoder {:.2}× as fast",
                    "",
                    peer_bytes as f64 / 1e3,
                    ms / enc.max(1e-9)
                )?;
                serde_json::json!({"encoder": "jpeg-encoder", "encode_ms": ms, "bytes": peer_bytes})
            }
            ImageFormat::Png => serde_json::Value::Null,
        };
        codec.push(serde_json::json!({
            "format": fname, "frames": all.len(), "encode_ms": enc, "decode_ms": dec, "bytes": bytes,
            "peer": peer,
            "all_cores": {
                "threads": rayon::current_num_threads(), "encode_ms": par_enc, "decode_ms": par_dec,
            },
        }));
    }
    let trivial: Arc<dyn Planner> = Arc::new(Instant64);
    let grpc = fogline_remote::egodriver::serve(
        "127.0.0.1:0".parse()?,
        trivial.clone(),
        Default::default(),
    )
    .context("cannot start the egodriver server on loopback")?;
    let http =
        fogline_remote::http::serve("127.0.0.1:0".parse()?, trivial.clone(), Default::default())
            .context("cannot start the HTTP server on loopback")?;
    let mut paths: Vec<(String, Box<dyn Planner>, f64)> = Vec::new();
    for (format, fname, goal) in formats {
        let g = fogline_remote::egodriver::Client::new(fogline_remote::egodriver::ClientOptions {
            endpoint: grpc.local_addr().to_string(),
            image_format: format,
            ..Default::default()
        })?;
        let hc = fogline_remote::http::Client::new(fogline_remote::http::ClientOptions {
            url: format!("http://{}", http.local_addr()),
            image_format: format,
            ..Default::default()
        })?;
        paths.push((format!("egodriver gRPC, {fname}"), Box::new(g), goal));
        paths.push((format!("HTTP/JSON, {fname}"), Box::new(hc), goal));
    }
    // Run after run, each timing every path: a slow spell of the machine lands in one run's
    // figures rather than in one path's.
    let mut direct = Vec::with_capacity(runs);
    let mut ms = vec![Vec::with_capacity(runs); paths.len()];
    for _ in 0..runs {
        direct.push(median(time_calls(trivial.as_ref(), &req, a.calls)?));
        for (k, (_, p, _)) in paths.iter().enumerate() {
            ms[k].push(median(time_calls(p.as_ref(), &req, a.calls)?));
        }
    }
    grpc.shutdown()?;
    http.shutdown()?;
    writeln!(
        out,
        "  {:<24} {:>9} {:>12} {:>20}   goal",
        "path", "ms/call", "overhead ms", "runs' overhead ms"
    )?;
    let d = median(direct.clone());
    writeln!(out, "  {:<24} {d:>9.3} {:>12}", "in-process", "—")?;
    let mut rows = vec![serde_json::json!({"path": "in-process", "ms": d, "runs_ms": direct})];
    for (k, (name, _, goal)) in paths.iter().enumerate() {
        let overheads: Vec<f64> = ms[k].iter().zip(&direct).map(|(m, d)| m - d).collect();
        let m = median(ms[k].clone());
        let o = median(overheads.clone());
        let each = overheads
            .iter()
            .map(|v| format!("{v:.1}"))
            .collect::<Vec<_>>()
            .join(" / ");
        let met = if o <= *goal { "met" } else { "not met" };
        writeln!(
            out,
            "  {name:<24} {m:>9.3} {o:>12.3} {each:>20}   ≤ {goal:.0} ms: {met}"
        )?;
        rows.push(serde_json::json!({
            "path": name, "ms": m, "overhead_ms": o, "runs_overhead_ms": overheads,
            "goal_ms": goal, "met": o <= *goal,
        }));
    }
    Ok(serde_json::json!({
        "condition": condition, "cameras": cams, "frames_per_camera": per, "width": w,
        "height": h, "calls": a.calls, "runs": runs, "cpu": crate::embed::cpu_name(),
        "codec_one_thread": codec, "paths": rows,
    }))
}
