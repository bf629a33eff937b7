//! The analysis result: plain data, serialised as `envelope.json` (schema in
//! `docs/envelope-schema.md`). Every float is finite; quantities that cannot be computed are
//! `None` (JSON `null`) with the reason in `statistics.undefined` or `notes`.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::input::{ConditionInfo, InputInfo};
use crate::params::EnvelopeParams;

/// Version of the `envelope.json` schema. Bumped on any incompatible change.
pub const SCHEMA_VERSION: u32 = 1;

/// Name of the pseudo-scenario pooling the classified scenarios.
pub const AGG_CLASSIFIED: &str = "AGGREGATE_CLASSIFIED";
/// Name of the pseudo-scenario pooling every clip (OTHER included).
pub const AGG_ALL: &str = "AGGREGATE_ALL";

/// The whole envelope.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Envelope {
    /// Schema version ([`SCHEMA_VERSION`]).
    pub schema_version: u32,
    /// The producing tool and version.
    pub generated_by: String,
    /// Where the pairs came from.
    pub input: InputInfo,
    /// The parameters used.
    pub parameters: EnvelopeParams,
    /// The bootstrap resampling actually used (`multinomial`, `poisson`, or `none`).
    pub bootstrap_method: String,
    /// Every convention the paper leaves open, as chosen here.
    pub conventions: BTreeMap<String, String>,
    /// What the corpus holds.
    pub corpus: Corpus,
    /// Ordered severity axes (families, with brightness split into darken/brighten).
    pub axes: Vec<Axis>,
    /// Dose-response per group (classified scenarios + aggregates), axis and level.
    pub dose_response: Vec<DosePoint>,
    /// Scenario × condition ΔADE map (every scenario label, plus the aggregates).
    pub delta_ade_map: Vec<MapCell>,
    /// Thresholds per group, axis and budget.
    pub thresholds: Vec<Threshold>,
    /// The GMM severity bands.
    pub severity: Severity,
    /// High-severity shares.
    pub high_severity: HighSeverity,
    /// Joint scenario × band distribution of changed pairs (classified scenarios).
    pub joint: Joint,
    /// The two-dimensional ODD entries.
    pub odd: Vec<OddEntry>,
    /// The paper's statistics.
    pub statistics: Statistics,
    /// The action transition matrix of changed pairs (classified scenarios).
    pub transitions: Transitions,
    /// The ISO 21448 assurance mapping (table 5), filled from the numbers.
    pub assurance: Assurance,
    /// Warnings and explanations a reader should see.
    pub notes: Vec<String>,
}

/// Corpus summary (table 1).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Corpus {
    /// Pairs (rows).
    pub n_pairs: usize,
    /// Clips.
    pub n_clips: usize,
    /// Pairs whose CoC changed.
    pub n_changed: usize,
    /// Clips lacking some condition (accepted with `allow_incomplete`).
    pub n_incomplete_clips: usize,
    /// The taxonomy's classified labels, in rank order.
    pub taxonomy: Vec<String>,
    /// The label treated as unclassified.
    pub other_label: String,
    /// Labels in the data that are not in the taxonomy (treated as unclassified).
    pub unclassified_labels: Vec<String>,
    /// The conditions found.
    pub conditions: Vec<ConditionInfo>,
    /// Per scenario label.
    pub scenarios: Vec<ScenarioSummary>,
}

/// One scenario label's summary.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ScenarioSummary {
    /// Label.
    pub scenario: String,
    /// Complexity rank in the taxonomy (None when unclassified).
    pub rank: Option<usize>,
    /// Whether it takes part in per-scenario analysis.
    pub classified: bool,
    /// Clips.
    pub n_clips: usize,
    /// Pairs.
    pub n_pairs: usize,
    /// Pairs whose CoC changed.
    pub n_changed: usize,
    /// Mean clean ADE over its pairs (m).
    pub clean_ade_mean_m: f64,
    /// CoC flip rate (changed / pairs).
    pub flip_rate: f64,
    /// Fewer clips than `min_clips`.
    pub pilot: bool,
}

