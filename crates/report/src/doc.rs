//! `envelope.json` (schema version 1) as the report reads it.
//!
//! The analysis's own [`fogline_envelope::Envelope`] is write-only (it serialises, it does not
//! parse); the report reads the documented JSON contract instead, so a page can be rebuilt
//! from any `envelope.json` on disk, and an in-memory envelope goes through the same path
//! ([`EnvelopeDoc::from_envelope`]). Fields the report does not draw are not mirrored;
//! unknown fields are ignored, so later additions to the schema do not break old reports.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::{ReportError, Result};

/// The schema version read here.
pub const SCHEMA_VERSION: u32 = 1;

/// The whole envelope.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvelopeDoc {
    /// Schema version.
    pub schema_version: u32,
    /// Producing tool and version.
    pub generated_by: String,
    /// The pairs table analysed.
    pub input: InputDoc,
    /// The bootstrap actually used (`multinomial`, `poisson`, `none`).
    #[serde(default)]
    pub bootstrap_method: String,
    /// Every parameter, as written (rendered generically, in key order).
    pub parameters: serde_json::Map<String, serde_json::Value>,
    /// Every convention, by topic.
    #[serde(default)]
    pub conventions: BTreeMap<String, String>,
    /// Table 1.
    pub corpus: CorpusDoc,
    /// Severity axes.
    #[serde(default)]
    pub axes: Vec<AxisDoc>,
    /// Dose-response points.
    #[serde(default)]
    pub dose_response: Vec<DosePointDoc>,
    /// Scenario × condition ΔADE cells.
    #[serde(default)]
    pub delta_ade_map: Vec<MapCellDoc>,
    /// Thresholds per group × axis × budget.
    #[serde(default)]
    pub thresholds: Vec<ThresholdDoc>,
    /// The GMM severity analysis.
    pub severity: SeverityDoc,
    /// High-severity shares.
    pub high_severity: HighSeverityDoc,
    /// Joint scenario × band counts.
    pub joint: JointDoc,
    /// Table 4.
    #[serde(default)]
    pub odd: Vec<OddDoc>,
    /// The statistics.
    pub statistics: StatisticsDoc,
    /// Action transitions.
    pub transitions: TransitionsDoc,
    /// Table 5.
    pub assurance: AssuranceDoc,
    /// Warnings.
    #[serde(default)]
    pub notes: Vec<String>,
}

/// Where the pairs came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputDoc {
    /// Path as given to the analysis.
    pub path: String,
    /// `csv`, `parquet`, `jsonl`.
    pub format: String,
    /// SHA-256 of the file (may be empty for in-memory tables).
    #[serde(default)]
    pub sha256: String,
    /// Rows read.
    pub n_rows: usize,
}

/// Corpus summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CorpusDoc {
    /// Pairs.
    pub n_pairs: usize,
    /// Clips.
    pub n_clips: usize,
    /// Changed pairs.
    pub n_changed: usize,
    /// Incomplete clips.
    #[serde(default)]
    pub n_incomplete_clips: usize,
    /// Classified labels in rank order.
    #[serde(default)]
    pub taxonomy: Vec<String>,
    /// The unclassified label.
    #[serde(default)]
    pub other_label: String,
    /// Labels outside the taxonomy.
    #[serde(default)]
    pub unclassified_labels: Vec<String>,
    /// Conditions.
    #[serde(default)]
    pub conditions: Vec<ConditionDoc>,
    /// Per scenario label.
    #[serde(default)]
    pub scenarios: Vec<ScenarioDoc>,
}

/// A condition.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConditionDoc {
    /// Name.
    pub name: String,
    /// Family.
    pub family: String,
    /// Level.
    pub level: f64,
}

/// One row of table 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenarioDoc {
    /// Label.
    pub scenario: String,
    /// Complexity rank.
    pub rank: Option<usize>,
    /// Analysed per scenario.
    pub classified: bool,
    /// Clips.
    pub n_clips: usize,
    /// Pairs.
    pub n_pairs: usize,
    /// Changed pairs.
    pub n_changed: usize,
    /// Mean clean ADE (m).
    pub clean_ade_mean_m: f64,
    /// Changed / pairs.
    pub flip_rate: f64,
    /// Pilot.
    pub pilot: bool,
}

/// An ordered axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisDoc {
    /// Axis name.
    pub axis: String,
    /// Family.
    pub family: String,
    /// Levels, least to most severe.
    pub levels: Vec<f64>,
    /// Conditions at each level.
    #[serde(default)]
    pub conditions: Vec<Vec<String>>,
}

