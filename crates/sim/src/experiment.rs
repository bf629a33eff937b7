//! Experiments: every configuration on every route of a suite for every seed, in parallel,
//! and the summaries shaped like the paper's tables 1–3 and figure 8.
//!
//! Each run is a pure function of (suite, route, configuration, seed, run parameters): the
//! runs are spread over a thread pool and collected in a fixed order, so the results do not
//! depend on the number of threads (only the recorded wall-clock times do).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use fogline_types::planner::Planner;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::config::{Config, modules_label};
use crate::run::{Limit, RouteRecord, RunParams, run_route_with};
use crate::score::{EventKind, MeanStd, RouteScore, infractions_per_km};
use crate::sense::DeficitKind;
use crate::suite::{Suite, SuiteParams};

/// What to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExperimentParams {
    /// The suite.
    pub suite: SuiteParams,
    /// Seeds (each seed draws its own towns, routes and traffic).
    pub seeds: Vec<u64>,
    /// The configurations.
    pub configs: Vec<Config>,
    /// Cameras, agent, dynamics, traffic, scoring.
    pub run: RunParams,
    /// Table 2's system-time limit, s (the paper: 30 minutes).
    pub system_time_limit_s: f64,
    /// Latency counted per LLM call for system time, ms (`None`: the measured latency).
    pub llm_latency_ms: Option<f64>,
    /// Only these routes of the suite (0-based; `None`: all), e.g. to re-run one route with
    /// trace logging.
    #[serde(default)]
    pub routes: Option<Vec<usize>>,
}

impl ExperimentParams {
    /// Whether `record` ran under a configuration with a deficit (the runs the suite's speed
    /// goal counts).
    pub fn is_deficit_run(&self, record: &RouteRecord) -> bool {
        self.configs
            .iter()
            .any(|c| c.name == record.config && c.deficit.is_some())
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), SimError> {
        self.suite.validate()?;
        self.run.sensors.validate()?;
        self.run.bicycle.validate()?;
        if let Some(r) = &self.routes {
            let n = self.suite.n_routes();
            if let Some(bad) = r.iter().find(|&&k| k >= n) {
                return Err(SimError::Params(format!(
                    "route {bad}: the suite has {n} route(s) (0-based)"
                )));
            }
            if r.is_empty() {
                return Err(SimError::Params("the route list is empty".into()));
            }
        }
        if self.seeds.is_empty() {
            return Err(SimError::Params("at least one seed is needed".into()));
        }
        if self.configs.is_empty() {
            return Err(SimError::Params(
                "at least one configuration is needed".into(),
            ));
        }
        if !(self.system_time_limit_s.is_finite() && self.system_time_limit_s > 0.0) {
            return Err(SimError::Params(format!(
                "system_time_limit_s = {}: must be positive",
                self.system_time_limit_s
            )));
        }
        if let Some(ms) = self.llm_latency_ms
            && !(ms.is_finite() && ms >= 0.0)
        {
            return Err(SimError::Params(format!(
                "llm_latency_ms = {ms}: must be finite and >= 0"
            )));
        }
        if !(0.0..=1.0).contains(&self.run.stop_sign_penalty) {
            return Err(SimError::Params(format!(
                "stop_sign_penalty = {}: must be within [0, 1]",
                self.run.stop_sign_penalty
            )));
        }
        Ok(())
    }

    /// The system-time limit of table 2 as a [`Limit`].
    pub fn system_limit(&self) -> Limit {
        Limit {
            game_time_s: None,
            system_time_s: Some(self.system_time_limit_s),
            llm_latency_ms: self.llm_latency_ms,
        }
    }
}

