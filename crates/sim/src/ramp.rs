//! Condition ramps: sensor noise, darkness or fog that rise and fall mid-route (the exits
//! from the operational design domain a deployed car meets), and the guard that hands the
//! car to the override while it is outside its envelope.
//!
//! A ramp is a function of game time, not of place: the condition rolls in and clears as a
//! fog bank drifting over the road or a camera's gain failing and recovering would, so a car
//! that stops for it sees it clear. Each route of a seed draws one ramp from the run's seed:
//! the axis (`gaussian_noise`, `darken` or `fog`, in turn by route), when it starts
//! (25–75 s), how long it takes to rise and fall (10–20 s each), how long it holds at its
//! peak (40–90 s), and the peak (σ 55–80 on the 0–255 scale, gain 0.08–0.18, fog opacity
//! α 0.85–0.95), each past the reference planner's envelope on that axis.
//!
//! The condition is the campaign's perturbation of the same name (`noise_<σ>`,
//! `gain_<g>`, `fog_<α>`: the families the envelope analysis measured), applied to every
//! frame the agent and the override get, after the weather. Levels are rounded (σ to 1,
//! gain and α to 0.01) so a run prepares each level once.
//!
//! [`GuardMode`] names the four configurations of `--configs ramps`: no guard; the guard
//! driven by the runtime monitor ([`fogline_monitor::Monitor`] on the front-wide and cross
//! cameras, [`calibrated_monitor`]);
//! the guard driven by the true condition (the oracle hand-over, the upper bound of any
//! monitor); the override always in control.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use fogline_monitor::{ConditionParams, MonitorParams, NullProfile};
use fogline_perturb::{Frame, FrameInput, FrameKey, Perturbation, Prepared};
use fogline_stats::seed::rng;
use fogline_types::clip::{CameraCalib, CameraId};
use fogline_types::odd::{AxisThreshold, OddSpec};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::route::Route;
use crate::sense::{Daylight, Lens, PartsCache, Weather, look, scene_at, see};
use crate::suite::{Suite, SuiteParams};
use crate::traffic::{Traffic, TrafficParams};
use crate::vehicle::VehicleState;

/// The condition axes a ramp can move (the envelope's names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RampAxis {
    /// Gaussian sensor noise, σ on the 0–255 scale.
    GaussianNoise,
    /// Darkness: a photometric gain below 1.
    Darken,
    /// Homogeneous fog of opacity α.
    Fog,
}

impl RampAxis {
    /// All axes, in the order routes take them.
    pub const ALL: [RampAxis; 3] = [Self::GaussianNoise, Self::Darken, Self::Fog];

    /// The envelope's name of the axis.
    pub fn name(self) -> &'static str {
        match self {
            Self::GaussianNoise => "gaussian_noise",
            Self::Darken => "darken",
            Self::Fog => "fog",
        }
    }

    /// The level at which the axis leaves a frame unchanged.
    pub fn identity(self) -> f64 {
        match self {
            Self::GaussianNoise | Self::Fog => 0.0,
            Self::Darken => 1.0,
        }
    }

    /// The level rounded as runs prepare it (σ to 1; gain and α to 0.01).
    pub fn round(self, level: f64) -> f64 {
        match self {
            Self::GaussianNoise => level.round(),
            Self::Darken | Self::Fog => (level * 100.0).round() / 100.0,
        }
    }

    /// The campaign's name of the condition at `level` (None at the identity).
    pub fn condition(self, level: f64) -> Option<String> {
        let l = self.round(level);
        if l == self.round(self.identity()) {
            return None;
        }
        Some(match self {
            Self::GaussianNoise => format!("noise_{l}"),
            Self::Darken => format!("gain_{l}"),
            Self::Fog => format!("fog_{l}"),
        })
    }
}

/// One route's ramp: the condition rises linearly from the identity to `peak` over
/// `rise_s` from `start_s`, holds for `hold_s`, and falls back over `fall_s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ramp {
    /// The axis.
    pub axis: RampAxis,
    /// The level at the peak (σ, gain or α).
    pub peak: f64,
    /// Game time the rise starts, s.
    pub start_s: f64,
    /// Duration of the rise, s.
    pub rise_s: f64,
    /// Duration at the peak, s.
    pub hold_s: f64,
    /// Duration of the fall, s.
    pub fall_s: f64,
}

