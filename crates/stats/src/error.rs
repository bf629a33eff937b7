//! The error type of fogline-stats.

/// Why a statistic could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum StatsError {
    /// Fewer samples than the statistic needs.
    #[error("{what} needs at least {needed} samples, got {got}")]
    TooFewSamples {
        /// The statistic or input.
        what: &'static str,
        /// The minimum number of samples.
        needed: usize,
        /// The number given.
        got: usize,
    },
    /// A sample has zero variance where the statistic divides by it.
    #[error("{what} is undefined for a constant sample")]
    ConstantSample {
        /// The statistic or input.
        what: &'static str,
    },
    /// A value is NaN or infinite.
    #[error("{what}: value at index {index} is not finite")]
    NonFinite {
        /// The statistic or input.
        what: &'static str,
        /// Index of the first offending value.
        index: usize,
    },
    /// Two inputs that must have the same length do not.
    #[error("{what}: lengths differ ({left} vs {right})")]
    LengthMismatch {
        /// The statistic or input.
        what: &'static str,
        /// Length of the first input.
        left: usize,
        /// Length of the second input.
        right: usize,
    },
    /// A parameter is out of its valid range.
    #[error("parameter {name}: {reason}")]
    InvalidParam {
        /// The parameter's name.
        name: &'static str,
        /// What was expected.
        reason: String,
    },
    /// The statistic is mathematically undefined for this input (reason given).
    #[error("{what} is undefined: {reason}")]
    Undefined {
        /// The statistic.
        what: &'static str,
        /// Why.
        reason: String,
    },
}

/// Checks every value is finite, naming the first that is not.
pub(crate) fn check_finite(what: &'static str, x: &[f64]) -> Result<(), StatsError> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(StatsError::NonFinite { what, index }),
        None => Ok(()),
    }
}
