//! Integration tests of fogline-perturb: the "must show" list of issue 3.

#![allow(clippy::unwrap_used)]

mod determinism;
mod faults;
mod formulas;
mod invariants;
mod statistics;

use fogline_perturb::{Frame, FrameInput, FrameKey, Perturbation};

/// A frame whose samples cycle through every value 0–255 in a scrambled order.
pub fn ramp(width: u32, height: u32) -> Frame {
    let n = (width * height * 3) as usize;
    let data = (0..n).map(|i| ((i * 7 + i / 256) % 256) as u8).collect();
    Frame::new(width, height, data).unwrap()
}

/// `name` applied with `seed` to `frame` under `key`.
pub fn apply(name: &str, seed: u64, frame: &Frame, key: FrameKey) -> Frame {
    Perturbation::parse(name)
        .unwrap()
        .prepare(seed)
        .unwrap()
        .apply(&FrameInput::new(frame, key))
        .unwrap()
        .frame
}
