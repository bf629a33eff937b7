//! AlpaSim's `egodriver.EgodriverService` gRPC contract, both ways round.
//!
//! - [`Client`]: a remote driving policy as a [`Planner`](crate::Planner). One
//!   [`plan`](crate::Planner::plan) call is one session: `start_session`, the camera frames
//!   (`submit_image_observation`, oldest first), the ego history
//!   (`submit_egomotion_observation`), `drive`, and `close_session` (always, best effort).
//! - [`serve`]: any [`Planner`](crate::Planner) as an egodriver service, for AlpaSim-style
//!   runtimes and carla-driver-interface clients.
//!
//! Times: fogline's clips are relative to `t0`; on the wire `t0` is [`T0_US`] and every
//! other time is `T0_US + t·10⁶` µs. Frames: the "local" frame of the contract is the rig
//! frame at `t0` (x forward, y left, z up), so the ego history ends at the identity pose.
//! Cameras are declared as contract revision 2 ([`CONTRACT_REVISION`]) declares them:
//! `rig_to_camera` is the camera's optical frame (x right, y down, z along the axis), and
//! the client says so in the [`CONTRACT_METADATA_KEY`] metadata of `start_session`.
//!
//! See `docs/remote.md` for the whole contract as fogline speaks it.

mod client;
mod server;

pub use client::{Client, ClientOptions, channel, declare_camera, endpoint_url};
pub use server::{ServeOptions, parse_camera_map, serve, serve_contract};

pub use crate::{ImageFormat, Limits, ServerHandle};

/// The generated messages and service of the contract (our own `.proto` files under
/// `crates/remote/proto/`, wire-compatible with AlpaSim's).
#[allow(missing_docs, clippy::all, clippy::pedantic)]
pub mod wire {
    /// Package `common`: poses, trajectories, versions.
    pub mod common {
        tonic::include_proto!("common");
    }
    /// Package `nre.grpc.protos.sensorsim` (the camera declarations only).
    pub mod nre {
        /// `nre.grpc`.
        pub mod grpc {
            /// `nre.grpc.protos`.
            pub mod protos {
                /// `nre.grpc.protos.sensorsim`.
                pub mod sensorsim {
                    tonic::include_proto!("nre.grpc.protos.sensorsim");
                }
            }
        }
    }
    /// Package `egodriver`: the service and its messages.
    pub mod egodriver {
        tonic::include_proto!("egodriver");
    }
}

/// The gRPC metadata key of the contract revision (carla-driver-interface's convention).
pub const CONTRACT_METADATA_KEY: &str = "carla-driver-interface-contract";

/// The contract revision fogline speaks: `rig_to_camera` is the camera's optical frame.
pub const CONTRACT_REVISION: u32 = 2;

/// The wire time of `t0`, µs (10 s: every time of a clip, from `t0 − 1.5 s` on, is
/// positive, as the contract's unsigned timestamps need).
pub const T0_US: u64 = 10_000_000;

/// The largest gRPC message either end sends or accepts (32 MiB: one camera frame per
/// message, and a 4K PNG fits).
pub const MAX_MESSAGE_BYTES: usize = 32 * 1024 * 1024;

/// The `alpasim_grpc` API version the contract was taken from, reported by `get_version`.
pub const ALPASIM_API_VERSION: (u32, u32, u32) = (0, 55, 0);

/// The default keys of a JSON `unstructured_debug_info` that hold the explanation, in
/// order of preference.
pub const DEFAULT_EXPLANATION_FIELDS: [&str; 3] = ["coc", "reasoning", "explanation"];

/// Wire time of a time relative to `t0`, s.
pub(crate) fn wire_time(t_s: f64) -> u64 {
    (T0_US as f64 + t_s * 1e6).round().max(0.0) as u64
}

/// A wire pose from a translation and a `[w, x, y, z]` quaternion (the contract's floats).
pub(crate) fn wire_pose(x: f64, y: f64, z: f64, q: [f64; 4]) -> wire::common::Pose {
    wire::common::Pose {
        vec: Some(wire::common::Vec3 {
            x: x as f32,
            y: y as f32,
            z: z as f32,
        }),
        quat: Some(wire::common::Quat {
            w: q[0] as f32,
            x: q[1] as f32,
            y: q[2] as f32,
            z: q[3] as f32,
        }),
    }
}

/// A wire pose at `(x, y, z)` heading `yaw` about z.
pub(crate) fn wire_pose_yaw(x: f64, y: f64, z: f64, yaw: f64) -> wire::common::Pose {
    wire_pose(x, y, z, crate::geom::quat_from_yaw(yaw))
}