/// Everything an experiment produced.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Results {
    /// Who drove: the baseline's rules, or the planner under test (its description).
    #[serde(default)]
    pub driver: String,
    /// The parameters.
    pub params: ExperimentParams,
    /// One record per (seed, configuration, route), in that order.
    pub records: Vec<RouteRecord>,
    /// The summaries.
    pub summary: Summary,
    /// Wall-clock time of all runs, s (not deterministic).
    pub wall_s: f64,
    /// Worker threads used (not part of the results' identity).
    pub threads: usize,
    /// Problems found before running (e.g. an unreachable LLM endpoint: its queries fall
    /// back to decelerate-to-stop, counted in the records).
    pub warnings: Vec<String>,
}

/// Runs every configuration on every route for every seed with `threads` workers (0: the
/// current rayon pool), calling `progress(done, total)` after each run.
pub fn run_experiment(
    params: &ExperimentParams,
    threads: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Results, SimError> {
    run_experiment_with(params, None, threads, progress)
}

/// [`run_experiment`] with a planner under test driving every run instead of the
/// baseline's rules (`None`: the baseline; see [`crate::agent::Baseline::driven_by`]).
pub fn run_experiment_with(
    params: &ExperimentParams,
    driver: Option<Arc<dyn Planner>>,
    threads: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Results, SimError> {
    params.validate()?;
    let mut warnings: Vec<String> = Vec::new();
    for c in &params.configs {
        if let Some(r) = &c.rco {
            // Fail early on a backend that cannot even be set up; warn (and run: every
            // query then falls back safely) when its endpoint does not answer.
            r.build(params.run.sensors.agent_hz)?;
            if let Err(e) = r.backend.probe(2000) {
                let w = format!(
                    "LLM backend {}: {e}; every RCO query will fail and fall back to decelerate-to-stop (counted as fallbacks in the results)",
                    r.backend.describe()
                );
                if !warnings.contains(&w) {
                    log::warn!("{w}");
                    warnings.push(w);
                }
            }
        }
    }
    let suites: Vec<Suite> = params
        .seeds
        .iter()
        .map(|&seed| Suite::build(&params.suite, seed, params.run.traffic.events_per_km))
        .collect::<Result<_, _>>()?;
    let mut items: Vec<(usize, usize, usize)> = Vec::new();
    for (si, suite) in suites.iter().enumerate() {
        for ci in 0..params.configs.len() {
            for ri in 0..suite.cases.len() {
                if params.routes.as_ref().is_some_and(|r| !r.contains(&ri)) {
                    continue;
                }
                items.push((si, ci, ri));
            }
        }
    }
    let total = items.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let wall = Instant::now();
    let work = || {
        items
            .par_iter()
            .map(|&(si, ci, ri)| {
                let suite = &suites[si];
                let case = &suite.cases[ri];
                let r = run_route_with(
                    &suite.towns[case.town],
                    case,
                    &params.configs[ci],
                    &params.run,
                    params.seeds[si],
                    driver.as_ref(),
                );
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n, total);
                r
            })
            .collect::<Result<Vec<RouteRecord>, SimError>>()
    };
    let (records, used) = if threads == 0 {
        (work()?, rayon::current_num_threads())
    } else {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| SimError::Params(format!("cannot start {threads} threads: {e}")))?;
        (pool.install(work)?, threads)
    };
    let wall_s = wall.elapsed().as_secs_f64();
    let summary = Summary::of(params, &records);
    Ok(Results {
        driver: driver.map_or_else(
            || "the baseline's rules on the reference planner".to_string(),
            |d| d.describe(),
        ),
        params: params.clone(),
        records,
        summary,
        wall_s,
        threads: used,
        warnings,
    })
}

/// Mean ± std of one metric: over every route run, and over the seeds' route means.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stat {
    /// Over every (route, seed) run.
    pub by_route: MeanStd,
    /// Over the per-seed means (`None` with a single seed).
    pub by_seed: Option<MeanStd>,
}