/// An ordered severity axis.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Axis {
    /// Axis name (`gaussian_noise`, `fog`, `darken`, `brighten`, or a user family).
    pub axis: String,
    /// The family it comes from.
    pub family: String,
    /// Levels, least to most severe.
    pub levels: Vec<f64>,
    /// Condition names at each level (several names may share a level).
    pub conditions: Vec<Vec<String>>,
}

/// One point of a dose-response curve.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DosePoint {
    /// Scenario or aggregate.
    pub scenario: String,
    /// Axis.
    pub axis: String,
    /// Level.
    pub level: f64,
    /// Pairs at this level.
    pub n_pairs: usize,
    /// Mean clean ADE (m).
    pub mean_ade_clean_m: f64,
    /// Mean perturbed ADE (m).
    pub mean_ade_attacked_m: f64,
    /// ΔADE = mean attacked − mean clean (m).
    pub delta_ade_m: f64,
    /// Bootstrap percentile 95 % interval of ΔADE (None without bootstrap).
    pub delta_ade_ci95_m: Option<[f64; 2]>,
    /// mean attacked / mean clean (None when the clean mean is 0).
    pub ratio: Option<f64>,
    /// Whether the level is within each budget (key: budget).
    pub within_budget: BTreeMap<String, bool>,
}

/// One cell of the scenario × condition ΔADE map.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MapCell {
    /// Scenario label or aggregate.
    pub scenario: String,
    /// Condition name.
    pub condition: String,
    /// Pairs in the cell.
    pub n_pairs: usize,
    /// ΔADE (m).
    pub delta_ade_m: f64,
}

/// Position of a scenario's threshold relative to the aggregate's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VsAggregate {
    /// Fails at a smaller level than the aggregate.
    Tighter,
    /// Same threshold.
    Matches,
    /// Tolerates a larger level.
    Looser,
}

impl VsAggregate {
    /// The name `envelope.json` writes (`tighter`, `matches`, `looser`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Tighter => "tighter",
            Self::Matches => "matches",
            Self::Looser => "looser",
        }
    }
}

/// One threshold σ*(s) with its bootstrap.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Threshold {
    /// Scenario or aggregate.
    pub scenario: String,
    /// `scenario` or `aggregate`.
    pub kind: String,
    /// Axis.
    pub axis: String,
    /// Budget b.
    pub budget: f64,
    /// Rule name.
    pub rule: String,
    /// Clips in the group.
    pub n_clips: usize,
    /// The threshold level; None = "none" (the smallest level already fails).
    pub sigma_star: Option<f64>,
    /// No tested level fails: the true threshold may be higher.
    pub right_censored: bool,
    /// Percentile 95 % interval over resamples, on the ordinal scale none < levels; a null
    /// bound means "none". None without bootstrap.
    pub ci95: Option<[Option<f64>; 2]>,
    /// Share of resamples at each outcome (`none` or the level).
    pub bootstrap_share: BTreeMap<String, f64>,
    /// Against the all-clips aggregate at the same axis and budget (None for aggregates).
    pub vs_aggregate: Option<VsAggregate>,
    /// Fewer clips than `min_clips`.
    pub pilot: bool,
}

/// One row of the BIC table.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BicRow {
    /// Number of components.
    pub k: usize,
    /// BIC under each restart seed.
    pub per_seed: Vec<f64>,
    /// Minimum over seeds.
    pub min: f64,
    /// Restart seeds whose BIC-optimal k is this k.
    pub chosen_count: usize,
    /// BIC gain from k−1 to k (min over seeds); None for the first k.
    pub gain: Option<f64>,
    /// gain(k) / gain(k+1); None where undefined.
    pub gain_ratio: Option<f64>,
}

