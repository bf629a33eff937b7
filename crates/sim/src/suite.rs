//! The route suite: towns and routes modelled on Longest6 (36 routes, six per town, about
//! 1.5 km on average, 686 m to 2842 m, each with its own weather × daylight), drawn from a
//! seed, or described in a suite file (TOML or JSON).
//!
//! ```toml
//! # suite.toml — every field is optional
//! name = "longest6-like"
//! towns = 6
//! routes_per_town = 6
//! min_route_m = 686.0
//! max_route_m = 2842.0
//! mean_route_m = 1500.0
//!
//! [town]            # grid and signal timing of every town
//! block_min_m = 80.0
//! block_max_m = 130.0
//!
//! [[routes]]        # explicit routes replace the generated ones
//! town = 0
//! length_m = 1200.0
//! weather = "hard_rain"
//! daylight = "night"
//! ```
//!
//! Route `k` of a generated suite lies in town `k / routes_per_town`, has weather
//! `k mod 6` and daylight `(k / 6 + k) mod 6` of Longest6's lists (so 36 routes cover all
//! 36 combinations), and a length from the quantiles of a triangular distribution on
//! `[min, max]` whose mode gives the asked mean, shuffled by the seed.

use std::path::Path;

use fogline_stats::seed::child;
use fogline_world::scene::Draw;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::route::{self, Route};
use crate::sense::{Daylight, Weather};
use crate::town::{Town, TownParams};

/// An explicit route of a suite file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RouteSpec {
    /// Its town's index.
    pub town: usize,
    /// Length, m.
    pub length_m: f64,
    /// Weather.
    pub weather: Weather,
    /// Daylight.
    pub daylight: Daylight,
}

/// What a suite holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SuiteParams {
    /// Its name.
    pub name: String,
    /// Towns.
    pub towns: usize,
    /// Routes per town (generated suites).
    pub routes_per_town: usize,
    /// Shortest route, m.
    pub min_route_m: f64,
    /// Longest route, m.
    pub max_route_m: f64,
    /// Mean route length, m.
    pub mean_route_m: f64,
    /// The towns' grid and signal timing.
    pub town: TownParams,
    /// Explicit routes (replace the generated ones when present).
    pub routes: Vec<RouteSpec>,
}

impl Default for SuiteParams {
    fn default() -> Self {
        Self::longest6()
    }
}

impl SuiteParams {
    /// The default suite: 6 towns × 6 routes, 686–2842 m, mean 1.5 km.
    pub fn longest6() -> Self {
        Self {
            name: "longest6-like".into(),
            towns: 6,
            routes_per_town: 6,
            min_route_m: 686.0,
            max_route_m: 2842.0,
            mean_route_m: 1500.0,
            town: TownParams::default(),
            routes: Vec::new(),
        }
    }

    /// The quick suite for CI and the demo: 2 towns × 2 routes of 350–550 m.
    pub fn quick() -> Self {
        Self {
            name: "quick".into(),
            towns: 2,
            routes_per_town: 2,
            min_route_m: 350.0,
            max_route_m: 550.0,
            mean_route_m: 450.0,
            town: TownParams {
                nx: 4,
                ny: 4,
                ..TownParams::default()
            },
            routes: Vec::new(),
        }
    }

