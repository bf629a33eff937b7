//! The closed-loop section's input: leaderboard-style scores per configuration.
//!
//! The closed-loop simulator (`fogline-sim`) writes `closed_loop.json` and defines its type
//! (`fogline_sim::output::ClosedLoop`): one row per configuration (no deficit, each deficit
//! with and without the RCO override, …) with the CARLA leaderboard 1.0 metrics. Anything
//! that produces these rows can fill the section; `fogline report --sim DIR` reads them from
//! `DIR/closed_loop.json` (see `docs/report.md`). This module parses and checks it.

use crate::error::{ReportError, Result};

pub use fogline_sim::output::{ClosedLoop, ClosedLoopRow};

/// Parses `closed_loop.json` (its one typed definition is `fogline_sim::output::ClosedLoop`)
/// and checks it ([`check_closed_loop`]); `what` names the document in errors, which name
/// the field at fault.
pub fn closed_loop_from_json(text: &str, what: &str) -> Result<ClosedLoop> {
    let de = &mut serde_json::Deserializer::from_str(text);
    let cl: ClosedLoop = serde_path_to_error::deserialize(de).map_err(|e| ReportError::Schema {
        what: what.to_string(),
        path: e.path().to_string(),
        source: e.into_inner(),
    })?;
    check_closed_loop(&cl)?;
    Ok(cl)
}

/// Every score is finite and in its range.
pub fn check_closed_loop(cl: &ClosedLoop) -> Result<()> {
    for (i, r) in cl.configurations.iter().enumerate() {
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
