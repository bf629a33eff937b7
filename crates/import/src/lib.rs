//! Real driving data into fogline's clip format (`docs/clip-format.md`), so that a campaign
//! runs on logged drives as it runs on the synthetic world.
//!
//! The one source so far is the PhysicalAI-Autonomous-Vehicles dataset (the clips of the
//! envelope paper), read from its published layout without unpacking its chunk zips to disk:
//!
//! - [`layout`]: the tree (`features.csv`, `clip_index.parquet`, `camera/<cam>/….zip`,
//!   `labels/egomotion/….zip`) and the zip members of a clip, read into memory one at a time;
//! - [`video`]: the frames a planner needs, decoded and resized by an `ffmpeg` child process
//!   (found as [`video::Ffmpeg::locate`] says), the MP4 piped on stdin when its index comes
//!   first;
//! - [`egomotion`] and [`spline`]: the ego history and the ground-truth future (64 waypoints
//!   at 10 Hz in the rig frame at `t0`), interpolated as the dataset's devkit interpolates;
//! - [`labels`]: scenario labels from the user's CSV (`OTHER` for the clips it omits);
//! - [`import`]: the job, [`import_physicalai_av`], with its manifest `import.json`.
//!
//! Use it through `fogline clips import physicalai-av ROOT --out DIR` (docs/data.md), or as a
//! library:
//!
//! ```no_run
//! use fogline_import::{ImportParams, import_physicalai_av};
//!
//! let summary = import_physicalai_av(&ImportParams {
//!     root: "/data/PhysicalAI-Autonomous-Vehicles".into(),
//!     out: "clips/".into(),
//!     labels: Some("my_labels.csv".into()),
//!     limit: Some(10),
//!     ..ImportParams::default()
//! })?;
//! println!("{} clips, e.g. {}", summary.n_clips, summary.clips[0].id);
//! # Ok::<(), fogline_import::ImportError>(())
//! ```

pub mod egomotion;
pub mod error;
pub mod import;
pub mod labels;
pub mod layout;
pub mod spline;
pub mod table;
pub mod video;

pub use error::ImportError;
pub use import::{ImportParams, ImportSummary, MANIFEST, import_physicalai_av};
pub use video::Ffmpeg;

/// A Parquet file of `columns` in memory, for the unit tests.
#[cfg(test)]
pub(crate) fn parquet_bytes(columns: Vec<(&str, arrow_array::ArrayRef)>) -> Vec<u8> {
    #![allow(clippy::unwrap_used)]
    let batch = arrow_array::RecordBatch::try_from_iter(columns).unwrap();
    let mut out = Vec::new();
    let mut w = parquet::arrow::ArrowWriter::try_new(&mut out, batch.schema(), None).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
    out
}
