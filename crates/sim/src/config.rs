//! Experiment configurations: which deficit, whether the RCO controller takes over (with
//! which modules, planning step limit and backend), and how infractions are scored.

use std::sync::Arc;

use fogline_rco::{
    HostileBackend, Modules, OpenAiBackend, OpenAiParams, Rco, RcoParams, RulesBackend, RulesParams,
};
use fogline_types::odd::OddSpec;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::ramp::GuardMode;
use crate::score::ScoringParams;
use crate::sense::DeficitKind;

/// The backend the RCO controller asks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum BackendSetup {
    /// The offline rule-based backend.
    Rules,
    /// An OpenAI-compatible server.
    Openai(OpenAiParams),
    /// The red-team backend ([`fogline_rco::HostileBackend`]): the most dangerous
    /// well-formed answers, to show what the hard limits and the shield hold.
    Hostile {
        /// Ask for a deceleration limit that would take braking authority away.
        weak_brakes: bool,
    },
}

impl BackendSetup {
    /// Checks that an `openai` endpoint accepts connections (a TCP connect within
    /// `timeout_ms`); `Err` says why not. The `rules` backend is always reachable.
    pub fn probe(&self, timeout_ms: u64) -> Result<(), String> {
        use std::net::ToSocketAddrs as _;
        let BackendSetup::Openai(p) = self else {
            return Ok(());
        };
        let with_port = p.parsed_url().map_err(|e| e.to_string())?.authority;
        let addrs: Vec<std::net::SocketAddr> = with_port
            .to_socket_addrs()
            .map_err(|e| format!("{}: cannot resolve {with_port}: {e}", p.base_url))?
            .collect();
        let timeout = std::time::Duration::from_millis(timeout_ms.max(1));
        let mut last = String::from("no address");
        for a in addrs {
            match std::net::TcpStream::connect_timeout(&a, timeout) {
                Ok(_) => return Ok(()),
                Err(e) => last = e.to_string(),
            }
        }
        Err(format!("{} is unreachable ({last})", p.base_url))
    }

    /// A short description (`rules`, `openai <model> at <url>`).
    pub fn describe(&self) -> String {
        match self {
            BackendSetup::Rules => "rules".into(),
            BackendSetup::Openai(p) => format!("openai {} at {}", p.model, p.base_url),
            BackendSetup::Hostile { weak_brakes: false } => "hostile".into(),
            BackendSetup::Hostile { weak_brakes: true } => "hostile (weak brakes)".into(),
        }
    }
}

/// How the RCO controller is set up in a configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RcoSetup {
    /// Module switches (HI, ST, AV, SC).
    pub modules: Modules,
    /// The planning step limit.
    pub plan_limit: usize,
    /// The backend.
    pub backend: BackendSetup,
}

impl Default for RcoSetup {
    fn default() -> Self {
        Self {
            modules: Modules::default(),
            plan_limit: RcoParams::default().plan_limit,
            backend: BackendSetup::Rules,
        }
    }
}

impl RcoSetup {
    /// The modules as the paper's table 3 writes them (`HI+ST+AV+SC`, `none`).
    pub fn modules_label(&self) -> String {
        modules_label(&self.modules)
    }

    /// Builds a controller stepped `hz` times per second. The controller's settings that
    /// count ticks (designed for 10 Hz: waits, the hold limit, rule S3's window, the
    /// constraint refresh) are scaled to keep their durations, the per-tick shift limit of
    /// the verifier to keep its speed, and the PID's time step is `1/hz`.
    pub fn build(&self, hz: f64) -> Result<Rco, SimError> {
        let f = hz / 10.0;
        let ticks = |n: f64| (n * f).round().max(1.0);
        let d = RcoParams::default();
        let mut params = RcoParams {
            modules: self.modules,
            plan_limit: self.plan_limit,
            dt_s: 1.0 / hz,
            wait_limit: ticks(f64::from(d.wait_limit)) as u32,
            max_hold_ticks: ticks(f64::from(d.max_hold_ticks)) as u32,
            ..d
        };
        params.verifier.max_shift_frac = (params.verifier.max_shift_frac / f).min(0.5);
        params.safety.refresh_ticks = ticks(params.safety.refresh_ticks as f64) as u64;
        let r = RulesParams::default();
        let rules = RulesParams {
            resume_window_ticks: ticks(r.resume_window_ticks as f64) as u64,
            vru_wait_ticks: ticks(f64::from(r.vru_wait_ticks)) as u32,
            sign_wait_ticks: ticks(f64::from(r.sign_wait_ticks)) as u32,
            ..r
        };
        let rco = match &self.backend {
            BackendSetup::Rules => Rco::new(params, Box::new(RulesBackend::new(rules))),
            BackendSetup::Openai(p) => {
                let b = OpenAiBackend::new(p.clone()).map_err(|e| SimError::Rco(e.to_string()))?;
                Rco::new(params, Box::new(b))
            }
            BackendSetup::Hostile { weak_brakes } => Rco::new(
                params,
                Box::new(HostileBackend {
                    weak_brakes: *weak_brakes,
                }),
            ),
        };
        rco.map_err(|e| SimError::Rco(e.to_string()))
    }
}

