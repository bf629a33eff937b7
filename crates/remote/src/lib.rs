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
