//! The closed-loop section's input: leaderboard-style scores per configuration.
//!
//! The closed-loop simulator (`fogline-sim`) is not built yet. This is the report's side of
//! the contract: one row per configuration (a baseline agent, the RCO controller with some
//! modules, a step limit, …), with the CARLA leaderboard 1.0 metrics. Anything that produces
//! these rows can fill the section; `fogline report --sim DIR` reads them from
//! `DIR/closed_loop.json` (see `docs/report.md`).

use serde::{Deserialize, Serialize};

use crate::error::{ReportError, Result};

/// Closed-loop results to show.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClosedLoop {
    /// What produced the rows (tool and version, suite name), shown under the section title.
    pub source: String,
    /// One row per configuration, in the order to show.
    pub configurations: Vec<ClosedLoopRow>,
    /// Remarks to show under the figure.
    #[serde(default)]
    pub notes: Vec<String>,
}

/// Leaderboard-style scores of one configuration, averaged over its routes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClosedLoopRow {
    /// Configuration name (e.g. `baseline`, `rco hi+st+ve+sc`).
    pub configuration: String,
    /// Routes driven.
    pub n_routes: usize,
    /// Mean driving score, 0–100 (route completion × infraction score, per route).
    pub driving_score: f64,
    /// Mean route completion, 0–100 (%).
    pub route_completion: f64,
    /// Mean infraction score (penalty product), 0–1.
    pub infraction_score: f64,
}

impl ClosedLoop {
    /// Parses `closed_loop.json`; `what` names the document in errors.
    pub fn from_json(text: &str, what: &str) -> Result<Self> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let cl: Self = serde_path_to_error::deserialize(de).map_err(|e| ReportError::Schema {
            what: what.to_string(),
            path: e.path().to_string(),
            source: e.into_inner(),
        })?;
        cl.check()?;
        Ok(cl)
    }

    /// Every score is finite and in its range.
    pub fn check(&self) -> Result<()> {
        for (i, r) in self.configurations.iter().enumerate() {
            let bad = |field: &str, range: &str| {
                Err(ReportError::Invalid {
                    what: format!("configurations[{i}].{field}"),
                    reason: format!("expected a number in {range}"),
                })
            };
            if !(r.driving_score.is_finite() && (0.0..=100.0).contains(&r.driving_score)) {
                return bad("driving_score", "[0, 100]");
            }
            if !(r.route_completion.is_finite() && (0.0..=100.0).contains(&r.route_completion)) {
                return bad("route_completion", "[0, 100]");
            }
            if !(r.infraction_score.is_finite() && (0.0..=1.0).contains(&r.infraction_score)) {
                return bad("infraction_score", "[0, 1]");
            }
        }
        Ok(())
    }
}