/// A dose-response point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DosePointDoc {
    /// Group.
    pub scenario: String,
    /// Axis.
    pub axis: String,
    /// Level.
    pub level: f64,
    /// Pairs.
    pub n_pairs: usize,
    /// Mean clean ADE (m).
    pub mean_ade_clean_m: f64,
    /// Mean perturbed ADE (m).
    pub mean_ade_attacked_m: f64,
    /// ΔADE (m).
    pub delta_ade_m: f64,
    /// Bootstrap 95 % interval of ΔADE (m).
    pub delta_ade_ci95_m: Option<[f64; 2]>,
    /// attacked / clean.
    pub ratio: Option<f64>,
    /// Within each budget (key: the budget as written).
    #[serde(default)]
    pub within_budget: BTreeMap<String, bool>,
}

/// A ΔADE map cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapCellDoc {
    /// Group.
    pub scenario: String,
    /// Condition.
    pub condition: String,
    /// Pairs.
    pub n_pairs: usize,
    /// ΔADE (m).
    pub delta_ade_m: f64,
}

/// A threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThresholdDoc {
    /// Group.
    pub scenario: String,
    /// `scenario` or `aggregate`.
    pub kind: String,
    /// Axis.
    pub axis: String,
    /// Budget.
    pub budget: f64,
    /// Rule.
    pub rule: String,
    /// Clips.
    pub n_clips: usize,
    /// σ* (None = none).
    pub sigma_star: Option<f64>,
    /// Right-censored.
    pub right_censored: bool,
    /// 95 % interval (a None bound = none).
    pub ci95: Option<[Option<f64>; 2]>,
    /// Share of resamples per outcome.
    #[serde(default)]
    pub bootstrap_share: BTreeMap<String, f64>,
    /// `tighter`, `matches`, `looser` (None for aggregates).
    pub vs_aggregate: Option<String>,
    /// Pilot.
    pub pilot: bool,
}

/// A BIC row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BicRowDoc {
    /// k.
    pub k: usize,
    /// Minimum BIC over seeds.
    pub min: f64,
    /// Seeds choosing this k.
    pub chosen_count: usize,
    /// Gain from k − 1.
    pub gain: Option<f64>,
    /// gain(k) / gain(k+1).
    pub gain_ratio: Option<f64>,
}

/// A cross-validation row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CvRowDoc {
    /// k.
    pub k: usize,
    /// Mean held-out log-likelihood.
    pub mean: f64,
    /// Folds in which k beats k − 1.
    pub folds_beating_previous: usize,
    /// Per fold.
    #[serde(default)]
    pub folds: Vec<f64>,
}

/// A band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BandDoc {
    /// `C0`…
    pub name: String,
    /// Mean (m).
    pub mean_m: f64,
    /// Standard deviation (m).
    pub std_m: f64,
    /// Mixture weight.
    pub weight: f64,
    /// Share of changed pairs assigned.
    pub share: f64,
    /// Pairs assigned.
    pub n: usize,
}

/// A per-scenario mixture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenarioMixtureDoc {
    /// Scenario.
    pub scenario: String,
    /// Changed pairs.
    pub n_changed: usize,
    /// Chosen k.
    pub chosen_k: Option<usize>,
    /// Why undefined.
    pub reason: Option<String>,
}

/// The severity analysis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeverityDoc {
    /// A mixture was fitted.
    pub defined: bool,
    /// Why not.
    pub reason: Option<String>,
    /// Changed pairs.
    pub n_changed: usize,
    /// `auto` or `fixed`.
    #[serde(default)]
    pub bands_mode: String,
    /// BIC table.
    #[serde(default)]
    pub bic: Vec<BicRowDoc>,
    /// Chosen k per seed.
    #[serde(default)]
    pub chosen_per_seed: Vec<usize>,
    /// Chosen k.
    pub chosen_k: Option<usize>,
    /// Cross-validation.
    #[serde(default)]
    pub cv_loglik: Vec<CvRowDoc>,
    /// Bands.
    #[serde(default)]
    pub bands: Vec<BandDoc>,
    /// Band boundaries (m).
    #[serde(default)]
    pub boundaries_m: Vec<f64>,
    /// Per-scenario mixtures.
    #[serde(default)]
    pub per_scenario: Vec<ScenarioMixtureDoc>,
}

