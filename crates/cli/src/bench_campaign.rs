//! `fogline bench campaign`: parses its arguments; the benchmark is
//! `fogline_bench::campaign`.

use std::process::ExitCode;

use anyhow::Result;
use clap::Args;

/// Arguments of `fogline bench campaign`.
#[derive(Args)]
pub struct BenchCampaignArgs {
    /// Clips of the timed campaign (0 skips it; the paper's corpus has 1,996).
    #[arg(long, default_value_t = 1996)]
    clips: usize,
    /// Remote calls timed per protocol and image format (0 skips the overhead part).
    #[arg(long, default_value_t = 200)]
    calls: usize,
    /// Runs of --calls calls each (the overhead is the median of the runs' medians).
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// Runs `fogline bench campaign`.
pub fn bench_campaign(a: BenchCampaignArgs) -> Result<ExitCode> {
    let opts = fogline_bench::campaign::CampaignBench {
        clips: a.clips,
        calls: a.calls,
        runs: a.runs,
        json: a.json,
    };
    fogline_bench::campaign::run(&opts, &mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}
