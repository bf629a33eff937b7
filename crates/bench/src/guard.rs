//! `fogline bench guard`: the latency `fogline guard` adds to each `drive` call (issue 20).
//!
//! One process, loopback only: the reference planner served over egodriver (what `fogline
//! serve egodriver` serves) and the guard in front of it ([`fogline_guard::guard`]). Two
//! sessions run the same loop ([`fogline_guard::session::LoopSession`]: a frame of the
//! front-wide camera, the ego's pose, `drive`), one straight to the driver and one through
//! the guard, interleaved step by step on the same live frames (world clips rendered at
//! `width × height`, four frames each, cycled: the frames change every step, so the monitor
//! sees a live camera). After `warmup` unmeasured steps each, `calls` steps per path are
//! timed on this side of the wire: the whole step (frame + pose + `drive`, what the guard
//! adds: decoding and monitoring the frame, forwarding three calls) and the `drive` call
//! alone. The report gives the median and the 99th percentile (linear interpolation between
//! order statistics, NumPy's default) of both paths and of the paired difference
//! (guarded − direct, step by step). Who answered through the guard is counted from its log
//! records: with the default `odd.json` entry (σ* 20) the clean frames stay inside, so the
//! driver answers every call and the difference is the guard's cost. Wall-clock figures on
//! a shared machine: measured and printed, never asserted.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use fogline_guard::GuardParams;
use fogline_guard::session::{LoopSession, connect};
use fogline_remote::Planner;
use fogline_types::clip::CameraId;
use fogline_types::odd::OddSpec;
use serde::Serialize;