impl Ramp {
    /// The ramp of route `route` under `seed` (see the module documentation).
    pub fn for_route(seed: u64, route: usize) -> Self {
        let mut r = rng(seed, &[route as u64, 0x7a3b]);
        let axis = RampAxis::ALL[route % RampAxis::ALL.len()];
        let peak = match axis {
            RampAxis::GaussianNoise => r.random_range(55.0..80.0f64).round(),
            RampAxis::Darken => (r.random_range(0.08..0.18f64) * 100.0).round() / 100.0,
            RampAxis::Fog => (r.random_range(0.85..0.95f64) * 100.0).round() / 100.0,
        };
        Self {
            axis,
            peak,
            start_s: r.random_range(25.0..75.0f64).round(),
            rise_s: r.random_range(10.0..20.0f64).round(),
            hold_s: r.random_range(40.0..90.0f64).round(),
            fall_s: r.random_range(10.0..20.0f64).round(),
        }
    }

    /// The level at game time `t` (rounded as runs prepare it).
    pub fn level(&self, t: f64) -> f64 {
        let id = self.axis.identity();
        let u = t - self.start_s;
        let share = if u <= 0.0 {
            0.0
        } else if u < self.rise_s {
            u / self.rise_s
        } else if u <= self.rise_s + self.hold_s {
            1.0
        } else if u < self.rise_s + self.hold_s + self.fall_s {
            1.0 - (u - self.rise_s - self.hold_s) / self.fall_s
        } else {
            0.0
        };
        self.axis.round(id + share * (self.peak - id))
    }

    /// Game time the condition is back at the identity, s.
    pub fn end_s(&self) -> f64 {
        self.start_s + self.rise_s + self.hold_s + self.fall_s
    }
}

/// Who decides that the car has left its envelope, in a ramps configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GuardMode {
    /// No guard: the baseline drives through the ramp on its degraded frames.
    None,
    /// The runtime monitor on the front-wide frames (estimates only).
    Monitor,
    /// The true condition against the envelope (the oracle hand-over).
    Oracle,
    /// The override drives whenever the ramp has started and not ended (no monitor).
    Always,
}

impl GuardMode {
    /// All modes, in the order of `--configs ramps`.
    pub const ALL: [GuardMode; 4] = [Self::None, Self::Monitor, Self::Oracle, Self::Always];

    /// The configuration's name.
    pub fn config_name(self) -> &'static str {
        match self {
            Self::None => "ramps/no_guard",
            Self::Monitor => "ramps/guard",
            Self::Oracle => "ramps/oracle",
            Self::Always => "ramps/rco",
        }
    }
}

/// Applies a run's ramp to frames, preparing each rounded level once.
#[derive(Debug)]
pub struct RampLens {
    ramp: Ramp,
    seed: u64,
    prepared: HashMap<u64, Prepared>,
}

impl RampLens {
    /// The lens of `ramp`, its noise drawn from `seed`.
    pub fn new(ramp: Ramp, seed: u64) -> Self {
        Self {
            ramp,
            seed,
            prepared: HashMap::new(),
        }
    }

    /// The ramp.
    pub fn ramp(&self) -> &Ramp {
        &self.ramp
    }

    /// `frame` under the condition at game time `t` (unchanged at the identity).
    pub fn apply(&mut self, frame: Frame, t: f64, key: FrameKey) -> Result<Frame, SimError> {
        let level = self.ramp.level(t);
        let Some(name) = self.ramp.axis.condition(level) else {
            return Ok(frame);
        };
        let slot = level.to_bits();
        if !self.prepared.contains_key(&slot) {
            let p = Perturbation::parse(&name)
                .and_then(|p| p.prepare(self.seed))
                .map_err(|e| SimError::Params(format!("ramp condition {name}: {e}")))?;
            self.prepared.insert(slot, p);
        }
        let Some(p) = self.prepared.get(&slot) else {
            return Ok(frame);
        };
        let input = FrameInput::new(frame.view(), key);
        p.apply(&input)
            .map(|a| a.frame)
            .map_err(|e| SimError::Params(format!("ramp condition {name}: {e}")))
    }
}

/// Whether `level` on `axis` is inside the threshold `t` (an axis with no threshold on
/// record is inside only at its identity).
pub fn inside(t: Option<&AxisThreshold>, axis: RampAxis, level: f64) -> bool {
    match t {
        Some(t) => t.inside(level),
        None => level == axis.identity(),
    }
}

