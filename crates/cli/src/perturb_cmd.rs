//! `fogline perturb` and `fogline bench …`: their arguments and output; the jobs are
//! `fogline_api::perturb_dir` and the `fogline_bench` engines.

use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};

#[derive(Args)]
pub struct PerturbArgs {
    /// Directory of frames: PNG or JPEG, 8-bit RGB, searched recursively. Each directory is a
    /// clip; its frames are its image files in name order.
    #[arg(long)]
    input: PathBuf,
    /// Output directory (created if missing): the same relative paths and names, plus
    /// perturb.json (written last, so its presence means the run completed).
    #[arg(long)]
    output: PathBuf,
    /// Condition: noise_30, dark, bright, fog_07, jpeg_20, mask_class_pedestrian,
    /// drop_0.1, noise_30+fog_03, … (see docs/perturb.md).
    #[arg(long)]
    condition: String,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Object boxes for deficit masks: JSON Lines, one box per line:
    /// {"frame": "clip/0001.png", "class": "car", "track_id": 3, "x": 10, "y": 20,
    /// "width": 40, "height": 30} (pixels, origin top-left; frame relative to --input).
    #[arg(long)]
    boxes: Option<PathBuf>,
    /// Depth maps for Koschmieder fog: a directory mirroring --input with one 16-bit grey PNG
    /// per frame (same relative path, extension .png); 0 means no return (sky).
    #[arg(long)]
    depth: Option<PathBuf>,
    /// Metres per unit of the depth PNGs.
    #[arg(long, default_value_t = 0.001)]
    depth_scale: f64,
    /// Outline of masked boxes: a colour RRGGBB, or `none`.
    #[arg(long, default_value = "ff0000")]
    outline: String,
    /// Outline width in pixels.
    #[arg(long, default_value_t = 2)]
    outline_width: u32,
    /// Quality of JPEG outputs (JPEG inputs are written back as JPEG).
    #[arg(long, default_value_t = 95)]
    jpeg_quality: u8,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    what: BenchCommand,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Per-family ms/frame of the perturbation engine on a synthetic frame, one thread, next to
    /// the memory floor (and, with --peers, next to the Python libraries).
    #[command(
        after_help = "Examples:\n  fogline bench perturb\n  fogline bench perturb --width 640 --height 360 --runs 3 --json\n  scripts/perturb-peers.sh    # installs the Python peers, then runs --peers"
    )]
    Perturb(BenchPerturbArgs),
    /// Generating + rendering clips in memory on every core (s, clips/s, ms/clip), then the
    /// reference planner's time per clip on one thread (median, p95), next to their goals.
    #[command(
        after_help = "Examples:\n  fogline bench world                    # 1,996 clips at 576x320\n  fogline bench world --clips 200 --json"
    )]
    World(crate::planner_cmd::BenchWorldArgs),
    /// The paper-size campaign with the built-in planner (s, runs/s), and the runner's
    /// overhead per remote call (egodriver gRPC and HTTP on loopback, PNG and JPEG).
    #[command(
        after_help = "Examples:\n  fogline bench campaign                  # 1,996 clips × 9 conditions, then 200 calls per path\n  fogline bench campaign --clips 0 --calls 500"
    )]
    Campaign(crate::bench_campaign::BenchCampaignArgs),
    /// Blind noise estimator vs scikit-image's estimate_sigma: MAE per sigma, ms/frame, ratio.
    #[command(
        after_help = "Examples:\n  fogline bench monitor\n  fogline bench monitor --clips 1 --json"
    )]
    Monitor(fogline_bench::monitor::MonitorBench),
    /// The runtime ODD monitor on the demo corpus, sigma drawn uniformly per clip, against
    /// the decision of the true sigma under an odd.json (issue 20).
    #[command(
        after_help = "Examples:\n  fogline demo --no-closed-loop --out fogline-demo\n  fogline bench monitor-eval --odd fogline-demo/odd.json\n  fogline bench monitor-eval --odd fogline-demo/odd.json --seed 1 --json"
    )]
    MonitorEval(fogline_bench::monitor_eval::MonitorEval),
    /// The latency fogline guard adds per drive call (median, p99), on live frames over loopback.
    #[command(after_help = "Examples:\n  fogline bench guard\n  fogline bench guard --json")]
    Guard(fogline_bench::guard::GuardBench),
    /// The semantic similarity of two explanations (all-MiniLM-L6-v2 on the CPU): ms per pair.
    #[command(after_help = "Examples:\n  fogline bench embed\n  fogline bench embed --json")]
    Embed(fogline_bench::embed::EmbedBench),
}

