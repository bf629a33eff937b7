//! `odd.json`: the operational design domain an envelope analysis found, as a runtime
//! monitor loads it.
//!
//! One typed, versioned definition for the file's writer (`fogline envelope`, through
//! `fogline_envelope::odd_spec`) and its readers (the runtime monitor, the Python package,
//! your own tools): [`OddSpec::to_json`] writes it and [`OddSpec::from_json`] reads it back,
//! checking its kind, its schema version and its numbers.
//!
//! Each entry holds the headline threshold (the analysis's ODD family, `axis` /
//! `sigma_star`) and, in [`OddEntry::thresholds`], the threshold of every perturbation family
//! the pairs table tested (`gaussian_noise`, `darken`, `brighten`, `fog`, …), so a runtime
//! monitor has an envelope for each condition it estimates. Files written before that field
//! existed read as entries with an empty list; [`OddEntry::axis_thresholds`] then gives the
//! headline threshold alone.
//!
//! ```
//! use fogline_types::odd::{OddEntry, OddSpec};
//!
//! let spec = OddSpec::new("fogline 0.1.0", "ab12", Some("gaussian_noise".into()), 0.15, "first-violation");
//! let text = spec.to_json();
//! assert_eq!(OddSpec::from_json(&text)?, spec);
//! assert!(OddSpec::from_json("{\"kind\": \"something.else\"}").is_err());
//! # Ok::<(), fogline_types::odd::OddError>(())
//! ```

use serde::{Deserialize, Serialize};

/// The `kind` of an `odd.json` file.
pub const KIND: &str = "fogline.odd";

/// The schema version this crate writes and reads.
pub const SCHEMA_VERSION: u32 = 1;

/// The contents of `odd.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OddSpec {
    /// [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// [`KIND`].
    pub kind: String,
    /// The producing tool and version.
    pub generated_by: String,
    /// SHA-256 of the pairs table the analysis read.
    pub input_sha256: String,
    /// The severity axis of the thresholds (`gaussian_noise`, …).
    pub axis: Option<String>,
    /// The relative ADE budget of the thresholds.
    pub budget: f64,
    /// The threshold rule (`first-violation` or `max-passing`).
    pub rule: String,
    /// The severity bands that count as high.
    pub high_bands: Vec<String>,
    /// The residual-risk budget π*, when acceptance was asked for.
    pub pi_star: Option<f64>,
    /// The operating level σ_op, when given.
    pub sigma_op: Option<f64>,
    /// One entry per scenario (and the aggregates).
    pub entries: Vec<OddEntry>,
}

/// The two-dimensional ODD entry of one scenario (table 4 of the envelope paper): where it
/// starts to fail (σ*) and how badly once it does (P(high | changed)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OddEntry {
    /// Scenario.
    pub scenario: String,
    /// Rank in the taxonomy.
    pub rank: Option<usize>,
    /// Clips.
    pub n_clips: usize,
    /// Changed pairs.
    pub n_changed: usize,
    /// Fewer clips than the analysis's `min_clips`.
    pub pilot: bool,
    /// Axis of the threshold.
    pub axis: String,
    /// Budget of the threshold.
    pub budget: f64,
    /// σ*(s) (None = none).
    pub sigma_star: Option<f64>,
    /// Right-censored threshold.
    pub right_censored: bool,
    /// Bootstrap CI of σ*.
    pub ci95: Option<[Option<f64>; 2]>,
    /// P(high bands | changed, s).
    pub p_high: Option<f64>,
    /// `tight`, `match`, `loose`, or `undefined`.
    pub threshold_group: String,
    /// `mild`, `moderate`, `severe`, or `undefined`.
    pub severity_group: String,
    /// `<threshold_group> + <severity_group>`.
    pub quadrant: String,
    /// With π*: σ_op ≤ σ*(s) and P(high | s) ≤ π*.
    pub accepted: Option<bool>,
    /// Why (not) accepted.
    pub acceptance_reason: Option<String>,
    /// The threshold on every axis the analysis had (one per perturbation family; brightness
    /// splits into `darken` and `brighten`), at the same budget; the headline axis is among
    /// them. Empty in files written before this field existed (read them through
    /// [`OddEntry::axis_thresholds`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub thresholds: Vec<AxisThreshold>,
}

