//! Solids the scenes are made of: vehicles, pedestrians, cyclists, signs, lights, clutter.
//!
//! Local frame: origin on the ground at the object's centre, `x` forward (its heading),
//! `y` left, `z` up. Dimensions are typical real ones (a car is 4.5 × 1.8 m).

use crate::scene::{Draw, ObjectClass, Part, Rgb, Solid};

/// Vehicle paints.
pub const PAINTS: [Rgb; 10] = [
    [235.0, 235.0, 232.0],
    [175.0, 178.0, 182.0],
    [40.0, 42.0, 46.0],
    [150.0, 28.0, 30.0],
    [32.0, 62.0, 140.0],
    [30.0, 80.0, 52.0],
    [205.0, 170.0, 40.0],
    [110.0, 112.0, 118.0],
    [22.0, 32.0, 70.0],
    [120.0, 90.0, 60.0],
];

/// Lit brake lamps.
pub const BRAKE_ON: Rgb = [255.0, 34.0, 28.0];
/// Tail lamps with the brakes released.
pub const BRAKE_OFF: Rgb = [105.0, 24.0, 24.0];
/// Lit red lamp of a traffic light.
pub const LAMP_RED: Rgb = [255.0, 42.0, 30.0];
/// Lit amber lamp.
pub const LAMP_AMBER: Rgb = [255.0, 176.0, 20.0];
/// Lit green lamp.
pub const LAMP_GREEN: Rgb = [40.0, 245.0, 130.0];
/// An unlit lamp.
pub const LAMP_OFF: Rgb = [48.0, 46.0, 44.0];
/// Stop-sign red.
pub const SIGN_RED: Rgb = [196.0, 22.0, 32.0];

/// Dimensions of a car, m (length, width).
pub const CAR_SIZE: (f64, f64) = (4.5, 1.8);

fn cuboid(centre: [f64; 3], size: [f64; 3], color: Rgb) -> Part {
    Part::Cuboid {
        centre,
        half: [size[0] / 2.0, size[1] / 2.0, size[2] / 2.0],
        color,
    }
}

fn plate(
    centre: [f64; 3],
    radius: f64,
    sides: u32,
    facing: f64,
    color: Rgb,
    emissive: bool,
) -> Part {
    Part::Plate {
        centre,
        radius,
        sides,
        facing,
        color,
        emissive,
    }
}

/// A car (or, with `truck`, a box van): body, cabin, wheels, rear lamps (lit when `braking`).
pub fn vehicle(d: &mut Draw, truck: bool, braking: bool) -> Vec<Part> {
    let paint = d.pick(&PAINTS);
    let glass: Rgb = [38.0, 46.0, 56.0];
    let tyre: Rgb = [22.0, 22.0, 24.0];
    let (l, w) = if truck {
        (6.4, 2.2)
    } else {
        (d.range(4.2, 4.8), d.range(1.75, 1.9))
    };
    let mut parts = Vec::new();
    if truck {
        parts.push(cuboid([-0.6, 0.0, 1.65], [l - 1.2, w, 2.5], paint));
        parts.push(cuboid(
            [l / 2.0 - 0.6, 0.0, 1.25],
            [1.2, w, 1.7],
            [200.0, 200.0, 198.0],
        ));
        parts.push(cuboid(
            [l / 2.0 - 0.1, 0.0, 1.55],
            [0.2, w - 0.2, 0.7],
            glass,
        ));
    } else {
        parts.push(cuboid([0.0, 0.0, 0.68], [l, w, 0.72], paint));
        parts.push(cuboid(
            [-0.25, 0.0, 1.27],
            [l * 0.52, w - 0.16, 0.48],
            glass,
        ));
        parts.push(cuboid([-0.25, 0.0, 1.53], [l * 0.5, w - 0.2, 0.04], paint));
    }
    for (x, y) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        parts.push(cuboid(
            [x * (l / 2.0 - 0.9), y * (w / 2.0 - 0.12), 0.33],
            [0.66, 0.26, 0.66],
            tyre,
        ));
    }
    let lamp = if braking { BRAKE_ON } else { BRAKE_OFF };
    let z = if truck { 0.9 } else { 0.85 };
    for y in [w / 2.0 - 0.22, -(w / 2.0 - 0.22)] {
        parts.push(plate(
            [-l / 2.0 - 0.01, y, z],
            0.14,
            4,
            std::f64::consts::PI,
            lamp,
            braking,
        ));
        parts.push(plate(
            [l / 2.0 + 0.01, y, 0.75],
            0.12,
            6,
            0.0,
            [225.0, 225.0, 210.0],
            false,
        ));
    }
    parts
}

/// A pedestrian, 1.6–1.9 m tall.
pub fn pedestrian(d: &mut Draw) -> Vec<Part> {
    let h = d.range(1.6, 1.9);
    let shirt = d.pick(&[
        [200.0, 40.0, 40.0],
        [40.0, 90.0, 180.0],
        [230.0, 200.0, 60.0],
        [60.0, 60.0, 60.0],
        [235.0, 235.0, 235.0],
        [60.0, 140.0, 80.0],
    ]);
    let legs = d.pick(&[[40.0, 45.0, 70.0], [30.0, 30.0, 30.0], [120.0, 100.0, 80.0]]);
    let skin = d.pick(&[
        [224.0, 182.0, 150.0],
        [160.0, 112.0, 80.0],
        [96.0, 64.0, 46.0],
    ]);
    let leg_h = h * 0.48;
    let torso_h = h * 0.36;
    vec![
        cuboid([0.0, 0.0, leg_h / 2.0], [0.28, 0.36, leg_h], legs),
        cuboid(
            [0.0, 0.0, leg_h + torso_h / 2.0],
            [0.3, 0.48, torso_h],
            shirt,
        ),
        cuboid([0.0, 0.0, h - 0.1], [0.22, 0.2, 0.22], skin),
    ]
}

