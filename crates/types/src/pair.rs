//! The pairs-table row: one clip under one perturbed condition, against its clean run.

use serde::{Deserialize, Serialize};

/// One row of the pairs table (the input contract of the envelope analysis).
///
/// Distances are in metres. `ade_*` are measured against the same ground-truth trajectory;
/// `l2_m` is the deviation of the perturbed prediction from the clean prediction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Pair {
    /// Clip identifier.
    pub clip_id: String,
    /// Scenario label of the clip.
    pub scenario: String,
    /// Condition name (`noise_30`, `dark`, …).
    pub condition: String,
    /// Family name of the condition (`gaussian_noise`, `brightness`, `fog`, …).
    pub family: String,
    /// Level of the condition within its family.
    pub level: f64,
    /// ADE of the clean prediction against ground truth (m).
    pub ade_clean_m: f64,
    /// ADE of the perturbed prediction against ground truth (m).
    pub ade_attacked_m: f64,
    /// Deviation of the perturbed prediction from the clean prediction (m).
    pub l2_m: f64,
    /// Chain-of-Causation text of the clean run.
    pub coc_clean: String,
    /// Chain-of-Causation text of the perturbed run.
    pub coc_attacked: String,
}