/// The threshold of one scenario on one severity axis (a perturbation family).
///
/// A level is *inside* the envelope when it is no more severe than `sigma_star`: for an
/// ascending axis (`gaussian_noise` σ, `fog` α, `brighten` gain) when level ≤ σ*, for a
/// descending one (`darken`: the gain falls as it gets worse) when level ≥ σ*. With
/// `sigma_star` none (the smallest tested level already fails) only `identity_level` is
/// known to be inside.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisThreshold {
    /// The axis (`gaussian_noise`, `darken`, `brighten`, `fog`, or a family of your own).
    pub axis: String,
    /// The perturbation family it belongs to (`brightness` for `darken` and `brighten`).
    pub family: String,
    /// True when severity grows as the level falls (`darken`).
    pub descending: bool,
    /// The level at which the family leaves a frame unchanged (σ 0, gain 1, α 0).
    pub identity_level: f64,
    /// The levels the analysis tested, least severe first.
    pub levels: Vec<f64>,
    /// σ*(s) on this axis (None = none: the least severe level fails).
    pub sigma_star: Option<f64>,
    /// Right-censored threshold (no tested level fails).
    pub right_censored: bool,
    /// Bootstrap CI of σ* (a null bound means none).
    pub ci95: Option<[Option<f64>; 2]>,
    /// `tight`, `match`, `loose`, or `undefined` (against the all-clips aggregate).
    pub threshold_group: String,
}

impl AxisThreshold {
    /// The last level known to be inside the envelope: σ*, or the identity level when σ*
    /// is none.
    pub fn limit(&self) -> f64 {
        self.sigma_star.unwrap_or(self.identity_level)
    }

    /// Whether `level` is inside the envelope on this axis (no more severe than
    /// [`AxisThreshold::limit`]).
    ///
    /// ```
    /// use fogline_types::odd::AxisThreshold;
    /// let darken = AxisThreshold {
    ///     axis: "darken".into(), family: "brightness".into(), descending: true,
    ///     identity_level: 1.0, levels: vec![0.7, 0.4], sigma_star: Some(0.7),
    ///     right_censored: false, ci95: None, threshold_group: "match".into(),
    /// };
    /// assert!(darken.inside(0.8) && darken.inside(0.7) && !darken.inside(0.5));
    /// ```
    pub fn inside(&self, level: f64) -> bool {
        if self.descending {
            level >= self.limit()
        } else {
            level <= self.limit()
        }
    }
}

impl OddEntry {
    /// The thresholds of every axis: [`OddEntry::thresholds`], or for a file written before
    /// that field existed, the headline threshold alone (`axis`, `sigma_star`; its direction
    /// and identity level from the axis name: `darken` descends from 1, `brighten` ascends
    /// from 1, any other axis ascends from 0).
    pub fn axis_thresholds(&self) -> Vec<AxisThreshold> {
        if !self.thresholds.is_empty() {
            return self.thresholds.clone();
        }
        let (family, descending, identity_level) = match self.axis.as_str() {
            "darken" => ("brightness", true, 1.0),
            "brighten" => ("brightness", false, 1.0),
            other => (other, false, 0.0),
        };
        vec![AxisThreshold {
            axis: self.axis.clone(),
            family: family.into(),
            descending,
            identity_level,
            levels: Vec::new(),
            sigma_star: self.sigma_star,
            right_censored: self.right_censored,
            ci95: self.ci95,
            threshold_group: self.threshold_group.clone(),
        }]
    }

    /// The threshold on `axis`, if the entry has one ([`OddEntry::axis_thresholds`]).
    pub fn threshold(&self, axis: &str) -> Option<AxisThreshold> {
        self.axis_thresholds().into_iter().find(|t| t.axis == axis)
    }
}

/// Why an `odd.json` could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OddError(pub String);

impl std::fmt::Display for OddError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for OddError {}

impl OddSpec {
    /// An empty specification (no entries) of the current schema.
    pub fn new(
        generated_by: &str,
        input_sha256: &str,
        axis: Option<String>,
        budget: f64,
        rule: &str,
    ) -> Self {
        Self {
            schema_version: SCHEMA_VERSION,
            kind: KIND.into(),
            generated_by: generated_by.into(),
            input_sha256: input_sha256.into(),
            axis,
            budget,
            rule: rule.into(),
            high_bands: Vec::new(),
            pi_star: None,
            sigma_op: None,
            entries: Vec::new(),
        }
    }

