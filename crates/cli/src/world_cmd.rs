//! `fogline world generate` (a corpus of synthetic clips in the clip format, see
//! docs/clip-format.md) and `fogline world show` (a summary of one clip directory, which also
//! checks it against the format).

use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use fogline_world::{ScenarioMix, WorldConfig};

#[derive(Args)]
pub struct WorldArgs {
    #[command(subcommand)]
    what: WorldCommand,
}

#[derive(Subcommand)]
enum WorldCommand {
    /// Generate a corpus of synthetic clips: four cameras (RGB, depth, boxes), ego history,
    /// the expert's ground-truth future; one directory per clip, then corpus.json.
    #[command(
        after_help = "Examples:\n  fogline world generate --out corpus/                       # the paper's 1,996-clip mix\n  fogline world generate --out small/ --clips 80 --mix uniform --width 288 --height 160\n  fogline world generate --out stops/ --clips 50 --scenario STOP_SIGNAL --seed 3"
    )]
    Generate(GenerateArgs),
    /// Print a summary of one clip directory; fails (exit 2) naming the file when the
    /// directory does not follow the clip format (docs/clip-format.md).
    #[command(after_help = "Example:\n  fogline world show corpus/stop_signal_00695")]
    Show(ShowArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum MixArg {
    /// The envelope paper's proportions (213/7/475/177/40/302/344/438 of 1,996).
    Paper,
    /// The same number of clips for every scenario.
    Uniform,
}

#[derive(Args)]
struct GenerateArgs {
    /// Output directory (created if missing): one directory per clip, named by its id, and
    /// corpus.json (written last, so its presence means the run completed).
    #[arg(long)]
    out: PathBuf,
    /// Clips in the corpus.
    #[arg(long, default_value_t = 1996)]
    clips: usize,
    /// Corpus seed: clip i draws its randomness from (seed, i), whatever else is generated.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Scenario mix, scaled to --clips.
    #[arg(long, value_enum, default_value = "paper")]
    mix: MixArg,
    /// Generate only this scenario: LANE_KEEPING, NUDGE_RIGHT, FOLLOW_VEHICLE, PASSING,
    /// TURN_RIGHT, STOP_SIGNAL, INTERSECTION or OTHER.
    #[arg(long, conflicts_with = "mix")]
    scenario: Option<String>,
    /// Image width of every camera, pixels (16..=1920).
    #[arg(long, default_value_t = 576)]
    width: u32,
    /// Image height of every camera, pixels (16..=1080).
    #[arg(long, default_value_t = 320)]
    height: u32,
    /// Do not render depth maps (Koschmieder fog needs them).
    #[arg(long)]
    no_depth: bool,
    /// Clips generated in parallel (default: --threads, else all cores). The corpus does not
    /// depend on it.
    #[arg(long)]
    jobs: Option<usize>,
}

#[derive(Args)]
struct ShowArgs {
    /// A clip directory (the one holding clip.json).
    clip: PathBuf,
}

pub fn world(a: WorldArgs) -> Result<ExitCode> {
    match a.what {
        WorldCommand::Generate(g) => generate(g),
        WorldCommand::Show(s) => show(&s),
    }
}

fn generate(a: GenerateArgs) -> Result<ExitCode> {
    let t0 = Instant::now();
    if a.clips == 0 {
        bail!("--clips must be at least 1");
    }
    let mix = match (&a.scenario, a.mix) {
        (Some(s), _) => ScenarioMix::only(s, a.clips).context("--scenario")?,
        (None, MixArg::Paper) => ScenarioMix::paper_scaled(a.clips),
        (None, MixArg::Uniform) => ScenarioMix::spread(a.clips),
    };
    let config = WorldConfig {
        seed: a.seed,
        width: a.width,
        height: a.height,
        depth: !a.no_depth,
        mix,
    };
    let corpus = fogline_api::world::generate_corpus(&config, &a.out, a.jobs)?;
    let secs = t0.elapsed().as_secs_f64();
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{} clips (seed {}, {}x{}, {}) in {secs:.2} s, {:.1} clips/s, into {}",
        corpus.n_clips,
        config.seed,
        config.width,
        config.height,
        if config.depth {
            "with depth"
        } else {
            "no depth"
        },
        corpus.n_clips as f64 / secs.max(1e-9),
        a.out.display()
    )?;
    writeln!(out, "{:<16} {:>6}", "scenario", "clips")?;
    for (s, _) in config.mix.counts.iter().filter(|(_, n)| *n > 0) {
        let n = corpus.clips.iter().filter(|c| &c.scenario == s).count();
        writeln!(out, "{s:<16} {n:>6}")?;
    }
    writeln!(
        out,
        "{}",
        a.out.join(fogline_world::corpus::CORPUS_FILE).display()
    )?;
    Ok(ExitCode::SUCCESS)
}

fn show(a: &ShowArgs) -> Result<ExitCode> {
    fogline_api::world::show_clip(&a.clip, &mut std::io::stdout().lock())?;
    Ok(ExitCode::SUCCESS)
}
