//! The runtime ODD monitor: per-frame condition estimates, smoothed over time, against the
//! envelope's `odd.json` entry of the scenario → in or out of the envelope, with the
//! entry's severity quadrant, hysteresis and a minimum dwell.
//!
//! The policy, step by step (every number is a field of [`MonitorParams`]):
//!
//! 1. **Estimates.** Each step reads one frame's estimates ([`Observation`]: noise σ, gain
//!    and fog opacity with their standard errors; [`Monitor::step_frame`] measures them from
//!    the pixels with [`estimate_frame`] and also follows the stream's
//!    temporal faults).
//! 2. **Smoothing.** Per axis an exponentially weighted moving average (EWMA) with weight
//!    `ewma_alpha` on the newest frame: `m ← (1 − a)·m + a·x`, and of the squared standard
//!    error, `u² ← (1 − a)·u² + a·se²`. The smoothed uncertainty `u` is *not* shrunk by the
//!    averaging (frames of one scene share their scene-driven error), so it stays
//!    conservative. The first frame starts both at its own values.
//! 3. **Conservative bound.** `b = m + z·u` on an ascending axis (`gaussian_noise` σ, `fog`
//!    α, `brighten` gain), `b = m − z·u` on `darken` (severity grows as the gain falls). The
//!    uncertainty `u` is the *calibrated* one where the camera's null profile
//!    ([`NullProfile`]) measured it: on `fog` its standard deviation on clean frames, on
//!    `darken` / `brighten` its relative one times `m` (the gain's errors are relative); on
//!    `gaussian_noise` the smoothed model error (it grows with σ; its null spread is used
//!    when larger). The model-based errors of gain and fog describe the reference profile,
//!    not this camera: measured on fogline's front-wide camera they understate the gain's
//!    error (0.09 vs 0.15) and overstate the fog's (0.09 vs 0.06).
//! 4. **Threshold.** The entry's threshold on the axis ([`AxisThreshold::limit`]): σ*. A
//!    right-censored σ* (no tested level failed) is used as it is: beyond the largest tested
//!    level nothing is known. When σ* is none (the least severe tested level already fails,
//!    so only the unperturbed camera is known to be inside) the axis is decided by a **test
//!    against nominal** instead: no estimator reads exactly the identity level on a clean
//!    frame, so asking the bound to reach it would leave the envelope on every frame. The
//!    smoothed estimate `m` itself is compared with the null profile's quantile at the
//!    false-alarm rate (`upper`, the 99th percentile of clean frames by default; `lower`, the
//!    1st, on `darken`): out when the camera reads significantly more degraded than its clean
//!    frames do, at a false-alarm rate of 1 % per axis. The record's `test` says which rule
//!    an axis used (`limit` or `nominal`) and its `limit` is then the quantile.
//! 5. **Decision with hysteresis.** The first step decides directly: out when the bound of
//!    any watched axis is beyond its limit. Afterwards the monitor *leaves* the envelope when
//!    some axis's bound is beyond `limit + margin` (`limit − margin` on `darken`) and
//!    *re-enters* when every axis's bound is back within `limit − margin` (never past the
//!    identity level, which any estimate reaches).
//! 6. **Minimum dwell.** A state, once entered, lasts at least `min_dwell_steps` steps; a
//!    switch the estimates ask for earlier is held (`held` in the record). A camera fault
//!    (a black or frozen frame, from [`Monitor::step_frame`]) leaves the envelope at once,
//!    dwell or not, and its frame does not enter the averages.
//!
//! Every step returns one [`MonitorRecord`], the JSON-lines log's row (`fogline monitor
//! run` prints it, the Python package returns it as a dict).
//!
//! ```
//! use fogline_monitor::{Monitor, MonitorParams, Observation};
//! use fogline_types::odd::{AxisThreshold, OddEntry, OddSpec};
//!
//! // An odd.json with one scenario whose noise threshold is σ* = 30.
//! let mut odd = OddSpec::new("doc", "00", Some("gaussian_noise".into()), 0.15, "first-violation");
//! odd.entries.push(OddEntry {
//!     scenario: "LANE_KEEPING".into(), rank: Some(1), n_clips: 40, n_changed: 9,
//!     pilot: false, axis: "gaussian_noise".into(), budget: 0.15, sigma_star: Some(30.0),
//!     right_censored: false, ci95: None, p_high: Some(0.2), threshold_group: "match".into(),
//!     severity_group: "mild".into(), quadrant: "match + mild".into(), accepted: None,
//!     acceptance_reason: None, thresholds: Vec::new(),
//! });
//! let params = MonitorParams { min_dwell_steps: 2, ..MonitorParams::default() };
//! let mut m = Monitor::new(&odd, "LANE_KEEPING", params)?;
//! let at = |sigma: f64| Observation { noise_sigma: sigma, noise_sigma_se: 0.3, ..Observation::clean() };
//! assert!(m.step(&at(20.0))?.in_envelope);
//! // One frame at σ 45 moves the average to 27.5: still inside.
//! assert!(m.step(&at(45.0))?.in_envelope);
//! let r = m.step(&at(45.0))?; // 32.75 + z·0.3 > 30 + 2: out
//! assert!(!r.in_envelope && r.switched);
//! assert_eq!(r.quadrant, "match + mild");
//! # Ok::<(), fogline_monitor::MonitorError>(())
//! ```

use serde::{Deserialize, Serialize};

use fogline_types::odd::{AxisThreshold, OddEntry, OddSpec};