    /// Reads a suite file (`.toml` or `.json`; unknown fields are errors).
    pub fn read(path: &Path) -> Result<Self, SimError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SimError::Suite {
            file: file.clone(),
            message: format!("cannot read it: {e}"),
        })?;
        let json = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        let p: SuiteParams = if json {
            serde_json::from_str(&text).map_err(|e| SimError::Suite {
                file: file.clone(),
                message: e.to_string(),
            })?
        } else {
            toml::from_str(&text).map_err(|e| SimError::Suite {
                file: file.clone(),
                message: e.to_string().trim_end().to_string(),
            })?
        };
        p.validate().map_err(|e| SimError::Suite {
            file,
            message: match e {
                SimError::Params(m) => m,
                other => other.to_string(),
            },
        })?;
        Ok(p)
    }

    /// Checks every field; the message names it.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |m: String| Err(SimError::Params(m));
        if !(1..=64).contains(&self.towns) {
            return bad(format!("towns = {}: must be within 1..=64", self.towns));
        }
        if self.routes.is_empty() && !(1..=64).contains(&self.routes_per_town) {
            return bad(format!(
                "routes_per_town = {}: must be within 1..=64",
                self.routes_per_town
            ));
        }
        let lens_ok = self.min_route_m.is_finite()
            && self.max_route_m.is_finite()
            && self.mean_route_m.is_finite()
            && self.min_route_m >= 100.0
            && self.max_route_m <= 10_000.0
            && self.min_route_m <= self.mean_route_m
            && self.mean_route_m <= self.max_route_m;
        if !lens_ok {
            return bad(format!(
                "route lengths: need 100 <= min_route_m ({}) <= mean_route_m ({}) <= max_route_m ({}) <= 10000",
                self.min_route_m, self.mean_route_m, self.max_route_m
            ));
        }
        let t = &self.town;
        if !(2..=12).contains(&t.nx) || !(2..=12).contains(&t.ny) {
            return bad(format!(
                "town.nx = {}, town.ny = {}: each must be within 2..=12",
                t.nx, t.ny
            ));
        }
        if !(t.block_min_m >= 40.0 && t.block_min_m <= t.block_max_m && t.block_max_m <= 400.0) {
            return bad(format!(
                "town.block_min_m = {}, town.block_max_m = {}: need 40 <= min <= max <= 400",
                t.block_min_m, t.block_max_m
            ));
        }
        if !(0.0..=1.0).contains(&t.signal_share) {
            return bad(format!(
                "town.signal_share = {}: must be within [0, 1]",
                t.signal_share
            ));
        }
        for (name, v) in [
            ("town.green_s", t.green_s),
            ("town.amber_s", t.amber_s),
            ("town.all_red_s", t.all_red_s),
        ] {
            if !(v.is_finite() && (0.5..=300.0).contains(&v)) {
                return bad(format!("{name} = {v}: must be within 0.5..=300 s"));
            }
        }
        for (i, r) in self.routes.iter().enumerate() {
            if r.town >= self.towns {
                return bad(format!(
                    "routes[{i}].town = {}: the suite has {} town(s) (0-based)",
                    r.town, self.towns
                ));
            }
            if !(r.length_m.is_finite() && (100.0..=10_000.0).contains(&r.length_m)) {
                return bad(format!(
                    "routes[{i}].length_m = {}: must be within 100..=10000 m",
                    r.length_m
                ));
            }
        }
        Ok(())
    }

    /// Routes in the suite.
    pub fn n_routes(&self) -> usize {
        if self.routes.is_empty() {
            self.towns * self.routes_per_town
        } else {
            self.routes.len()
        }
    }

    fn town_params(&self, t: usize) -> TownParams {
        // Towns differ in size as well as layout.
        let mut p = self.town;
        if self.routes.is_empty() {
            p.nx = (p.nx + t % 3).saturating_sub(1).max(3);
            p.ny = (p.ny + (t + 1) % 3).saturating_sub(1).max(3);
        }
        p
    }

    /// The route specifications (explicit, or generated from `seed`).
    pub fn specs(&self, seed: u64) -> Vec<RouteSpec> {
        if !self.routes.is_empty() {
            return self.routes.clone();
        }
        let n = self.n_routes();
        let (a, b) = (self.min_route_m, self.max_route_m);
        let c = (3.0 * self.mean_route_m - a - b).clamp(a, b);
        let mut lengths: Vec<f64> = (0..n)
            .map(|k| triangular_quantile((k as f64 + 0.5) / n as f64, a, b, c))
            .collect();
        // Shuffle (Fisher–Yates) with the seed.
        let mut d = Draw::new(seed, &[0x5017E]);
        for i in (1..n).rev() {
            let j = d.index(i + 1);
            lengths.swap(i, j);
        }
        (0..n)
            .map(|k| RouteSpec {
                town: k / self.routes_per_town,
                length_m: lengths[k].round(),
                weather: Weather::ALL[k % 6],
                daylight: Daylight::ALL[(k / 6 + k) % 6],
            })
            .collect()
    }
}