/// One row of the cross-validation table.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CvRow {
    /// Number of components.
    pub k: usize,
    /// Held-out mean log-likelihood per fold.
    pub folds: Vec<f64>,
    /// Mean over folds.
    pub mean: f64,
    /// Folds in which k beats k−1.
    pub folds_beating_previous: usize,
}

/// A severity band.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Band {
    /// `C0`, `C1`, … by increasing mean.
    pub name: String,
    /// Component mean (m).
    pub mean_m: f64,
    /// Component standard deviation (m).
    pub std_m: f64,
    /// Mixture weight.
    pub weight: f64,
    /// Share of changed pairs hard-assigned to it.
    pub share: f64,
    /// Changed pairs hard-assigned to it.
    pub n: usize,
}

/// Per-scenario mixture choice.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ScenarioMixture {
    /// Scenario.
    pub scenario: String,
    /// Changed pairs.
    pub n_changed: usize,
    /// (k, BIC) pairs tried.
    pub bic: Vec<(usize, f64)>,
    /// BIC-optimal k (None when undefined).
    pub chosen_k: Option<usize>,
    /// Why undefined.
    pub reason: Option<String>,
}

/// The GMM severity analysis of changed pairs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Severity {
    /// Whether a mixture could be fitted.
    pub defined: bool,
    /// Why not.
    pub reason: Option<String>,
    /// Changed pairs.
    pub n_changed: usize,
    /// `auto` or `fixed`.
    pub bands_mode: String,
    /// BIC table.
    pub bic: Vec<BicRow>,
    /// The BIC-optimal k of each restart seed (seed index order).
    pub chosen_per_seed: Vec<usize>,
    /// Chosen k.
    pub chosen_k: Option<usize>,
    /// Cross-validated held-out log-likelihood.
    pub cv_loglik: Vec<CvRow>,
    /// Bands C0.. by mean.
    pub bands: Vec<Band>,
    /// L2 values where the hard assignment switches band (m), ascending.
    pub boundaries_m: Vec<f64>,
    /// Final model's mean log-likelihood per sample.
    pub lower_bound: Option<f64>,
    /// Per-scenario mixtures.
    pub per_scenario: Vec<ScenarioMixture>,
}

/// High-severity share of one group.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct HighRow {
    /// Scenario, aggregate or condition.
    pub group: String,
    /// Changed pairs.
    pub n_changed: usize,
    /// Of which in the high bands.
    pub n_high: usize,
    /// n_high / n_changed (None when no changed pairs or no high band).
    pub share: Option<f64>,
    /// Mean L2 of its changed pairs (m).
    pub mean_l2_changed_m: Option<f64>,
}

/// High-severity shares.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct HighSeverity {
    /// Which bands count as high.
    pub bands: Vec<String>,
    /// Per classified scenario and the aggregates.
    pub by_scenario: Vec<HighRow>,
    /// Per condition (all scenarios).
    pub by_condition: Vec<HighRow>,
}

/// Joint scenario × band distribution.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Joint {
    /// Rows.
    pub scenarios: Vec<String>,
    /// Columns.
    pub bands: Vec<String>,
    /// Counts `[scenario][band]`.
    pub counts: Vec<Vec<usize>>,
    /// Row shares `[scenario][band]` (each row sums to 1; empty rows are all 0).
    pub row_shares: Vec<Vec<f64>>,
}

/// The two-dimensional ODD entry of one scenario (table 4): one definition with `odd.json`'s
/// readers, in `fogline_types::odd`.
pub use fogline_types::odd::{AxisThreshold, OddEntry};

/// A correlation with its p-value.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct Corr {
    /// Coefficient.
    pub r: f64,
    /// Two-sided p-value.
    pub p_value: f64,
    /// Sample size.
    pub n: usize,
}