/// `HI+ST+AV+SC` or `none`.
pub fn modules_label(m: &Modules) -> String {
    let mut parts = Vec::new();
    if m.hazard_inference {
        parts.push("HI");
    }
    if m.motion_planner {
        parts.push("ST");
    }
    if m.verifier {
        parts.push("AV");
    }
    if m.safety_constraints {
        parts.push("SC");
    }
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join("+")
    }
}

/// One experiment configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Config {
    /// Unique name (`no_deficit`, `traffic_light/no_rco`, `bicycle/rco/hi+st`, …).
    pub name: String,
    /// The deficit, if any.
    pub deficit: Option<DeficitKind>,
    /// The RCO take-over, if any.
    pub rco: Option<RcoSetup>,
    /// A ramps configuration: the condition ramp of each route and who hands the car to
    /// the override ([`crate::ramp`]); with [`GuardMode::None`] `rco` is none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guard: Option<GuardMode>,
    /// The envelope the ramps' guard and oracle judge by (None: the reference planner's,
    /// [`crate::ramp::reference_odd`]).
    #[serde(skip)]
    pub odd: Option<Arc<OddSpec>>,
}

impl Config {
    /// The scoring of this configuration: Leaderboard 1.0's coefficients with `stop_sign`
    /// as given, and (as in the paper) red lights excluded under a traffic-light deficit
    /// and stop signs under a stop-sign deficit.
    pub fn scoring(&self, stop_sign_penalty: f64) -> ScoringParams {
        let mut s = ScoringParams {
            stop_sign: stop_sign_penalty,
            ..ScoringParams::default()
        };
        match self.deficit {
            Some(DeficitKind::TrafficLight) => s.red_light = 1.0,
            Some(DeficitKind::StopSign) => s.stop_sign = 1.0,
            _ => {}
        }
        s
    }

    /// No deficit, no RCO.
    pub fn no_deficit() -> Self {
        Self {
            name: "no_deficit".into(),
            deficit: None,
            rco: None,
            guard: None,
            odd: None,
        }
    }

    /// A deficit without the take-over.
    pub fn deficit(kind: DeficitKind) -> Self {
        Self {
            name: format!("{}/no_rco", kind.name()),
            deficit: Some(kind),
            rco: None,
            guard: None,
            odd: None,
        }
    }

    /// A deficit with the RCO take-over.
    pub fn with_rco(kind: DeficitKind, setup: RcoSetup) -> Self {
        let default = RcoSetup {
            backend: setup.backend.clone(),
            ..RcoSetup::default()
        };
        let mut name = format!("{}/rco", kind.name());
        if setup.modules != default.modules {
            name.push('/');
            name.push_str(&setup.modules_label().to_lowercase());
        }
        if setup.plan_limit != default.plan_limit {
            name.push_str(&format!("/limit{}", setup.plan_limit));
        }
        Self {
            name,
            deficit: Some(kind),
            rco: Some(setup),
            guard: None,
            odd: None,
        }
    }

    /// A ramps configuration: every route with its condition ramp, the override (set up as
    /// `setup`) handed the car as `mode` says.
    pub fn ramps(mode: GuardMode, setup: RcoSetup) -> Self {
        Self {
            name: mode.config_name().into(),
            deficit: None,
            rco: (mode != GuardMode::None).then_some(setup),
            guard: Some(mode),
            odd: None,
        }
    }
}

