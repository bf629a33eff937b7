//! Towns: a grid of two-way streets (one lane each way, right-hand traffic) meeting at
//! junctions that are signalised, all-way stop or (at the grid's corners) plain bends; lanes,
//! the paths through every junction, traffic lights and their cycles, stop signs, buildings,
//! and the ground strips the renderer draws.
//!
//! Geometry (metres; a junction's centre is its node):
//!
//! - lane width 3.5, shoulder 0.5 (half a road is 4 m), sidewalks 3 m wide;
//! - the junction box is the square of half-size 6 m around the node (a plaza, as at CARLA's
//!   multi-lane junctions); the zebra crossing of each approach lies 0.5–3.5 m before the
//!   box (as in the world crate's junction scenes, which the reference planner was built
//!   on), the stop line (0.5 m wide) 9 m before it — 5 m before the zebra, so that a car
//!   waiting at the line has no paint in the planner's road-brightness reference; zebra and
//!   stop line are
//!   painted across the approach lane only (the planner takes paint across its own lane
//!   beyond the first zebra for an obstacle), the zebra's stripes are 0.4 m wide every 1 m
//!   (so that a car standing at it still finds mostly asphalt in the planner's road-brightness
//!   window);
//! - the paths through a junction start and end 9.75 m from the node (just past the stop
//!   line): straight, a right turn of radius 8 m or a left turn of radius 11.5 m;
//! - a traffic light stands past the junction on the approach's right, its arm reaching over
//!   the approach lane, head 5.2 m up; a stop sign stands right of the approach lane, 0.4 m
//!   past its stop line.

use std::f64::consts::FRAC_PI_2;

use fogline_world::scene::{Bar, Centre, Draw, Mark, Strip};
use serde::{Deserialize, Serialize};

use crate::geom::{Obb, P2, Poly, add, dist, right_of};

/// Travel directions: east, north, west, south.
pub const DIRS: [P2; 4] = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]];
/// Lane width, m.
pub const LANE_W_M: f64 = 3.5;
/// Shoulder beyond the edge lines, m.
pub const SHOULDER_M: f64 = 0.5;
/// Half a road, m.
pub const HALF_ROAD_M: f64 = LANE_W_M + SHOULDER_M;
/// Sidewalk width, m.
pub const WALK_M: f64 = 3.0;
/// Half-size of a junction box, m (a plaza wider than the streets, as at CARLA's multi-lane
/// junctions: a far-side signal head stays in the telephoto camera's view while the car
/// waits at the stop line).
pub const BOX_M: f64 = 6.0;
/// Distance from the node at which the paths through a junction start and end, m (just past
/// the stop line).
pub const ZONE_M: f64 = BOX_M + 3.75;
/// Lateral position of a sidewalk's middle from its street's centre line, m.
pub const WALK_MID_M: f64 = HALF_ROAD_M + WALK_M / 2.0;
/// Distance from the node to an approach's stop line (its centre), m: 5 m before the zebra,
/// so that a car standing at the line has no paint in the reference planner's
/// road-brightness window (1.3–5.3 m ahead of its bumper).
pub const STOP_LINE_M: f64 = BOX_M + 9.0;
/// Distance along the lane from the stop line to the start of the path through the
/// junction, m.
pub const LINE_TO_ZONE_M: f64 = STOP_LINE_M - ZONE_M;
/// Distance from the node to the zebra's centre line (also where pedestrians cross), m.
pub const ZEBRA_M: f64 = BOX_M + 2.0;
/// Height of a signal head, m.
pub const LIGHT_HEAD_M: f64 = 5.2;

const WHITE: [f32; 3] = [232.0, 232.0, 226.0];
const YELLOW: [f32; 3] = [226.0, 186.0, 40.0];

/// A junction's traffic control.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Control {
    /// No control (a bend at a grid corner).
    None,
    /// Traffic lights.
    Signal,
    /// Stop signs on every approach.
    Stop,
}

/// A light's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Light {
    /// Red.
    Red,
    /// Amber.
    Amber,
    /// Green.
    Green,
}

/// A junction.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Centre, m.
    pub pos: P2,
    /// Its control.
    pub control: Control,
    /// Which streets leave it (east, north, west, south).
    pub arms: [bool; 4],
    /// Offset of its signal cycle, s.
    pub phase_offset_s: f64,
}

