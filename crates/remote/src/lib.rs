//! Planners behind an endpoint, both ways round.
//!
//! - [`Planner`]: the one interface a campaign drives — the reference planner in-process, a
//!   remote policy over AlpaSim's `egodriver.EgodriverService` gRPC contract
//!   ([`egodriver`]), or a planner behind the small HTTP/JSON protocol ([`http`]).
//! - Servers: any [`Planner`] can be served over either protocol, so fogline's reference
//!   planner can be driven by AlpaSim-style runtimes and CARLA bridges.
//!
//! Conventions (those of `fogline_types::clip`): frames are RGB8 row-major, oldest first, at
//! `t0 − 0.1·(n−1−j)` s; the ego history ends at `t0` and is expressed in the rig frame at
//! `t0` (x forward, y left, metres); the answer is 64 waypoints at `t0 + 0.1 … t0 + 6.4` s
//! in the same frame.

pub mod egodriver;
pub mod http;

mod codec;
mod geom;
mod serving;

pub use serving::{Limits, ServerHandle};

/// How a client encodes camera frames for the wire: PNG (lossless, the default: the planner
/// sees exactly the pixels fogline produced) or JPEG at a quality of 1–100 (smaller, lossy;
/// AlpaSim's renderers send JPEG too).
pub use fogline_io::ImageFormat;

pub use fogline_types::planner::{FailureKind, PlanFailure, PlanRequest, Planner};

/// A decoded camera frame: RGB8 row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedFrame {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// `width × height × 3` bytes.
    pub rgb: Vec<u8>,
}

/// Decodes a PNG or JPEG camera frame (as the egodriver contract carries them) to RGB8,
/// refusing from its header alone an image of more than `max_pixels` pixels.
pub fn decode_frame(bytes: &[u8], max_pixels: u64) -> Result<DecodedFrame, String> {
    let d = codec::decode_capped(bytes, max_pixels)?;
    Ok(DecodedFrame {
        width: d.width,
        height: d.height,
        rgb: d.rgb,
    })
}