fn triangular_quantile(u: f64, a: f64, b: f64, c: f64) -> f64 {
    if b - a < 1e-9 {
        return a;
    }
    let fc = (c - a) / (b - a);
    if u < fc {
        a + (u * (b - a) * (c - a)).sqrt()
    } else {
        b - ((1.0 - u) * (b - a) * (b - c)).sqrt()
    }
}

/// A route to drive: the town it is in, the route, the weather and daylight, its seed.
#[derive(Debug, Clone)]
pub struct RouteCase {
    /// Index in the suite.
    pub id: usize,
    /// Index of its town.
    pub town: usize,
    /// The route.
    pub route: Route,
    /// Weather.
    pub weather: Weather,
    /// Daylight.
    pub daylight: Daylight,
    /// Seed of its traffic.
    pub seed: u64,
}

/// A built suite: its towns and routes.
#[derive(Debug, Clone)]
pub struct Suite {
    /// The parameters it was built from.
    pub params: SuiteParams,
    /// The seed.
    pub seed: u64,
    /// Towns.
    pub towns: Vec<Town>,
    /// Routes.
    pub cases: Vec<RouteCase>,
}

impl Suite {
    /// Builds the towns and routes of `params` from `seed`, with `events_per_km` crossing
    /// events per km of route.
    pub fn build(params: &SuiteParams, seed: u64, events_per_km: f64) -> Result<Self, SimError> {
        params.validate()?;
        let towns: Vec<Town> = (0..params.towns)
            .map(|t| Town::generate(params.town_params(t), seed, t as u64))
            .collect();
        let cases = params
            .specs(seed)
            .into_iter()
            .enumerate()
            .map(|(k, spec)| {
                let mut d = Draw::new(seed, &[0x2007E, k as u64]);
                let route: Route =
                    route::generate(&towns[spec.town], spec.length_m, events_per_km, &mut d)?;
                Ok(RouteCase {
                    id: k,
                    town: spec.town,
                    route,
                    weather: spec.weather,
                    daylight: spec.daylight,
                    seed: child(seed, &[k as u64]),
                })
            })
            .collect::<Result<Vec<_>, SimError>>()?;
        Ok(Self {
            params: params.clone(),
            seed,
            towns,
            cases,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn longest6_like_lengths_and_conditions() {
        let p = SuiteParams::longest6();
        let specs = p.specs(0);
        assert_eq!(specs.len(), 36);
        let mean = specs.iter().map(|s| s.length_m).sum::<f64>() / 36.0;
        assert!((mean - 1500.0).abs() < 15.0, "{mean}");
        assert!(specs.iter().all(|s| (686.0..=2842.0).contains(&s.length_m)));
        let mut combos: Vec<(Weather, Daylight)> =
            specs.iter().map(|s| (s.weather, s.daylight)).collect();
        combos.sort();
        combos.dedup();
        assert_eq!(combos.len(), 36);
        assert_eq!(specs[35].town, 5);
    }

    #[test]
    fn invalid_fields_are_named() {
        let mut p = SuiteParams::longest6();
        p.min_route_m = 50.0;
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("min_route_m"), "{e}");
        let mut p = SuiteParams::longest6();
        p.routes.push(RouteSpec {
            town: 9,
            length_m: 500.0,
            weather: Weather::Wet,
            daylight: Daylight::Noon,
        });
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("routes[0].town"), "{e}");
    }
}
