//! What every section needs: the input plus a few derived lookups.

use fogline_envelope::Envelope;
use fogline_envelope::model::{DosePoint, OddEntry, Threshold};

use crate::ReportParams;
use crate::closed_loop::ClosedLoop;

/// Name of the all-clips aggregate group in `envelope.json`.
pub(crate) const AGG_ALL: &str = fogline_envelope::model::AGG_ALL;
/// Name of the classified-clips aggregate group.
pub(crate) const AGG_CLASSIFIED: &str = fogline_envelope::model::AGG_CLASSIFIED;

/// The rendering context.
pub(crate) struct Ctx<'a> {
    pub(crate) env: &'a Envelope,
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
        env: &'a Envelope,
        changed_l2_m: Option<&'a [f64]>,
        closed_loop: Option<&'a ClosedLoop>,
        params: &'a ReportParams,
    ) -> Self {
        let mut scenarios: Vec<String> = Vec::new();
        for t in &env.corpus.taxonomy {
            if env
                .corpus
                .scenarios
                .iter()
                .any(|s| &s.scenario == t && s.classified)
            {
                scenarios.push(t.clone());
            }
        }
        for s in &env.corpus.scenarios {
            if s.classified && !scenarios.contains(&s.scenario) {
                scenarios.push(s.scenario.clone());
            }
        }
        Self {
            env,
            changed_l2_m,
            closed_loop,
            params,
            hb: env.parameters.headline_budget,
            axis: odd_axis(env),
            scenarios,
        }
    }

    /// The threshold of a group on an axis at a budget.
    pub(crate) fn threshold(&self, group: &str, axis: &str, budget: f64) -> Option<&'a Threshold> {
        self.env
            .thresholds
            .iter()
            .find(|t| t.scenario == group && t.axis == axis && t.budget == budget)
    }

    /// The headline threshold of a group on the ODD axis.
    pub(crate) fn headline(&self, group: &str) -> Option<&'a Threshold> {
        let axis = self.axis.as_deref()?;
        self.threshold(group, axis, self.hb)
    }

    /// The ODD entry of a scenario.
    pub(crate) fn odd(&self, scenario: &str) -> Option<&'a OddEntry> {
        self.env.odd.iter().find(|o| o.scenario == scenario)
    }

    /// Dose-response points of a group on an axis, in level order of the axis.
    pub(crate) fn dose(&self, group: &str, axis: &str) -> Vec<&'a DosePoint> {
        let levels: Vec<f64> = self
            .env
            .axes
            .iter()
            .find(|a| a.axis == axis)
            .map(|a| a.levels.clone())
            .unwrap_or_default();
        let mut pts: Vec<&DosePoint> = self
            .env
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
        self.env
            .corpus
            .scenarios
            .iter()
            .any(|s| s.scenario == scenario && s.pilot)
    }

    /// Clips of a group (thresholds carry them for aggregates too).
    pub(crate) fn n_clips(&self, group: &str) -> Option<usize> {
        self.env
            .corpus
            .scenarios
            .iter()
            .find(|s| s.scenario == group)
            .map(|s| s.n_clips)
            .or_else(|| self.headline(group).map(|t| t.n_clips))
    }

    /// Whether a dose point passes the headline budget.
    pub(crate) fn passes(&self, d: &DosePoint) -> bool {
        let key = format!("{}", self.hb);
        d.within_budget
            .get(&key)
            .copied()
            .unwrap_or(d.mean_ade_attacked_m < (1.0 + self.hb) * d.mean_ade_clean_m)
    }

    /// The corpus-wide high-severity share (all changed pairs).
    pub(crate) fn p_high_all(&self) -> Option<f64> {
        self.env
            .high_severity
            .by_scenario
            .iter()
            .find(|r| r.group == AGG_ALL)
            .and_then(|r| r.share)
    }

    /// The `severe_factor` parameter.
    pub(crate) fn severe_factor(&self) -> f64 {
        self.env.parameters.severe_factor
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
        if self.env.high_severity.bands.is_empty() {
            "high".into()
        } else {
            self.env.high_severity.bands.join("/")
        }
    }
}

/// The axis of the ODD entry: the first ODD row's, else the `odd_family` parameter's, else
/// the first axis.
fn odd_axis(env: &Envelope) -> Option<String> {
    if let Some(o) = env.odd.first() {
        return Some(o.axis.clone());
    }
    let fam = &env.parameters.odd_family;
    env.axes
        .iter()
        .find(|a| &a.axis == fam)
        .or(env.axes.first())
        .map(|a| a.axis.clone())
}
