//! A route through a town: its junction movements, the dense route (one point per metre,
//! the leaderboard's route), the traffic controls along it, and the crossing events that a
//! route triggers (Longest6's scenario 3: a pedestrian or cyclist crossing in front).

use fogline_world::scene::Draw;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::geom::{P2, Poly, add, dist, right_of};
use crate::score::DenseRoute;
use crate::town::{Control, DIRS, LANE_W_M, LINE_TO_ZONE_M, Town, turn_of};

/// One junction the route passes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RouteJunction {
    /// The node.
    pub node: usize,
    /// Travel direction in.
    pub din: usize,
    /// Travel direction out.
    pub dout: usize,
    /// Route distance where the path through the junction starts, m.
    pub s_entry_m: f64,
    /// Route distance where it ends, m.
    pub s_exit_m: f64,
    /// Route distance of the approach's stop line, m.
    pub s_stop_line_m: f64,
    /// The junction's control.
    pub control: Control,
}

impl RouteJunction {
    /// 0 straight, 1 left, 3 right.
    pub fn turn(&self) -> usize {
        turn_of(self.din, self.dout)
    }
}

/// Someone crossing the road in front of the ego, triggered by its progress.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CrossingEvent {
    /// Route distance where the actor crosses, m.
    pub s_m: f64,
    /// The actor starts when the ego is this far before `s_m` (along the route), m.
    pub trigger_m: f64,
    /// A cyclist (else a pedestrian).
    pub cyclist: bool,
    /// Starts on the right sidewalk (else the left one).
    pub from_right: bool,
    /// Walking or riding speed, m/s.
    pub speed_mps: f64,
}

/// A route.
#[derive(Debug, Clone)]
pub struct Route {
    /// The dense route (the ego lane's centre, one point per metre).
    pub dense: DenseRoute,
    /// The path the dense route was sampled from.
    pub path: Poly,
    /// Junctions along it, in order.
    pub junctions: Vec<RouteJunction>,
    /// Crossing events, in order.
    pub events: Vec<CrossingEvent>,
    /// Start node and direction of the first lane.
    pub start: (usize, usize),
}

/// Draws a route of about `length_m` in `town` from `draw`: a start on a random lane, then
/// at every junction straight (weight 2), left or right (1 each) among the exits whose lane
/// the route has not used yet, until the length is reached. `events_per_km` crossing events
/// are placed on lane stretches at least 20 m from any junction.
pub fn generate(
    town: &Town,
    length_m: f64,
    events_per_km: f64,
    draw: &mut Draw,
) -> Result<Route, SimError> {
    if !(length_m.is_finite() && length_m >= 100.0) {
        return Err(SimError::Params(format!(
            "route length {length_m} m must be at least 100 m"
        )));
    }
    // Start lane.
    let mut candidates = Vec::new();
    for n in 0..town.nodes.len() {
        for d in 0..4 {
            if town.lane(n, d).is_some() {
                candidates.push((n, d));
            }
        }
    }
    let (n0, d0) = candidates[draw.index(candidates.len())];
    let mut used = vec![false; town.nodes.len() * 4];
    used[n0 * 4 + d0] = true;
    let first = town
        .lane(n0, d0)
        .ok_or_else(|| SimError::Params("start lane missing".into()))?;
    let start_s = first.length() * draw.range(0.2, 0.5);
    let mut path = Poly::new(Vec::new());
    // The start lane from start_s.
    let (p_start, _) = first.pose(start_s);
    path.extend(&Poly::new(
        std::iter::once(p_start)
            .chain(
                first
                    .pts
                    .iter()
                    .zip(&first.s)
                    .filter(|(_, s)| **s > start_s + 0.5)
                    .map(|(p, _)| *p),
            )
            .collect(),
    ));
    let mut junctions = Vec::new();
    let (mut node, mut din) = (
        town.neighbor(n0, d0)
            .ok_or_else(|| SimError::Params("start lane has no end".into()))?,
        d0,
    );
    while path.length() < length_m {
        let exits = town.exits(node, din);
        let fresh: Vec<usize> = exits
            .iter()
            .copied()
            .filter(|&d| !used[node * 4 + d])
            .collect();
        let pool = if fresh.is_empty() { exits } else { fresh };
        let weights: Vec<f64> = pool
            .iter()
            .map(|&d| if d == din { 2.0 } else { 1.0 })
            .collect();
        let total: f64 = weights.iter().sum();
        let mut u = draw.unit() * total;
        let mut dout = pool[pool.len() - 1];
        for (k, w) in weights.iter().enumerate() {
            if u < *w {
                dout = pool[k];
                break;
            }
            u -= w;
        }
        let conn = town
            .connector(node, din, dout)
            .ok_or_else(|| SimError::Params("missing connector".into()))?;
        let s_entry = path.length();
        path.extend(conn);
        let s_exit = path.length();
        junctions.push(RouteJunction {
            node,
            din,
            dout,
            s_entry_m: s_entry,
            s_exit_m: s_exit,
            s_stop_line_m: s_entry - LINE_TO_ZONE_M,
            control: town.nodes[node].control,
        });
        used[node * 4 + dout] = true;
        let lane = town
            .lane(node, dout)
            .ok_or_else(|| SimError::Params("missing lane".into()))?;
        let remaining = length_m - path.length();
        if remaining <= lane.length() - 10.0 {
            // End on this lane.
            let end_s = remaining.max(5.0);
            let (p_end, _) = lane.pose(end_s);
            let mut pts: Vec<P2> = lane
                .pts
                .iter()
                .zip(&lane.s)
                .filter(|(_, s)| **s < end_s - 0.5)
                .map(|(p, _)| *p)
                .collect();
            pts.push(p_end);
            path.extend(&Poly::new(pts));
            break;
        }
        path.extend(lane);
        node = town
            .neighbor(node, dout)
            .ok_or_else(|| SimError::Params("lane without an end node".into()))?;
        din = dout;
    }
    // Dense route: one point per metre.
    let n = path.length().floor() as usize;
    let mut pts: Vec<P2> = (0..=n).map(|k| path.pose(k as f64).0).collect();
    let last = *path.pts.last().unwrap_or(&[0.0, 0.0]);
    if dist(last, pts[pts.len() - 1]) > 0.05 {
        pts.push(last);
    }
    let dense = DenseRoute::new(pts)?;
    // Crossing events on lane stretches away from junctions.
    let mut events = Vec::new();
    let total = path.length();
    let n_events = (events_per_km * total / 1000.0).round() as usize;
    if n_events > 0 {
        let spacing = total / n_events as f64;
        for k in 0..n_events {
            for _ in 0..20 {
                let s = spacing * (k as f64 + draw.range(0.25, 0.75));
                let near_junction = junctions
                    .iter()
                    .any(|j| s > j.s_stop_line_m - 25.0 && s < j.s_exit_m + 20.0);
                if s < 60.0 || s > total - 20.0 || near_junction {
                    continue;
                }
                let cyclist = draw.chance(0.4);
                let trigger_m = draw.range(22.0, 38.0);
                // From the sidewalk on the ego lane's side, as CARLA's scenario 3
                // (DynamicObjectCrossing) places its adversary; the draw that once chose a
                // side is kept so that the other draws of a seed stay what they were.
                let _ = draw.chance(0.5);
                events.push(CrossingEvent {
                    s_m: s,
                    trigger_m,
                    cyclist,
                    from_right: true,
                    speed_mps: if cyclist {
                        draw.range(3.0, 4.5)
                    } else {
                        draw.range(1.2, 1.8)
                    },
                });
                break;
            }
        }
    }
    Ok(Route {
        dense,
        path,
        junctions,
        events,
        start: (n0, d0),
    })
}

