//! `fogline monitor estimate` and `fogline monitor run`: their arguments and output; the
//! jobs are in `fogline_api::monitor`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use fogline_api::in_memory::monitor::MonitorParams;
use fogline_api::in_memory::types::clip::CameraId;
use fogline_api::monitor::{
    MonitorRun, estimate_images, run_monitor, write_header, write_row, write_run_summary,
};

#[derive(Args)]
pub struct MonitorArgs {
    #[command(subcommand)]
    what: MonitorCommand,
}

#[derive(Subcommand)]
enum MonitorCommand {
    /// Blind estimates from each image alone: Gaussian noise σ (0–255), photometric gain and
    /// fog opacity, each with its standard error, and the ms they took.
    #[command(
        after_help = "Examples:\n  fogline monitor estimate frame.png\n  fogline monitor estimate frames/*.png --json"
    )]
    Estimate(EstimateArgs),
    /// The runtime ODD monitor: per-frame estimates smoothed over time against the scenario's
    /// entry of an odd.json → in / out of the envelope (hysteresis, minimum dwell), one JSON
    /// line per frame on stdout.
    #[command(
        after_help = "Examples:\n  fogline monitor run clips/ --odd fogline-demo/odd.json\n  fogline monitor run frames/*.png --odd odd.json --scenario LANE_KEEPING\n  fogline monitor run clips/c000001 --odd odd.json --camera front_tele --min-dwell-steps 1"
    )]
    Run(RunArgs),
}

#[derive(Args)]
struct RunArgs {
    /// PNG/JPEG images (one stream, in order), clip directories or corpus directories.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The envelope's odd.json (`fogline envelope`, `fogline demo`).
    #[arg(long)]
    odd: PathBuf,
    /// Scenario of the odd.json entry (required for images; default: each clip's label).
    #[arg(long)]
    scenario: Option<String>,
    /// The camera of a clip that is monitored.
    #[arg(long, default_value = "front_wide", value_parser = parse_camera)]
    camera: CameraId,
    /// Axes watched, comma-separated (gaussian_noise, darken, brighten, fog).
    #[arg(long, value_delimiter = ',')]
    axes: Option<Vec<String>>,
    /// Steps a state lasts at least once entered.
    #[arg(long)]
    min_dwell_steps: Option<usize>,
    /// Weight of the newest frame in the moving averages, (0, 1].
    #[arg(long)]
    ewma_alpha: Option<f64>,
}

fn parse_camera(s: &str) -> Result<CameraId, String> {
    CameraId::parse(s)
        .ok_or_else(|| format!("{s:?}: expected cross_left, front_wide, cross_right or front_tele"))
}

#[derive(Args)]
struct EstimateArgs {
    /// PNG or JPEG images.
    #[arg(required = true)]
    images: Vec<PathBuf>,
    /// One JSON object per image on stdout (path, noise_sigma, gain, fog, ms and errors).
    #[arg(long)]
    json: bool,
}

pub fn monitor(a: MonitorArgs) -> Result<ExitCode> {
    let a = match a.what {
        MonitorCommand::Estimate(a) => a,
        MonitorCommand::Run(r) => return run(r),
    };
    let params = fogline_api::in_memory::monitor::ConditionParams::default();
    let out = &mut std::io::stdout().lock();
    write_header(a.json, out)?;
    let mut failed = 0;
    for r in estimate_images(&a.images, &params) {
        match r {
            Ok(e) => write_row(&e, a.json, out)?,
            Err(e) => {
                eprintln!("error: {e:#}");
                failed += 1;
            }
        }
    }
    Ok(if failed > 0 {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    })
}

fn run(a: RunArgs) -> Result<ExitCode> {
    let d = MonitorParams::default();
    let params = MonitorParams {
        axes: a.axes.unwrap_or(d.axes.clone()),
        min_dwell_steps: a.min_dwell_steps.unwrap_or(d.min_dwell_steps),
        ewma_alpha: a.ewma_alpha.unwrap_or(d.ewma_alpha),
        ..d
    };
    let job = MonitorRun {
        inputs: a.inputs,
        odd: a.odd,
        scenario: a.scenario,
        camera: a.camera,
        params,
    };
    let s = run_monitor(&job, &mut std::io::stdout().lock())?;
    for e in &s.errors {
        eprintln!("error: {e}");
    }
    write_run_summary(&s, &mut std::io::stderr().lock())?;
    Ok(if s.errors.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(2)
    })
}
