//! Temporal faults of one camera's stream, from its frames in order: blackout (black
//! frames), dropped frames (the previous frame delivered again once) and a frozen camera
//! (the same frame delivered again and again).
//!
//! A repeated frame is bit-identical to the one before it (that is how a camera or a
//! transport repeats a frame, and how `fogline perturb` injects `drop_<p>` and `freeze_<f>`),
//! while two captures of a live scene always differ somewhere: sensor noise alone changes
//! most pixels. So a repeat is a frame whose sampled pixels differ from the previous
//! frame's by at most [`TemporalParams::repeat_diff`] on average.

use serde::{Deserialize, Serialize};

use crate::{MonitorError, check};

/// Parameters of [`TemporalMonitor`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TemporalParams {
    /// A frame whose sampled pixels average at most this level (0–255) and none of which
    /// exceeds `4 ×` it is black.
    pub black_level: f64,
    /// A frame whose sampled pixels differ from the previous frame's by at most this much
    /// on average (levels) repeats it.
    pub repeat_diff: f64,
    /// This many repeats in a row mean the camera is frozen (fewer: dropped frames).
    pub frozen_after: usize,
}

impl Default for TemporalParams {
    fn default() -> Self {
        Self {
            black_level: 2.0,
            repeat_diff: 0.01,
            frozen_after: 2,
        }
    }
}

impl TemporalParams {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), MonitorError> {
        if !(self.black_level.is_finite() && (0.0..64.0).contains(&self.black_level)) {
            return Err(MonitorError::Params {
                what: "black_level",
                expected: "a level in [0, 64)",
            });
        }
        if !(self.repeat_diff.is_finite() && (0.0..8.0).contains(&self.repeat_diff)) {
            return Err(MonitorError::Params {
                what: "repeat_diff",
                expected: "a level difference in [0, 8)",
            });
        }
        if self.frozen_after == 0 {
            return Err(MonitorError::Params {
                what: "frozen_after",
                expected: "at least 1 repeat",
            });
        }
        Ok(())
    }
}

/// What [`TemporalMonitor::step`] found in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TemporalReading {
    /// The frame is black (blackout).
    pub black: bool,
    /// The frame repeats the previous one (not counting black frames).
    pub repeated: bool,
    /// A repeat in a run shorter than `frozen_after`: a dropped frame.
    pub dropped: bool,
    /// A repeat in a run of `frozen_after` or more: the camera is frozen.
    pub frozen: bool,
    /// Repeats in a row up to this frame.
    pub repeat_run: usize,
    /// Mean absolute difference of the sampled pixels from the previous frame (levels;
    /// `None` for the first frame or after a size change): the evidence for `repeated`,
    /// with the threshold `repeat_diff` it is compared with as its margin.
    pub mean_abs_diff: Option<f64>,
    /// Mean level of the sampled pixels: the evidence for `black`.
    pub mean_level: f64,
}

impl TemporalReading {
    /// Any fault in this frame.
    pub fn faulty(&self) -> bool {
        self.black || self.repeated
    }
}

/// Follows one camera's stream frame by frame (one monitor per camera).
///
/// ```
/// use fogline_monitor::{TemporalMonitor, TemporalParams};
/// let mut m = TemporalMonitor::new(TemporalParams::default())?;
/// let a: Vec<u8> = (0..32 * 24 * 3).map(|i| (i * 7 % 251) as u8).collect();
/// let b: Vec<u8> = a.iter().map(|v| v.wrapping_add(3)).collect();
/// assert!(!m.step(&a, 32, 24)?.faulty());
/// assert!(m.step(&a, 32, 24)?.dropped);             // the same frame again
/// assert!(m.step(&a, 32, 24)?.frozen);              // and again
/// assert!(!m.step(&b, 32, 24)?.faulty());           // live again
/// assert!(m.step(&vec![0; 32 * 24 * 3], 32, 24)?.black);
/// # Ok::<(), fogline_monitor::MonitorError>(())
/// ```
#[derive(Debug, Clone)]
pub struct TemporalMonitor {
    params: TemporalParams,
    /// The previous frame's size and sampled bytes.
    previous: Option<(usize, usize, Vec<u8>)>,
    repeat_run: usize,
}

/// Pixels sampled per frame (a regular grid, all three channels).
const SAMPLED_PIXELS: usize = 16_000;