use crate::{
    ConditionParams, FrameEstimate, MonitorError, TemporalMonitor, TemporalParams, estimate_frame,
};

/// The axes whose condition the monitor can estimate, in the order it reports them.
pub const ESTIMATED_AXES: [&str; 4] = ["gaussian_noise", "darken", "brighten", "fog"];

/// Parameters of [`Monitor`] (see the module documentation for the policy).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MonitorParams {
    /// Weight of the newest frame in the moving averages, in (0, 1] (1: no smoothing).
    pub ewma_alpha: f64,
    /// One-sided normal quantile of the conservative bound (1.645: 95 %; 0: the smoothed
    /// estimate itself).
    pub z: f64,
    /// Steps a state lasts at least once entered (≥ 1; 1: no dwell).
    pub min_dwell_steps: usize,
    /// Hysteresis half-width on the `gaussian_noise` axis, σ levels (0–255 scale).
    pub noise_margin: f64,
    /// Hysteresis half-width on the `darken` and `brighten` axes, gain.
    pub gain_margin: f64,
    /// Hysteresis half-width on the `fog` axis, opacity α.
    pub fog_margin: f64,
    /// The axes watched (of [`ESTIMATED_AXES`]); an axis the scenario's entry has no
    /// threshold for is not watched.
    pub axes: Vec<String>,
    /// Leave the envelope on a black or frozen frame ([`Monitor::step_frame`]).
    pub faults_enabled: bool,
    /// The reference profile of the gain and fog estimates ([`Monitor::step_frame`]).
    pub condition: ConditionParams,
    /// The temporal-fault detector ([`Monitor::step_frame`]).
    pub temporal: TemporalParams,
    /// The estimators' null distribution on clean frames of the camera (the calibrated
    /// uncertainty and the test against nominal); default: fogline's front-wide camera.
    pub null: NullProfile,
}

impl Default for MonitorParams {
    fn default() -> Self {
        Self {
            ewma_alpha: 0.3,
            z: 1.645,
            min_dwell_steps: 10,
            noise_margin: 2.0,
            gain_margin: 0.05,
            fog_margin: 0.05,
            axes: ESTIMATED_AXES.iter().map(|a| a.to_string()).collect(),
            faults_enabled: true,
            condition: ConditionParams::default(),
            temporal: TemporalParams::default(),
            null: NullProfile::default(),
        }
    }
}

impl MonitorParams {
    /// Checks the ranges (and those of the condition and temporal parameters).
    pub fn validate(&self) -> Result<(), MonitorError> {
        let bad =
            |what: &'static str, expected: &'static str| MonitorError::Params { what, expected };
        if !(self.ewma_alpha.is_finite() && self.ewma_alpha > 0.0 && self.ewma_alpha <= 1.0) {
            return Err(bad("ewma_alpha", "a weight in (0, 1]"));
        }
        if !(self.z.is_finite() && (0.0..=10.0).contains(&self.z)) {
            return Err(bad("z", "a quantile in [0, 10]"));
        }
        if self.min_dwell_steps == 0 {
            return Err(bad("min_dwell_steps", "at least 1 step"));
        }
        for (m, what) in [
            (self.noise_margin, "noise_margin"),
            (self.gain_margin, "gain_margin"),
            (self.fog_margin, "fog_margin"),
        ] {
            if !(m.is_finite() && m >= 0.0) {
                return Err(bad(what, "a non-negative number"));
            }
        }
        if self.axes.is_empty()
            || !self
                .axes
                .iter()
                .all(|a| ESTIMATED_AXES.contains(&a.as_str()))
        {
            return Err(bad(
                "axes",
                "one or more of gaussian_noise, darken, brighten, fog",
            ));
        }
        self.condition.validate()?;
        self.null.validate()?;
        self.temporal.validate()
    }

    fn margin(&self, axis: &str) -> f64 {
        match axis {
            "gaussian_noise" => self.noise_margin,
            "fog" => self.fog_margin,
            _ => self.gain_margin,
        }
    }
}

/// The null distribution of one estimator: what it reads on clean frames of the camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NullAxis {
    /// Median of the estimates.
    pub center: f64,
    /// Their standard deviation (sample, `n − 1`): the estimator's error spread at the
    /// identity level.
    pub sd: f64,
    /// Their quantile at the false-alarm rate (the `darken` test's limit).
    pub lower: f64,
    /// Their quantile at one minus the false-alarm rate (the limit of the ascending axes'
    /// test against nominal).
    pub upper: f64,
}

