//! fogline's facade: the jobs its two front-ends run — the `fogline` CLI and the Python
//! package — as one library API, so both only parse, dispatch and format.
//!
//! - [`demo`]: the whole pipeline offline on built-in data (`fogline demo`);
//! - [`envelope`]: an analysis's files and the HTML report (`fogline envelope`, `fogline
//!   report`);
//! - [`perturb_dir`]: perturb a directory of frames (`fogline perturb`);
//! - [`planner_eval`]: the reference planner on generated clips, clean and perturbed
//!   (`fogline planner eval`);
//! - [`sim`]: the closed-loop evaluation's run, files and summary (`fogline sim run`);
//! - [`world`]: a corpus of clips on disk (`fogline world generate`).
//!
//! The benchmark engines are in `fogline-bench`; the analyses, the world, the planner, the
//! campaign runner, the closed loop and the report in their own crates, which this one sits
//! on.

pub mod demo;
pub mod envelope;
pub mod perturb_dir;
pub mod planner_eval;
pub mod sim;
pub mod world;
