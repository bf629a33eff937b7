//! What every section needs: the input plus a few derived lookups.

use crate::ReportParams;
use crate::closed_loop::ClosedLoop;
use crate::doc::{DosePointDoc, EnvelopeDoc, OddDoc, ThresholdDoc};

/// Name of the all-clips aggregate group in `envelope.json`.
pub(crate) const AGG_ALL: &str = fogline_envelope::model::AGG_ALL;
/// Name of the classified-clips aggregate group.
pub(crate) const AGG_CLASSIFIED: &str = fogline_envelope::model::AGG_CLASSIFIED;

/// The rendering context.
pub(crate) struct Ctx<'a> {
    pub(crate) doc: &'a EnvelopeDoc,
    pub(crate) changed_l2_m: Option<&'a [f64]>,
    pub(crate) closed_loop: Option<&'a ClosedLoop>,
    pub(crate) params: &'a ReportParams,
    /// Headline budget.
    pub(crate) hb: f64,
    /// Axis of the ODD entry.
    pub(crate) axis: Option<String>,
    /// Classified scenarios present in the corpus, in taxonomy (rank) order.
    pub(crate) scenarios: Vec<String>,
}

impl<'a> Ctx<'a> {
    pub(crate) fn new(
        doc: &'a EnvelopeDoc,
        changed_l2_m: Option<&'a [f64]>,
        closed_loop: Option<&'a ClosedLoop>,
        params: &'a ReportParams,
    ) -> Self {
        let mut scenarios: Vec<String> = Vec::new();
        for t in &doc.corpus.taxonomy {
            if doc
                .corpus
                .scenarios
                .iter()
                .any(|s| &s.scenario == t && s.classified)
            {
                scenarios.push(t.clone());
            }
        }
        for s in &doc.corpus.scenarios {
            if s.classified && !scenarios.contains(&s.scenario) {
                scenarios.push(s.scenario.clone());
            }
        }
        Self {
            doc,
            changed_l2_m,
            closed_loop,
            params,
            hb: doc.headline_budget(),
            axis: doc.odd_axis(),
            scenarios,
        }
    }

    /// The headline threshold of a group on the ODD axis.
    pub(crate) fn headline(&self, group: &str) -> Option<&'a ThresholdDoc> {
        let axis = self.axis.as_deref()?;
        self.doc.threshold(group, axis, self.hb)
    }

    /// The ODD entry of a scenario.
    pub(crate) fn odd(&self, scenario: &str) -> Option<&'a OddDoc> {
        self.doc.odd.iter().find(|o| o.scenario == scenario)
    }

    /// Dose-response points of a group on an axis, in level order of the axis.
    pub(crate) fn dose(&self, group: &str, axis: &str) -> Vec<&'a DosePointDoc> {
        let levels: Vec<f64> = self
            .doc
            .axes
            .iter()
            .find(|a| a.axis == axis)
            .map(|a| a.levels.clone())
            .unwrap_or_default();
        let mut pts: Vec<&DosePointDoc> = self
            .doc
            .dose_response
            .iter()
            .filter(|d| {
                d.scenario == group
                    && d.axis == axis
                    && d.delta_ade_m.is_finite()
                    && d.mean_ade_clean_m.is_finite()
            })
            .collect();
        pts.sort_by_key(|d| {
            levels
                .iter()
                .position(|l| *l == d.level)
                .unwrap_or(usize::MAX)
        });
        pts
    }

    /// Whether the scenario is a pilot.
    pub(crate) fn pilot(&self, scenario: &str) -> bool {
        self.doc
            .corpus
            .scenarios
            .iter()
            .any(|s| s.scenario == scenario && s.pilot)
    }

    /// Clips of a group (thresholds carry them for aggregates too).
    pub(crate) fn n_clips(&self, group: &str) -> Option<usize> {
        self.doc
            .corpus
            .scenarios
            .iter()
            .find(|s| s.scenario == group)
            .map(|s| s.n_clips)
            .or_else(|| self.headline(group).map(|t| t.n_clips))
    }

    /// Whether a dose point passes the headline budget.
    pub(crate) fn passes(&self, d: &DosePointDoc) -> bool {
        let key = format!("{}", self.hb);
        d.within_budget
            .get(&key)
            .copied()
            .unwrap_or(d.mean_ade_attacked_m < (1.0 + self.hb) * d.mean_ade_clean_m)
    }

    /// The corpus-wide high-severity share (all changed pairs).
    pub(crate) fn p_high_all(&self) -> Option<f64> {
        self.doc
            .high_severity
            .by_scenario
            .iter()
            .find(|r| r.group == AGG_ALL)
            .and_then(|r| r.share)
    }

    /// The `severe_factor` parameter.
    pub(crate) fn severe_factor(&self) -> f64 {
        self.doc.param_f64("severe_factor").unwrap_or(1.5)
    }

    /// Display name of a group.
    pub(crate) fn group_name(group: &str) -> String {
        match group {
            AGG_ALL => "all clips (aggregate)".into(),
            AGG_CLASSIFIED => "classified clips (aggregate)".into(),
            g => g.to_string(),
        }
    }

    /// The high-band names joined (`C4/C5`), or `high`.
    pub(crate) fn high_name(&self) -> String {
        if self.doc.high_severity.bands.is_empty() {
            "high".into()
        } else {
            self.doc.high_severity.bands.join("/")
        }
    }
}