/// The Mann–Whitney comparison of complete rewrites vs mid-range edits.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MwuOut {
    /// U of the low-Jaccard group.
    pub u: f64,
    /// z score.
    pub z: f64,
    /// Two-sided p-value.
    pub p_value: f64,
    /// Cohen's d (low − mid).
    pub cohens_d: f64,
    /// Pairs with J < jaccard_low.
    pub n_low: usize,
    /// Pairs with jaccard_low ≤ J ≤ jaccard_high.
    pub n_mid: usize,
    /// Effect size of the power computation.
    pub power_effect_size: f64,
    /// Post-hoc power to detect that effect size.
    pub power: f64,
}

/// χ² test of independence.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Chi2Out {
    /// Statistic.
    pub statistic: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// p-value.
    pub p_value: f64,
}

/// Intraclass correlations of per-clip flip flags across conditions.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct IccOut {
    /// ICC(2,1).
    pub icc2_1: f64,
    /// ICC(3,1).
    pub icc3_1: f64,
    /// Clips used (complete ones).
    pub n_clips: usize,
    /// Conditions.
    pub n_conditions: usize,
}

/// The paper's statistics.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Statistics {
    /// Pairs.
    pub n_pairs: usize,
    /// Changed pairs.
    pub n_changed: usize,
    /// Share of changed pairs.
    pub change_rate: f64,
    /// Point-biserial r of coc_changed vs L2.
    pub point_biserial_r: Option<f64>,
    /// Its p-value.
    pub point_biserial_p: Option<f64>,
    /// Cohen's d of L2, changed vs unchanged.
    pub cohens_d: Option<f64>,
    /// Mean L2 of changed pairs (m).
    pub mean_l2_changed_m: Option<f64>,
    /// Mean L2 of unchanged pairs (m).
    pub mean_l2_unchanged_m: Option<f64>,
    /// Mean L2 changed / unchanged.
    pub l2_ratio: Option<f64>,
    /// Pearson of per-condition change rate vs mean L2.
    pub change_rate_vs_l2: Option<Corr>,
    /// Pearson r of Jaccard vs L2 on changed pairs.
    pub jaccard_l2_pearson: Option<f64>,
    /// Spearman ρ of Jaccard vs L2 on changed pairs.
    pub jaccard_l2_spearman: Option<f64>,
    /// Both with p-values.
    pub jaccard_l2: Option<[Corr; 2]>,
    /// Mann–Whitney of complete rewrites vs mid-range edits.
    pub mwu: Option<MwuOut>,
    /// Changed pairs with a semantic similarity (`coc_cosine`: the cosine of the two CoC
    /// texts' all-MiniLM-L6-v2 sentence embeddings). 0 in files written before it existed.
    #[serde(default)]
    pub n_cosine: usize,
    /// Pearson and Spearman of the semantic similarity vs L2 on changed pairs with one: the
    /// paper's magnitude-vs-deviation check with an embedding instead of token overlap.
    #[serde(default)]
    pub cosine_l2: Option<[Corr; 2]>,
    /// The same within the mid-range Jaccard band (`jaccard_low` ≤ J ≤ `jaccard_high`), where
    /// the paper asks whether an embedding tells paraphrases from semantically distinct
    /// rewrites.
    #[serde(default)]
    pub cosine_l2_mid_jaccard: Option<[Corr; 2]>,
    /// Bimodality coefficient of L2 on changed pairs.
    pub bimodality_coefficient: Option<f64>,
    /// χ² of the joint scenario × band table.
    pub chi2: Option<Chi2Out>,
    /// Cramér's V of that table.
    pub cramers_v: Option<f64>,
    /// ICC of flip flags.
    pub icc: Option<IccOut>,
    /// Share of clips whose CoC never flips.
    pub never_flip_share: f64,
    /// Share of clips whose CoC flips under every condition.
    pub always_flip_share: f64,
    /// Why a statistic is null.
    pub undefined: BTreeMap<String, String>,
}