/// A high-severity row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HighRowDoc {
    /// Group.
    pub group: String,
    /// Changed pairs.
    pub n_changed: usize,
    /// High-severity pairs.
    pub n_high: usize,
    /// Share.
    pub share: Option<f64>,
    /// Mean L2 of changed pairs (m).
    pub mean_l2_changed_m: Option<f64>,
}

/// High-severity shares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HighSeverityDoc {
    /// High bands.
    #[serde(default)]
    pub bands: Vec<String>,
    /// Per scenario.
    #[serde(default)]
    pub by_scenario: Vec<HighRowDoc>,
    /// Per condition.
    #[serde(default)]
    pub by_condition: Vec<HighRowDoc>,
}

/// Joint scenario × band counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointDoc {
    /// Rows.
    #[serde(default)]
    pub scenarios: Vec<String>,
    /// Columns.
    #[serde(default)]
    pub bands: Vec<String>,
    /// Counts.
    #[serde(default)]
    pub counts: Vec<Vec<usize>>,
}

/// An ODD entry (table 4): the one definition `odd.json` and `envelope.json` share.
pub type OddDoc = fogline_types::odd::OddEntry;

/// A correlation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CorrDoc {
    /// r.
    pub r: f64,
    /// p.
    pub p_value: f64,
    /// n.
    pub n: usize,
}

/// Mann–Whitney.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MwuDoc {
    /// U.
    pub u: f64,
    /// z.
    pub z: f64,
    /// p.
    pub p_value: f64,
    /// Cohen's d.
    pub cohens_d: f64,
    /// Low group size.
    pub n_low: usize,
    /// Mid group size.
    pub n_mid: usize,
    /// Effect size of the power computation.
    pub power_effect_size: f64,
    /// Power.
    pub power: f64,
}

/// χ².
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Chi2Doc {
    /// Statistic.
    pub statistic: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// p.
    pub p_value: f64,
}

/// ICC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IccDoc {
    /// ICC(2,1).
    pub icc2_1: f64,
    /// ICC(3,1).
    pub icc3_1: f64,
    /// Clips.
    pub n_clips: usize,
    /// Conditions.
    pub n_conditions: usize,
}

/// The statistics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatisticsDoc {
    /// Pairs.
    pub n_pairs: usize,
    /// Changed pairs.
    pub n_changed: usize,
    /// Change rate.
    pub change_rate: f64,
    /// Point-biserial r.
    pub point_biserial_r: Option<f64>,
    /// Its p.
    pub point_biserial_p: Option<f64>,
    /// Cohen's d.
    pub cohens_d: Option<f64>,
    /// Mean L2 changed (m).
    pub mean_l2_changed_m: Option<f64>,
    /// Mean L2 unchanged (m).
    pub mean_l2_unchanged_m: Option<f64>,
    /// Ratio.
    pub l2_ratio: Option<f64>,
    /// Per-condition change rate vs mean L2.
    pub change_rate_vs_l2: Option<CorrDoc>,
    /// Jaccard vs L2 (Pearson, Spearman).
    pub jaccard_l2: Option<[CorrDoc; 2]>,
    /// Mann–Whitney.
    pub mwu: Option<MwuDoc>,
    /// Bimodality coefficient.
    pub bimodality_coefficient: Option<f64>,
    /// χ².
    pub chi2: Option<Chi2Doc>,
    /// Cramér's V.
    pub cramers_v: Option<f64>,
    /// ICC.
    pub icc: Option<IccDoc>,
    /// Never-flip share.
    pub never_flip_share: f64,
    /// Always-flip share.
    pub always_flip_share: f64,
    /// Why a statistic is undefined.
    #[serde(default)]
    pub undefined: BTreeMap<String, String>,
}

/// Per-action diagonal share.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActionDiagonalDoc {
    /// Action.
    pub action: String,
    /// Pairs.
    pub n: usize,
    /// Diagonal share.
    pub diagonal_share: Option<f64>,
}

/// The action transition matrix.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransitionsDoc {
    /// Labels.
    #[serde(default)]
    pub labels: Vec<String>,
    /// Counts, indexed `[clean][perturbed]`.
    #[serde(default)]
    pub counts: Vec<Vec<usize>>,
    /// Pairs.
    pub n: usize,
    /// Per action.
    #[serde(default)]
    pub by_action: Vec<ActionDiagonalDoc>,
    /// Trace / total.
    pub diagonal_share: Option<f64>,
}