impl NullAxis {
    /// The null of `values` (at least 2) at `false_alarm`: median, sample standard deviation
    /// and the quantiles with linear interpolation (`numpy.quantile`'s default, exact).
    pub fn from_values(values: &[f64], false_alarm: f64) -> Result<Self, MonitorError> {
        if values.len() < 2 || !values.iter().all(|v| v.is_finite()) {
            return Err(MonitorError::Params {
                what: "null profile values",
                expected: "at least 2 finite estimates",
            });
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| {
            let h = (v.len() - 1) as f64 * p;
            let i = h.floor() as usize;
            let j = (i + 1).min(v.len() - 1);
            v[i] + (h - i as f64) * (v[j] - v[i])
        };
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        Ok(Self {
            center: q(0.5),
            sd,
            lower: q(false_alarm),
            upper: q(1.0 - false_alarm),
        })
    }

    fn validate(&self) -> Result<(), MonitorError> {
        let all = [self.center, self.sd, self.lower, self.upper];
        let ordered = self.lower <= self.center && self.center <= self.upper;
        if !(all.iter().all(|v| v.is_finite() && *v >= 0.0) && ordered) {
            return Err(MonitorError::Params {
                what: "null",
                expected: "finite, non-negative center, sd, lower, upper with lower ≤ center ≤ upper",
            });
        }
        Ok(())
    }
}

/// The camera's null profile: each estimator's readings on clean (unperturbed) frames of the
/// same camera, at a false-alarm rate. The monitor uses it twice (module documentation,
/// steps 3 and 4): as the calibrated uncertainty of gain and fog, and as the test against
/// nominal on an axis whose threshold is the identity level.
///
/// Measure it on your own camera's clean frames with [`NullProfile::from_clean_frames`]
/// (a few hundred frames of varied scenes: the quantiles at 1 % need them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NullProfile {
    /// The one-sided false-alarm rate of the test against nominal, per axis.
    pub false_alarm: f64,
    /// Clean frames measured.
    pub frames: usize,
    /// Noise σ̂.
    pub noise_sigma: NullAxis,
    /// Gain.
    pub gain: NullAxis,
    /// Fog opacity α̂.
    pub fog: NullAxis,
}

impl Default for NullProfile {
    /// fogline's world, front-wide camera at the campaign's 576×320: 1,600 clean frames
    /// (400 clips of world seed 99 in the paper's mix, 4 frames each; a seed the
    /// benchmarks do not use), estimated with the default [`ConditionParams`], false-alarm
    /// rate 1 %. The world's surfaces are flat-shaded, so σ̂ reads 0 on all of them.
    fn default() -> Self {
        Self {
            false_alarm: 0.01,
            frames: 1600,
            noise_sigma: NullAxis {
                center: 0.0,
                sd: 0.0,
                lower: 0.0,
                upper: 0.0,
            },
            gain: NullAxis {
                center: 0.9889,
                sd: 0.1528,
                lower: 0.5935,
                upper: 1.2121,
            },
            fog: NullAxis {
                center: 0.0233,
                sd: 0.0639,
                lower: 0.0,
                upper: 0.2194,
            },
        }
    }
}

impl NullProfile {
    /// Checks the rate and every axis.
    pub fn validate(&self) -> Result<(), MonitorError> {
        if !(self.false_alarm.is_finite() && self.false_alarm > 0.0 && self.false_alarm < 0.5) {
            return Err(MonitorError::Params {
                what: "null.false_alarm",
                expected: "a rate in (0, 0.5)",
            });
        }
        self.noise_sigma.validate()?;
        self.gain.validate()?;
        if self.gain.center <= 0.0 {
            return Err(MonitorError::Params {
                what: "null.gain.center",
                expected: "a positive gain",
            });
        }
        self.fog.validate()
    }

    /// The profile of estimates made on clean frames (at least 2).
    pub fn from_observations(obs: &[Observation], false_alarm: f64) -> Result<Self, MonitorError> {
        let axis = |f: fn(&Observation) -> f64| {
            NullAxis::from_values(&obs.iter().map(f).collect::<Vec<_>>(), false_alarm)
        };
        let p = Self {
            false_alarm,
            frames: obs.len(),
            noise_sigma: axis(|o| o.noise_sigma)?,
            gain: axis(|o| o.gain)?,
            fog: axis(|o| o.fog)?,
        };
        p.validate()?;
        Ok(p)
    }

    /// Measures the profile on clean RGB8 frames of the camera (`(rgb, width, height)`
    /// each), with the reference profile the monitor will use.
    pub fn from_clean_frames<'a>(
        frames: impl IntoIterator<Item = (&'a [u8], usize, usize)>,
        condition: &ConditionParams,
        false_alarm: f64,
    ) -> Result<Self, MonitorError> {
        let mut obs = Vec::new();
        for (rgb, w, h) in frames {
            obs.push(Observation::from(&estimate_frame(rgb, w, h, condition)?));
        }
        Self::from_observations(&obs, false_alarm)
    }

    fn on(&self, axis: &str) -> &NullAxis {
        match axis {
            "gaussian_noise" => &self.noise_sigma,
            "fog" => &self.fog,
            _ => &self.gain,
        }
    }
}

/// One frame's condition estimates, as the monitor reads them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Observation {
    /// Gaussian noise σ, 0–255 scale.
    pub noise_sigma: f64,
    /// Its standard error.
    pub noise_sigma_se: f64,
    /// Photometric gain (1 = as the reference).
    pub gain: f64,
    /// Its standard error.
    pub gain_se: f64,
    /// Fog opacity α in [0, 1].
    pub fog: f64,
    /// Its standard error.
    pub fog_se: f64,
}

impl Observation {
    /// An unperturbed frame, exactly known: σ 0, gain 1, fog 0, no uncertainty.
    pub fn clean() -> Self {
        Self {
            noise_sigma: 0.0,
            noise_sigma_se: 0.0,
            gain: 1.0,
            gain_se: 0.0,
            fog: 0.0,
            fog_se: 0.0,
        }
    }

    fn check(&self) -> Result<(), MonitorError> {
        let values = [self.noise_sigma, self.gain, self.fog];
        let ses = [self.noise_sigma_se, self.gain_se, self.fog_se];
        if !values.iter().all(|v| v.is_finite()) || !ses.iter().all(|s| s.is_finite() && *s >= 0.0)
        {
            return Err(MonitorError::Params {
                what: "observation",
                expected: "finite estimates and non-negative standard errors",
            });
        }
        Ok(())
    }