#[derive(Args)]
struct BenchPerturbArgs {
    /// Frame width in pixels.
    #[arg(long, default_value_t = 1920)]
    width: u32,
    /// Frame height in pixels.
    #[arg(long, default_value_t = 1080)]
    height: u32,
    /// Timed runs per family (the median is reported), after one warm-up.
    #[arg(long, default_value_t = 9)]
    runs: usize,
    /// Only conditions whose name contains this.
    #[arg(long)]
    filter: Option<String>,
    /// Also time the Python peers (numpy, OpenCV, albumentations, imagecorruptions) on the same
    /// frame and print every ratio.
    #[arg(long)]
    peers: bool,
    /// Python interpreter for --peers (default: $FOGLINE_PYTHON, else
    /// target/perturb-peers-venv/bin/python when it exists, else python3).
    #[arg(long)]
    python: Option<PathBuf>,
    /// The peers script (default: the copy of scripts/perturb_peers.py shipped in the binary).
    #[arg(long)]
    peers_script: Option<PathBuf>,
    /// Print the results as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Runs `fogline perturb`.
pub fn perturb(a: PerturbArgs) -> Result<ExitCode> {
    let job = fogline_api::perturb_dir::PerturbDir {
        input: a.input,
        output: a.output,
        condition: a.condition,
        seed: a.seed,
        boxes: a.boxes,
        depth: a.depth,
        depth_scale: a.depth_scale,
        outline: a.outline,
        outline_width: a.outline_width,
        jpeg_quality: a.jpeg_quality,
    };
    let s = fogline_api::perturb_dir::run(&job)?;
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&s)?)?;
    } else {
        writeln!(
            out,
            "{} frames perturbed with {} (seed {}) into {}",
            s.n_frames,
            s.condition,
            s.seed,
            s.output.display()
        )?;
        writeln!(out, "{}", s.manifest.display())?;
    }
    Ok(ExitCode::SUCCESS)
}

// ---------------------------------------------------------------------------------------------
// fogline bench perturb
// ---------------------------------------------------------------------------------------------

pub fn bench(a: BenchArgs) -> Result<ExitCode> {
    match a.what {
        BenchCommand::Perturb(a) => {
            let opts = fogline_bench::perturb::PerturbBench {
                width: a.width,
                height: a.height,
                runs: a.runs,
                filter: a.filter,
                peers: a.peers,
                python: a.python,
                peers_script: a.peers_script,
                json: a.json,
            };
            fogline_bench::perturb::run(&opts, &mut std::io::stdout().lock())?;
            Ok(ExitCode::SUCCESS)
        }
        BenchCommand::World(w) => crate::planner_cmd::bench_world(w),
        BenchCommand::Campaign(c) => crate::bench_campaign::bench_campaign(c),
        BenchCommand::Monitor(m) => fogline_bench::monitor::run(&m, &mut std::io::stdout().lock())
            .map(|()| ExitCode::SUCCESS),
        BenchCommand::MonitorEval(m) => {
            fogline_bench::monitor_eval::run(&m, &mut std::io::stdout().lock())
                .map(|()| ExitCode::SUCCESS)
        }
        BenchCommand::Guard(g) => {
            fogline_bench::guard::run(&g, &mut std::io::stdout().lock()).map(|()| ExitCode::SUCCESS)
        }
        BenchCommand::Embed(e) => {
            fogline_bench::embed::run(&e, &mut std::io::stdout().lock()).map(|()| ExitCode::SUCCESS)
        }
    }
}
