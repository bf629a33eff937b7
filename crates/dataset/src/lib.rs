//! DriveLM-Deficit from fogline's own world (the LLM-RCO paper's section 5, figure 5b,
//! figure 6 and appendix A.3), and the evaluation of any backend on it.
//!
//! Use it to make fine-tuning data for hazard inference and planning under perception
//! deficits at any scale, or to score a backend (the offline `rules` one, or any
//! OpenAI-compatible model) on the same samples.
//!
//! - [`scene`]: a sample's scene as a plan, the seeded drawing of plans (one of the four
//!   classes hidden, with its motion), the world scene it renders to, and the privileged
//!   expert that labels it (class, motion, `move` or `stop-observe-move`, one rationale
//!   sentence each);
//! - [`build`](mod@build): five frames at 1 fps on the RCO's three views at the closed loop's sizes,
//!   the hidden object masked as the closed loop masks it, seeded, on all cores, split by
//!   town, written as one set;
//! - [`sample`]: the on-disk format (`manifest.json`, `samples.jsonl`, `images/`);
//! - [`export`]: LLaMA-Factory ShareGPT (per task and joint, with `dataset_info.json`),
//!   DriveLM-style QA, the balance (figure 5b);
//! - [`import`](mod@import): samples from a user's own logs (per-frame boxes and the expert's brake
//!   state);
//! - [`observe`], [`eval`]: a sample as the controller sees it, and the figure-6 scoring
//!   through the controller's own prompt, backend and validation.
//!
//! ```
//! use fogline_dataset::scene::{draw_plan, label};
//!
//! let plan = draw_plan(7, 2, 4, 0); // sample 2 hides a pedestrian (classes cycle)
//! let labels = label(&plan);
//! assert_eq!(labels.class.name(), "pedestrian");
//! assert_eq!(label(&draw_plan(7, 2, 4, 0)), labels); // seeded
//! ```

pub mod build;
pub mod error;
pub mod eval;
pub mod export;
pub mod import;
pub mod observe;
pub mod sample;
pub mod scene;

pub use build::{BuildParams, Built, ImageKind, build};
pub use error::DatasetError;
pub use eval::{EvalParams, evaluate, markdown as eval_markdown, write_eval, write_eval_with};
pub use import::{ImportParams, import};
pub use sample::{Manifest, SampleRecord, Split};

/// Pretty JSON with a final newline.
pub(crate) fn pretty_json<T: serde::Serialize>(v: &T) -> Result<Vec<u8>, DatasetError> {
    let mut out = serde_json::to_vec_pretty(v).map_err(|e| DatasetError::Params(e.to_string()))?;
    out.push(b'\n');
    Ok(out)
}