    /// The estimate and standard error the monitor reads on `axis`.
    fn on(&self, axis: &str) -> (f64, f64) {
        match axis {
            "gaussian_noise" => (self.noise_sigma, self.noise_sigma_se),
            "fog" => (self.fog, self.fog_se),
            _ => (self.gain, self.gain_se),
        }
    }
}

impl From<&FrameEstimate> for Observation {
    fn from(e: &FrameEstimate) -> Self {
        Self {
            noise_sigma: e.noise.sigma,
            noise_sigma_se: e.noise.sigma_se,
            gain: e.condition.gain,
            gain_se: e.condition.gain_se,
            fog: e.condition.fog,
            fog_se: e.condition.fog_se,
        }
    }
}

/// One axis of one step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisReading {
    /// The axis (`gaussian_noise`, `darken`, `brighten`, `fog`).
    pub axis: String,
    /// This frame's estimate (None on a faulty frame, which is not read).
    pub estimate: Option<f64>,
    /// Its standard error.
    pub se: Option<f64>,
    /// The moving average.
    pub smoothed: f64,
    /// The smoothed standard error.
    pub smoothed_se: f64,
    /// What is compared with the limit: the conservative bound (upper; lower on `darken`),
    /// or with `test` `nominal` the smoothed estimate itself.
    pub bound: f64,
    /// The limit: σ* of the axis, or with `test` `nominal` (σ* none) the null profile's
    /// quantile at the false-alarm rate.
    pub limit: f64,
    /// The rule: `limit` (the bound against σ*) or `nominal` (σ* is none: the test against
    /// the camera's clean frames).
    pub test: String,
    /// σ* as the entry gives it.
    pub sigma_star: Option<f64>,
    /// σ* is right-censored (no tested level failed).
    pub right_censored: bool,
    /// The bound is beyond the limit (no margin): this axis alone would be out.
    pub beyond: bool,
}

/// One step of the monitor: a row of the JSON-lines log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MonitorRecord {
    /// Steps before this one (0 for the first frame).
    pub step: u64,
    /// What the frame was (a file, a clip's camera frame); set by the caller.
    pub source: Option<String>,
    /// The scenario whose entry was used.
    pub scenario: String,
    /// The decision after this step.
    pub in_envelope: bool,
    /// The decision changed at this step (the first step counts as a change).
    pub switched: bool,
    /// The estimates asked for a switch that the minimum dwell held back.
    pub held: bool,
    /// Why: the axes beyond their limit, or a fault.
    pub reason: String,
    /// The entry's severity quadrant (`<tight|match|loose> + <mild|moderate|severe>`).
    pub quadrant: String,
    /// The entry's threshold group on its headline axis.
    pub threshold_group: String,
    /// The entry's severity group.
    pub severity_group: String,
    /// P(high severity | changed) of the scenario.
    pub p_high: Option<f64>,
    /// A temporal fault of this frame (`black`, `frozen`, `dropped`), with
    /// [`Monitor::step_frame`].
    pub fault: Option<String>,
    /// The watched axes.
    pub axes: Vec<AxisReading>,
}

#[derive(Debug, Clone)]
struct Watched {
    threshold: AxisThreshold,
    margin: f64,
    /// The estimator's null on this axis.
    null: NullAxis,
    /// Moving average and mean squared standard error.
    smooth: Option<(f64, f64)>,
}

impl Watched {
    /// σ* is none: the test against nominal decides the axis.
    fn nominal(&self) -> bool {
        self.threshold.sigma_star.is_none()
    }

    /// σ*, or on a nominal axis the null's quantile in the severe direction.
    fn limit(&self) -> f64 {
        match (self.nominal(), self.threshold.descending) {
            (false, _) => self.threshold.limit(),
            (true, true) => self.null.lower,
            (true, false) => self.null.upper,
        }
    }

    /// The uncertainty of the smoothed estimate `m` whose mean squared model error is `v`.
    fn uncertainty(&self, m: f64, v: f64) -> f64 {
        match self.threshold.axis.as_str() {
            "gaussian_noise" => v.sqrt().max(self.null.sd),
            "fog" => self.null.sd,
            // Gain: relative errors.
            _ => self.null.sd * m.max(0.0) / self.null.center,
        }
    }

    fn bound(&self, z: f64) -> Option<f64> {
        let (m, v) = self.smooth?;
        if self.nominal() {
            return Some(m);
        }
        let u = self.uncertainty(m, v);
        Some(if self.threshold.descending {
            m - z * u
        } else {
            m + z * u
        })
    }

    /// How far the bound is beyond `limit + extra` (in the severe direction; > 0: beyond).
    fn excess(&self, bound: f64, extra: f64) -> f64 {
        let limit = self.limit();
        if self.threshold.descending {
            (limit - extra) - bound
        } else {
            bound - (limit + extra)
        }
    }

    /// Back within `limit − margin` (never asking for more than the identity level).
    fn back_inside(&self, bound: f64) -> bool {
        let t = &self.threshold;
        if t.descending {
            bound >= (self.limit() + self.margin).min(t.identity_level)
        } else {
            bound <= (self.limit() - self.margin).max(t.identity_level)
        }
    }
}