impl Stat {
    fn of(values: &[(u64, f64)]) -> Option<Self> {
        let all: Vec<f64> = values.iter().map(|v| v.1).collect();
        let by_route = MeanStd::of(&all)?;
        let mut per: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
        for (s, v) in values {
            per.entry(*s).or_default().push(*v);
        }
        let by_seed = if per.len() >= 2 {
            let means: Vec<f64> = per
                .values()
                .map(|v| v.iter().sum::<f64>() / v.len() as f64)
                .collect();
            MeanStd::of(&means)
        } else {
            None
        };
        Some(Self { by_route, by_seed })
    }

    /// The mean and the std shown in tables: over seeds when there are several, else over
    /// routes.
    pub fn shown(&self) -> MeanStd {
        self.by_seed.unwrap_or(self.by_route)
    }
}

/// The leaderboard metrics of one configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Route completion, %.
    pub route_completion: Stat,
    /// Infraction score.
    pub infraction_score: Stat,
    /// Driving score.
    pub driving_score: Stat,
    /// Average speed (route length driven / game time), m/s.
    pub avg_speed_mps: Stat,
    /// Runs.
    pub runs: usize,
}

/// One configuration's summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConfigSummary {
    /// The configuration's name.
    pub config: String,
    /// Its deficit.
    pub deficit: Option<DeficitKind>,
    /// Its RCO modules (`None`: no RCO).
    pub rco_modules: Option<String>,
    /// Its planning step limit (RCO configurations).
    pub plan_limit: Option<usize>,
    /// Unlimited game time (the route's own timeout only): table 1.
    pub unlimited: Metrics,
    /// With the system-time limit: table 2.
    pub system_limited: Metrics,
    /// Infractions per km driven, by kind (every infraction, also those the scoring
    /// excludes).
    pub infractions_per_km: BTreeMap<EventKind, f64>,
    /// How the runs ended: count per termination.
    pub terminations: BTreeMap<String, usize>,
    /// Red-light behaviour on the routes' signalised approaches.
    pub signals: SignalSummary,
    /// Share of game time with a deficit present.
    pub deficit_share: f64,
    /// Share of game time the RCO controller drove.
    pub takeover_share: f64,
    /// LLM (backend) calls, all runs.
    pub llm_calls: u64,
    /// Measured backend latency per call, ms.
    pub llm_ms_per_call: Option<f64>,
    /// RCO fallbacks, all runs.
    pub fallbacks: u64,
    /// Times the baseline's unstick rule fired (it stood `unstick_after_s`, 55 s by default,
    /// and was moved on), all runs: where a deficit costs time rather than score (a masked
    /// sign read as a red light that never turns green).
    #[serde(default)]
    pub unstick: u64,
    /// Wall-clock time of its runs, s (not deterministic).
    pub wall_s: f64,
}

/// Red-light behaviour summed over runs.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SignalSummary {
    /// Signalised approaches reached.
    pub approaches: u32,
    /// Approaches with a red light while the ego was within 40 m of the stop line.
    pub red_encounters: u32,
    /// Of those, how many the ego stood still before the line.
    pub stopped_at_red: u32,
    /// Red-light infractions.
    pub red_light_infractions: u32,
    /// `stopped_at_red / red_encounters`.
    pub stop_rate: Option<f64>,
    /// Red-light infractions per km driven.
    pub red_lights_per_km: f64,
}

/// One row of the step-limit sweep: the change against the same deficit without RCO.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepRow {
    /// The deficit.
    pub deficit: DeficitKind,
    /// The planning step limit.
    pub plan_limit: usize,
    /// ΔRC, ΔIS, ΔDS (means; RCO minus no RCO), with the system-time limit.
    pub delta_limited: [f64; 3],
    /// The same without the limit.
    pub delta_unlimited: [f64; 3],
}