/// An assurance node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvidenceDoc {
    /// E1…A2.
    pub id: String,
    /// Clause.
    pub clause: String,
    /// Text.
    pub text: String,
}

/// Budget sensitivity row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensitivityDoc {
    /// Group.
    pub scenario: String,
    /// σ* at b(1 − s).
    pub sigma_star_low: Option<f64>,
    /// σ* at b.
    pub sigma_star: Option<f64>,
    /// σ* at b(1 + s).
    pub sigma_star_high: Option<f64>,
    /// All equal.
    pub stable: bool,
}

/// Table 5.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AssuranceDoc {
    /// Goal.
    pub goal: String,
    /// Strategy.
    pub strategy: String,
    /// Nodes.
    #[serde(default)]
    pub nodes: Vec<EvidenceDoc>,
    /// A1 check.
    #[serde(default)]
    pub budget_sensitivity: Vec<SensitivityDoc>,
}

impl EnvelopeDoc {
    /// Parses `envelope.json` text; `what` names the document in errors.
    pub fn from_json(text: &str, what: &str) -> Result<Self> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let doc: Self = serde_path_to_error::deserialize(de).map_err(|e| ReportError::Schema {
            what: what.to_string(),
            path: e.path().to_string(),
            source: e.into_inner(),
        })?;
        doc.check()?;
        Ok(doc)
    }

    /// The report's view of an in-memory analysis result.
    pub fn from_envelope(env: &fogline_envelope::Envelope) -> Result<Self> {
        let value = serde_json::to_value(env).map_err(|source| ReportError::Schema {
            what: "envelope".into(),
            path: ".".into(),
            source,
        })?;
        let doc: Self =
            serde_path_to_error::deserialize(value).map_err(|e| ReportError::Schema {
                what: "envelope".into(),
                path: e.path().to_string(),
                source: e.into_inner(),
            })?;
        doc.check()?;
        Ok(doc)
    }

    /// Schema version and the invariants the drawing relies on (finite numbers, matrix shapes).
    pub fn check(&self) -> Result<()> {
        if self.schema_version != SCHEMA_VERSION {
            return Err(ReportError::SchemaVersion {
                found: self.schema_version,
                expected: SCHEMA_VERSION,
            });
        }
        let bad = |what: String, reason: &str| {
            Err(ReportError::Invalid {
                what,
                reason: reason.to_string(),
            })
        };
        let j = &self.joint;
        if j.counts.len() != j.scenarios.len() || j.counts.iter().any(|r| r.len() != j.bands.len())
        {
            return bad(
                "joint.counts".into(),
                "shape differs from scenarios × bands",
            );
        }
        let t = &self.transitions;
        if t.counts.len() != t.labels.len() || t.counts.iter().any(|r| r.len() != t.labels.len()) {
            return bad(
                "transitions.counts".into(),
                "shape differs from labels × labels",
            );
        }
        for a in &self.axes {
            if a.levels.iter().any(|l| !l.is_finite()) {
                return bad(format!("axes[{}].levels", a.axis), "not finite");
            }
        }
        Ok(())
    }

    /// A parameter as a number.
    pub fn param_f64(&self, key: &str) -> Option<f64> {
        self.parameters.get(key).and_then(serde_json::Value::as_f64)
    }

    /// A parameter as text (strings as they are, other values as JSON).
    pub fn param_text(&self, key: &str) -> Option<String> {
        self.parameters.get(key).map(|v| match v {
            serde_json::Value::String(s) => s.clone(),
            other => other.to_string(),
        })
    }

    /// The headline budget (0.15 when the parameters do not say).
    pub fn headline_budget(&self) -> f64 {
        self.param_f64("headline_budget").unwrap_or(0.15)
    }

    /// The axis of the ODD entry (the first ODD row's, else the `odd_family` parameter's,
    /// else the first axis).
    pub fn odd_axis(&self) -> Option<String> {
        if let Some(o) = self.odd.first() {
            return Some(o.axis.clone());
        }
        let fam = self.param_text("odd_family");
        self.axes
            .iter()
            .find(|a| Some(&a.axis) == fam.as_ref())
            .or(self.axes.first())
            .map(|a| a.axis.clone())
    }

    /// The threshold of a group on an axis at a budget.
    pub fn threshold(&self, group: &str, axis: &str, budget: f64) -> Option<&ThresholdDoc> {
        self.thresholds
            .iter()
            .find(|t| t.scenario == group && t.axis == axis && t.budget == budget)
    }
}