/// Diagonal share of one action's row.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ActionDiagonal {
    /// Action of the clean CoC.
    pub action: String,
    /// Changed pairs starting from it.
    pub n: usize,
    /// Share keeping the same action (None when n = 0).
    pub diagonal_share: Option<f64>,
}

/// The action transition matrix.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Transitions {
    /// Action labels (rows: clean, columns: perturbed).
    pub labels: Vec<String>,
    /// Counts `[clean][perturbed]`.
    pub counts: Vec<Vec<usize>>,
    /// Pairs in the matrix.
    pub n: usize,
    /// Per action.
    pub by_action: Vec<ActionDiagonal>,
    /// Trace / total.
    pub diagonal_share: Option<f64>,
}

/// One evidence node of the assurance argument.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EvidenceNode {
    /// E1, E2, E3, A1, A2.
    pub id: String,
    /// ISO 21448:2022 clause(s).
    pub clause: String,
    /// The claim, filled from the numbers.
    pub text: String,
}

/// Threshold under budget ±sensitivity (assumption A1).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sensitivity {
    /// Scenario or aggregate.
    pub scenario: String,
    /// σ* at b·(1 − s).
    pub sigma_star_low: Option<f64>,
    /// σ* at b.
    pub sigma_star: Option<f64>,
    /// σ* at b·(1 + s).
    pub sigma_star_high: Option<f64>,
    /// All three agree.
    pub stable: bool,
}

/// The ISO 21448 assurance mapping (table 5).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Assurance {
    /// Goal.
    pub goal: String,
    /// Strategy.
    pub strategy: String,
    /// E1–E3 and A1–A2.
    pub nodes: Vec<EvidenceNode>,
    /// The A1 sensitivity check.
    pub budget_sensitivity: Vec<Sensitivity>,
}

/// `Some(x)` for a finite `x`: statistics that cannot be computed are `null` in the JSON,
/// never NaN.
pub(crate) fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl Envelope {
    /// Reads an `envelope.json` back into the model that wrote it (`name` stands for the file
    /// in errors): its schema version first, then every field (the message names the field
    /// by its JSON path, e.g. `severity.bands[0].mean_m`, then serde's message with line and
    /// column). The round trip is exact: floats parse bit for bit.
    pub fn from_json(text: &str, name: &str) -> crate::Result<Self> {
        let bad = |detail: String| crate::EnvelopeError::NotFormat {
            path: name.into(),
            expected: "envelope.json",
            detail,
        };
        #[derive(Deserialize)]
        struct Head {
            schema_version: Option<u32>,
        }
        let head: Head = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        match head.schema_version {
            Some(SCHEMA_VERSION) => {}
            Some(v) => {
                return Err(bad(format!(
                    "schema_version {v} is not supported (this build reads {SCHEMA_VERSION})"
                )));
            }
            None => return Err(bad("no schema_version field".into())),
        }
        let de = &mut serde_json::Deserializer::from_str(text);
        let env: Self = serde_path_to_error::deserialize(&mut *de)
            .map_err(|e| bad(format!("at `{}`: {}", e.path(), e.inner())))?;
        de.end().map_err(|e| bad(e.to_string()))?;
        Ok(env)
    }

    /// The ODD specification a runtime monitor loads (`odd.json`): the headline budget's
    /// entries with what they were computed under.
    pub fn odd_spec(&self) -> fogline_types::odd::OddSpec {
        let p = &self.parameters;
        let mut spec = fogline_types::odd::OddSpec::new(
            &self.generated_by,
            &self.input.sha256,
            self.odd.first().map(|o| o.axis.clone()),
            p.headline_budget,
            p.rule.name(),
        );
        spec.high_bands = self.high_severity.bands.clone();
        spec.pi_star = p.pi_star;
        spec.sigma_op = p.sigma_op;
        spec.entries = self.odd.clone();
        spec
    }
}