/// The reference planner's envelope on a ladder of levels of every axis a ramp moves (σ
/// 10–80 by 10, gain 0.9–0.2 by 0.1 and 1.3, 1.6, fog α 0.1–0.9 by 0.1; 300 world clips of
/// seed 0 at 576×320, budget 0.15, first violation): the `odd.json` that
/// `data/reference_campaign.toml` gives through `fogline campaign run`, `fogline campaign
/// export` and `fogline envelope` (docs/sim.md). The ramps' guard and oracle use it unless
/// given another.
pub const REFERENCE_ODD: &str = include_str!("../data/reference_odd.json");

/// [`REFERENCE_ODD`], read.
pub fn reference_odd() -> Result<OddSpec, SimError> {
    OddSpec::from_json(REFERENCE_ODD)
        .map_err(|e| SimError::Params(format!("the built-in reference odd.json: {e}")))
}

/// The situations a ramps run looks its envelope up by (entries of the reference
/// `odd.json`): near a junction on the route, behind a car, or keeping its lane.
pub const RAMP_SCENARIOS: [&str; 3] = ["LANE_KEEPING", "INTERSECTION", "FOLLOW_VEHICLE"];

/// The situation of a ramps run: within 30 m of a junction of the route (or in it), behind
/// a perceived car within 30 m, else keeping its lane. From the route, the pose and the
/// agent's perception, as the planner's decision would name it.
pub fn ramp_scenario(route: &Route, route_s: f64, lead_gap_m: Option<f64>) -> &'static str {
    let junction = route
        .next_junction(route_s)
        .is_some_and(|j| j.s_entry_m - route_s < 30.0);
    if junction {
        RAMP_SCENARIOS[1]
    } else if lead_gap_m.is_some_and(|g| g < 30.0) {
        RAMP_SCENARIOS[2]
    } else {
        RAMP_SCENARIOS[0]
    }
}

/// The seed of the monitor's calibration drive (a quick suite no experiment seed builds).
pub const CALIBRATION_SEED: u64 = 0xCA11_B0A7;

/// Metres between the calibration drive's frames.
const CALIBRATION_STEP_M: f64 = 10.0;

type CalibrationKey = (Weather, Daylight, u32, u32, u64);

/// The guard's monitor, calibrated as a deployed camera's would be. It reads the front-wide
/// and both cross cameras (at the front camera's size) stacked as one image ([`mosaic`]): a
/// global condition reaches every view, a dark car crossing close ahead fills one. Its
/// reference luminance profile and its null profile (the estimators' readings on clean
/// frames, at a 1 % false-alarm rate) are measured on clean mosaics under the same weather
/// and daylight, from a calibration drive (the quick suite of [`CALIBRATION_SEED`]: 2 towns,
/// 4 routes, a frame every 10 m with its traffic; no route of any experiment). It decides on
/// the smoothed estimates themselves (`z` 0): with the gain's spread on clean scenes a 95 %
/// bound cannot certify a clean frame inside a junction's darkness threshold of 0.8, and
/// the car would be held at every junction (docs/sim.md measures both). The temporal faults
/// are off: the simulator's frames carry no sensor noise, so a car standing before a red
/// light sees identical frames, which the frozen-frame test would call a fault (ramps
/// inject no temporal faults). Calibrations are kept for the process, one per weather,
/// daylight and camera size.
pub fn calibrated_monitor(
    weather: Weather,
    daylight: Daylight,
    wide: &CameraCalib,
) -> Result<MonitorParams, SimError> {
    static KEPT: OnceLock<Mutex<HashMap<CalibrationKey, Arc<MonitorParams>>>> = OnceLock::new();
    let key = (
        weather,
        daylight,
        wide.width,
        wide.height,
        wide.fx.to_bits(),
    );
    let kept = KEPT.get_or_init(|| Mutex::new(HashMap::new()));
    if let Some(p) = kept.lock().ok().and_then(|m| m.get(&key).cloned()) {
        return Ok((*p).clone());
    }
    let p = Arc::new(calibrate(weather, daylight, wide)?);
    if let Ok(mut m) = kept.lock() {
        m.insert(key, Arc::clone(&p));
    }
    Ok((*p).clone())
}

