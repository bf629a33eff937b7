//! From perception to a decision, a trajectory and a one-sentence explanation.

use crate::perceive::{Lamp, ObjectKind, Perception};
use fogline_types::clip::{Decision, Trajectory};
use fogline_types::motion::{
    EGO_FRONT_M, EGO_WIDTH_M, Idm, Lateral, Lead, Path, cruise, follow, rollout, slow_for_turn,
    stop_within,
};

/// Turn radius the planner assumes at a junction, m.
const TURN_RADIUS: f64 = 8.5;
/// Turn speed, m/s.
const TURN_SPEED: f64 = 5.0;
/// Deceleration assumed for a lead showing brake lamps, m/s².
const LEAD_BRAKING: f64 = 2.6;
/// Closing speed above which a lead counts as slow, m/s.
const SLOW_LEAD: f64 = 2.5;

/// What the planner decided, with the trajectory and the explanation.
pub struct Plan {
    /// The decision.
    pub decision: Decision,
    /// The trajectory.
    pub trajectory: Trajectory,
    /// One sentence.
    pub explanation: String,
    /// Where the plan stands still, m ahead of the rear axle, for the decisions that stop
    /// (a red or amber light, a stop sign, a road user crossing): the perceived stop point
    /// itself, which the trajectory reaches only if its horizon is long enough.
    pub stop_at: Option<f64>,
}

/// Where no crossing is nearer, the car yields this far short of a walker in its lane, m.
pub const WALKER_GAP_M: f64 = 2.5;
/// The farthest a red light's head stands beyond its stop line, m (the far side of a wide
/// junction: a crossing, the cross road's lanes and shoulders).
pub const LIGHT_TO_LINE_MAX_M: f64 = 40.0;

/// Decides and plans.
pub fn plan(p: &Perception) -> Plan {
    let v0 = p.speed;
    let path = Path::arc(p.kappa);
    let shifted = |lat: Lateral| -> Lateral {
        let mut l = lat;
        if p.lane_offset.abs() > 1e-6 {
            l.ramps.insert(0, (0.0, 20.0, p.lane_offset));
        }
        l
    };
    let lead = p.lead.filter(|l| l.contact_x < 60.0);
    // 1. Someone crossing in front.
    if let Some(l) = lead.filter(|l| l.kind == ObjectKind::Person && l.contact_x < 45.0) {
        let stop_at = match p.zebra {
            Some(z) if z < l.contact_x + 1.0 => z - 1.0 - EGO_FRONT_M,
            _ => l.contact_x - WALKER_GAP_M - EGO_FRONT_M,
        };
        let traj = rollout(
            &Path::straight(),
            &shifted(Lateral::none()),
            &stop_within(v0, stop_at),
        );
        return Plan {
            decision: Decision::YieldToCrossing,
            trajectory: traj,
            explanation: say_yield(l.contact_x),
            stop_at: Some(stop_at),
        };
    }
    // 2. Red or amber light.
    if let Some((lamp, d_light)) = p.light
        && lamp != Lamp::Green
    {
        // The line of this light's junction: short of the head, by less than a junction's
        // width and the crossing before it (a line far short of it belongs to another
        // junction on the way, where the car would wait for a green that never comes).
        let line = p
            .stop_line
            .filter(|&s| s < d_light && d_light - s < LIGHT_TO_LINE_MAX_M)
            .unwrap_or((d_light - 13.5).max(2.0));
        let stop_at = line - EGO_FRONT_M - 0.5;
        let traj = rollout(
            &Path::straight(),
            &shifted(Lateral::none()),
            &stop_within(v0, stop_at),
        );
        return Plan {
            decision: Decision::StopForRedLight,
            trajectory: traj,
            explanation: say_red(lamp, line),
            stop_at: Some(stop_at),
        };
    }
    // 3. Stop sign.
    if let Some(d_sign) = p.stop_sign {
        let line = p
            .stop_line
            .filter(|&s| (s - d_sign).abs() < 6.0)
            .unwrap_or(d_sign - 0.4);
        let stop_at = line - EGO_FRONT_M - 0.5;
        let traj = rollout(
            &Path::straight(),
            &shifted(Lateral::none()),
            &stop_within(v0, stop_at),
        );
        return Plan {
            decision: Decision::StopForSign,
            trajectory: traj,
            explanation: say_sign(line),
            stop_at: Some(stop_at),
        };
    }
    // 4. The road ends: turn right.
    if let Some(x_end) = p.road_end
        && p.right_branch
    {
        let w = p.lane_width;
        let exit_lane = x_end - 0.45 - 1.5 * w;
        let x_c = (exit_lane - TURN_RADIUS).max(0.0);
        let turn = Path::right_turn(x_c, TURN_RADIUS);
        let dist = slow_for_turn(
            v0,
            TURN_SPEED,
            2.0,
            x_c,
            TURN_RADIUS * std::f64::consts::FRAC_PI_2,
            1.0,
            8.0,
        );
        return Plan {
            decision: Decision::TurnRight,
            trajectory: rollout(&turn, &shifted(Lateral::none()), &dist),
            explanation: say_turn(x_c),
            stop_at: None,
        };
    }
    // 5./6. Something in the lane.
    if let Some(l) = lead {
        let w = p.lane_width;
        let room_right = l.right_edge - (-w / 2.0);
        if l.right_edge > -0.25 && room_right >= EGO_WIDTH_M + 0.3 && l.contact_x < 45.0 {
            let edge = l.right_edge;
            let offset =
                (edge - 0.5 - EGO_WIDTH_M / 2.0).clamp(-(w / 2.0 - EGO_WIDTH_M / 2.0 + 0.3), 0.0);
            let rear = l.contact_x - 3.0;
            let front = l.contact_x + 8.0;
            let lat = Lateral {
                ramps: vec![
                    (rear - 16.0, rear - 3.0, offset),
                    (front + 3.0, front + 16.0, -offset),
                ],
            };
            return Plan {
                decision: Decision::NudgeRight,
                trajectory: rollout(&path, &shifted(lat), &cruise(v0)),
                explanation: say_nudge(l.contact_x, offset),
                stop_at: None,
            };
        }
        let idm = Idm::urban(v0.max(1.0));
        if l.braking {
            let dist = follow(
                v0,
                Lead {
                    gap_m: l.gap,
                    speed_mps: l.speed,
                    accel_mps2: -LEAD_BRAKING,
                },
                &idm,
            );
            return Plan {
                decision: Decision::SlowForLead,
                trajectory: rollout(&path, &shifted(Lateral::none()), &dist),
                explanation: say_slow(l.gap, l.width_m),
                stop_at: None,
            };
        }
        if v0 - l.speed > SLOW_LEAD && p.left_lane_free {
            let lat = Lateral {
                ramps: vec![(2.0, 2.0 + v0 * 3.0, w)],
            };
            return Plan {
                decision: Decision::PassLeft,
                trajectory: rollout(&path, &shifted(lat), &cruise(v0)),
                explanation: say_pass(l.gap, l.width_m),
                stop_at: None,
            };
        }
        let dist = follow(
            v0,
            Lead {
                gap_m: l.gap,
                speed_mps: l.speed,
                accel_mps2: 0.0,
            },
            &idm,
        );
        return Plan {
            decision: Decision::FollowLead,
            trajectory: rollout(&path, &shifted(Lateral::none()), &dist),
            explanation: say_follow(l.gap, l.width_m),
            stop_at: None,
        };
    }
    // 7. Green light.
    if let Some((Lamp::Green, d)) = p.light {
        return Plan {
            decision: Decision::ProceedOnGreen,
            trajectory: rollout(&path, &shifted(Lateral::none()), &cruise(v0)),
            explanation: say_green(d),
            stop_at: None,
        };
    }
    Plan {
        decision: Decision::KeepLane,
        trajectory: rollout(&path, &shifted(Lateral::none()), &cruise(v0)),
        explanation: say_keep(p.kappa, p.lane.is_some()),
        stop_at: None,
    }
}

