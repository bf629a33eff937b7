//! `fogline monitor estimate`: its arguments and output; the job is `fogline_api::monitor`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use fogline_api::monitor::{estimate_images, write_header, write_row};

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
    let MonitorCommand::Estimate(a) = a.what;
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