impl Node {
    /// Whether traffic arrives travelling in direction `din` (the street behind exists).
    pub fn has_approach(&self, din: usize) -> bool {
        self.arms[(din + 2) % 4]
    }
}

/// A building: its footprint and looks.
#[derive(Debug, Clone, PartialEq)]
pub struct Building {
    /// Footprint.
    pub obb: Obb,
    /// Draw seed for its colour and height.
    pub seed: u64,
}

/// A traffic light of one approach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightPost {
    /// Its id (also its track id in boxes).
    pub id: u64,
    /// The junction.
    pub node: usize,
    /// The approach's travel direction.
    pub din: usize,
    /// The pole's foot, m.
    pub pos: P2,
    /// Heading of the approach (the lamps face against it), rad.
    pub yaw: f64,
    /// Arm length, m.
    pub arm_m: f64,
}

/// A stop sign of one approach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignPost {
    /// Its id (also its track id in boxes).
    pub id: u64,
    /// The junction.
    pub node: usize,
    /// The approach's travel direction.
    pub din: usize,
    /// The pole's foot, m.
    pub pos: P2,
    /// Heading of the approach, rad.
    pub yaw: f64,
}

/// A ground strip with a bounding circle for culling.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedStrip {
    /// Centre of the bounding circle, m.
    pub centre: P2,
    /// Radius of the bounding circle, m.
    pub radius: f64,
    /// The strip (world frame).
    pub strip: Strip,
}

/// How a town is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TownParams {
    /// Junctions along x.
    pub nx: usize,
    /// Junctions along y.
    pub ny: usize,
    /// Shortest block (node to node), m.
    pub block_min_m: f64,
    /// Longest block, m.
    pub block_max_m: f64,
    /// Share of junctions with three or four arms that are signalised (the rest: all-way stop).
    pub signal_share: f64,
    /// Green per axis, s.
    pub green_s: f64,
    /// Amber, s.
    pub amber_s: f64,
    /// All red between phases, s.
    pub all_red_s: f64,
}

impl Default for TownParams {
    fn default() -> Self {
        Self {
            nx: 6,
            ny: 6,
            block_min_m: 80.0,
            block_max_m: 130.0,
            signal_share: 0.55,
            green_s: 14.0,
            amber_s: 3.0,
            all_red_s: 2.0,
        }
    }
}

/// Turn index of a movement: 0 straight, 1 left, 3 right (2 would be a U-turn).
pub fn turn_of(din: usize, dout: usize) -> usize {
    (dout + 4 - din) % 4
}

/// A town.
#[derive(Debug, Clone)]
pub struct Town {
    /// Its parameters.
    pub params: TownParams,
    /// Node x positions.
    pub xs: Vec<f64>,
    /// Node y positions.
    pub ys: Vec<f64>,
    /// Junctions, index `j·nx + i`.
    pub nodes: Vec<Node>,
    lanes: Vec<Option<Poly>>,
    conns: Vec<Option<Poly>>,
    conflicts: Vec<[u16; 16]>,
    /// Buildings.
    pub buildings: Vec<Building>,
    /// Traffic lights.
    pub lights: Vec<LightPost>,
    /// Stop signs.
    pub signs: Vec<SignPost>,
    /// Ground strips.
    pub strips: Vec<PlacedStrip>,
    /// Ground texture seed.
    pub texture_seed: u64,
}