impl TemporalMonitor {
    /// A monitor that has seen no frame yet.
    pub fn new(params: TemporalParams) -> Result<Self, MonitorError> {
        params.validate()?;
        Ok(Self {
            params,
            previous: None,
            repeat_run: 0,
        })
    }

    /// Reads the next frame of the stream (RGB8, `width × height`).
    ///
    /// Cost: about 16,000 pixels read and kept (≈ 0.02 ms a 1080p frame).
    pub fn step(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
    ) -> Result<TemporalReading, MonitorError> {
        check(rgb, width, height)?;
        let step = (((width * height) as f64 / SAMPLED_PIXELS as f64)
            .sqrt()
            .floor() as usize)
            .max(1);
        let mut sampled = Vec::with_capacity(3 * SAMPLED_PIXELS + 64);
        for y in (0..height).step_by(step) {
            for x in (0..width).step_by(step) {
                let i = (y * width + x) * 3;
                sampled.extend_from_slice(&rgb[i..i + 3]);
            }
        }
        let n = sampled.len() as f64;
        let sum: u64 = sampled.iter().map(|&v| u64::from(v)).sum();
        let mean_level = sum as f64 / n;
        let max = sampled.iter().copied().max().unwrap_or(0);
        let black = mean_level <= self.params.black_level
            && f64::from(max) <= 4.0 * self.params.black_level.max(0.25);
        let mean_abs_diff = match &self.previous {
            Some((w, h, prev)) if *w == width && *h == height => {
                let d: u64 = prev
                    .iter()
                    .zip(&sampled)
                    .map(|(&p, &q)| u64::from(p.abs_diff(q)))
                    .sum();
                Some(d as f64 / n)
            }
            _ => None,
        };
        let repeated = !black && mean_abs_diff.is_some_and(|d| d <= self.params.repeat_diff);
        self.repeat_run = if repeated { self.repeat_run + 1 } else { 0 };
        self.previous = Some((width, height, sampled));
        Ok(TemporalReading {
            black,
            repeated,
            dropped: repeated && self.repeat_run < self.params.frozen_after,
            frozen: repeated && self.repeat_run >= self.params.frozen_after,
            repeat_run: self.repeat_run,
            mean_abs_diff,
            mean_level,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A frame of a live scene: a pattern moved by `shift` with a little noise.
    fn live(w: usize, h: usize, shift: usize) -> Vec<u8> {
        (0..w * h * 3)
            .map(|i| ((i + shift) * 13 % 200 + (i * 7 + shift * 31) % 3) as u8)
            .collect()
    }

    #[test]
    fn r20_repeats_blackouts_and_runs_are_told_apart() {
        let (w, h) = (64, 48);
        let mut m = TemporalMonitor::new(TemporalParams::default()).unwrap();
        let black = vec![0u8; w * h * 3];
        // live, live, drop, live, freeze ×3, black ×2, live.
        let seq = [
            live(w, h, 0),
            live(w, h, 1),
            live(w, h, 1),
            live(w, h, 2),
            live(w, h, 2),
            live(w, h, 2),
            live(w, h, 2),
            black.clone(),
            black,
            live(w, h, 3),
        ];
        let r: Vec<TemporalReading> = seq.iter().map(|f| m.step(f, w, h).unwrap()).collect();
        let flags: Vec<(bool, bool, bool)> =
            r.iter().map(|r| (r.black, r.dropped, r.frozen)).collect();
        let (n, d, f, b) = (
            (false, false, false),
            (false, true, false),
            (false, false, true),
            (true, false, false),
        );
        assert_eq!(flags, [n, n, d, n, d, f, f, b, b, n]);
        assert_eq!(r[0].mean_abs_diff, None);
        assert_eq!(r[6].repeat_run, 3);
        assert!(r[1].mean_abs_diff.unwrap() > 1.0);
        // A size change starts over.
        assert_eq!(
            m.step(&live(32, 24, 0), 32, 24).unwrap().mean_abs_diff,
            None
        );
        assert!(m.step(&[0u8; 5], 2, 2).is_err());
        let bad = TemporalParams {
            frozen_after: 0,
            ..TemporalParams::default()
        };
        assert!(TemporalMonitor::new(bad).is_err());
    }
}