impl Route {
    /// Length, m.
    pub fn length_m(&self) -> f64 {
        self.dense.length_m()
    }

    /// The next junction at or after route distance `s_m` (including the one being crossed).
    pub fn next_junction(&self, s_m: f64) -> Option<&RouteJunction> {
        self.junctions.iter().find(|j| j.s_exit_m >= s_m)
    }

    /// The route's position and direction at `s_m`.
    pub fn pose(&self, s_m: f64) -> (P2, P2) {
        self.path.pose(s_m)
    }

    /// Where an event's actor starts and ends (sidewalk to sidewalk across the road).
    pub fn event_endpoints(&self, e: &CrossingEvent) -> (P2, P2) {
        let (p, u) = self.path.pose(e.s_m);
        let r = right_of(u);
        // The lane centre is 1.75 m right of the road's centre line; sidewalks' middles are
        // 1.5 m beyond the 4 m half-road.
        let right_walk = add(p, r, 2.25 + 1.5);
        let left_walk = add(p, r, -(LANE_W_M / 2.0 + 4.0 + 1.5));
        if e.from_right {
            (right_walk, left_walk)
        } else {
            (left_walk, right_walk)
        }
    }

    /// Travel direction vector of a junction's approach.
    pub fn approach_dir(j: &RouteJunction) -> P2 {
        DIRS[j.din]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::town::TownParams;

    #[test]
    fn routes_have_the_asked_length_and_follow_lanes() {
        let town = Town::generate(TownParams::default(), 1, 0);
        let mut d = Draw::new(5, &[1]);
        for len in [300.0, 1500.0, 2800.0] {
            let r = generate(&town, len, 6.0, &mut d).unwrap();
            assert!(
                (r.length_m() - len).abs() < 12.0,
                "{} vs {len}",
                r.length_m()
            );
            // Dense points are about a metre apart.
            for w in r.dense.points.windows(2) {
                let d = dist(w[0], w[1]);
                assert!(d > 0.05 && d < 1.01, "{d}");
            }
            for j in &r.junctions {
                assert!(j.s_exit_m > j.s_entry_m);
                assert_ne!(j.turn(), 2);
            }
            for e in &r.events {
                assert!(
                    r.junctions
                        .iter()
                        .all(|j| e.s_m < j.s_stop_line_m - 25.0 || e.s_m > j.s_exit_m + 20.0)
                );
                // From the sidewalk on the ego lane's side (CARLA's scenario 3), across the
                // whole road: the start is right of the route, the end left of it.
                assert!(e.from_right);
                let (a, b) = r.event_endpoints(e);
                let (p, u) = r.path.pose(e.s_m);
                let left = |q: P2| -u[1] * (q[0] - p[0]) + u[0] * (q[1] - p[1]);
                assert!(left(a) < -3.0 && left(b) > 5.0, "{} {}", left(a), left(b));
            }
        }
    }
}
