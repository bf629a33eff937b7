//! Campaigns: clips × conditions × seeds against a planner, every run committed to an
//! embedded SQLite store, exported as the runs table and the clean-vs-perturbed pairs table
//! that `fogline envelope` reads.
//!
//! - [`config`]: the `CONFIG.toml` schema, its validation and its hash;
//! - [`runner`]: the work, its units and workers, retries with backoff;
//! - [`store`]: the crash-safe SQLite store (WAL; one row per run; resume; shards);
//! - [`merge`]: shard stores merged exactly, and a store's status;
//! - [`export`]: runs and pairs tables to CSV and Parquet;
//! - [`similarity`]: explanations embedded with all-MiniLM-L6-v2 (`fogline-embed`) for the
//!   pairs table's `coc_cosine`, when the model is installed;
//! - [`builtin`]: the reference planner in-process; [`planner_for`] builds any configured
//!   planner (built-in, `egodriver` gRPC, HTTP).

pub mod builtin;
pub mod config;
pub mod error;
pub mod export;
pub mod merge;
pub mod runner;
pub mod similarity;
pub mod store;

use std::sync::Arc;

pub use builtin::BuiltinPlanner;
pub use config::CampaignConfig;
pub use error::CampaignError;
pub use runner::{Campaign, RunOptions, RunSummary, run};
pub use store::{Shard, Store};

use fogline_remote::Planner;

/// The planner a configuration names.
pub fn planner_for(config: &CampaignConfig) -> Result<Arc<dyn Planner>, CampaignError> {
    planner_from(&config.planner, config.run.timeout())
}

/// The planner a `[planner]` table names, its requests timed out after `timeout`.
pub fn planner_from(
    p: &config::PlannerConfig,
    timeout: std::time::Duration,
) -> Result<Arc<dyn Planner>, CampaignError> {
    let image_format = if p.image_format == "jpeg" {
        fogline_remote::ImageFormat::Jpeg {
            quality: p.jpeg_quality,
        }
    } else {
        fogline_remote::ImageFormat::Png
    };
    let endpoint = p.endpoint.clone().unwrap_or_default();
    let planner: Arc<dyn Planner> = match p.kind.as_str() {
        "builtin" => Arc::new(BuiltinPlanner::new()),
        "egodriver" => Arc::new(
            fogline_remote::egodriver::Client::new(fogline_remote::egodriver::ClientOptions {
                endpoint,
                timeout,
                image_format,
                explanation_fields: p.explanation_fields.clone(),
            })
            .map_err(|e| CampaignError::Planner(e.to_string()))?,
        ),
        "http" => Arc::new(
            fogline_remote::http::Client::new(fogline_remote::http::ClientOptions {
                url: endpoint,
                timeout,
                image_format,
            })
            .map_err(|e| CampaignError::Planner(e.to_string()))?,
        ),
        other => {
            return Err(CampaignError::Planner(format!(
                "unknown planner kind {other:?}"
            )));
        }
    };
    Ok(planner)
}

/// The run options a configuration implies for `shard`.
pub fn run_options(config: &CampaignConfig, shard: Shard) -> RunOptions {
    RunOptions {
        shard,
        concurrency: config.concurrency(),
        retries: config.run.retries,
        backoff: std::time::Duration::from_millis(config.run.backoff_ms),
        per_clip: config.planner.kind == "builtin",
        embedder: similarity::shared().ok(),
    }
}

/// Runs (or, with `resume` and an existing store, resumes) the campaign of `config` into the
/// store at `store_path` for `shard`, with the planner the configuration names and a progress
/// bar on stderr; `retry_failed` first deletes the failed runs so they run again. What
/// `fogline campaign run` and `fogline demo` do.
pub fn run_into_store(
    config: CampaignConfig,
    store_path: &std::path::Path,
    shard: Shard,
    resume: bool,
    retry_failed: bool,
) -> Result<(Campaign, RunSummary), CampaignError> {
    let planner = planner_for(&config)?;
    let opts = run_options(&config, shard);
    let campaign = Campaign::new(config)?;
    let meta = campaign.store_meta(shard);
    let mut store = if resume && store_path.exists() {
        Store::resume(store_path, &meta)?
    } else {
        Store::create(store_path, &meta)?
    };
    if retry_failed {
        let n = store.delete_failed()?;
        log::info!("{n} failed runs will run again");
    }
    log::info!(
        "campaign {}: {} clips × {} conditions × {} seeds, shard {shard}, {} → {}",
        &campaign.hash[..12],
        campaign.clips.len(),
        campaign.conditions.len(),
        campaign.seeds().len(),
        planner.describe(),
        store_path.display()
    );
    let progress = fogline_io::Progress::new(0, "runs");
    let summary = run(&campaign, &mut store, planner.as_ref(), &opts, &progress)?;
    progress.finish();
    Ok((campaign, summary))
}