/// Picks a phrasing from the perceived details (deterministic: the same perception gives the
/// same sentence; a different distance bucket or object kind may give a rewording).
fn pick<'a>(options: &[&'a str], key: u64) -> &'a str {
    let h = key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 59;
    options[(h as usize) % options.len()]
}

fn bucket(d: f64, step: f64) -> u64 {
    (d.max(0.0) / step).round() as u64
}

fn fmt_m(d: f64) -> String {
    format!("{}", ((d / 5.0).round() * 5.0).max(5.0) as i64)
}

fn vehicle_word(width: f64) -> &'static str {
    if width >= 2.0 { "truck" } else { "car" }
}

fn say_yield(d: f64) -> String {
    let o = [
        "Stop and yield to the pedestrian crossing ahead.",
        "Brake to a stop because someone is crossing in front of the car.",
        "Yield: a road user is on the crossing about DIST m ahead.",
    ];
    pick(&o, bucket(d, 5.0)).replace("DIST", &fmt_m(d))
}

fn say_red(lamp: Lamp, line: f64) -> String {
    let o = if lamp == Lamp::Amber {
        [
            "Stop at the line because the light is turning red.",
            "Slow to a stop; the signal ahead shows amber.",
            "Stop about DIST m ahead as the light changes.",
        ]
    } else {
        [
            "Stop because the traffic light ahead is red.",
            "Come to a stop at the line; the signal is red.",
            "Brake to stop about DIST m ahead for the red light.",
        ]
    };
    pick(&o, bucket(line, 5.0) + 1).replace("DIST", &fmt_m(line))
}

fn say_sign(line: f64) -> String {
    let o = [
        "Stop at the line for the stop sign ahead.",
        "Slow down and stop: there is a stop sign about DIST m ahead.",
        "Come to a full stop at the stop sign.",
    ];
    pick(&o, bucket(line, 5.0) + 2).replace("DIST", &fmt_m(line))
}