fn calibrate(
    weather: Weather,
    daylight: Daylight,
    wide: &CameraCalib,
) -> Result<MonitorParams, SimError> {
    static DRIVE: OnceLock<Result<Suite, String>> = OnceLock::new();
    let suite = DRIVE
        .get_or_init(|| {
            Suite::build(&SuiteParams::quick(), CALIBRATION_SEED, 0.0).map_err(|e| e.to_string())
        })
        .as_ref()
        .map_err(|e| SimError::Params(format!("the monitor's calibration drive: {e}")))?;
    let lens = Lens::new(weather, None)?;
    let lk = look(weather, daylight);
    let sides = [CameraId::CrossLeft, CameraId::CrossRight]
        .map(|id| CameraCalib::standard(id, wide.width, wide.height));
    let mut frames: Vec<(Vec<u8>, usize, usize)> = Vec::new();
    for case in &suite.cases {
        let town = &suite.towns[case.town];
        let cache = PartsCache::new(town);
        let traffic = Traffic::new(town, &case.route, TrafficParams::default(), case.seed);
        let mut s = 0.0;
        while s < case.route.length_m() {
            let (p, u) = case.route.pose(s);
            let ego = VehicleState::standing(p, u);
            let sc = scene_at(town, &traffic, &cache, &ego, 0.0, lk);
            let key = |c: &CameraCalib| {
                FrameKey::new(case.id as u64, c.id.index() as u64, frames.len() as u64)
            };
            let views = [wide, &sides[0], &sides[1]].map(|c| see(&sc, c, &lens, key(c)).frame);
            frames.push(mosaic(&[&views[0], &views[1], &views[2]]));
            s += CALIBRATION_STEP_M;
        }
    }
    let views = || frames.iter().map(|(px, w, h)| (px.as_slice(), *w, *h));
    let fail = |e: fogline_monitor::MonitorError| {
        SimError::Params(format!("the monitor's calibration: {e}"))
    };
    let condition = ConditionParams::from_clean_frames(views(), 204.0).map_err(fail)?;
    let null = NullProfile::from_clean_frames(views(), &condition, 0.01).map_err(fail)?;
    log::debug!(
        "monitor calibrated on {} clean frames ({}, {}): gain {:.3} ± {:.3} [{:.3}, {:.3}], fog {:.3} ± {:.3}, σ̂ {:.2} ± {:.2}",
        frames.len(),
        weather.name(),
        daylight.name(),
        null.gain.center,
        null.gain.sd,
        null.gain.lower,
        null.gain.upper,
        null.fog.center,
        null.fog.sd,
        null.noise_sigma.center,
        null.noise_sigma.sd
    );
    Ok(MonitorParams {
        z: 0.0,
        faults_enabled: false,
        condition,
        null,
        ..MonitorParams::default()
    })
}

