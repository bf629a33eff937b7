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
        // One clip of the default size, under noise_30, every camera.
        let cfg = CampaignConfig::from_toml("[clips]\ncount = 1\n")?;
        let campaign = Campaign::new(cfg)?;
        let clip = campaign.clips.load(0, None).map_err(anyhow::Error::msg)?;
        let noise = fogline_perturb::Perturbation::parse("noise_30")?.prepare(0)?;
        let frames = condition_frames(&clip, 0, &noise).map_err(anyhow::Error::msg)?;
        let req = PlanRequest {
            scene_id: &clip.id,
            seed: 0,
            input: planner_input(&clip, &frames),
        };
        let trivial: Arc<dyn Planner> = Arc::new(Instant64);
        let direct = median(time_calls(trivial.as_ref(), &req, a.calls)?);
        let grpc = fogline_remote::egodriver::serve(
            "127.0.0.1:0".parse()?,
            trivial.clone(),
            Default::default(),
        )
        .context("cannot start the egodriver server on loopback")?;
        let http = fogline_remote::http::serve(
            "127.0.0.1:0".parse()?,
            trivial.clone(),
            Default::default(),
        )
        .context("cannot start the HTTP server on loopback")?;
        let cams = req.input.cameras.len();
        let per = req.input.cameras.first().map_or(0, |c| c.frames.len());
        let (w, h) = req
            .input
            .cameras
            .first()
            .map_or((0, 0), |c| (c.calib.width, c.calib.height));
        writeln!(
            out,
            "remote call overhead: {cams} cameras × {per} frames of {w}×{h}, trivial planner, loopback, median of {} calls",
            a.calls
        )?;
        writeln!(
            out,
            "  on {}; frames encoded in parallel, PNG by the {}, JPEG by {}",
            crate::embed::cpu_name(),
            fogline_io::encoder_name(ImageFormat::Png, fogline_io::PngSpeed::Wire),
            fogline_io::encoder_name(
                ImageFormat::Jpeg { quality: 95 },
                fogline_io::PngSpeed::Wire
            )
        )?;
        writeln!(
            out,
            "  {:<28} {:>10} {:>12}",
            "path", "ms/call", "overhead ms"
        )?;
        writeln!(out, "  {:<28} {direct:>10.3} {:>12}", "in-process", "—")?;
        let mut rows = vec![serde_json::json!({"path": "in-process", "ms": direct})];
        for (format, fname) in [
            (ImageFormat::Png, "png"),
            (ImageFormat::Jpeg { quality: 95 }, "jpeg95"),
        ] {
            let g =
                fogline_remote::egodriver::Client::new(fogline_remote::egodriver::ClientOptions {
                    endpoint: grpc.local_addr().to_string(),
                    image_format: format,
                    ..Default::default()
                })?;
            let hc = fogline_remote::http::Client::new(fogline_remote::http::ClientOptions {
                url: format!("http://{}", http.local_addr()),
                image_format: format,
                ..Default::default()
            })?;
            for (name, p) in [
                (format!("egodriver gRPC, {fname}"), &g as &dyn Planner),
                (format!("HTTP/JSON, {fname}"), &hc as &dyn Planner),
            ] {
                let m = median(time_calls(p, &req, a.calls)?);
                writeln!(out, "  {name:<28} {m:>10.3} {:>12.3}", m - direct)?;
                rows.push(serde_json::json!({"path": name, "ms": m, "overhead_ms": m - direct}));
            }
        }
        grpc.shutdown()?;
        http.shutdown()?;
        json.insert("remote_overhead".into(), serde_json::Value::Array(rows));
    }
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&json)?)?;
    }
    Ok(())
}