fn say_turn(x: f64) -> String {
    let o = [
        "Slow down and turn right where the road ends ahead.",
        "Turn right at the junction about DIST m ahead.",
        "Reduce speed for the right turn ahead.",
    ];
    pick(&o, bucket(x, 5.0) + 3).replace("DIST", &fmt_m(x))
}

fn say_nudge(d: f64, offset: f64) -> String {
    let o = [
        "Nudge right to keep clearance from the vehicle blocking the left of the lane.",
        "Shift slightly right to pass the obstacle intruding from the left.",
        "Move right within the lane to clear the parked vehicle about DIST m ahead.",
    ];
    pick(&o, bucket(d, 5.0) + bucket(-offset, 0.25) * 7 + 4).replace("DIST", &fmt_m(d))
}

/// A lead-vehicle phrasing with its kind (`VEH`) and gap (`DIST`) filled in.
fn about_lead(options: &[&str], gap: f64, width: f64, salt: u64) -> String {
    pick(options, bucket(gap, 5.0) + salt)
        .replace("VEH", vehicle_word(width))
        .replace("DIST", &fmt_m(gap))
}

fn say_slow(gap: f64, width: f64) -> String {
    let o = [
        "Slow down because the lead VEH is braking ahead.",
        "Brake: the VEH in front shows brake lights DIST m ahead.",
        "Decelerate to keep distance from the braking VEH.",
    ];
    about_lead(&o, gap, width, 5)
}

fn say_pass(gap: f64, width: f64) -> String {
    let o = [
        "Change to the left lane to overtake the slow VEH ahead.",
        "Pass the slower VEH on the left; the left lane is clear.",
        "Overtake the VEH about DIST m ahead using the free left lane.",
    ];
    about_lead(&o, gap, width, 6)
}

fn say_follow(gap: f64, width: f64) -> String {
    let o = [
        "Follow the VEH ahead at a safe distance.",
        "Keep a steady gap of about DIST m behind the lead VEH.",
        "Match the speed of the VEH in front and stay in the lane.",
    ];
    about_lead(&o, gap, width, 7)
}

fn say_green(d: f64) -> String {
    let o = [
        "Proceed through the intersection; the light is green.",
        "Continue at speed: the signal ahead is green.",
        "Keep going through the junction on green.",
    ];
    pick(&o, bucket(d, 10.0) + 8).to_string()
}

fn say_keep(kappa: f64, saw_lane: bool) -> String {
    if !saw_lane {
        return "Keep going straight at the current speed; no lane markings are visible."
            .to_string();
    }
    if kappa.abs() > 1.0 / 180.0 {
        let side = if kappa > 0.0 { "left" } else { "right" };
        let o = [
            "Follow the SIDE-hand curve and keep the lane.",
            "Steer gently SIDE to stay in the lane through the bend.",
        ];
        return pick(&o, bucket(kappa.abs() * 1000.0, 3.0) + 9).replace("SIDE", side);
    }
    let o = [
        "Keep the lane and hold speed; the road ahead is clear.",
        "Continue in the current lane at a steady speed.",
        "Stay centred in the lane; nothing ahead requires action.",
    ];
    pick(&o, bucket(kappa.abs() * 1000.0, 1.0) + 10).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perceive::ImageQuality;

    /// A straight empty lane at 6 m/s, nothing else seen.
    fn open_road() -> Perception {
        Perception {
            speed: 6.0,
            kappa_history: 0.0,
            kappa: 0.0,
            lane_width: 3.5,
            lane_offset: 0.0,
            lane_heading: 0.0,
            lane: None,
            road_lum: 90.0,
            lead: None,
            left_lane_free: false,
            road_end: None,
            right_branch: false,
            stop_line: None,
            zebra: None,
            light: None,
            stop_sign: None,
            quality: ImageQuality {
                noise_sigma: 0.0,
                white: 255.0,
                gain: 1.0,
            },
            left_object: None,
            kerb_object: None,
        }
    }

    #[test]
    fn a_red_light_stops_the_car_at_its_own_junctions_line_not_at_a_nearer_one() {
        let front = EGO_FRONT_M + 0.5;
        // The head 24 m off, its line 9 m short of it: the car stops 0.5 m before the line.
        let mut p = open_road();
        p.light = Some((Lamp::Red, 24.0));
        p.stop_line = Some(15.0);
        let plan = plan(&p);
        assert_eq!(plan.decision, Decision::StopForRedLight);
        assert!((plan.stop_at.expect("stops") - (15.0 - front)).abs() < 1e-9);
        // A head 90 m off and a line 15 m ahead: the line is another junction's (a stop
        // sign's, say); the car plans to stop short of the far head, not at that line.
        p.light = Some((Lamp::Red, 90.0));
        let plan = super::plan(&p);
        assert_eq!(plan.decision, Decision::StopForRedLight);
        let at = plan.stop_at.expect("stops");
        assert!((at - (90.0 - 13.5 - front)).abs() < 1e-9, "stops at {at}");
    }
}