/// Frames of one width stacked top to bottom: `(rgb, width, height)` (frames of another
/// width than the first are left out).
pub fn mosaic(frames: &[&Frame]) -> (Vec<u8>, usize, usize) {
    let width = frames.first().map_or(0, |f| f.width() as usize);
    let mut px = Vec::with_capacity(frames.iter().map(|f| f.data().len()).sum());
    let mut height = 0;
    for f in frames.iter().filter(|f| f.width() as usize == width) {
        px.extend_from_slice(f.data());
        height += f.height() as usize;
    }
    (px, width, height)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sense::Weather;

    #[test]
    fn a_ramp_rises_holds_and_falls_back_to_the_identity() {
        for route in 0..12 {
            let r = Ramp::for_route(7, route);
            let id = r.axis.identity();
            assert_eq!(r.level(0.0), id);
            assert_eq!(r.level(r.start_s), id);
            assert_eq!(r.level(r.start_s + r.rise_s + 1.0), r.peak);
            assert_eq!(r.level(r.start_s + r.rise_s + r.hold_s), r.peak);
            assert_eq!(r.level(r.end_s() + 0.1), id);
            let mid = r.level(r.start_s + r.rise_s / 2.0);
            assert!((mid - (id + r.peak) / 2.0).abs() <= 0.51, "{mid} {r:?}");
            assert_eq!(r.axis, RampAxis::ALL[route % 3]);
            assert_eq!(r, Ramp::for_route(7, route), "drawn from the seed");
        }
        assert_ne!(Ramp::for_route(7, 0), Ramp::for_route(8, 0));
    }

    #[test]
    fn every_peak_is_outside_the_reference_envelope_on_its_axis() {
        let odd = reference_odd().unwrap();
        for seed in 0..4 {
            for route in 0..36 {
                let r = Ramp::for_route(seed, route);
                for scenario in RAMP_SCENARIOS {
                    let e = odd.entry(scenario).unwrap();
                    let t = e.threshold(r.axis.name());
                    assert!(!inside(t.as_ref(), r.axis, r.peak), "{r:?} {}", e.scenario);
                }
            }
        }
    }

    #[test]
    fn the_lens_applies_the_campaigns_condition_and_leaves_clean_time_alone() {
        let frame = Frame::filled(32, 24, [120, 110, 100]).unwrap();
        let ramp = Ramp {
            axis: RampAxis::Darken,
            peak: 0.25,
            start_s: 10.0,
            rise_s: 10.0,
            hold_s: 10.0,
            fall_s: 10.0,
        };
        let mut lens = RampLens::new(ramp, 3);
        let key = FrameKey::new(0, 0, 0);
        assert_eq!(lens.apply(frame.clone(), 5.0, key).unwrap(), frame);
        let dark = lens.apply(frame.clone(), 25.0, key).unwrap();
        assert_eq!(dark.pixel(3, 3), [30, 28, 25]);
        let noisy = RampLens::new(
            Ramp {
                axis: RampAxis::GaussianNoise,
                peak: 60.0,
                ..ramp
            },
            3,
        )
        .apply(frame.clone(), 25.0, key)
        .unwrap();
        assert_ne!(noisy, frame);
    }

    #[test]
    fn the_calibrated_monitor_reads_unseen_clean_scenes_in_and_each_peak_out() {
        use fogline_monitor::Monitor;
        // Scenes of a suite the calibration drive is not (seed 3), at noon and at night.
        let suite = Suite::build(&SuiteParams::quick(), 3, 0.0).unwrap();
        let sensors = crate::run::SensorParams::default();
        let ([_, wide, _], _) = sensors.cameras();
        let sides = [CameraId::CrossLeft, CameraId::CrossRight]
            .map(|id| CameraCalib::standard(id, sensors.width, sensors.height));
        let odd = reference_odd().unwrap();
        for daylight in [Daylight::Noon, Daylight::Night] {
            let weather = Weather::Cloudy;
            let params = calibrated_monitor(weather, daylight, &wide).unwrap();
            let (lens, lk) = (Lens::new(weather, None).unwrap(), look(weather, daylight));
            let case = &suite.cases[1];
            let town = &suite.towns[case.town];
            let cache = PartsCache::new(town);
            let traffic = Traffic::new(town, &case.route, TrafficParams::default(), case.seed);
            let peaks = [
                None,
                Some((RampAxis::GaussianNoise, 60.0)),
                Some((RampAxis::Darken, 0.15)),
                Some((RampAxis::Fog, 0.9)),
            ];
            for peak in peaks {
                let mut m = Monitor::new(&odd, "LANE_KEEPING", params.clone()).unwrap();
                let mut lens_ramp = peak.map(|(axis, peak)| {
                    RampLens::new(
                        Ramp {
                            axis,
                            peak,
                            start_s: 0.0,
                            rise_s: 1.0,
                            hold_s: 1000.0,
                            fall_s: 1.0,
                        },
                        9,
                    )
                });
                let mut last = None;
                for k in 0..30u64 {
                    let (p, u) = case.route.pose(15.0 + 8.0 * k as f64);
                    let ego = VehicleState::standing(p, u);
                    let sc = scene_at(town, &traffic, &cache, &ego, 0.0, lk);
                    let views = [&wide, &sides[0], &sides[1]].map(|c| {
                        let key = FrameKey::new(7, c.id.index() as u64, k);
                        let f = see(&sc, c, &lens, key).frame;
                        match lens_ramp.as_mut() {
                            Some(l) => l.apply(f, 10.0, key).unwrap(),
                            None => f,
                        }
                    });
                    let (px, w, h) = mosaic(&[&views[0], &views[1], &views[2]]);
                    last = Some(m.step_frame(&px, w, h).unwrap());
                }
                let rec = last.unwrap();
                assert_eq!(
                    rec.in_envelope,
                    peak.is_none(),
                    "{daylight:?} {peak:?}: {} {:?}",
                    rec.reason,
                    rec.axes
                );
            }
        }
    }
}