/// The paired per-route difference of the driving score (unlimited game time), the
/// override's configuration minus the same deficit without it: the routes (and seeds) are
/// the same, so each route is its own control.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedDiff {
    /// The deficit.
    pub deficit: DeficitKind,
    /// The configuration with the override.
    pub config: String,
    /// The configuration without it.
    pub baseline: String,
    /// Routes × seeds paired.
    pub pairs: usize,
    /// Mean of the per-route differences (DS points).
    pub mean: f64,
    /// The 95 % percentile bootstrap interval of the mean ([`BOOTSTRAP_RESAMPLES`]
    /// resamples of the pairs, seeded by [`BOOTSTRAP_SEED`]; numpy-linear percentiles).
    pub ci95: [f64; 2],
    /// Collisions (vehicles, pedestrians, layout) per km driven: without, with the override.
    pub collisions_per_km: [f64; 2],
}

/// A ramps configuration against no guard, paired by route (DS, unlimited game time).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RampPaired {
    /// The configuration (`ramps/guard`, `ramps/oracle`, `ramps/rco`).
    pub config: String,
    /// Routes × seeds paired.
    pub pairs: usize,
    /// Mean of the per-route differences against `ramps/no_guard` (DS points).
    pub mean: f64,
    /// Its 95 % percentile bootstrap interval (as [`PairedDiff::ci95`]).
    pub ci95: [f64; 2],
    /// Collisions per km: no guard, this configuration.
    pub collisions_per_km: [f64; 2],
}

/// One route of the ramps: its condition and how long each configuration was in override.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RampRoute {
    /// Seed.
    pub seed: u64,
    /// Route.
    pub route: usize,
    /// The ramp.
    pub ramp: crate::ramp::Ramp,
    /// Game time with the true condition outside the envelope, s (the oracle's run).
    pub out_s: Option<f64>,
    /// Per configuration (`ramps/guard`, `ramps/oracle`, `ramps/rco`): game time in
    /// override, s.
    pub override_s: BTreeMap<String, f64>,
    /// Per configuration (all four): the route's driving score.
    pub driving_score: BTreeMap<String, f64>,
}

/// A configuration's runs by seed and route.
type ByRoute<'a> = BTreeMap<(u64, usize), &'a RouteRecord>;

/// The runs of configuration `name` by seed and route.
fn by_route<'a>(records: &'a [RouteRecord], name: &str) -> ByRoute<'a> {
    records
        .iter()
        .filter(|r| r.config == name)
        .map(|r| ((r.seed, r.route), r))
        .collect()
}

/// The per-route DS differences `with − base` over the runs both have.
fn ds_differences(base: &ByRoute<'_>, with: &ByRoute<'_>) -> Vec<f64> {
    with.iter()
        .filter_map(|(k, r)| {
            base.get(k)
                .map(|b| r.score.driving_score - b.score.driving_score)
        })
        .collect()
}

/// Collisions per km of configuration `name` (0 when it did not run).
fn collisions_of(configs: &[ConfigSummary], name: &str) -> f64 {
    configs.iter().find(|c| c.config == name).map_or(0.0, |c| {
        crate::score::collisions_per_km(&c.infractions_per_km)
    })
}

/// The ramps' comparison: each guard configuration against no guard, the monitor-driven
/// guard against the oracle, and the time in override per route.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RampsSummary {
    /// Guard, oracle and always-on override against no guard.
    pub paired: Vec<RampPaired>,
    /// Mean DS of the monitor-driven guard over that of the oracle hand-over.
    pub guard_to_oracle: Option<f64>,
    /// Per route and seed.
    pub routes: Vec<RampRoute>,
}

impl RampsSummary {
    /// The mean over routes of what `f` gives (None when it gives nothing).
    pub fn mean_over_routes(&self, f: impl Fn(&RampRoute) -> Option<f64>) -> Option<f64> {
        let v: Vec<f64> = self.routes.iter().filter_map(f).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    }