/// What `fogline bench guard` runs.
#[derive(Debug, Clone, clap::Args)]
pub struct GuardBench {
    /// Timed `drive` calls per path (direct, through the guard).
    #[arg(long, default_value_t = 300)]
    pub calls: usize,
    /// Unmeasured steps per path first.
    #[arg(long, default_value_t = 10)]
    pub warmup: usize,
    /// World clips rendered for the frames (four front-wide frames each, cycled).
    #[arg(long, default_value_t = 10)]
    pub clips: usize,
    /// World seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Frame width, px.
    #[arg(long, default_value_t = 576)]
    pub width: u32,
    /// Frame height, px.
    #[arg(long, default_value_t = 320)]
    pub height: u32,
    /// An odd.json to guard with (default: one LANE_KEEPING entry, σ* 20, darken 0.4,
    /// brighten 1.6, fog 0.7).
    #[arg(long)]
    pub odd: Option<PathBuf>,
    /// The scenario of the odd.json the guard watches.
    #[arg(long, default_value = "LANE_KEEPING")]
    pub scenario: String,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Median and 99th percentile of a latency, ms.
#[derive(Debug, Clone, Serialize)]
pub struct Spread {
    /// Median, ms.
    pub median_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
}

/// One timed quantity on both paths.
#[derive(Debug, Clone, Serialize)]
pub struct PathTimes {
    /// Straight to the driver.
    pub direct: Spread,
    /// Through the guard.
    pub guarded: Spread,
    /// Guarded − direct, step by step.
    pub added: Spread,
}

/// The benchmark's result.
#[derive(Debug, Clone, Serialize)]
pub struct GuardBenchReport {
    /// Timed calls per path.
    pub calls: usize,
    /// Distinct frames cycled.
    pub frames: usize,
    /// Frame size, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// The whole step: frame, pose, `drive`.
    pub step: PathTimes,
    /// The `drive` call alone.
    pub drive: PathTimes,
    /// Timed calls through the guard by who answered (`driver`, `override`, …).
    pub answered_by: BTreeMap<String, usize>,
}

/// The `q` quantile (0–1) of `v` by linear interpolation between order statistics
/// (`numpy.quantile`'s default); `v` must not be empty.
pub fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (s.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    s[lo] + (s[hi] - s[lo]) * (pos - lo as f64)
}

fn spread(v: &[f64]) -> Spread {
    Spread {
        median_ms: quantile(v, 0.5),
        p99_ms: quantile(v, 0.99),
    }
}

fn times(direct: &[f64], guarded: &[f64]) -> PathTimes {
    let added: Vec<f64> = guarded.iter().zip(direct).map(|(g, d)| g - d).collect();
    PathTimes {
        direct: spread(direct),
        guarded: spread(guarded),
        added: spread(&added),
    }
}

/// Runs the benchmark.
pub fn measure(a: &GuardBench) -> Result<GuardBenchReport> {
    if a.calls == 0 || a.clips == 0 {
        bail!("--calls and --clips must be at least 1");
    }
    let odd = match &a.odd {
        Some(p) => OddSpec::read(p).map_err(anyhow::Error::msg)?,
        None => fogline_guard::example_odd("fogline bench guard"),
    };
    let cfg = fogline_api::planner_eval::world_config(a.clips, a.seed, a.width, a.height)?;
    let cfg = fogline_world::WorldConfig {
        depth: false,
        ..cfg
    };
    log::info!(
        "bench guard: rendering {} world clips at {}x{}",
        a.clips,
        a.width,
        a.height
    );
    let mut frames = Vec::new();
    let mut calib = None;
    for i in 0..a.clips {
        let clip = fogline_world::generate_clip_cameras(&cfg, i, &[CameraId::FrontWide])?;
        let cam = clip.cameras.first().context("no front-wide camera")?;
        calib = Some(cam.calib);
        for f in &cam.frames {
            let img = &f.image;
            frames.push(
                fogline_io::encode(
                    img.data(),
                    img.width(),
                    img.height(),
                    fogline_io::ImageFormat::Png,
                )
                .map_err(anyhow::Error::msg)?,
            );
        }
    }
    let calib = calib.context("no frames rendered")?;
    let loopback: std::net::SocketAddr = "127.0.0.1:0".parse()?;
    let planner: Arc<dyn Planner> = Arc::new(fogline_campaign::BuiltinPlanner::new());
    let driver = fogline_remote::egodriver::serve(
        loopback,
        planner,
        fogline_remote::egodriver::ServeOptions::default(),
    )
    .context("cannot serve the driver on 127.0.0.1")?;
    let log = fogline_guard::MemoryLog::default();
    let sink = log.sink();
    let guard = fogline_guard::guard(
        loopback,
        odd,
        GuardParams {
            driver: format!("http://{}", driver.local_addr()),
            scenario: a.scenario.clone(),
            driver_timeout_ms: 10_000,
            ..GuardParams::default()
        },
        Some(sink),
    )
    .context("cannot start the guard on 127.0.0.1")?;
    log::info!(
        "bench guard: driver on {}, guard on {}; {} + {} steps per path",
        driver.local_addr(),
        guard.local_addr(),
        a.warmup,
        a.calls
    );
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let (d_addr, g_addr) = (driver.local_addr(), guard.local_addr());
    let timed = rt.block_on(async {
        let mut direct = LoopSession::start(connect(d_addr).await?, "direct", &calib, 8.0).await?;
        let mut guarded =
            LoopSession::start(connect(g_addr).await?, "guarded", &calib, 8.0).await?;
        let mut t = [Vec::new(), Vec::new(), Vec::new(), Vec::new()];
        for k in 0..a.warmup + a.calls {
            let f = &frames[k % frames.len()];
            let d = direct.step(f.clone()).await?;
            let g = guarded.step(f.clone()).await?;
            if k >= a.warmup {
                t[0].push(d.cycle_ms);
                t[1].push(g.cycle_ms);
                t[2].push(d.drive_ms);
                t[3].push(g.drive_ms);
            }
        }
        direct.close().await?;
        guarded.close().await?;
        anyhow::Ok(t)
    })?;
    drop(rt); // closes the connections
    guard.shutdown().context("stopping the guard")?;
    driver.shutdown().context("stopping the driver")?;
    let text = String::from_utf8(log.contents())?;
    let mut answered_by = BTreeMap::new();
    for line in text.lines().skip(a.warmup) {
        let r: fogline_guard::GuardRecord = serde_json::from_str(line)?;
        *answered_by.entry(r.source).or_insert(0) += 1;
    }
    Ok(GuardBenchReport {
        calls: a.calls,
        frames: frames.len(),
        width: a.width,
        height: a.height,
        step: times(&timed[0], &timed[1]),
        drive: times(&timed[2], &timed[3]),
        answered_by,
    })
}

fn write_report(r: &GuardBenchReport, out: &mut dyn Write) -> Result<()> {
    writeln!(
        out,
        "fogline guard, added latency: {} steps per path on 127.0.0.1, {} live frames {}x{} \
         cycled, driver = the reference planner over egodriver",
        r.calls, r.frames, r.width, r.height
    )?;
    writeln!(out, "{:<44} {:>12} {:>12}", "", "median (ms)", "p99 (ms)")?;
    for (what, t) in [("step (frame+pose+drive)", &r.step), ("drive", &r.drive)] {
        for (path, s) in [
            ("direct", &t.direct),
            ("through the guard", &t.guarded),
            ("added by the guard", &t.added),
        ] {
            writeln!(
                out,
                "{:<44} {:>12.2} {:>12.2}",
                format!("{what}: {path}"),
                s.median_ms,
                s.p99_ms
            )?;
        }
    }
    let by: Vec<String> = r
        .answered_by
        .iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect();
    writeln!(out, "answered through the guard: {}", by.join(", "))?;
    Ok(())
}

/// Runs the benchmark and writes its report (a table, or JSON with `json`).
pub fn run(a: &GuardBench, out: &mut dyn Write) -> Result<()> {
    let r = measure(a)?;
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&r)?)?;
    } else {
        write_report(&r, out)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_matches_numpy() {
        // numpy.quantile([1, 2, 3, 4], [0.5, 0.99]) = [2.5, 3.97]
        let v = [4.0, 1.0, 3.0, 2.0];
        assert!((quantile(&v, 0.5) - 2.5).abs() < 1e-12);
        assert!((quantile(&v, 0.99) - 3.97).abs() < 1e-12);
        assert_eq!(quantile(&[7.0], 0.99), 7.0);
    }
}
