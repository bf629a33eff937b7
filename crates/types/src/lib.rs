//! The shared vocabulary of fogline.
//!
//! Every other crate speaks in these types: driving [`scenario`] labels and the paper's
//! default taxonomy, perturbation [`condition`]s with their family and level, and the
//! [`pair`] row that joins a clean and a perturbed run of the same clip.
//!
//! This crate holds data and parsing only: no I/O, no randomness.
//!
//! ```
//! use fogline_types::condition::{Condition, Family};
//!
//! let c = Condition::parse("noise_30").unwrap();
//! assert_eq!(c.family, Family::GaussianNoise);
//! assert_eq!(c.level, 30.0);
//! let fog = Condition::parse("fog_07").unwrap();
//! assert_eq!(fog.level, 0.7);
//! ```

pub mod clip;
pub mod condition;
pub mod motion;
pub mod odd;
pub mod pair;
pub mod planner;
pub mod scenario;

pub use condition::{Condition, Family};
pub use pair::Pair;
pub use scenario::Taxonomy;