    /// The summary of the ramps configurations in `records` (None when `ramps/no_guard`
    /// did not run).
    pub fn of(configs: &[ConfigSummary], records: &[RouteRecord]) -> Option<Self> {
        use crate::ramp::GuardMode;
        let base = GuardMode::None.config_name();
        configs.iter().find(|c| c.config == base)?;
        let of = |name: &str| by_route(records, name);
        let none = of(base);
        let collisions = |name: &str| collisions_of(configs, name);
        let mut paired = Vec::new();
        for mode in [GuardMode::Monitor, GuardMode::Oracle, GuardMode::Always] {
            let name = mode.config_name();
            let d = ds_differences(&none, &of(name));
            let Some((mean, ci95)) = paired_bootstrap(&d, BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED)
            else {
                continue;
            };
            paired.push(RampPaired {
                config: name.into(),
                pairs: d.len(),
                mean,
                ci95,
                collisions_per_km: [collisions(base), collisions(name)],
            });
        }
        let mean_ds = |name: &str| {
            configs
                .iter()
                .find(|c| c.config == name)
                .map(|c| c.unlimited.driving_score.by_route.mean)
        };
        let guard_to_oracle = match (
            mean_ds(GuardMode::Monitor.config_name()),
            mean_ds(GuardMode::Oracle.config_name()),
        ) {
            (Some(g), Some(o)) if o > 0.0 => Some(g / o),
            _ => None,
        };
        let by_mode: Vec<(GuardMode, ByRoute<'_>)> = GuardMode::ALL
            .iter()
            .map(|m| (*m, of(m.config_name())))
            .collect();
        let routes = none
            .iter()
            .filter_map(|(&(seed, route), r)| {
                let ramp = r.ramp?;
                let mut override_s = BTreeMap::new();
                let mut driving_score = BTreeMap::new();
                let mut out_s = None;
                for (m, recs) in &by_mode {
                    let Some(x) = recs.get(&(seed, route)) else {
                        continue;
                    };
                    driving_score.insert(m.config_name().to_string(), x.score.driving_score);
                    if *m != GuardMode::None {
                        override_s.insert(m.config_name().to_string(), x.takeover_s);
                    }
                    if *m == GuardMode::Oracle {
                        out_s = Some(x.deficit_s);
                    }
                }
                Some(RampRoute {
                    seed,
                    route,
                    ramp,
                    out_s,
                    override_s,
                    driving_score,
                })
            })
            .collect();
        Some(Self {
            paired,
            guard_to_oracle,
            routes,
        })
    }
}

/// Resamples of the paired bootstrap.
pub const BOOTSTRAP_RESAMPLES: usize = 10_000;
/// The paired bootstrap's seed (fixed: the interval is a function of the records).
pub const BOOTSTRAP_SEED: u64 = 0x5EED_0017;

/// The mean of `d` and its 95 % percentile bootstrap interval (`resamples` resamples with
/// replacement, drawn from `seed`; numpy's linear percentile of the sorted resample means).
/// `None` for no data.
pub fn paired_bootstrap(d: &[f64], resamples: usize, seed: u64) -> Option<(f64, [f64; 2])> {
    if d.is_empty() || resamples == 0 {
        return None;
    }
    let n = d.len();
    let mean = d.iter().sum::<f64>() / n as f64;
    let mut rng = fogline_stats::seed::Xoshiro256pp::new(seed, &[n as u64]);
    let mut means: Vec<f64> = (0..resamples)
        .map(|_| {
            let mut sum = 0.0;
            for _ in 0..n {
                // An index uniform on 0..n (multiply-high: no modulo bias worth the name).
                let i = ((u128::from(rng.next_u64()) * n as u128) >> 64) as usize;
                sum += d[i];
            }
            sum / n as f64
        })
        .collect();
    means.sort_by(f64::total_cmp);
    let pct = |q: f64| {
        let pos = q * (means.len() - 1) as f64;
        let lo = pos.floor() as usize;
        let hi = pos.ceil() as usize;
        means[lo] + (means[hi] - means[lo]) * (pos - lo as f64)
    };
    Some((mean, [pct(0.025), pct(0.975)]))
}

/// Everything the tables show.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Per configuration, in the order given.
    pub configs: Vec<ConfigSummary>,
    /// The override against no override under each deficit, paired by route (configurations
    /// with the full override and the default step limit).
    #[serde(default)]
    pub paired: Vec<PairedDiff>,
    /// The step-limit sweep (figure 8), when its configurations ran.
    pub sweep: Vec<SweepRow>,
    /// Condition ramps, when their configurations ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ramps: Option<RampsSummary>,
    /// Wall-clock seconds of the runs with a deficit (the full-suite timing), summed over
    /// runs (divide by threads for the elapsed time), not deterministic.
    pub deficit_runs_wall_s: f64,
}

