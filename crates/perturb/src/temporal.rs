//! Temporal and camera faults: which captured frame (if any) is delivered at each time step.
//!
//! A clip's plan starts as the identity (delivered frame `i` is captured frame `i`) and every
//! temporal step of a condition rewrites it, in the order written:
//!
//! | fault | delivered frame `i` |
//! |---|---|
//! | `drop_<p>` | for `i >= 1`, with probability `p` the previous *delivered* frame again (a dropped frame repeats the last one), else unchanged |
//! | `latency_<k>` | what was delivered at `max(i − k, 0)` |
//! | `freeze_<f>` | what was delivered at `min(i, f)`: the camera freezes at frame `f` |
//! | `blackout_<f>` | black from frame `f` on (a crashed camera; `blackout_0`: the whole clip) |
//!
//! The drop decision of frame `i` draws from `child(seed, [clip, camera, condition, step, i])`,
//! so it does not depend on how many frames are planned. The spatial steps of the condition
//! are then applied to the delivered captured frame under that frame's own key, so a repeated
//! frame is bit-identical to its original; black frames stay black.

use serde::{Deserialize, Serialize};

use crate::rng::{WyRand, child};

/// What is delivered at a time step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameSource {
    /// The captured frame with this index.
    Captured(usize),
    /// A black frame.
    Black,
}

/// One temporal fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Fault {
    Drop(f64),
    Latency(u64),
    Freeze(u64),
    Blackout(u64),
}

/// Rewrites `plan` by `fault`; `stream` is `child(seed, [clip, camera, condition, step])`.
pub(crate) fn rewrite(plan: &mut [FrameSource], fault: Fault, stream: u64) {
    let old = plan.to_vec();
    let n = plan.len();
    match fault {
        Fault::Drop(p) => {
            for i in 1..n {
                if WyRand::new(child(stream, &[i as u64])).bernoulli(p) {
                    plan[i] = plan[i - 1];
                }
            }
        }
        Fault::Latency(k) => {
            for (i, v) in plan.iter_mut().enumerate() {
                *v = old[i.saturating_sub(k.min(usize::MAX as u64) as usize)];
            }
        }
        Fault::Freeze(f) => {
            for (i, v) in plan.iter_mut().enumerate() {
                *v = old[(i as u64).min(f) as usize];
            }
        }
        Fault::Blackout(f) => {
            for (i, v) in plan.iter_mut().enumerate() {
                if i as u64 >= f {
                    *v = FrameSource::Black;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use FrameSource::{Black, Captured};

    fn identity(n: usize) -> Vec<FrameSource> {
        (0..n).map(Captured).collect()
    }

    #[test]
    fn latency_freeze_blackout() {
        let mut p = identity(5);
        rewrite(&mut p, Fault::Latency(2), 0);
        assert_eq!(
            p,
            [
                Captured(0),
                Captured(0),
                Captured(0),
                Captured(1),
                Captured(2)
            ]
        );
        let mut p = identity(4);
        rewrite(&mut p, Fault::Freeze(1), 0);
        assert_eq!(p, [Captured(0), Captured(1), Captured(1), Captured(1)]);
        let mut p = identity(3);
        rewrite(&mut p, Fault::Blackout(1), 0);
        assert_eq!(p, [Captured(0), Black, Black]);
    }

    #[test]
    fn drop_repeats_the_previous_frame_and_is_prefix_stable() {
        let mut long = identity(400);
        rewrite(&mut long, Fault::Drop(0.3), 99);
        let mut short = identity(100);
        rewrite(&mut short, Fault::Drop(0.3), 99);
        assert_eq!(&long[..100], &short[..]);
        assert_eq!(long[0], Captured(0));
        let repeats = (1..400).filter(|&i| long[i] == long[i - 1]).count();
        assert!((80..160).contains(&repeats), "{repeats}");
        let mut none = identity(50);
        rewrite(&mut none, Fault::Drop(0.0), 99);
        assert_eq!(none, identity(50));
    }
}
