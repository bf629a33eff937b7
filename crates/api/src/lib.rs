//! fogline's facade: the jobs its two front-ends run — the `fogline` CLI and the Python
//! package — as one library API, so both only parse, dispatch and format.
//!
//! - [`dataset`]: DriveLM-Deficit, built from the world, and a backend scored on it
//!   (`fogline dataset deficit`, `fogline rco eval`); its own feature, `dataset` (part of
//!   `jobs`), which the Python package turns on;
//! - [`demo`]: the whole pipeline offline on built-in data (`fogline demo`);
//! - [`envelope`]: an analysis's files and the HTML report (`fogline envelope`, `fogline
//!   report`);
//! - [`monitor`]: blind noise, gain and fog estimates of image files (`fogline monitor
//!   estimate`);
//! - [`perturb_dir`]: perturb a directory of frames (`fogline perturb`);
//! - [`planner_eval`]: the reference planner on generated clips, clean and perturbed
//!   (`fogline planner eval`);
//! - [`rco`]: recorded observations through the LLM-RCO controller (`fogline rco replay`);
//! - [`sim`]: the closed-loop evaluation's run, files and summary (`fogline sim run`);
//! - [`world`]: a corpus of clips on disk (`fogline world generate`);
//! - [`in_memory`]: the in-memory API (arrays and tables in, results out) the Python package
//!   calls, available without the file-based jobs' `jobs` feature (on by default).
//!
//! The benchmark engines are in `fogline-bench`; the analyses, the world, the planner, the
//! campaign runner, the closed loop and the report in their own crates, which this one sits
//! on.

#[cfg(feature = "dataset")]
pub mod dataset;
#[cfg(feature = "jobs")]
pub mod demo;
#[cfg(feature = "jobs")]
pub mod envelope;
#[cfg(feature = "jobs")]
pub mod monitor;
#[cfg(feature = "jobs")]
pub mod perturb_dir;
#[cfg(feature = "jobs")]
pub mod planner_eval;
#[cfg(feature = "jobs")]
pub mod rco;
#[cfg(feature = "jobs")]
pub mod sim;
#[cfg(feature = "jobs")]
pub mod world;

/// The in-memory API, for front-ends that hand over arrays and tables instead of files
/// (the Python package): the library crates that do the work, re-exported so that a
/// front-end depends on this facade alone. Available without the `jobs` feature, which the
/// file-based jobs above need (and with it their SQLite, Parquet and simulator).
///
/// - [`in_memory::perturb`]: conditions by name (`"noise_30+fog_03"`), prepared once and applied
///   to borrowed frames, deficit masks from boxes;
/// - [`in_memory::envelope`]: the envelope analysis of a pairs table, also from Arrow record
///   batches (`read_pairs_arrow`), and its Markdown;
/// - [`in_memory::world`] and [`in_memory::planner`]: a generated clip's frames; the reference planner;
/// - [`in_memory::rco`]: the risk-averse control override and its backends;
/// - [`in_memory::monitor`]: blind noise, gain, fog and temporal-fault estimates of frames;
/// - [`in_memory::types`]: the vocabulary they share (cameras, clips, trajectories, decisions).
pub mod in_memory {
    pub use fogline_envelope as envelope;
    pub use fogline_monitor as monitor;
    pub use fogline_perturb as perturb;
    pub use fogline_planner as planner;
    pub use fogline_rco as rco;
    pub use fogline_types as types;
    pub use fogline_world as world;
}