impl Summary {
    /// Summarises `records` of `params`.
    pub fn of(params: &ExperimentParams, records: &[RouteRecord]) -> Self {
        let limit = params.system_limit();
        let mut configs = Vec::new();
        for c in &params.configs {
            let scoring = c.scoring(params.run.stop_sign_penalty);
            let rs: Vec<&RouteRecord> = records.iter().filter(|r| r.config == c.name).collect();
            if rs.is_empty() {
                continue;
            }
            let unl: Vec<(u64, RouteScore, f64)> = rs
                .iter()
                .map(|r| (r.seed, r.score, r.avg_speed_mps))
                .collect();
            let lim: Vec<(u64, RouteScore, f64)> = rs
                .iter()
                .map(|r| {
                    let (s, _, _) = r.limited(&limit, &scoring);
                    (r.seed, s, r.avg_speed_mps)
                })
                .collect();
            let per_km = infractions_per_km(
                &rs.iter()
                    .map(|r| (r.events.as_slice(), r.score.route_completion, r.length_m))
                    .collect::<Vec<_>>(),
            );
            let mut terminations: BTreeMap<String, usize> = BTreeMap::new();
            for r in &rs {
                let k = serde_json::to_value(r.termination)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default();
                *terminations.entry(k).or_default() += 1;
            }
            let mut sig = SignalSummary::default();
            for r in &rs {
                sig.approaches += r.signals.approaches;
                sig.red_encounters += r.signals.red_encounters;
                sig.stopped_at_red += r.signals.stopped_at_red;
                sig.red_light_infractions += r.signals.crossed_on_red;
            }
            sig.stop_rate = (sig.red_encounters > 0)
                .then(|| f64::from(sig.stopped_at_red) / f64::from(sig.red_encounters));
            sig.red_lights_per_km = per_km.get(&EventKind::RedLight).copied().unwrap_or(0.0);
            let game: f64 = rs.iter().map(|r| r.game_time_s).sum();
            let calls: u64 = rs
                .iter()
                .filter_map(|r| r.rco.as_ref())
                .map(|s| s.llm_calls)
                .sum();
            let ms: f64 = rs
                .iter()
                .filter_map(|r| r.rco.as_ref())
                .map(|s| s.llm_latency_ms)
                .sum();
            configs.push(ConfigSummary {
                config: c.name.clone(),
                deficit: c.deficit,
                rco_modules: c.rco.as_ref().map(|r| modules_label(&r.modules)),
                plan_limit: c.rco.as_ref().map(|r| r.plan_limit),
                unlimited: metrics(&unl),
                system_limited: metrics(&lim),
                infractions_per_km: per_km,
                terminations,
                signals: sig,
                deficit_share: rs.iter().map(|r| r.deficit_s).sum::<f64>() / game.max(1e-9),
                takeover_share: rs.iter().map(|r| r.takeover_s).sum::<f64>() / game.max(1e-9),
                llm_calls: calls,
                llm_ms_per_call: (calls > 0).then(|| ms / calls as f64),
                fallbacks: rs
                    .iter()
                    .filter_map(|r| r.rco.as_ref())
                    .map(|s| s.fallbacks_total())
                    .sum(),
                unstick: rs.iter().map(|r| u64::from(r.unstick)).sum(),
                wall_s: rs.iter().map(|r| r.wall_s).sum(),
            });
        }
        let mut sweep = Vec::new();
        for k in DeficitKind::ALL {
            let base = configs
                .iter()
                .find(|c| c.deficit == Some(k) && c.rco_modules.is_none());
            let Some(base) = base else { continue };
            let full = "HI+ST+AV+SC";
            let mut rows: Vec<&ConfigSummary> = configs
                .iter()
                .filter(|c| c.deficit == Some(k) && c.rco_modules.as_deref() == Some(full))
                .collect();
            if rows.len() < 2 {
                continue;
            }
            rows.sort_by_key(|c| c.plan_limit);
            for c in rows {
                let d = |a: &Metrics, b: &Metrics| {
                    [
                        a.route_completion.by_route.mean - b.route_completion.by_route.mean,
                        a.infraction_score.by_route.mean - b.infraction_score.by_route.mean,
                        a.driving_score.by_route.mean - b.driving_score.by_route.mean,
                    ]
                };
                sweep.push(SweepRow {
                    deficit: k,
                    plan_limit: c.plan_limit.unwrap_or(0),
                    delta_limited: d(&c.system_limited, &base.system_limited),
                    delta_unlimited: d(&c.unlimited, &base.unlimited),
                });
            }
        }
        let mut paired = Vec::new();
        for k in DeficitKind::ALL {
            let base = params
                .configs
                .iter()
                .find(|c| c.deficit == Some(k) && c.rco.is_none());
            let with = params.configs.iter().find(|c| {
                c.deficit == Some(k)
                    && c.rco.as_ref().is_some_and(|r| {
                        r.modules == fogline_rco::Modules::default() && r.plan_limit == 5
                    })
            });
            let (Some(base), Some(with)) = (base, with) else {
                continue;
            };
            let d = ds_differences(
                &by_route(records, &base.name),
                &by_route(records, &with.name),
            );
            let Some((mean, ci95)) = paired_bootstrap(&d, BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED)
            else {
                continue;
            };
            let collisions = |name: &str| collisions_of(&configs, name);
            paired.push(PairedDiff {
                deficit: k,
                config: with.name.clone(),
                baseline: base.name.clone(),
                pairs: d.len(),
                mean,
                ci95,
                collisions_per_km: [collisions(&base.name), collisions(&with.name)],
            });
        }
        let deficit_runs_wall_s = records
            .iter()
            .filter(|r| params.is_deficit_run(r))
            .map(|r| r.wall_s)
            // (`sum` of no values is −0.0, which prints as "-0.0")
            .fold(0.0, |a, b| a + b);
        let ramps = RampsSummary::of(&configs, records);
        Self {
            configs,
            paired,
            sweep,
            ramps,
            deficit_runs_wall_s,
        }
    }

    /// The summary of configuration `name`.
    pub fn config(&self, name: &str) -> Option<&ConfigSummary> {
        self.configs.iter().find(|c| c.config == name)
    }
}

fn metrics(v: &[(u64, RouteScore, f64)]) -> Metrics {
    let pick = |f: &dyn Fn(&(u64, RouteScore, f64)) -> f64| -> Stat {
        let vals: Vec<(u64, f64)> = v.iter().map(|x| (x.0, f(x))).collect();
        Stat::of(&vals).unwrap_or(Stat {
            by_route: MeanStd {
                mean: 0.0,
                std: 0.0,
                n: 0,
            },
            by_seed: None,
        })
    };
    Metrics {
        route_completion: pick(&|x| x.1.route_completion),
        infraction_score: pick(&|x| x.1.infraction_score),
        driving_score: pick(&|x| x.1.driving_score),
        avg_speed_mps: pick(&|x| x.2),
        runs: v.len(),
    }
}