impl Town {
    /// Draws town `index` of `seed`.
    pub fn generate(params: TownParams, seed: u64, index: u64) -> Town {
        let mut d = Draw::new(seed, &[0x70_57, index]);
        let (nx, ny) = (params.nx.max(2), params.ny.max(2));
        let mut xs = vec![0.0];
        for _ in 1..nx {
            let l = d.range(params.block_min_m, params.block_max_m).round();
            xs.push(xs[xs.len() - 1] + l);
        }
        let mut ys = vec![0.0];
        for _ in 1..ny {
            let l = d.range(params.block_min_m, params.block_max_m).round();
            ys.push(ys[ys.len() - 1] + l);
        }
        let cycle = 2.0 * (params.green_s + params.amber_s + params.all_red_s);
        let mut nodes = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let arms = [i + 1 < nx, j + 1 < ny, i > 0, j > 0];
                let n_arms = arms.iter().filter(|a| **a).count();
                let control = if n_arms < 3 {
                    Control::None
                } else if d.chance(params.signal_share) {
                    Control::Signal
                } else {
                    Control::Stop
                };
                nodes.push(Node {
                    pos: [xs[i], ys[j]],
                    control,
                    arms,
                    phase_offset_s: d.range(0.0, cycle),
                });
            }
        }
        let mut town = Town {
            params: TownParams { nx, ny, ..params },
            xs,
            ys,
            nodes,
            lanes: Vec::new(),
            conns: Vec::new(),
            conflicts: Vec::new(),
            buildings: Vec::new(),
            lights: Vec::new(),
            signs: Vec::new(),
            strips: Vec::new(),
            texture_seed: fogline_stats::seed::child(seed, &[0x7E47, index]),
        };
        town.build_paths();
        town.build_posts();
        town.build_buildings(&mut d);
        town.build_strips();
        town
    }

    /// Junctions along x.
    pub fn nx(&self) -> usize {
        self.params.nx
    }

    /// The neighbour of `node` in direction `d`.
    pub fn neighbor(&self, node: usize, d: usize) -> Option<usize> {
        let nx = self.params.nx;
        let (i, j) = (node % nx, node / nx);
        if !self.nodes[node].arms[d] {
            return None;
        }
        Some(match d {
            0 => j * nx + i + 1,
            1 => (j + 1) * nx + i,
            2 => j * nx + i - 1,
            _ => (j - 1) * nx + i,
        })
    }

    /// The lane leaving `node` in direction `d` (from the junction zone to the next one).
    pub fn lane(&self, node: usize, d: usize) -> Option<&Poly> {
        self.lanes.get(node * 4 + d).and_then(Option::as_ref)
    }

    /// The path through `node` from travel direction `din` to `dout`.
    pub fn connector(&self, node: usize, din: usize, dout: usize) -> Option<&Poly> {
        self.conns
            .get(node * 16 + din * 4 + dout)
            .and_then(Option::as_ref)
    }

    /// Whether movements `(din, dout)` and `(din2, dout2)` through a node cross or merge.
    pub fn conflicts(&self, node: usize, a: (usize, usize), b: (usize, usize)) -> bool {
        self.conflicts[node][a.0 * 4 + a.1] & (1 << (b.0 * 4 + b.1)) != 0
    }

    /// The allowed exits of `node` for traffic arriving in direction `din`.
    pub fn exits(&self, node: usize, din: usize) -> Vec<usize> {
        [din, (din + 1) % 4, (din + 3) % 4]
            .into_iter()
            .filter(|&dout| self.connector(node, din, dout).is_some())
            .collect()
    }

    /// The light of `node` for travel direction `din` at time `t_s`.
    pub fn light(&self, node: usize, din: usize, t_s: f64) -> Light {
        let p = &self.params;
        let n = &self.nodes[node];
        if n.control != Control::Signal {
            return Light::Green;
        }
        let half = p.green_s + p.amber_s + p.all_red_s;
        let cycle = 2.0 * half;
        let mut tau = (t_s + n.phase_offset_s).rem_euclid(cycle);
        if din % 2 == 1 {
            tau = (tau + half).rem_euclid(cycle);
        }
        if tau < p.green_s {
            Light::Green
        } else if tau < p.green_s + p.amber_s {
            Light::Amber
        } else {
            Light::Red
        }
    }

    /// Seconds of green left for direction `din` at `t_s` (0 when not green).
    pub fn green_left_s(&self, node: usize, din: usize, t_s: f64) -> f64 {
        let p = &self.params;
        let n = &self.nodes[node];
        if n.control != Control::Signal {
            return f64::INFINITY;
        }
        let half = p.green_s + p.amber_s + p.all_red_s;
        let mut tau = (t_s + n.phase_offset_s).rem_euclid(2.0 * half);
        if din % 2 == 1 {
            tau = (tau + half).rem_euclid(2.0 * half);
        }
        (p.green_s - tau).max(0.0)
    }

    /// The stop line of `node`'s approach `din`: its centre, m.
    pub fn stop_line_centre(&self, node: usize, din: usize) -> P2 {
        let u = DIRS[din];
        let r = right_of(u);
        add(
            add(self.nodes[node].pos, u, -STOP_LINE_M),
            r,
            LANE_W_M / 2.0,
        )
    }

    /// The stop line of `node`'s approach `din` for the red-light test.
    pub fn stop_line(&self, node: usize, din: usize) -> crate::score::StopLine {
        let u = DIRS[din];
        let r = right_of(u);
        let c = self.stop_line_centre(node, din);
        crate::score::StopLine {
            a: add(c, r, LANE_W_M / 2.0),
            b: add(c, r, -LANE_W_M / 2.0),
            forward: u,
        }
    }

    fn build_paths(&mut self) {
        let n = self.nodes.len();
        self.lanes = vec![None; n * 4];
        self.conns = vec![None; n * 16];
        self.conflicts = vec![[0u16; 16]; n];
        let w2 = LANE_W_M / 2.0;
        for a in 0..n {
            for dd in 0..4 {
                if let Some(b) = self.neighbor(a, dd) {
                    let u = DIRS[dd];
                    let r = right_of(u);
                    let p0 = add(add(self.nodes[a].pos, u, ZONE_M), r, w2);
                    let p1 = add(add(self.nodes[b].pos, u, -ZONE_M), r, w2);
                    self.lanes[a * 4 + dd] = Some(Poly::line(p0, p1, 2.0));
                }
            }
            for din in 0..4 {
                if !self.nodes[a].has_approach(din) {
                    continue;
                }
                let u = DIRS[din];
                let r = right_of(u);
                let p0 = add(add(self.nodes[a].pos, u, -ZONE_M), r, w2);
                for dout in 0..4 {
                    if !self.nodes[a].arms[dout] || dout == (din + 2) % 4 {
                        continue;
                    }
                    let poly = match turn_of(din, dout) {
                        0 => {
                            let p1 = add(add(self.nodes[a].pos, u, ZONE_M), r, w2);
                            Poly::line(p0, p1, 1.0)
                        }
                        1 => Poly::arc(p0, u, ZONE_M + w2, FRAC_PI_2, 0.75),
                        _ => Poly::arc(p0, u, ZONE_M - w2, -FRAC_PI_2, 0.75),
                    };
                    self.conns[a * 16 + din * 4 + dout] = Some(poly);
                }
            }
            // Conflicts: different approaches whose paths come within 2.5 m.
            for m1 in 0..16 {
                for m2 in 0..16 {
                    let (Some(p1), Some(p2)) = (
                        self.conns[a * 16 + m1].as_ref(),
                        self.conns[a * 16 + m2].as_ref(),
                    ) else {
                        continue;
                    };
                    if m1 / 4 == m2 / 4 {
                        continue;
                    }
                    let close = p1
                        .pts
                        .iter()
                        .any(|&q1| p2.pts.iter().any(|&q2| dist(q1, q2) < 2.5));
                    if close {
                        self.conflicts[a][m1] |= 1 << m2;
                    }
                }
            }
        }
    }

    fn build_posts(&mut self) {
        let mut id = 1_000_000u64;
        for (k, node) in self.nodes.iter().enumerate() {
            for din in 0..4 {
                if !node.has_approach(din) {
                    continue;
                }
                let u = DIRS[din];
                let r = right_of(u);
                let yaw = u[1].atan2(u[0]);
                match node.control {
                    Control::Signal => {
                        id += 1;
                        let pos = add(add(node.pos, u, BOX_M + 1.2), r, HALF_ROAD_M + 1.0);
                        self.lights.push(LightPost {
                            id,
                            node: k,
                            din,
                            pos,
                            yaw,
                            arm_m: HALF_ROAD_M + 1.0 - LANE_W_M / 2.0,
                        });
                    }
                    Control::Stop => {
                        id += 1;
                        let pos = add(add(node.pos, u, -(STOP_LINE_M - 0.4)), r, HALF_ROAD_M + 0.9);
                        self.signs.push(SignPost {
                            id,
                            node: k,
                            din,
                            pos,
                            yaw,
                        });
                    }
                    Control::None => {}
                }
            }
        }
    }

    fn build_buildings(&mut self, d: &mut Draw) {
        let m = HALF_ROAD_M + WALK_M + 1.5;
        let (nx, ny) = (self.params.nx, self.params.ny);
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let (x0, x1) = (self.xs[i] + m, self.xs[i + 1] - m);
                let (y0, y1) = (self.ys[j] + m, self.ys[j + 1] - m);
                // South and north rows along x, then west and east rows along y between them.
                for (y_edge, sign) in [(y0, 1.0), (y1, -1.0)] {
                    let mut x = x0 + d.range(0.0, 4.0);
                    loop {
                        let len = d.range(12.0, 28.0);
                        let depth = d.range(8.0, 14.0);
                        if x + len > x1 {
                            break;
                        }
                        self.buildings.push(Building {
                            obb: Obb {
                                c: [x + len / 2.0, y_edge + sign * depth / 2.0],
                                yaw: 0.0,
                                hl: len / 2.0,
                                hw: depth / 2.0,
                            },
                            seed: d.range(0.0, 1e12) as u64,
                        });
                        x += len + d.range(1.5, 7.0);
                    }
                }
                for (x_edge, sign) in [(x0, 1.0), (x1, -1.0)] {
                    let mut y = y0 + 16.0 + d.range(0.0, 4.0);
                    loop {
                        let len = d.range(12.0, 24.0);
                        let depth = d.range(8.0, 12.0);
                        if y + len > y1 - 16.0 {
                            break;
                        }
                        self.buildings.push(Building {
                            obb: Obb {
                                c: [x_edge + sign * depth / 2.0, y + len / 2.0],
                                yaw: FRAC_PI_2,
                                hl: len / 2.0,
                                hw: depth / 2.0,
                            },
                            seed: d.range(0.0, 1e12) as u64,
                        });
                        y += len + d.range(1.5, 7.0);
                    }
                }
            }
        }
    }

    fn build_strips(&mut self) {
        let w = LANE_W_M;
        let line = |dd: f64, color| Mark {
            d: dd,
            width: 0.15,
            dash: None,
            color,
            s_min: f64::NEG_INFINITY,
            s_max: f64::INFINITY,
        };
        // Junction boxes first (the first strip containing a point decides it).
        for node in &self.nodes {
            self.strips.push(PlacedStrip {
                centre: node.pos,
                radius: BOX_M * 1.5,
                strip: Strip {
                    centre: Centre::Line {
                        origin: [node.pos[0] - BOX_M, node.pos[1]],
                        dir: [1.0, 0.0],
                    },
                    s_min: 0.0,
                    s_max: 2.0 * BOX_M,
                    d_min: -BOX_M,
                    d_max: BOX_M,
                    walk: 0.0,
                    marks: Vec::new(),
                    bars: Vec::new(),
                },
            });
        }
        for a in 0..self.nodes.len() {
            for dd in [0usize, 1] {
                let Some(b) = self.neighbor(a, dd) else {
                    continue;
                };
                let u = DIRS[dd];
                let (pa, pb) = (self.nodes[a].pos, self.nodes[b].pos);
                let len = dist(pa, pb);
                let mut bars = Vec::new();
                let controlled = |n: usize| self.nodes[n].control != Control::None;
                if controlled(b) {
                    let e = len - BOX_M;
                    bars.push(Bar {
                        s_min: e - (STOP_LINE_M - BOX_M) - 0.25,
                        s_max: e - (STOP_LINE_M - BOX_M) + 0.25,
                        d_min: -w,
                        d_max: 0.0,
                        stripes: None,
                    });
                    bars.push(Bar {
                        s_min: e - 3.5,
                        s_max: e - 0.5,
                        d_min: -w,
                        d_max: 0.0,
                        stripes: Some((0.4, 1.0)),
                    });
                }
                if controlled(a) {
                    let e = BOX_M;
                    bars.push(Bar {
                        s_min: e + (STOP_LINE_M - BOX_M) - 0.25,
                        s_max: e + (STOP_LINE_M - BOX_M) + 0.25,
                        d_min: 0.0,
                        d_max: w,
                        stripes: None,
                    });
                    bars.push(Bar {
                        s_min: e + 0.5,
                        s_max: e + 3.5,
                        d_min: 0.0,
                        d_max: w,
                        stripes: Some((0.4, 1.0)),
                    });
                }
                self.strips.push(PlacedStrip {
                    centre: add(pa, u, len / 2.0),
                    radius: len / 2.0 + HALF_ROAD_M + WALK_M,
                    strip: Strip {
                        centre: Centre::Line { origin: pa, dir: u },
                        s_min: BOX_M,
                        s_max: len - BOX_M,
                        d_min: -HALF_ROAD_M,
                        d_max: HALF_ROAD_M,
                        walk: WALK_M,
                        marks: vec![
                            line(-w, WHITE),
                            line(-0.12, YELLOW),
                            line(0.12, YELLOW),
                            line(w, WHITE),
                        ],
                        bars,
                    },
                });
            }
        }
    }

    /// The region of the town, with a margin: `(x_min, y_min, x_max, y_max)`.
    pub fn bounds(&self) -> (f64, f64, f64, f64) {
        let (x1, y1) = (
            self.xs.last().copied().unwrap_or(0.0),
            self.ys.last().copied().unwrap_or(0.0),
        );
        (-20.0, -20.0, x1 + 20.0, y1 + 20.0)
    }

    /// Whether `p` lies on a road surface (a street's asphalt or a junction box).
    pub fn on_road(&self, p: P2) -> bool {
        for &x in &self.xs {
            if (p[0] - x).abs() <= HALF_ROAD_M
                && p[1] >= self.ys[0] - HALF_ROAD_M
                && p[1] <= self.ys[self.ys.len() - 1] + HALF_ROAD_M
            {
                return true;
            }
        }
        for &y in &self.ys {
            if (p[1] - y).abs() <= HALF_ROAD_M
                && p[0] >= self.xs[0] - HALF_ROAD_M
                && p[0] <= self.xs[self.xs.len() - 1] + HALF_ROAD_M
            {
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn town() -> Town {
        Town::generate(TownParams::default(), 3, 0)
    }

    #[test]
    fn lanes_and_connectors_join_up() {
        let t = town();
        for a in 0..t.nodes.len() {
            for dd in 0..4 {
                let Some(lane) = t.lane(a, dd) else { continue };
                let b = t.neighbor(a, dd).unwrap();
                let end = *lane.pts.last().unwrap();
                for dout in t.exits(b, dd) {
                    let c = t.connector(b, dd, dout).unwrap();
                    assert!(dist(c.pts[0], end) < 1e-9);
                    let next = t.lane(b, dout).unwrap();
                    assert!(dist(*c.pts.last().unwrap(), next.pts[0]) < 1e-6);
                }
            }
        }
    }

    #[test]
    fn signal_phases_never_give_both_axes_green() {
        let t = town();
        let k = t
            .nodes
            .iter()
            .position(|n| n.control == Control::Signal)
            .unwrap();
        let mut saw_red = false;
        for i in 0..800 {
            let ts = i as f64 * 0.1;
            let ew = t.light(k, 0, ts);
            let ns = t.light(k, 1, ts);
            assert!(!(ew != Light::Red && ns != Light::Red), "{ts}");
            assert_eq!(t.light(k, 0, ts), t.light(k, 2, ts));
            saw_red |= ew == Light::Red;
        }
        assert!(saw_red);
    }

    #[test]
    fn crossing_movements_conflict_and_followers_do_not() {
        let t = town();
        let k = t
            .nodes
            .iter()
            .position(|n| n.arms.iter().all(|a| *a))
            .unwrap();
        // Eastbound straight vs northbound straight: they cross.
        assert!(t.conflicts(k, (0, 0), (1, 1)));
        // Eastbound right turn vs westbound right turn: opposite corners.
        assert!(!t.conflicts(k, (0, 3), (2, 1)));
        // Eastbound left vs westbound straight: the left turn crosses it.
        assert!(t.conflicts(k, (0, 1), (2, 2)));
    }

    #[test]
    fn deterministic() {
        let a = town();
        let b = town();
        assert_eq!(a.xs, b.xs);
        assert_eq!(a.nodes, b.nodes);
        assert_eq!(a.buildings, b.buildings);
    }
}
