//! Parameters of the envelope analysis.

use fogline_types::Taxonomy;
use serde::{Deserialize, Serialize};

use crate::error::{EnvelopeError, Result};

/// How the per-scenario threshold is read off a dose-response curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ThresholdRule {
    /// The largest grid level before the first level at which mean ADE_attacked ≥
    /// (1+b)·mean ADE_clean; "none" when the smallest level fails; right-censored when no
    /// level fails.
    #[default]
    FirstViolation,
    /// The largest grid level at which mean ADE_attacked < (1+b)·mean ADE_clean, even if a
    /// smaller level failed; "none" when no level passes; right-censored when the largest passes.
    MaxPassing,
}

impl ThresholdRule {
    /// The rule's name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::FirstViolation => "first-violation",
            Self::MaxPassing => "max-passing",
        }
    }
}

/// How many severity bands to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Bands {
    /// The modal BIC-optimal k over the restart seeds.
    #[default]
    Auto,
    /// A fixed k (the BIC table is still reported).
    Fixed(usize),
}

/// How bootstrap resamples weight the clips of a scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum BootstrapMethod {
    /// Multinomial up to `poisson_min_clips` clips in the corpus, Poisson beyond.
    #[default]
    Auto,
    /// The classic bootstrap: n clips drawn with replacement from each scenario's n.
    Multinomial,
    /// The Poisson bootstrap: every clip gets an independent Poisson(1) weight; it streams
    /// clips in order and scales to millions of clips.
    Poisson,
}

/// Which taxonomy of scenario labels to use.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum TaxonomyChoice {
    /// The paper's seven classes + OTHER when any label of the data is one of them;
    /// otherwise the labels found in the data (with `OTHER` excluded).
    #[default]
    Auto,
    /// Exactly this taxonomy.
    Given(Taxonomy),
}

impl std::str::FromStr for ThresholdRule {
    type Err = String;

    /// `first-violation` or `max-passing`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        [Self::FirstViolation, Self::MaxPassing]
            .into_iter()
            .find(|r| r.name() == s)
            .ok_or_else(|| format!("expected `first-violation` or `max-passing`, got {s:?}"))
    }
}

impl std::str::FromStr for BootstrapMethod {
    type Err = String;

    /// `auto`, `multinomial` or `poisson`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            "multinomial" => Ok(Self::Multinomial),
            "poisson" => Ok(Self::Poisson),
            _ => Err(format!(
                "expected `auto`, `multinomial` or `poisson`, got {s:?}"
            )),
        }
    }
}

impl std::str::FromStr for TaxonomyChoice {
    type Err = String;

    /// `auto` (the paper's classes when the data has any of them, else the data's labels),
    /// `paper` (exactly the paper's seven classes + OTHER) or `data` (the labels found in
    /// the data, OTHER excluded).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            "paper" => Ok(Self::Given(Taxonomy::paper())),
            "data" => Ok(Self::Given(Taxonomy {
                classes: Vec::new(),
                other: fogline_types::scenario::OTHER.into(),
            })),
            _ => Err(format!("expected `auto`, `paper` or `data`, got {s:?}")),
        }
    }
}

impl std::str::FromStr for Bands {
    type Err = String;

    /// `auto` or a whole number of bands.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            k => k
                .parse()
                .map(Self::Fixed)
                .map_err(|_| format!("expected `auto` or a whole number, got {k:?}")),
        }
    }
}

/// Parameters of [`crate::analyze`]. Defaults follow the envelope paper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EnvelopeParams {
    /// ADE budgets b (relative degradation), e.g. 0.10, 0.15, 0.20.
    pub budgets: Vec<f64>,
    /// The budget used for the ODD entry and the headline tables; must be in `budgets`.
    pub headline_budget: f64,
    /// Threshold rule.
    pub rule: ThresholdRule,
    /// Clip-level bootstrap resamples.
    pub bootstrap: usize,
    /// Resampling scheme of the bootstrap.
    pub bootstrap_method: BootstrapMethod,
    /// With `Auto`, corpora with more clips than this use the Poisson bootstrap.
    pub poisson_min_clips: usize,
    /// Seed of every random draw (bootstrap, GMM starts, CV folds).
    pub seed: u64,
    /// Largest number of mixture components tried.
    pub k_max: usize,
    /// Restart seeds of the BIC study (seed index 0..restarts).
    pub restarts: usize,
    /// Starts per GMM fit, keeping the best lower bound.
    pub n_init: usize,
    /// Folds of the cross-validated log-likelihood.
    pub cv_folds: usize,
    /// Largest k of the per-scenario mixtures.
    pub per_scenario_k_max: usize,
    /// Number of bands.
    pub bands: Bands,
    /// How many of the top bands count as high severity.
    pub high_bands: usize,
    /// Residual-risk budget π* on P(high | changed, s); acceptance is evaluated only when set.
    pub pi_star: Option<f64>,
    /// Operating level σ_op for acceptance; defaults to the all-clips aggregate threshold.
    pub sigma_op: Option<f64>,
    /// Scenarios with fewer clips are marked pilot.
    pub min_clips: usize,
    /// How L2 was aggregated upstream (recorded, not used).
    pub l2_aggregation: String,
    /// Family whose threshold forms the ODD entry.
    pub odd_family: String,
    /// A scenario's high-severity share at or above `severe_factor` × the corpus share is "severe".
    pub severe_factor: f64,
    /// Relative budget perturbation of the A1 sensitivity check (±).
    pub budget_sensitivity: f64,
    /// Jaccard below this is a "complete rewrite" (Mann–Whitney low group).
    pub jaccard_low: f64,
    /// Jaccard at most this (and ≥ `jaccard_low`) is a "mid-range edit".
    pub jaccard_high: f64,
    /// Effect size for the post-hoc power of the Mann–Whitney comparison.
    pub power_effect_size: f64,
    /// Significance level of that power computation.
    pub alpha: f64,
    /// Scenario taxonomy.
    pub taxonomy: TaxonomyChoice,
}

