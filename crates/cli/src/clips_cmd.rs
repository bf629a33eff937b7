//! `fogline clips import physicalai-av`: real clips into the clip format (docs/data.md).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use fogline_import::ImportParams;
use fogline_types::clip::CameraId;

/// Arguments of `fogline clips`.
#[derive(Args)]
pub struct ClipsArgs {
    #[command(subcommand)]
    what: ClipsCommand,
}

#[derive(Subcommand)]
enum ClipsCommand {
    /// Read a dataset's clips into the clip format (frames, ego history, ground truth), ready
    /// for `[clips] source = "dir"` in a campaign.
    #[command(
        after_help = "Examples:\n  fogline clips import physicalai-av /data/PhysicalAI-Autonomous-Vehicles --out clips/ --limit 20\n  fogline clips import physicalai-av ROOT --out clips/ --labels labels.csv --t0-us 5100000,12000000 --cameras front_wide,front_tele"
    )]
    Import(ImportArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum Source {
    /// NVIDIA's PhysicalAI-Autonomous-Vehicles (clip_index.parquet, chunked camera and
    /// egomotion zips).
    #[value(name = "physicalai-av")]
    PhysicalaiAv,
}

#[derive(Args)]
struct ImportArgs {
    /// The dataset.
    #[arg(value_enum)]
    source: Source,
    /// The dataset's root directory (holding clip_index.parquet).
    root: PathBuf,
    /// Output directory: one clip directory per clip and t0, then import.json (written last).
    #[arg(long)]
    out: PathBuf,
    /// Scenario labels: a CSV with the columns clip_id,scenario (others are OTHER).
    #[arg(long)]
    labels: Option<PathBuf>,
    /// Decision times t0, µs on the dataset's clock, comma-separated: one clip each.
    #[arg(long, value_delimiter = ',', default_value = "5100000")]
    t0_us: Vec<i64>,
    /// Cameras, comma-separated (cross_left, front_wide, cross_right, front_tele).
    #[arg(long, value_delimiter = ',', default_value = "cross_left,front_wide,cross_right,front_tele", value_parser = camera)]
    cameras: Vec<CameraId>,
    /// Frame width, px (frames are resized).
    #[arg(long, default_value_t = 576)]
    width: u32,
    /// Frame height, px.
    #[arg(long, default_value_t = 320)]
    height: u32,
    /// Only these dataset clips (comma-separated ids).
    #[arg(long, value_delimiter = ',')]
    clip: Vec<String>,
    /// Only the clips of these chunks (comma-separated).
    #[arg(long, value_delimiter = ',')]
    chunk: Vec<i64>,
    /// At most this many dataset clips, in the index's order.
    #[arg(long)]
    limit: Option<usize>,
    /// Also the clips the index marks invalid.
    #[arg(long)]
    include_invalid: bool,
    /// Record a clip that fails in import.json and go on.
    #[arg(long)]
    keep_going: bool,
    /// The ffmpeg binary (default: FOGLINE_FFMPEG, PATH, then target/pyenv's imageio-ffmpeg).
    #[arg(long)]
    ffmpeg: Option<PathBuf>,
    /// Dataset clips imported in parallel (default: --threads, else all cores).
    #[arg(long)]
    jobs: Option<usize>,
}

fn camera(s: &str) -> Result<CameraId, String> {
    CameraId::parse(s).ok_or_else(|| {
        format!("unknown camera {s:?}: cross_left, front_wide, cross_right or front_tele")
    })
}

pub fn clips(a: ClipsArgs) -> Result<ExitCode> {
    let ClipsCommand::Import(a) = a.what;
    let Source::PhysicalaiAv = a.source;
    let start = Instant::now();
    let params = ImportParams {
        root: a.root,
        out: a.out,
        t0_us: a.t0_us,
        cameras: a.cameras,
        width: a.width,
        height: a.height,
        labels: a.labels,
        clip_ids: a.clip,
        chunks: a.chunk,
        limit: a.limit,
        include_invalid: a.include_invalid,
        keep_going: a.keep_going,
        ffmpeg: a.ffmpeg,
        jobs: a.jobs,
    };
    let summary = fogline_import::import_physicalai_av(&params).with_context(|| {
        format!(
            "cannot import PhysicalAI-AV clips from {}",
            params.root.display()
        )
    })?;
    log::info!("imported in {:.1} s", start.elapsed().as_secs_f64());
    summary.write_text(&params.out, &mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}