/// A cyclist on a bicycle.
pub fn cyclist(d: &mut Draw) -> Vec<Part> {
    let mut parts = vec![
        cuboid([0.0, 0.0, 0.55], [1.7, 0.08, 0.7], [30.0, 30.0, 34.0]),
        cuboid([0.55, 0.0, 0.35], [0.7, 0.06, 0.7], [20.0, 20.0, 20.0]),
        cuboid([-0.55, 0.0, 0.35], [0.7, 0.06, 0.7], [20.0, 20.0, 20.0]),
    ];
    for p in pedestrian(d) {
        if let Part::Cuboid {
            centre,
            half,
            color,
        } = p
        {
            parts.push(Part::Cuboid {
                centre: [centre[0] - 0.1, centre[1], centre[2] + 0.35],
                half,
                color,
            });
        }
    }
    parts
}

/// A stop sign on its pole, the face looking along local `-x` (towards traffic coming along
/// `+x`).
pub fn stop_sign() -> Vec<Part> {
    let back = std::f64::consts::PI;
    vec![
        cuboid([0.0, 0.0, 1.05], [0.07, 0.07, 2.1], [150.0, 150.0, 155.0]),
        plate(
            [-0.05, 0.0, 2.25],
            0.42,
            8,
            back,
            [240.0, 240.0, 240.0],
            false,
        ),
        plate([-0.06, 0.0, 2.25], 0.37, 8, back, SIGN_RED, false),
        cuboid(
            [-0.07, 0.0, 2.25],
            [0.005, 0.36, 0.09],
            [240.0, 240.0, 240.0],
        ),
    ]
}

/// Traffic-light state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightState {
    /// Red.
    Red,
    /// Amber.
    Amber,
    /// Green.
    Green,
}

impl LightState {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            LightState::Red => "red",
            LightState::Amber => "amber",
            LightState::Green => "green",
        }
    }
}

/// A traffic light on a mast arm: the pole at local `(0, 0)`, the arm reaching `arm` m to the
/// left (local `+y`), the head at its end at 5.2 m facing local `-x`.
pub fn traffic_light(state: LightState, arm: f64) -> Vec<Part> {
    let back = std::f64::consts::PI;
    let grey: Rgb = [120.0, 122.0, 126.0];
    let mut parts = vec![
        cuboid([0.0, 0.0, 2.9], [0.16, 0.16, 5.8], grey),
        cuboid([0.0, arm / 2.0, 5.75], [0.12, arm, 0.12], grey),
        cuboid([0.0, arm, 5.2], [0.3, 0.36, 1.05], [24.0, 24.0, 26.0]),
    ];
    for (k, (s, lit)) in [
        (LightState::Red, LAMP_RED),
        (LightState::Amber, LAMP_AMBER),
        (LightState::Green, LAMP_GREEN),
    ]
    .into_iter()
    .enumerate()
    {
        let on = s == state;
        parts.push(plate(
            [-0.16, arm, 5.52 - 0.32 * k as f64],
            0.13,
            12,
            back,
            if on { lit } else { LAMP_OFF },
            on,
        ));
    }
    parts
}

/// A tree: trunk and crown.
pub fn tree(d: &mut Draw) -> Vec<Part> {
    let h = d.range(2.0, 3.2);
    let c = d.range(2.0, 3.6);
    let green = d.pick(&[[52.0, 96.0, 40.0], [70.0, 110.0, 48.0], [40.0, 80.0, 44.0]]);
    vec![
        cuboid([0.0, 0.0, h / 2.0], [0.3, 0.3, h], [92.0, 70.0, 50.0]),
        cuboid([0.0, 0.0, h + c / 2.0 - 0.3], [c, c, c], green),
    ]
}

/// A building block (footprint `len × depth`, height `h`).
pub fn building(d: &mut Draw, len: f64, depth: f64) -> Vec<Part> {
    let h = d.range(7.0, 20.0);
    let wall = d.pick(&[
        [196.0, 180.0, 160.0],
        [170.0, 150.0, 140.0],
        [210.0, 205.0, 195.0],
        [150.0, 120.0, 100.0],
        [180.0, 186.0, 190.0],
    ]);
    vec![cuboid([0.0, 0.0, h / 2.0], [len, depth, h], wall)]
}

/// A traffic cone.
pub fn cone() -> Vec<Part> {
    vec![
        cuboid([0.0, 0.0, 0.35], [0.32, 0.32, 0.7], [245.0, 110.0, 20.0]),
        cuboid([0.0, 0.0, 0.45], [0.33, 0.33, 0.1], [240.0, 240.0, 240.0]),
    ]
}

/// A solid at rest.
pub fn at_rest(
    parts: Vec<Part>,
    pos: [f64; 2],
    yaw: f64,
    tag: Option<(ObjectClass, u64)>,
) -> Solid {
    Solid {
        parts,
        pos,
        yaw,
        speed: 0.0,
        accel: 0.0,
        tag,
    }
}