impl EnvelopeParams {
    /// A `Given` taxonomy without classes stands for "the labels found in the data" (the
    /// CLI's `--taxonomy data`): fills them in from `t`, keeping its `other` label.
    pub fn take_labels_from(&mut self, t: &crate::input::PairTable) {
        if let TaxonomyChoice::Given(tx) = &self.taxonomy
            && tx.classes.is_empty()
        {
            self.taxonomy = TaxonomyChoice::Given(Taxonomy::from_labels(
                t.scenarios.iter().map(String::as_str),
                &tx.other,
            ));
        }
    }
}

impl Default for EnvelopeParams {
    fn default() -> Self {
        Self {
            budgets: vec![0.10, 0.15, 0.20],
            headline_budget: 0.15,
            rule: ThresholdRule::FirstViolation,
            bootstrap: 10_000,
            bootstrap_method: BootstrapMethod::Auto,
            poisson_min_clips: 100_000,
            seed: 0,
            k_max: 8,
            restarts: 20,
            n_init: 3,
            cv_folds: 5,
            per_scenario_k_max: 6,
            bands: Bands::Auto,
            high_bands: 2,
            pi_star: None,
            sigma_op: None,
            min_clips: 30,
            l2_aggregation: "euclidean norm of the stacked xy waypoint differences (m)".into(),
            odd_family: "gaussian_noise".into(),
            severe_factor: 1.5,
            budget_sensitivity: 0.05,
            jaccard_low: 0.10,
            jaccard_high: 0.90,
            power_effect_size: 0.10,
            alpha: 0.05,
            taxonomy: TaxonomyChoice::Auto,
        }
    }
}

impl EnvelopeParams {
    /// The GMM model-selection parameters of the severity analysis (the BIC study over
    /// `restarts` seeds and k ≤ `k_max`, `n_init` starts per fit, `cv_folds`-fold CV).
    pub fn gmm_select_params(&self) -> fogline_stats::gmm::SelectParams {
        fogline_stats::gmm::SelectParams {
            k_max: self.k_max,
            restarts: self.restarts,
            n_init: self.n_init,
            cv_folds: self.cv_folds,
            seed: self.seed,
            ..fogline_stats::gmm::SelectParams::default()
        }
    }

    /// Checks every parameter; call before analysing.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |name: &'static str, reason: String| Err(EnvelopeError::InvalidParam { name, reason });
        if self.budgets.is_empty() {
            return bad("budgets", "give at least one budget".into());
        }
        for &b in &self.budgets {
            if !(b.is_finite() && b > 0.0 && b < 10.0) {
                return bad(
                    "budgets",
                    format!("{b} is not a relative budget in (0, 10)"),
                );
            }
        }
        if !self.budgets.contains(&self.headline_budget) {
            return bad(
                "headline_budget",
                format!(
                    "{} is not one of the budgets {:?}",
                    self.headline_budget, self.budgets
                ),
            );
        }
        if self.bootstrap == 1 || self.bootstrap > 10_000_000 {
            return bad(
                "bootstrap",
                "use 0 (off) or 2..=10,000,000 resamples".into(),
            );
        }
        if !(1..=16).contains(&self.k_max) {
            return bad("k_max", "must be in 1..=16".into());
        }
        if !(1..=16).contains(&self.per_scenario_k_max) {
            return bad("per_scenario_k_max", "must be in 1..=16".into());
        }
        if self.restarts == 0 || self.restarts > 1000 {
            return bad("restarts", "must be in 1..=1000".into());
        }
        if self.n_init == 0 || self.n_init > 100 {
            return bad("n_init", "must be in 1..=100".into());
        }
        if self.cv_folds == 1 || self.cv_folds > 100 {
            return bad("cv_folds", "use 0 (off) or 2..=100".into());
        }
        if let Bands::Fixed(k) = self.bands
            && !(1..=16).contains(&k)
        {
            return bad("bands", "a fixed band count must be in 1..=16".into());
        }
        if self.high_bands == 0 {
            return bad("high_bands", "must be at least 1".into());
        }
        if let Some(p) = self.pi_star
            && !(0.0..=1.0).contains(&p)
        {
            return bad("pi_star", format!("{p} is not a probability"));
        }
        if let Some(s) = self.sigma_op
            && !s.is_finite()
        {
            return bad("sigma_op", "must be finite".into());
        }
        if !(self.severe_factor.is_finite() && self.severe_factor >= 1.0) {
            return bad("severe_factor", "must be a finite factor >= 1".into());
        }
        if !(self.budget_sensitivity.is_finite() && (0.0..1.0).contains(&self.budget_sensitivity)) {
            return bad("budget_sensitivity", "must be in [0, 1)".into());
        }
        if !(0.0..=1.0).contains(&self.jaccard_low)
            || !(0.0..=1.0).contains(&self.jaccard_high)
            || self.jaccard_low > self.jaccard_high
        {
            return bad("jaccard_low/high", "need 0 <= low <= high <= 1".into());
        }
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return bad("alpha", "must be in (0, 1)".into());
        }
        if !(self.power_effect_size.is_finite() && self.power_effect_size > 0.0) {
            return bad("power_effect_size", "must be positive".into());
        }
        Ok(())
    }
}