    /// The file's text (pretty JSON, as `fogline envelope` writes it).
    pub fn to_json(&self) -> String {
        // Serialising plain data to a string cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Reads an `odd.json` text: checks `kind` and `schema_version` first (so a wrong file
    /// says what it is), then every field (named in the error), then that the numbers are
    /// in range (budget > 0, probabilities in [0, 1], thresholds ≥ 0).
    pub fn from_json(text: &str) -> Result<Self, OddError> {
        #[derive(Deserialize)]
        struct Header {
            kind: Option<String>,
            schema_version: Option<u32>,
        }
        let head: Header = serde_json::from_str(text)
            .map_err(|e| OddError(format!("not an odd.json file: {e}")))?;
        match head.kind.as_deref() {
            Some(KIND) => {}
            Some(other) => {
                return Err(OddError(format!(
                    "kind is {other:?}, expected {KIND:?}: not an odd.json file"
                )));
            }
            None => return Err(OddError(format!("no kind field: not a {KIND} file"))),
        }
        match head.schema_version {
            Some(SCHEMA_VERSION) => {}
            Some(v) => {
                return Err(OddError(format!(
                    "schema_version {v} is not supported (this build reads {SCHEMA_VERSION}): \
                     regenerate the file with this build's fogline envelope"
                )));
            }
            None => return Err(OddError("no schema_version field".into())),
        }
        let spec: OddSpec =
            serde_json::from_str(text).map_err(|e| OddError(format!("odd.json: {e}")))?;
        spec.check()?;
        Ok(spec)
    }

    /// Reads `odd.json` from `path` ([`OddSpec::from_json`]); errors name the file.
    pub fn read(path: &std::path::Path) -> Result<Self, OddError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| OddError(format!("cannot read {}: {e}", path.display())))?;
        Self::from_json(&text).map_err(|e| OddError(format!("{}: {e}", path.display())))
    }

    /// The entry of `scenario`, if any.
    pub fn entry(&self, scenario: &str) -> Option<&OddEntry> {
        self.entries.iter().find(|e| e.scenario == scenario)
    }

    fn check(&self) -> Result<(), OddError> {
        let prob = |v: Option<f64>| v.is_none_or(|p| (0.0..=1.0).contains(&p));
        if !(self.budget.is_finite() && self.budget > 0.0) {
            return Err(OddError(format!(
                "budget {} must be a positive number",
                self.budget
            )));
        }
        if !prob(self.pi_star) {
            return Err(OddError("pi_star must be in [0, 1]".into()));
        }
        if self.sigma_op.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
            return Err(OddError("sigma_op must be a non-negative number".into()));
        }
        for (i, e) in self.entries.iter().enumerate() {
            let at = |what: &str| OddError(format!("entries[{i}] ({}): {what}", e.scenario));
            if e.sigma_star.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
                return Err(at("sigma_star must be a non-negative number"));
            }
            if !prob(e.p_high) {
                return Err(at("p_high must be in [0, 1]"));
            }
            if !(e.budget.is_finite() && e.budget > 0.0) {
                return Err(at("budget must be a positive number"));
            }
            for (j, t) in e.thresholds.iter().enumerate() {
                let at = |what: &str| at(&format!("thresholds[{j}] ({}): {what}", t.axis));
                if t.axis.is_empty() {
                    return Err(at("axis must not be empty"));
                }
                if e.thresholds[..j].iter().any(|u| u.axis == t.axis) {
                    return Err(at("axis is listed twice"));
                }
                if !(t.identity_level.is_finite() && t.identity_level >= 0.0) {
                    return Err(at("identity_level must be a non-negative number"));
                }
                if !t.levels.iter().all(|l| l.is_finite() && *l >= 0.0) {
                    return Err(at("levels must be non-negative numbers"));
                }
                if t.sigma_star.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
                    return Err(at("sigma_star must be a non-negative number"));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn entry(scenario: &str, sigma: Option<f64>, p_high: Option<f64>) -> OddEntry {
        OddEntry {
            scenario: scenario.into(),
            rank: Some(1),
            n_clips: 40,
            n_changed: 9,
            pilot: false,
            axis: "gaussian_noise".into(),
            budget: 0.15,
            sigma_star: sigma,
            right_censored: false,
            ci95: Some([Some(10.0), None]),
            p_high,
            threshold_group: "tight".into(),
            severity_group: "severe".into(),
            quadrant: "tight + severe".into(),
            accepted: None,
            acceptance_reason: None,
            thresholds: Vec::new(),
        }
    }

    fn axis(axis: &str, descending: bool, identity: f64, sigma: Option<f64>) -> AxisThreshold {
        AxisThreshold {
            axis: axis.into(),
            family: if axis.ends_with("en") {
                "brightness".into()
            } else {
                axis.into()
            },
            descending,
            identity_level: identity,
            levels: vec![0.3, 0.7],
            sigma_star: sigma,
            right_censored: false,
            ci95: None,
            threshold_group: "match".into(),
        }
    }

    /// `odd.json` with a threshold per axis round-trips; a file without them (written
    /// before they existed) still reads, its headline threshold standing alone; a bad axis
    /// entry is named.
    #[test]
    fn r20_per_axis_thresholds_round_trip_and_old_files_read() {
        let mut spec = OddSpec::new("fogline 0.1.0", "ab", None, 0.15, "first-violation");
        let mut e = entry("LANE_KEEPING", Some(30.0), Some(0.2));
        e.thresholds = vec![
            axis("gaussian_noise", false, 0.0, Some(30.0)),
            axis("darken", true, 1.0, Some(0.4)),
            axis("brighten", false, 1.0, None),
            axis("fog", false, 0.0, Some(0.3)),
        ];
        spec.entries = vec![e, entry("TURN_LEFT", Some(10.0), None)];
        let text = spec.to_json();
        let back = OddSpec::from_json(&text).unwrap();
        assert_eq!(back, spec);
        let lk = back.entry("LANE_KEEPING").unwrap();
        assert_eq!(lk.axis_thresholds().len(), 4);
        let dark = lk.threshold("darken").unwrap();
        assert!(dark.inside(0.5) && !dark.inside(0.3));
        let bright = lk.threshold("brighten").unwrap();
        assert_eq!(bright.limit(), 1.0);
        assert!(bright.inside(1.0) && !bright.inside(1.1));
        // The entry without thresholds writes no field (as before) and reads as its
        // headline axis alone.
        let old = back.entry("TURN_LEFT").unwrap();
        let noise = old.axis_thresholds();
        assert_eq!(noise.len(), 1);
        assert_eq!(
            (noise[0].axis.as_str(), noise[0].limit()),
            ("gaussian_noise", 10.0)
        );
        assert!(old.threshold("fog").is_none());
        let file: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(file["entries"][1].get("thresholds").is_none());
        assert_eq!(file["entries"][0]["thresholds"][1]["axis"], "darken");

        let mut wrong = spec.clone();
        wrong.entries[0].thresholds[3].sigma_star = Some(-1.0);
        let msg = OddSpec::from_json(&wrong.to_json())
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("entries[0] (LANE_KEEPING): thresholds[3] (fog): sigma_star"),
            "{msg}"
        );
        let mut twice = spec.clone();
        twice.entries[0].thresholds[1].axis = "gaussian_noise".into();
        let msg = OddSpec::from_json(&twice.to_json())
            .unwrap_err()
            .to_string();
        assert!(msg.contains("listed twice"), "{msg}");
    }

    #[test]
    fn round_trips_and_rejects_what_is_not_an_odd_file() {
        let mut spec = OddSpec::new(
            "fogline 0.1.0",
            "ab",
            Some("gaussian_noise".into()),
            0.15,
            "first-violation",
        );
        spec.high_bands = vec!["B2".into(), "B3".into()];
        spec.entries = vec![
            entry("LANE_KEEPING", Some(30.0), Some(0.2)),
            entry("TURN_LEFT", None, None),
        ];
        let back = OddSpec::from_json(&spec.to_json()).unwrap();
        assert_eq!(back, spec);
        assert_eq!(back.entry("TURN_LEFT").unwrap().sigma_star, None);

        let bad = |text: &str| OddSpec::from_json(text).unwrap_err().to_string();
        assert!(bad("[1, 2").contains("not an odd.json file"));
        assert!(bad(r#"{"kind": "fogline.envelope"}"#).contains("expected \"fogline.odd\""));
        assert!(
            bad(r#"{"kind": "fogline.odd", "schema_version": 9}"#)
                .contains("schema_version 9 is not supported")
        );
        let text = spec.to_json().replace(
            "\"budget\": 0.15,\n  \"rule\"",
            "\"budget\": -1.0,\n  \"rule\"",
        );
        assert!(bad(&text).contains("budget -1 must be"), "{}", bad(&text));
        let mut wrong = spec.clone();
        wrong.entries[0].p_high = Some(1.5);
        assert!(bad(&wrong.to_json()).contains("entries[0] (LANE_KEEPING): p_high"));
        let text = spec
            .to_json()
            .replace("\"n_clips\": 40", "\"n_clips\": \"many\"");
        assert!(bad(&text).contains("invalid type"), "{}", bad(&text));
    }
}
