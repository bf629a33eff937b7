//! The simulator's side of one egodriver session, one step at a time: what AlpaSim's runtime
//! (or carla-driver-interface's loop) sends a driver every step — a frame of one camera, the
//! ego's newest pose, then `drive`. The latency benchmark (`fogline bench guard`), the
//! guard's tests and the load suite drive the guard, or a driver directly, with it.
//!
//! The ego moves straight along the local x axis at a constant speed; step `k` is at
//! `T0_US + k · STEP_US`. The first step also sends the 20 poses before it (2 s of history).
//!
//! ```no_run
//! # async fn demo(png: Vec<u8>) -> Result<(), Box<dyn std::error::Error>> {
//! use fogline_guard::session::{LoopSession, connect};
//! use fogline_types::clip::{CameraCalib, CameraId};
//!
//! let rpc = connect("127.0.0.1:50052".parse()?).await?;
//! let calib = CameraCalib::standard(CameraId::FrontWide, 576, 320);
//! let mut s = LoopSession::start(rpc, "run-1", &calib, 8.0).await?;
//! let step = s.step(png).await?;
//! println!("answered in {:.1} ms", step.cycle_ms);
//! s.close().await?;
//! # Ok(()) }
//! ```

use std::net::SocketAddr;
use std::time::Instant;

use fogline_remote::egodriver::wire::common::{DynamicState, Pose, PoseAtTime, Trajectory, Vec3};
use fogline_remote::egodriver::wire::egodriver::drive_session_request::rollout_spec::VehicleDefinition;
use fogline_remote::egodriver::wire::egodriver::drive_session_request::{DebugInfo, RolloutSpec};
use fogline_remote::egodriver::wire::egodriver::egodriver_service_client::EgodriverServiceClient;
use fogline_remote::egodriver::wire::egodriver::rollout_camera_image::CameraImage;
use fogline_remote::egodriver::wire::egodriver::{
    DriveRequest, DriveResponse, DriveSessionCloseRequest, DriveSessionRequest, RolloutCameraImage,
    RolloutEgoTrajectory,
};
use fogline_remote::egodriver::{MAX_MESSAGE_BYTES, T0_US, declare_camera};
use fogline_types::clip::CameraCalib;
use tonic::Status;
use tonic::transport::Channel;

/// A client of the egodriver contract.
pub type Rpc = EgodriverServiceClient<Channel>;

/// The time between two steps, µs (10 Hz, AlpaSim's default).
pub const STEP_US: u64 = 100_000;

/// Poses sent before the first step.
const HISTORY_POSES: u64 = 20;

/// Connects to an egodriver server (the guard or a driver) on `addr`.
pub async fn connect(addr: SocketAddr) -> Result<Rpc, tonic::transport::Error> {
    let rpc = EgodriverServiceClient::connect(format!("http://{addr}")).await?;
    Ok(rpc
        .max_decoding_message_size(MAX_MESSAGE_BYTES)
        .max_encoding_message_size(MAX_MESSAGE_BYTES))
}

/// One session, stepped by [`LoopSession::step`].
#[derive(Debug)]
pub struct LoopSession {
    rpc: Rpc,
    uuid: String,
    logical_id: String,
    speed_mps: f64,
    steps: u64,
}

/// One step's answer and its timings (wall clock, this side of the wire).
#[derive(Debug, Clone)]
pub struct LoopStep {
    /// The `drive` answer.
    pub response: DriveResponse,
    /// The whole step: frame, pose and `drive`, ms.
    pub cycle_ms: f64,
    /// The `drive` call alone, ms.
    pub drive_ms: f64,
}

fn pose_at(speed_mps: f64, t_us: u64) -> (PoseAtTime, DynamicState) {
    let t_s = (t_us as f64 - T0_US as f64) / 1e6;
    let pose = PoseAtTime {
        pose: Some(Pose {
            vec: Some(Vec3 {
                x: (speed_mps * t_s) as f32,
                y: 0.0,
                z: 0.0,
            }),
            quat: Some(fogline_remote::egodriver::wire::common::Quat {
                w: 1.0,
                x: 0.0,
                y: 0.0,
                z: 0.0,
            }),
        }),
        timestamp_us: t_us,
    };
    let state = DynamicState {
        linear_velocity: Some(Vec3 {
            x: speed_mps as f32,
            y: 0.0,
            z: 0.0,
        }),
        ..Default::default()
    };
    (pose, state)
}

impl LoopSession {
    /// Opens session `uuid` declaring one camera, `calib` (its PhysicalAI name is its
    /// logical id); the ego drives at `speed_mps`.
    pub async fn start(
        mut rpc: Rpc,
        uuid: &str,
        calib: &CameraCalib,
        speed_mps: f64,
    ) -> Result<Self, Status> {
        let camera = declare_camera(calib);
        let logical_id = camera.logical_id.clone();
        rpc.start_session(DriveSessionRequest {
            session_uuid: uuid.into(),
            random_seed: 0,
            debug_info: Some(DebugInfo {
                scene_id: "fogline-guard-loop".into(),
            }),
            rollout_spec: Some(RolloutSpec {
                vehicle: Some(VehicleDefinition {
                    available_cameras: vec![camera],
                }),
            }),
        })
        .await?;
        Ok(Self {
            rpc,
            uuid: uuid.into(),
            logical_id,
            speed_mps,
            steps: 0,
        })
    }

    /// The session's id.
    pub fn uuid(&self) -> &str {
        &self.uuid
    }

    /// One step: `image_bytes` (PNG or JPEG) of the declared camera, the ego's pose, and
    /// `drive` at the step's time.
    pub async fn step(&mut self, image_bytes: Vec<u8>) -> Result<LoopStep, Status> {
        let t_us = T0_US + self.steps * STEP_US;
        let first = if self.steps == 0 { HISTORY_POSES } else { 0 };
        let (poses, states): (Vec<_>, Vec<_>) = (0..=first)
            .rev()
            .map(|k| pose_at(self.speed_mps, t_us - k * STEP_US))
            .unzip();
        let start = Instant::now();
        self.rpc
            .submit_image_observation(RolloutCameraImage {
                session_uuid: self.uuid.clone(),
                camera_image: Some(CameraImage {
                    frame_start_us: t_us,
                    frame_end_us: t_us,
                    image_bytes,
                    logical_id: self.logical_id.clone(),
                }),
            })
            .await?;
        self.rpc
            .submit_egomotion_observation(RolloutEgoTrajectory {
                session_uuid: self.uuid.clone(),
                trajectory: Some(Trajectory { poses }),
                dynamic_states: states,
            })
            .await?;
        let drive_start = Instant::now();
        let response = self
            .rpc
            .drive(DriveRequest {
                session_uuid: self.uuid.clone(),
                time_now_us: t_us,
                time_query_us: t_us + STEP_US,
                renderer_data: Vec::new(),
            })
            .await?
            .into_inner();
        let drive_ms = drive_start.elapsed().as_secs_f64() * 1e3;
        let cycle_ms = start.elapsed().as_secs_f64() * 1e3;
        self.steps += 1;
        Ok(LoopStep {
            response,
            cycle_ms,
            drive_ms,
        })
    }

    /// Closes the session.
    pub async fn close(&mut self) -> Result<(), Status> {
        self.rpc
            .close_session(DriveSessionCloseRequest {
                session_uuid: self.uuid.clone(),
            })
            .await?;
        Ok(())
    }
}