/// The runtime ODD monitor of one camera stream (see the module documentation).
#[derive(Debug, Clone)]
pub struct Monitor {
    params: MonitorParams,
    odd: OddSpec,
    entry: OddEntry,
    watched: Vec<Watched>,
    /// Inside (`Some(true)`), outside, or no step yet.
    state: Option<bool>,
    /// Steps the current state has lasted.
    dwell: usize,
    steps: u64,
    temporal: TemporalMonitor,
}

impl Monitor {
    /// A monitor of `scenario` under the envelope `odd`.
    ///
    /// Errors: bad parameters; a scenario without an entry (the message lists the entries);
    /// an entry with no threshold on any watched axis.
    pub fn new(odd: &OddSpec, scenario: &str, params: MonitorParams) -> Result<Self, MonitorError> {
        params.validate()?;
        let temporal = TemporalMonitor::new(params.temporal.clone())?;
        let (entry, watched) = Self::watch(odd, scenario, &params, &[])?;
        Ok(Self {
            params,
            odd: odd.clone(),
            entry,
            watched,
            state: None,
            dwell: 0,
            steps: 0,
            temporal,
        })
    }

    fn watch(
        odd: &OddSpec,
        scenario: &str,
        params: &MonitorParams,
        keep: &[Watched],
    ) -> Result<(OddEntry, Vec<Watched>), MonitorError> {
        let Some(entry) = odd.entry(scenario) else {
            return Err(MonitorError::Scenario {
                scenario: scenario.to_string(),
                known: odd
                    .entries
                    .iter()
                    .map(|e| e.scenario.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        };
        let all = entry.axis_thresholds();
        let watched: Vec<Watched> = ESTIMATED_AXES
            .iter()
            .filter(|a| params.axes.iter().any(|w| w == *a))
            .filter_map(|a| all.iter().find(|t| t.axis == *a))
            .map(|t| Watched {
                threshold: t.clone(),
                margin: params.margin(&t.axis),
                null: *params.null.on(&t.axis),
                smooth: keep
                    .iter()
                    .find(|k| k.threshold.axis == t.axis)
                    .and_then(|k| k.smooth),
            })
            .collect();
        if watched.is_empty() {
            return Err(MonitorError::NoEnvelope {
                scenario: scenario.to_string(),
                axes: params.axes.join(", "),
            });
        }
        Ok((entry.clone(), watched))
    }

    /// Switches to another scenario's entry (e.g. the one the planner's decision names),
    /// keeping the averages and the current state.
    pub fn set_scenario(&mut self, scenario: &str) -> Result<(), MonitorError> {
        if scenario != self.entry.scenario {
            let (entry, watched) = Self::watch(&self.odd, scenario, &self.params, &self.watched)?;
            self.entry = entry;
            self.watched = watched;
        }
        Ok(())
    }

    /// The scenario whose entry is in use.
    pub fn scenario(&self) -> &str {
        &self.entry.scenario
    }

    /// The axes watched for the current scenario (those of `params.axes` its entry has a
    /// threshold for).
    pub fn watched_axes(&self) -> Vec<&str> {
        self.watched
            .iter()
            .map(|w| w.threshold.axis.as_str())
            .collect()
    }

    /// The decision so far (None before the first step).
    pub fn in_envelope(&self) -> Option<bool> {
        self.state
    }

    /// Forgets the stream: averages, state, dwell and the temporal detector.
    pub fn reset(&mut self) {
        for w in &mut self.watched {
            w.smooth = None;
        }
        self.state = None;
        self.dwell = 0;
        self.steps = 0;
        // The parameters were validated in `new`, so this cannot fail.
        if let Ok(t) = TemporalMonitor::new(self.params.temporal.clone()) {
            self.temporal = t;
        }
    }

    /// Reads one frame's estimates and decides.
    pub fn step(&mut self, obs: &Observation) -> Result<MonitorRecord, MonitorError> {
        obs.check()?;
        Ok(self.advance(Some(obs), None))
    }

    /// Measures one RGB8 frame ([`estimate_frame`] and the temporal
    /// detector) and decides. A black or frozen frame is a fault: not averaged, and out of
    /// the envelope at once when `faults_enabled`.
    pub fn step_frame(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
    ) -> Result<MonitorRecord, MonitorError> {
        let t = self.temporal.step(rgb, width, height)?;
        let fault = if t.black {
            Some("black")
        } else if t.frozen {
            Some("frozen")
        } else if t.dropped {
            Some("dropped")
        } else {
            None
        };
        if matches!(fault, Some("black" | "frozen")) {
            return Ok(self.advance(None, fault));
        }
        let e = estimate_frame(rgb, width, height, &self.params.condition)?;
        let obs = Observation::from(&e);
        obs.check()?;
        Ok(self.advance(Some(&obs), fault))
    }

    fn advance(&mut self, obs: Option<&Observation>, fault: Option<&str>) -> MonitorRecord {
        let (a, z) = (self.params.ewma_alpha, self.params.z);
        let mut readings = Vec::with_capacity(self.watched.len());
        for w in &mut self.watched {
            let this = obs.map(|o| o.on(&w.threshold.axis));
            if let Some((x, se)) = this {
                w.smooth = Some(match w.smooth {
                    None => (x, se * se),
                    Some((m, v)) => ((1.0 - a) * m + a * x, (1.0 - a) * v + a * se * se),
                });
            }
            let (m, v) = w.smooth.unwrap_or((w.threshold.identity_level, 0.0));
            let bound = w.bound(z).unwrap_or(m);
            readings.push(AxisReading {
                axis: w.threshold.axis.clone(),
                estimate: this.map(|t| t.0),
                se: this.map(|t| t.1),
                smoothed: m,
                smoothed_se: v.sqrt(),
                bound,
                limit: w.limit(),
                test: if w.nominal() { "nominal" } else { "limit" }.to_string(),
                sigma_star: w.threshold.sigma_star,
                right_censored: w.threshold.right_censored,
                beyond: w.excess(bound, 0.0) > 0.0,
            });
        }
        let faulted = self.params.faults_enabled && matches!(fault, Some("black" | "frozen"));
        // What the estimates ask for: Some(next state), None to stay.
        let want = match self.state {
            _ if faulted => Some(false),
            None => Some(!readings.iter().any(|r| r.beyond)),
            Some(true) => self
                .watched
                .iter()
                .zip(&readings)
                .any(|(w, r)| w.excess(r.bound, w.margin) > 0.0)
                .then_some(false),
            Some(false) => self
                .watched
                .iter()
                .zip(&readings)
                .all(|(w, r)| w.back_inside(r.bound))
                .then_some(true),
        };
        let (mut switched, mut held) = (false, false);
        if let Some(next) = want
            && self.state != Some(next)
        {
            if self.state.is_none() || faulted || self.dwell >= self.params.min_dwell_steps {
                self.state = Some(next);
                self.dwell = 0;
                switched = true;
            } else {
                held = true;
            }
        }
        self.dwell += 1;
        let inside = self.state.unwrap_or(true);
        let beyond: Vec<String> = readings
            .iter()
            .filter(|r| r.beyond)
            .map(|r| {
                let cmp = if r.axis == "darken" { "<" } else { ">" };
                format!("{} {:.3} {cmp} {:.3}", r.axis, r.bound, r.limit)
            })
            .collect();
        let reason = match (faulted, fault, beyond.is_empty()) {
            (true, Some(f), _) => format!("camera fault: {f} frame"),
            (_, _, true) => "every watched axis within its limit".to_string(),
            _ => format!("beyond the limit: {}", beyond.join(", ")),
        };
        let record = MonitorRecord {
            step: self.steps,
            source: None,
            scenario: self.entry.scenario.clone(),
            in_envelope: inside,
            switched,
            held,
            reason,
            quadrant: self.entry.quadrant.clone(),
            threshold_group: self.entry.threshold_group.clone(),
            severity_group: self.entry.severity_group.clone(),
            p_high: self.entry.p_high,
            fault: fault.map(str::to_string),
            axes: readings,
        };
        self.steps += 1;
        record
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn axis(name: &str, descending: bool, identity: f64, sigma: Option<f64>) -> AxisThreshold {
        AxisThreshold {
            axis: name.into(),
            family: name.into(),
            descending,
            identity_level: identity,
            levels: Vec::new(),
            sigma_star: sigma,
            right_censored: false,
            ci95: None,
            threshold_group: "match".into(),
        }
    }

    fn odd() -> OddSpec {
        let entry = |scenario: &str, noise: Option<f64>| OddEntry {
            scenario: scenario.into(),
            rank: None,
            n_clips: 40,
            n_changed: 5,
            pilot: false,
            axis: "gaussian_noise".into(),
            budget: 0.15,
            sigma_star: noise,
            right_censored: false,
            ci95: None,
            p_high: Some(0.3),
            threshold_group: "tight".into(),
            severity_group: "severe".into(),
            quadrant: "tight + severe".into(),
            accepted: None,
            acceptance_reason: None,
            thresholds: vec![
                axis("gaussian_noise", false, 0.0, noise),
                axis("darken", true, 1.0, Some(0.4)),
                axis("brighten", false, 1.0, Some(1.6)),
                axis("fog", false, 0.0, Some(0.3)),
            ],
        };
        let mut o = OddSpec::new("test", "00", None, 0.15, "first-violation");
        o.entries = vec![entry("A", Some(30.0)), entry("B", None)];
        o
    }

    fn noise(sigma: f64) -> Observation {
        Observation {
            noise_sigma: sigma,
            noise_sigma_se: 0.0,
            ..Observation::clean()
        }
    }

    fn unsmoothed(dwell: usize) -> MonitorParams {
        MonitorParams {
            ewma_alpha: 1.0,
            z: 0.0,
            min_dwell_steps: dwell,
            ..MonitorParams::default()
        }
    }

    /// Hysteresis: out only beyond σ* + δ, back in only below σ* − δ; between, the state
    /// holds in both directions.
    #[test]
    fn r20_hysteresis_leaves_above_and_returns_below_the_band() {
        let mut m = Monitor::new(&odd(), "A", unsmoothed(1)).unwrap();
        let seq = [
            (29.0, true),  // first step: direct, 29 ≤ 30
            (31.5, true),  // inside the band: stays in
            (32.5, false), // beyond 30 + 2: out
            (29.0, false), // inside the band: stays out
            (27.5, true),  // below 30 − 2: in
            (31.9, true),
        ];
        for (i, (sigma, inside)) in seq.into_iter().enumerate() {
            let r = m.step(&noise(sigma)).unwrap();
            assert_eq!(r.in_envelope, inside, "step {i} at σ {sigma}: {r:?}");
            assert!(!r.held);
        }
        // The first step decides with no band: 31 is out at once.
        let mut m = Monitor::new(&odd(), "A", unsmoothed(1)).unwrap();
        let r = m.step(&noise(31.0)).unwrap();
        assert!(!r.in_envelope && r.switched && r.step == 0);
        assert!(
            r.reason.contains("gaussian_noise 31.000 > 30.000"),
            "{}",
            r.reason
        );
    }

    /// Minimum dwell: a state lasts `min_dwell_steps` steps; an earlier switch is held and
    /// happens as soon as the dwell allows it if the estimates still ask for it.
    #[test]
    fn r20_minimum_dwell_holds_a_switch() {
        let mut m = Monitor::new(&odd(), "A", unsmoothed(3)).unwrap();
        let r = m.step(&noise(40.0)).unwrap(); // out, dwell 1
        assert!(!r.in_envelope && r.switched);
        let r = m.step(&noise(10.0)).unwrap(); // asks in, dwell 1 < 3: held
        assert!(!r.in_envelope && r.held);
        let r = m.step(&noise(10.0)).unwrap(); // dwell 2 < 3: held
        assert!(!r.in_envelope && r.held);
        let r = m.step(&noise(10.0)).unwrap(); // dwell 3: in
        assert!(r.in_envelope && r.switched && !r.held);
        let r = m.step(&noise(50.0)).unwrap(); // asks out, dwell 1: held
        assert!(r.in_envelope && r.held);
        let r = m.step(&noise(10.0)).unwrap(); // the request is gone: nothing held
        assert!(r.in_envelope && !r.held && !r.switched);
    }

    /// The EWMA smooths a single spike away; the conservative bound adds z·u.
    #[test]
    fn r20_smoothing_and_the_conservative_bound() {
        let p = MonitorParams {
            ewma_alpha: 0.25,
            z: 2.0,
            min_dwell_steps: 1,
            ..MonitorParams::default()
        };
        let mut m = Monitor::new(&odd(), "A", p).unwrap();
        let obs = |sigma: f64, se: f64| Observation {
            noise_sigma: sigma,
            noise_sigma_se: se,
            ..Observation::clean()
        };
        assert!(m.step(&obs(20.0, 1.0)).unwrap().in_envelope);
        let r = m.step(&obs(60.0, 1.0)).unwrap(); // m = 30, bound 32: not beyond 32
        assert_eq!(r.axes[0].smoothed, 30.0);
        assert_eq!(r.axes[0].bound, 32.0);
        assert!(r.in_envelope && r.axes[0].beyond);
        // The same mean with a larger error is out: 30 + 2·3 > 32.
        let mut m = Monitor::new(&odd(), "A", m.params.clone()).unwrap();
        m.step(&obs(30.0, 3.0)).unwrap();
        assert!(!m.in_envelope().unwrap());
    }

    /// Darkening is out below the gain limit; fog above its own; σ* none allows only the
    /// clean frame; a scenario change keeps the averages.
    #[test]
    fn r20_every_axis_and_the_none_threshold() {
        let mut m = Monitor::new(&odd(), "A", unsmoothed(1)).unwrap();
        let dark = Observation {
            gain: 0.3,
            ..Observation::clean()
        };
        let r = m.step(&dark).unwrap();
        assert!(
            !r.in_envelope && r.reason.contains("darken 0.300 < 0.400"),
            "{r:?}"
        );
        assert_eq!(m.watched_axes(), ESTIMATED_AXES.to_vec());
        let mut m = Monitor::new(&odd(), "A", unsmoothed(1)).unwrap();
        let fog = Observation {
            fog: 0.35,
            ..Observation::clean()
        };
        assert!(!m.step(&fog).unwrap().in_envelope);
        // B's noise σ* is none: σ 0 is inside, any noise is out, and only σ 0 re-enters.
        let mut m = Monitor::new(&odd(), "B", unsmoothed(1)).unwrap();
        assert!(m.step(&noise(0.0)).unwrap().in_envelope);
        assert!(!m.step(&noise(3.0)).unwrap().in_envelope);
        assert!(!m.step(&noise(0.5)).unwrap().in_envelope);
        assert!(m.step(&noise(0.0)).unwrap().in_envelope);
        // Watching the noise axis alone ignores the fog.
        let p = MonitorParams {
            axes: vec!["gaussian_noise".into()],
            ..unsmoothed(1)
        };
        let mut m = Monitor::new(&odd(), "A", p).unwrap();
        assert!(m.step(&fog).unwrap().in_envelope);
        m.set_scenario("B").unwrap();
        assert_eq!(m.scenario(), "B");
        assert!(m.step(&noise(4.0)).unwrap().axes[0].beyond);
    }

    #[test]
    fn r20_errors_name_what_is_wrong() {
        let e = Monitor::new(&odd(), "C", MonitorParams::default()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "odd.json has no entry for scenario \"C\" (entries: A, B)"
        );
        let mut old = odd();
        for e in &mut old.entries {
            e.thresholds.clear();
        }
        let p = MonitorParams {
            axes: vec!["fog".into()],
            ..MonitorParams::default()
        };
        let e = Monitor::new(&old, "A", p).unwrap_err().to_string();
        assert!(e.contains("no threshold on any watched axis (fog)"), "{e}");
        // An old file has its headline axis only.
        let m = Monitor::new(&old, "A", MonitorParams::default()).unwrap();
        assert_eq!(m.watched_axes(), vec!["gaussian_noise"]);
        for bad in [
            MonitorParams {
                ewma_alpha: 0.0,
                ..MonitorParams::default()
            },
            MonitorParams {
                min_dwell_steps: 0,
                ..MonitorParams::default()
            },
            MonitorParams {
                axes: vec!["blur".into()],
                ..MonitorParams::default()
            },
        ] {
            assert!(Monitor::new(&odd(), "A", bad).is_err());
        }
        let mut m = Monitor::new(&odd(), "A", MonitorParams::default()).unwrap();
        assert!(m.step(&noise(f64::NAN)).is_err());
        assert!(m.step_frame(&[0; 10], 4, 4).is_err());
    }

    /// A black frame is out at once (dwell or not) and does not enter the averages; the
    /// record round-trips through JSON.
    #[test]
    fn r20_faults_leave_at_once_and_records_round_trip() {
        let p = MonitorParams {
            axes: vec!["gaussian_noise".into()],
            ..MonitorParams::default()
        };
        let mut m = Monitor::new(&odd(), "A", p).unwrap();
        let (w, h) = (64, 48);
        // A smooth ramp: no noise.
        let ramp: Vec<u8> = (0..w * h * 3)
            .map(|i| (40 + (i / 3) % w + (i / 3 / w) / 2) as u8)
            .collect();
        let r = m.step_frame(&ramp, w, h).unwrap();
        assert!(r.fault.is_none() && r.in_envelope, "{r:?}");
        let before = r.axes.clone();
        let r = m.step_frame(&vec![0; w * h * 3], w, h).unwrap();
        assert!(!r.in_envelope && r.switched, "{r:?}");
        assert_eq!(r.fault.as_deref(), Some("black"));
        assert_eq!(r.axes[0].smoothed, before[0].smoothed);
        assert!(r.axes[0].estimate.is_none());
        let text = serde_json::to_string(&r).unwrap();
        let back: MonitorRecord = serde_json::from_str(&text).unwrap();
        assert_eq!(back, r);
    }

    /// Issue 20, task A: an axis whose σ* is none is decided by the test against nominal
    /// (clean frames of the camera read inside, a darker camera than its 1 % quantile out),
    /// and the fog bound uses the calibrated spread, not the model error.
    #[test]
    fn r20_nominal_test_and_calibrated_uncertainty() {
        let mut o = odd();
        for e in &mut o.entries {
            for t in &mut e.thresholds {
                if t.axis == "darken" {
                    t.sigma_star = None;
                }
            }
        }
        let p = MonitorParams {
            min_dwell_steps: 1,
            ..MonitorParams::default()
        };
        let null = p.null.clone();
        // A clean frame of a scene darker than the reference: gain 0.85 ± 0.09.
        let clean = Observation {
            gain: 0.85,
            gain_se: 0.09,
            fog: 0.16,
            fog_se: 0.09,
            ..Observation::clean()
        };
        let mut m = Monitor::new(&o, "A", p.clone()).unwrap();
        let r = m.step(&clean).unwrap();
        assert!(r.in_envelope, "{r:?}");
        let dark = r.axes.iter().find(|a| a.axis == "darken").unwrap();
        assert_eq!(
            (dark.test.as_str(), dark.limit),
            ("nominal", null.gain.lower)
        );
        assert_eq!(dark.bound, 0.85);
        let fog = r.axes.iter().find(|a| a.axis == "fog").unwrap();
        assert_eq!(fog.test, "limit");
        // 0.16 + 1.645 · 0.0639 < 0.3 (the model error would give 0.16 + 0.148 > 0.3).
        assert!(
            (fog.bound - (0.16 + 1.645 * null.fog.sd)).abs() < 1e-12,
            "{fog:?}"
        );
        // A camera at gain 0.5 reads below its clean frames' 1 % quantile: out.
        let mut m = Monitor::new(&o, "A", p.clone()).unwrap();
        let r = m.step(&Observation { gain: 0.5, ..clean }).unwrap();
        assert!(!r.in_envelope, "{r:?}");
        assert!(r.reason.contains("darken 0.500 < 0.594"), "{}", r.reason);
        // Hysteresis on the nominal axis: back in only above lower + margin (and the fog
        // bound below 0.3 − margin).
        assert!(
            !m.step(&Observation {
                gain: 0.62,
                fog: 0.05,
                ..clean
            })
            .unwrap()
            .in_envelope
        );
        assert!(
            m.step(&Observation {
                gain: 1.0,
                fog: 0.05,
                ..clean
            })
            .unwrap()
            .in_envelope
        );
    }

    #[test]
    fn r20_null_profile_from_observations() {
        let obs: Vec<Observation> = (0..=100)
            .map(|i| Observation {
                noise_sigma: 0.0,
                gain: 0.5 + f64::from(i) / 100.0,
                fog: f64::from(i) / 1000.0,
                ..Observation::clean()
            })
            .collect();
        let p = NullProfile::from_observations(&obs, 0.01).unwrap();
        assert_eq!(p.frames, 101);
        assert!((p.gain.center - 1.0).abs() < 1e-12);
        assert!((p.gain.lower - 0.51).abs() < 1e-12 && (p.gain.upper - 1.49).abs() < 1e-12);
        assert!((p.fog.upper - 0.099).abs() < 1e-12);
        assert_eq!(p.noise_sigma.sd, 0.0);
        assert!(NullProfile::from_observations(&obs[..1], 0.01).is_err());
        assert!(NullProfile::from_observations(&obs, 0.7).is_err());
        let bad = MonitorParams {
            null: NullProfile {
                gain: NullAxis {
                    center: 0.5,
                    sd: 0.1,
                    lower: 0.6,
                    upper: 1.0,
                },
                ..NullProfile::default()
            },
            ..MonitorParams::default()
        };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("invalid null"), "{e}");
    }
}
