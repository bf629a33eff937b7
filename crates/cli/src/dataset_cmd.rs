//! `fogline dataset deficit`: DriveLM-Deficit from the world (docs/dataset.md).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use fogline_dataset::{BuildParams, ImageKind};

/// Arguments of `fogline dataset`.
#[derive(Args)]
pub struct DatasetArgs {
    #[command(subcommand)]
    what: DatasetCommand,
}

#[derive(Subcommand)]
enum DatasetCommand {
    /// Five-frame clips (1 fps, the RCO's three views) with a traffic light, sign,
    /// pedestrian or bicycle hidden behind a deficit; labels, splits, fine-tuning exports.
    #[command(
        after_help = "Examples:\n  fogline dataset deficit --samples 200 --seed 7 --out deficit/\n  fogline dataset deficit --samples 10000 --out deficit/ --image jpeg"
    )]
    Deficit(DeficitArgs),
    /// The same samples from your own logs: LOGS/<log>/log.json with per-frame images, boxes
    /// and the expert's brake state (layout in docs/dataset.md).
    #[command(
        after_help = "Example:\n  fogline dataset import --logs my-logs/ --out deficit-mine/"
    )]
    Import(ImportArgs),
}

#[derive(Args)]
struct ImportArgs {
    /// The logs' directory.
    #[arg(long)]
    logs: PathBuf,
    /// The output directory.
    #[arg(long)]
    out: PathBuf,
    /// The split seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// A five-frame window starts every this many frames.
    #[arg(long, default_value_t = 5)]
    stride: usize,
}

#[derive(Clone, Copy, ValueEnum)]
enum ImageArg {
    Png,
    Jpeg,
}

#[derive(Args)]
struct DeficitArgs {
    /// Samples.
    #[arg(long, default_value_t = 1000)]
    samples: u64,
    /// The seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The output directory.
    #[arg(long)]
    out: PathBuf,
    /// Clips per town (a town is in one split only).
    #[arg(long, default_value_t = 4)]
    clips_per_town: u64,
    /// Shares of the towns in train, val and test.
    #[arg(long, value_delimiter = ',', default_value = "0.8,0.1,0.1")]
    split: Vec<f64>,
    /// Image files.
    #[arg(long, value_enum, default_value = "png")]
    image: ImageArg,
    /// JPEG quality (with --image jpeg).
    #[arg(long, default_value_t = 90)]
    jpeg_quality: u8,
}

/// Runs `fogline dataset …`.
pub fn dataset(a: DatasetArgs) -> Result<ExitCode> {
    let d = match a.what {
        DatasetCommand::Deficit(d) => d,
        DatasetCommand::Import(i) => {
            let p = fogline_dataset::ImportParams {
                seed: i.seed,
                stride_frames: i.stride,
                ..Default::default()
            };
            let built = fogline_api::dataset::import(&p, &i.logs, &i.out)?;
            built.write_text(&mut std::io::stdout().lock())?;
            return Ok(ExitCode::SUCCESS);
        }
    };
    let [train, val, test] = d.split[..] else {
        bail!(
            "--split takes three shares (train,val,test), got {:?}",
            d.split
        );
    };
    let params = BuildParams {
        samples: d.samples,
        seed: d.seed,
        clips_per_town: d.clips_per_town,
        split_fractions: [train, val, test],
        image: match d.image {
            ImageArg::Png => ImageKind::Png,
            ImageArg::Jpeg => ImageKind::Jpeg,
        },
        jpeg_quality: d.jpeg_quality,
        threads: 0,
    };
    let built = fogline_api::dataset::deficit(&params, &d.out)?;
    built.write_text(&mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}
