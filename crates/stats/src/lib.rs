//! Pure numerics over `&[f64]` for the envelope analysis.
//!
//! Every statistic here documents its formula, the SciPy / scikit-learn call it matches and
//! to what tolerance, its edge cases and its cost. Degenerate inputs (too few samples, a
//! constant sample, non-finite values) return [`StatsError`], never NaN. Every sampling
//! function takes an explicit seed, and per-item child seeds come from [`seed::child`], so
//! results do not depend on the number of threads.
//!
//! ```
//! use fogline_stats::correlation::pearson;
//!
//! let r = pearson(&[1.0, 2.0, 3.0, 4.0], &[1.0, 3.0, 2.0, 4.0]).unwrap();
//! assert!((r.r - 0.8).abs() < 1e-12);
//! ```

pub mod contingency;
pub mod correlation;
pub mod describe;
pub mod effect;
pub mod error;
pub mod gmm;
pub mod icc;
pub mod proportion;
pub mod rank;
pub mod seed;
pub mod special;

pub use error::StatsError;

/// Result alias of this crate.
pub type Result<T, E = StatsError> = std::result::Result<T, E>;