/// Named sets of configurations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConfigSet {
    /// Tables 1 and 2: no deficit; each deficit without and with RCO (9 configurations).
    Main,
    /// Table 3: the module ablation under the bicycle deficit (none, ST, HI+ST, HI+ST+AV, all).
    Ablation,
    /// Figure 8: the planning step-limit sweep (1, 3, 5, 8, 12) for every deficit.
    Sweep,
    /// Condition ramps (noise, darkness, fog rising and falling mid-route): no guard, the
    /// monitor-driven guard, the oracle hand-over, the override always on.
    Ramps,
}

impl ConfigSet {
    /// Parses `main`, `ablation`, `sweep`, `ramps`.
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim() {
            "main" => Some(Self::Main),
            "ablation" => Some(Self::Ablation),
            "sweep" => Some(Self::Sweep),
            "ramps" => Some(Self::Ramps),
            _ => None,
        }
    }

    /// The name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Main => "main",
            Self::Ablation => "ablation",
            Self::Sweep => "sweep",
            Self::Ramps => "ramps",
        }
    }
}

/// The ablation rows of table 3 (module switches).
pub fn ablation_rows() -> Vec<Modules> {
    let m = |hi, st, av, sc| Modules {
        hazard_inference: hi,
        motion_planner: st,
        verifier: av,
        safety_constraints: sc,
    };
    vec![
        m(false, false, false, false),
        m(false, true, false, false),
        m(true, true, false, false),
        m(true, true, true, false),
        m(true, true, true, true),
    ]
}

/// The step limits of the sweep.
pub const SWEEP_LIMITS: [usize; 5] = [1, 3, 5, 8, 12];

/// The configurations of `sets` (deduplicated by name, in order), the RCO ones with
/// `backend`.
pub fn configs(
    sets: &[ConfigSet],
    deficits: &[DeficitKind],
    backend: &BackendSetup,
) -> Vec<Config> {
    let mut out: Vec<Config> = Vec::new();
    let mut push = |c: Config| {
        if !out.iter().any(|o| o.name == c.name) {
            out.push(c);
        }
    };
    let setup = |modules, plan_limit| RcoSetup {
        modules,
        plan_limit,
        backend: backend.clone(),
    };
    for set in sets {
        match set {
            ConfigSet::Main => {
                push(Config::no_deficit());
                for &k in deficits {
                    push(Config::deficit(k));
                    push(Config::with_rco(k, setup(Modules::default(), 5)));
                }
            }
            ConfigSet::Ablation => {
                push(Config::deficit(DeficitKind::Bicycle));
                for m in ablation_rows() {
                    push(Config::with_rco(DeficitKind::Bicycle, setup(m, 5)));
                }
            }
            ConfigSet::Sweep => {
                for &k in deficits {
                    push(Config::deficit(k));
                    for l in SWEEP_LIMITS {
                        push(Config::with_rco(k, setup(Modules::default(), l)));
                    }
                }
            }
            ConfigSet::Ramps => {
                for mode in GuardMode::ALL {
                    push(Config::ramps(mode, setup(Modules::default(), 5)));
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn main_set_has_nine_configurations() {
        let c = configs(&[ConfigSet::Main], &DeficitKind::ALL, &BackendSetup::Rules);
        assert_eq!(c.len(), 9);
        assert_eq!(c[0].name, "no_deficit");
        assert_eq!(c[2].name, "traffic_light/rco");
        let s = c[1].scoring(0.8);
        assert_eq!(s.red_light, 1.0);
        assert_eq!(s.stop_sign, 0.8);
        let s = c[3].scoring(0.8);
        assert_eq!(s.stop_sign, 1.0);
        assert_eq!(s.red_light, 0.7);
    }

    #[test]
    fn ablation_and_sweep_names_are_unique() {
        let c = configs(
            &[ConfigSet::Main, ConfigSet::Ablation, ConfigSet::Sweep],
            &DeficitKind::ALL,
            &BackendSetup::Rules,
        );
        let mut names: Vec<&str> = c.iter().map(|c| c.name.as_str()).collect();
        let n = names.len();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), n);
        assert!(names.contains(&"bicycle/rco/none"));
        assert!(names.contains(&"bicycle/rco/hi+st+av"));
        assert!(names.contains(&"pedestrian/rco/limit12"));
    }
}
