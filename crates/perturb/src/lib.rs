//! Exact, seeded sensor corruptions and perception deficits on RGB pixel buffers.
//!
//! Use this crate to turn a clean camera frame into the frame a degraded sensor would have
//! delivered: the envelope paper's grid (Gaussian noise, gain, fog), the robustness
//! benchmarks' families (shot and impulse noise, contrast, saturation, defocus and motion
//! blur, JPEG, pixelation, colour quantisation, dead pixels, lens dirt, glare), temporal faults
//! (frame drop, latency, blackout, freeze) and the LLM-RCO paper's perception deficits (object
//! boxes blacked out with a red outline). It is pure: pixel buffers in, pixel buffers out, no
//! files, no threads, no OS randomness.
//!
//! ```
//! use fogline_perturb::{Frame, FrameInput, FrameKey, Perturbation};
//!
//! let grey = Frame::filled(64, 48, [128, 128, 128])?;
//! let noisy = Perturbation::parse("noise_30")?.prepare(7)?;
//! let out = noisy.apply(&FrameInput::new(&grey, FrameKey::new(0, 0, 0)))?;
//! assert_ne!(out.frame, grey);
//! // Same seed, same key, same condition: the same bytes, whatever thread runs it.
//! let again = noisy.apply(&FrameInput::new(&grey, FrameKey::new(0, 0, 0)))?;
//! assert_eq!(out.frame, again.frame);
//! // A chain: noise, then the paper's `dark` gain.
//! let chain = Perturbation::parse("noise_30+dark")?.prepare(7)?;
//! assert_eq!(chain.perturbation().steps.len(), 2);
//! # Ok::<(), fogline_perturb::PerturbError>(())
//! ```
//!
//! # Families and names
//!
//! `J` is an input sample (one channel of one pixel, 0–255), `⌊v + ½⌋` is rounding to nearest
//! (ties up), every output is clipped to [0, 255]. A condition name is one step or several
//! joined by `+` (applied left to right); `clean` is the identity. The paper's names
//! (`noise_<σ>`, `dark`, `bright`, `fog_<NN>`) are parsed by [`fogline_types::Condition`].
//!
//! | name | family | formula | identity |
//! |---|---|---|---|
//! | `noise_<σ>` | `gaussian_noise` | `clip(J + K)`, `P(K = k) = Φ((k+½)/σ) − Φ((k−½)/σ)`, sampled exactly ([`noise`]) | σ = 0 |
//! | `dark`, `bright`, `gain_<g>` | `brightness` | `⌊g·J + ½⌋` (`dark` g = 0.4, `bright` g = 1.6) | g = 1 |
//! | `fog_<NN>`, `fog_<α>` | `fog` | no depth: `⌊(1−α)·J + α·A + ½⌋`; with depth `d`: `⌊A + (J − A)·t + ½⌋`, `t = exp(−β·d)`, `β = −ln(1−α)/50 m` | α = 0 |
//! | `visibility_<V>` | `fog_visibility` | Koschmieder with `β = 3.912/V` (needs depth) | — |
//! | `shot_<s>` | `shot_noise` | `⌊s·N + ½⌋`, `N ~ Poisson(J/s)`, exact table sampling | s = 0 |
//! | `impulse_<p>` | `impulse_noise` | 0 or 255 with probability `p/2` each | p = 0 |
//! | `contrast_<c>` | `contrast` | `⌊m + c·(J − m) + ½⌋`, `m` = the frame's mean sample | c = 1 |
//! | `saturation_<s>` | `saturation` | `⌊L + s·(J − L) + ½⌋`, `L` = BT.601 luma of the pixel | s = 1 |
//! | `defocus_<r>` | `defocus_blur` | mean over the disk `dx² + dy² <= r²` (integer rounding) | r < 1 |
//! | `motion_<L>` | `motion_blur` | mean over `L` pixels along a line (angle 0 = horizontal) | L = 1 |
//! | `jpeg_<q>` | `jpeg` | the lossy half of a baseline JPEG round trip at quality q ([`jpeg`]) | — |
//! | `pixelate_<b>` | `pixelate` | mean of each `b × b` tile | b = 1 |
//! | `quantize_<bits>` | `quantize` | `⌊⌊J·L/255 + ½⌋·255/L + ½⌋`, `L = 2^bits − 1` | bits = 8 |
//! | `dead_<p>` | `dead_pixels` | each pixel black with probability p, fixed per camera | p = 0 |
//! | `dirt_<n>` | `lens_dirt` | n opaque discs, radius 2–6 % of min(W, H), fixed per camera | n = 0 |
//! | `glare_<s>` | `glare` | `⌊J + (255 − J)·s·gx·gy + ½⌋`, Gaussian spot at (0.7 W, 0.3 H), σ = 0.15·diagonal | s = 0 |
//! | `drop_<p>`, `latency_<k>`, `blackout_<f>`, `freeze_<f>` | temporal ([`temporal`]) | which captured frame is delivered | p = 0, k = 0 |
//! | `mask_all`, `mask_class_<c>`, `mask_track_<id>` | `deficit_mask` | boxes filled black, red 2 px outline ([`deficit`]) | — |
//!
//! `A` (airlight) is 204 by default ([`params::DEFAULT_AIRLIGHT`]); every parameter that a
//! name does not carry is a public field of the family's `XxxParams` (build a [`Step`] and
//! [`Perturbation::from_steps`] to change it).
//!
//! # Determinism
//!
//! Every random draw comes from a [`rng::WyRand`] stream (Gaussian noise: eight
//! [`rng::Xoshiro8`] lanes seeded from one) seeded with
//! [`rng::child`]`(seed, path)`:
//!
//! - pixel noise: `path = [clip, camera, frame, condition, step]` then `[row]` per image row,
//!   where `condition` is [`rng::name_id`] of the condition's name and `step` its position in
//!   the chain;
//! - defects fixed to a camera (dead pixels, lens dirt): `[clip, camera, condition, step]`;
//! - frame drops: `[clip, camera, condition, step]` then `[frame]`.
//!
//! So a frame's output depends only on (seed, clip, camera, frame, condition) and its pixels:
//! it is bit-identical across runs, thread counts and processing orders. Across platforms the
//! integer kernels (noise, gain, fog without depth, blurs, masks) are identical too; the
//! Koschmieder fog and JPEG use single-precision arithmetic and the noise tables `exp` from
//! the platform's maths library, so a different CPU architecture may differ in rare samples.

pub mod blur;
pub mod bytemap;
pub mod deficit;
pub mod error;
pub mod frame;
pub mod jpeg;
pub mod noise;
pub mod occlusion;
pub mod params;
pub mod perturbation;
pub mod photometric;
pub mod rng;
pub mod temporal;

pub use deficit::{DeficitParams, DeficitRegion, DeficitTarget, Outline};
pub use error::PerturbError;
pub use frame::{DepthMap, Frame, FrameKey, FrameMut, FrameRef, ObjectBox, PixelRect};
pub use perturbation::{Applied, FrameInput, Perturbation, Prepared, Step};
pub use temporal::FrameSource;
