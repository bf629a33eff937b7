//! The egodriver client: a remote policy as a [`Planner`].

use std::future::Future;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use fogline_types::clip::{CameraCalib, DT_S, Decision, HORIZON, PlannerOutput, Trajectory};
use tokio::runtime::Runtime;
use tonic::metadata::MetadataValue;
use tonic::transport::{Channel, Endpoint};
use tonic::{Code, Status};

use super::wire::common::{DynamicState, PoseAtTime, Vec3};
use super::wire::egodriver::drive_session_request::rollout_spec::VehicleDefinition;
use super::wire::egodriver::drive_session_request::{DebugInfo, RolloutSpec};
use super::wire::egodriver::egodriver_service_client::EgodriverServiceClient;
use super::wire::egodriver::rollout_camera_image::CameraImage;
use super::wire::egodriver::{
    DriveRequest, DriveResponse, DriveSessionCloseRequest, DriveSessionRequest, RolloutCameraImage,
    RolloutEgoTrajectory,
};
use super::wire::nre::grpc::protos::sensorsim::available_cameras_return::AvailableCamera;
use super::wire::nre::grpc::protos::sensorsim::camera_spec::CameraParam;
use super::wire::nre::grpc::protos::sensorsim::{
    CameraSpec, OpenCvPinholeCameraParam, ShutterType,
};
use super::wire_pose;
use super::{
    CONTRACT_METADATA_KEY, CONTRACT_REVISION, DEFAULT_EXPLANATION_FIELDS, MAX_MESSAGE_BYTES, T0_US,
    wire_time,
};
use crate::geom::{CameraFrame, camera_rotation, quat_from_matrix, quat_from_yaw};
use crate::{FailureKind, ImageFormat, PlanFailure, PlanRequest, Planner, codec};

/// Horizon a plan must cover, s (`HORIZON · DT_S`).
const HORIZON_S: f64 = HORIZON as f64 * DT_S;
/// How much short of the horizon an answer may end (rounding of µs timestamps).
const COVER_TOLERANCE_S: f64 = 0.002;

/// Settings of an egodriver [`Client`].
#[derive(Debug, Clone, PartialEq)]
pub struct ClientOptions {
    /// The policy's address, `host:port` or `http://host:port` (plain), or
    /// `https://host[:port]` (TLS, HTTP/2 negotiated by ALPN).
    pub endpoint: String,
    /// The time limit of each RPC (and of connecting).
    pub timeout: Duration,
    /// How frames are encoded.
    pub image_format: ImageFormat,
    /// Keys of a JSON `unstructured_debug_info` that hold the explanation, in order of
    /// preference.
    pub explanation_fields: Vec<String>,
}

impl Default for ClientOptions {
    fn default() -> Self {
        Self {
            endpoint: "127.0.0.1:50051".into(),
            timeout: Duration::from_secs(30),
            image_format: ImageFormat::Png,
            explanation_fields: DEFAULT_EXPLANATION_FIELDS
                .iter()
                .map(|s| s.to_string())
                .collect(),
        }
    }
}

/// A driving policy behind AlpaSim's egodriver contract, as a [`Planner`].
///
/// Synchronous: each call blocks on an internal tokio runtime, and any number of threads
/// may call at once (their calls share one HTTP/2 connection). The connection is made on
/// first use and remade after a failure. Do not call from inside an async runtime.
pub struct Client {
    opts: ClientOptions,
    channel: Channel,
    // Declared last: dropped after the channel, whose tasks live on it.
    runtime: Runtime,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("egodriver::Client")
            .field("opts", &self.opts)
            .finish_non_exhaustive()
    }
}

impl Client {
    /// A client for `opts.endpoint`. It does not connect yet: an unreachable endpoint shows
    /// up as [`FailureKind::Unavailable`] on the first [`Planner::plan`]. An `https://`
    /// policy's certificate is checked against the bundled roots and the process's CA
    /// certificate file (`fogline_io::http::set_default_ca_cert`, `--ca-cert`).
    pub fn new(opts: ClientOptions) -> Result<Self, PlanFailure> {
        let tls = fogline_io::http::Tls::process_default()
            .map_err(|e| PlanFailure::new(FailureKind::Input, format!("egodriver client: {e}")))?;
        Self::with_tls(opts, tls)
    }

    /// A client for `opts.endpoint` whose `https://` connections are checked by `tls`.
    pub fn with_tls(opts: ClientOptions, tls: fogline_io::http::Tls) -> Result<Self, PlanFailure> {
        let input = |m: String| PlanFailure::new(FailureKind::Input, m);
        if opts.timeout.is_zero() {
            return Err(input(
                "egodriver client: the timeout must be positive".into(),
            ));
        }
        let runtime = crate::serving::client_runtime("fogline-egodriver-client")
            .map_err(|e| input(format!("cannot start the egodriver client runtime: {e}")))?;
        let channel = {
            let _guard = runtime.enter();
            channel(&opts.endpoint, tls, opts.timeout, None).map_err(input)?
        };
        Ok(Self {
            opts,
            channel,
            runtime,
        })
    }

    /// The client's settings.
    pub fn options(&self) -> &ClientOptions {
        &self.opts
    }

    async fn session(
        &self,
        start: DriveSessionRequest,
        cameras: Vec<CameraStream>,
        ego: RolloutEgoTrajectory,
        drive: DriveRequest,
    ) -> Result<PlannerOutput, PlanFailure> {
        let mut rpc = EgodriverServiceClient::new(self.channel.clone())
            .max_decoding_message_size(MAX_MESSAGE_BYTES)
            .max_encoding_message_size(MAX_MESSAGE_BYTES);
        let uuid = start.session_uuid.clone();
        let timeout = self.opts.timeout;
        let mut start = tonic::Request::new(start);
        start.metadata_mut().insert(
            CONTRACT_METADATA_KEY,
            MetadataValue::from(CONTRACT_REVISION),
        );
        start.set_timeout(timeout);
        let started = call("start_session", timeout, rpc.start_session(start)).await;
        let outcome = match started {
            // Nothing was opened on an endpoint that cannot be reached.
            Err(e) if e.kind == FailureKind::Unavailable => return Err(e),
            Err(e) => Err(e),
            Ok(_) => {
                self.observe_and_drive(&mut rpc, &uuid, cameras, ego, drive)
                    .await
            }
        };
        // Always, best effort: the answer (or the first error) is what the caller gets.
        let close = DriveSessionCloseRequest {
            session_uuid: uuid.clone(),
        };
        let limit = timeout.min(Duration::from_secs(5));
        let closed = call(
            "close_session",
            limit,
            rpc.close_session(with_timeout(close, limit)),
        )
        .await;
        if let Err(e) = closed {
            log::debug!("egodriver session {uuid}: {e}");
        }
        outcome
    }

    async fn observe_and_drive(
        &self,
        rpc: &mut EgodriverServiceClient<Channel>,
        uuid: &str,
        cameras: Vec<CameraStream>,
        ego: RolloutEgoTrajectory,
        drive: DriveRequest,
    ) -> Result<PlannerOutput, PlanFailure> {
        let timeout = self.opts.timeout;
        // One task per camera, each sending its frames oldest first as the encoders finish
        // them: the cameras' frames travel and are decoded by the server at once (and while
        // later frames are still being encoded), each camera's still in order.
        let mut tasks = tokio::task::JoinSet::new();
        for (k, camera) in cameras.into_iter().enumerate() {
            let mut rpc = rpc.clone();
            let uuid = uuid.to_string();
            tasks.spawn(async move {
                let CameraStream {
                    logical_id,
                    label,
                    frames,
                } = camera;
                for (j, (t_us, encoded)) in frames.into_iter().enumerate() {
                    let bytes = match encoded.await {
                        Ok(Ok(bytes)) => bytes,
                        Ok(Err(e)) => {
                            return Err((k, input_failure(format!("{label} frame {j}: {e}"))));
                        }
                        Err(_) => {
                            return Err((
                                k,
                                input_failure(format!(
                                    "{label} frame {j}: the encoder stopped before the frame"
                                )),
                            ));
                        }
                    };
                    let image = RolloutCameraImage {
                        session_uuid: uuid.clone(),
                        camera_image: Some(CameraImage {
                            frame_start_us: t_us,
                            frame_end_us: t_us,
                            image_bytes: bytes,
                            logical_id: logical_id.clone(),
                        }),
                    };
                    call(
                        "submit_image_observation",
                        timeout,
                        rpc.submit_image_observation(with_timeout(image, timeout)),
                    )
                    .await
                    .map_err(|e| (k, e))?;
                }
                Ok::<(), (usize, PlanFailure)>(())
            });
        }
        // Every camera's calls end (each stops at its first failure); the failure reported
        // is the first camera's, whichever finished first.
        let mut failed: Option<(usize, PlanFailure)> = None;
        while let Some(joined) = tasks.join_next().await {
            let failure = match joined {
                Ok(Ok(())) => continue,
                Ok(Err(f)) => f,
                Err(e) if e.is_panic() => std::panic::resume_unwind(e.into_panic()),
                // Cancelled: the client's runtime is shutting down.
                Err(e) => (
                    usize::MAX,
                    PlanFailure::new(
                        FailureKind::Unavailable,
                        format!("egodriver submit_image_observation: {e}"),
                    ),
                ),
            };
            if failed.as_ref().is_none_or(|(k, _)| failure.0 < *k) {
                failed = Some(failure);
            }
        }
        if let Some((_, failure)) = failed {
            return Err(failure);
        }
        call(
            "submit_egomotion_observation",
            timeout,
            rpc.submit_egomotion_observation(with_timeout(ego, timeout)),
        )
        .await?;
        let answer = call("drive", timeout, rpc.drive(with_timeout(drive, timeout))).await?;
        read_answer(&answer, &self.opts.explanation_fields)
    }
}

impl Planner for Client {
    fn describe(&self) -> String {
        format!("egodriver at {}", self.opts.endpoint)
    }

    fn plan(&self, request: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        let format = self.opts.image_format;
        let Session {
            start,
            cameras,
            ego,
            drive,
        } = build_session(request, format)?;
        // The frames are encoded on worker threads while the session runs: `start_session`
        // goes out at once, and each frame is sent (and decoded by the server) as soon as it
        // is ready rather than after every frame is encoded. Every camera's oldest frame is
        // encoded first, then every camera's next one, so all cameras start sending early.
        let most = cameras.iter().map(|c| c.frames.len()).max().unwrap_or(0);
        let jobs: Vec<(usize, usize)> = (0..most)
            .flat_map(|j| {
                cameras
                    .iter()
                    .enumerate()
                    .filter(move |(_, c)| j < c.frames.len())
                    .map(move |(k, _)| (k, j))
            })
            .collect();
        let mut senders = Vec::with_capacity(jobs.len());
        let mut receivers: Vec<Vec<_>> = cameras.iter().map(|_| Vec::new()).collect();
        for &(k, _) in &jobs {
            let (tx, rx) = tokio::sync::oneshot::channel::<Result<Vec<u8>, String>>();
            senders.push(std::sync::Mutex::new(Some(tx)));
            // Jobs list each camera's frames oldest first: its receivers come in order.
            receivers[k].push(rx);
        }
        let streams: Vec<CameraStream> = cameras
            .iter()
            .zip(receivers)
            .map(|(c, rx)| CameraStream {
                logical_id: c.calib.id.name().to_string(),
                label: c.calib.id.to_string(),
                frames: c.times.iter().copied().zip(rx).collect(),
            })
            .collect();
        let bytes: usize = cameras
            .iter()
            .flat_map(|c| &c.frames)
            .map(|f| f.len())
            .sum();
        let workers = if bytes < codec::PARALLEL_BYTES {
            1
        } else {
            std::thread::available_parallelism()
                .map_or(1, |n| n.get())
                .min(jobs.len())
                .max(1)
        };
        let next = AtomicUsize::new(0);
        let stop = AtomicBool::new(false);
        std::thread::scope(|s| {
            for _ in 0..workers {
                s.spawn(|| {
                    while !stop.load(Ordering::Relaxed) {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(&(k, j)) = jobs.get(i) else { break };
                        let c = &cameras[k];
                        let encoded =
                            codec::encode(c.frames[j], c.calib.width, c.calib.height, format);
                        let tx = senders[i]
                            .lock()
                            .unwrap_or_else(std::sync::PoisonError::into_inner)
                            .take();
                        if let Some(tx) = tx {
                            // The session may have ended already (a failure): nobody waits.
                            let _ = tx.send(encoded);
                        }
                    }
                });
            }
            let out = self
                .runtime
                .block_on(self.session(start, streams, ego, drive));
            // Frames not yet encoded are not needed any more (the session ended early).
            stop.store(true, Ordering::Relaxed);
            out
        })
    }
}

/// The URL of an egodriver `endpoint`: `host:port` or `http://host:port` (plain HTTP/2) or
/// `https://host[:port]` (TLS). The error names the endpoint and what is wrong with it.
pub fn endpoint_url(endpoint: &str) -> Result<fogline_io::http::BaseUrl, String> {
    let raw = endpoint.trim();
    let url = if raw.starts_with("http://") || raw.starts_with("https://") {
        raw.to_string()
    } else if raw.contains("://") {
        return Err(format!(
            "egodriver endpoint {raw:?}: expected host:port, http://host:port or https://host[:port]"
        ));
    } else {
        format!("http://{raw}")
    };
    let base = fogline_io::http::BaseUrl::parse(&url)
        .map_err(|e| format!("egodriver endpoint {raw:?}: {e}"))?;
    if !base.prefix.is_empty() {
        return Err(format!(
            "egodriver endpoint {raw:?}: a gRPC endpoint takes no path"
        ));
    }
    Ok(base)
}

/// A gRPC channel to an egodriver `endpoint` ([`endpoint_url`]) whose every connection goes
/// through `fogline_io::http::connect` — TLS checked by `tls` for `https://`, HTTP/2 chosen
/// by ALPN `h2` — so certificate problems are said in words. It connects on first use,
/// within `connect_timeout`; `request_timeout` bounds each call when given. Call it inside a
/// tokio runtime (the channel's worker is spawned on it).
pub fn channel(
    endpoint: &str,
    tls: fogline_io::http::Tls,
    connect_timeout: Duration,
    request_timeout: Option<Duration>,
) -> Result<Channel, String> {
    let base = endpoint_url(endpoint)?;
    let raw = endpoint.trim();
    let mut endpoint = Endpoint::from_shared(base.origin())
        .map_err(|e| format!("egodriver endpoint {raw:?}: {e}"))?
        .connect_timeout(connect_timeout)
        .tcp_nodelay(true);
    if let Some(t) = request_timeout {
        endpoint = endpoint.timeout(t);
    }
    let connector = tower::service_fn(move |_: tonic::codegen::http::Uri| {
        let (base, tls) = (base.clone(), tls.clone());
        async move {
            fogline_io::http::connect(&base, &tls, fogline_io::http::Alpn::H2)
                .await
                .map(hyper_util::rt::TokioIo::new)
                .map_err(|e| ConnectFailure(format!("{}: {e}", base.origin())))
        }
    });
    Ok(endpoint.connect_with_connector_lazy(connector))
}

/// Why the connector could not open a connection (its text names the endpoint and the
/// problem: a certificate's, the TCP connection's).
#[derive(Debug)]
struct ConnectFailure(String);

impl std::fmt::Display for ConnectFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ConnectFailure {}

/// The messages of one session, built (and the frames checked) before any RPC; the frames
/// are encoded while the session runs.
struct Session<'a> {
    start: DriveSessionRequest,
    cameras: Vec<CameraFrames<'a>>,
    ego: RolloutEgoTrajectory,
    drive: DriveRequest,
}

/// A camera's frames to send, oldest first, with their wire times.
struct CameraFrames<'a> {
    calib: &'a CameraCalib,
    frames: Vec<&'a [u8]>,
    times: Vec<u64>,
}

/// What a camera's task sends: its frames, oldest first, as the encoders deliver them.
struct CameraStream {
    logical_id: String,
    /// The camera's name in error messages.
    label: String,
    /// Wire time and the encoded frame (or why it could not be encoded).
    frames: Vec<(u64, EncodedFrame)>,
}

/// A frame being encoded: its bytes, or why it could not be encoded, when the encoder is done.
type EncodedFrame = tokio::sync::oneshot::Receiver<Result<Vec<u8>, String>>;

fn input_failure(m: String) -> PlanFailure {
    PlanFailure::new(FailureKind::Input, m)
}

fn build_session<'r>(
    request: &'r PlanRequest<'_>,
    format: ImageFormat,
) -> Result<Session<'r>, PlanFailure> {
    let input = &request.input;
    if input.cameras.is_empty() {
        return Err(input_failure("the request has no camera".into()));
    }
    if input.ego_history.is_empty() {
        return Err(input_failure("the request has no ego history".into()));
    }
    let uuid = codec::session_uuid();
    let mut declared = Vec::with_capacity(input.cameras.len());
    let mut cameras = Vec::with_capacity(input.cameras.len());
    for cam in &input.cameras {
        let c = &cam.calib;
        c.validate().map_err(input_failure)?;
        declared.push(declare_camera(c));
        let n = cam.frames.len();
        // What the encoder would refuse is refused now, before the session opens.
        for (j, f) in cam.frames.iter().enumerate() {
            fogline_io::check_frame(f.len(), c.width, c.height, format)
                .map_err(|e| input_failure(format!("{} frame {j}: {e}", c.id)))?;
        }
        cameras.push(CameraFrames {
            calib: c,
            frames: cam.frames.clone(),
            times: (0..n)
                .map(|j| wire_time(-DT_S * (n - 1 - j) as f64))
                .collect(),
        });
    }
    let mut poses = Vec::with_capacity(input.ego_history.len());
    let mut states = Vec::with_capacity(input.ego_history.len());
    for (k, p) in input.ego_history.iter().enumerate() {
        let vals = [p.t_s, p.x_m, p.y_m, p.yaw_rad, p.speed_mps];
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(input_failure(format!("ego history pose {k} is not finite")));
        }
        if p.t_s > 1e-9 {
            return Err(input_failure(format!(
                "ego history pose {k} is after t0 (t = {} s)",
                p.t_s
            )));
        }
        poses.push(PoseAtTime {
            pose: Some(wire_pose(p.x_m, p.y_m, 0.0, quat_from_yaw(p.yaw_rad))),
            timestamp_us: wire_time(p.t_s),
        });
        states.push(DynamicState {
            linear_velocity: Some(Vec3 {
                x: p.speed_mps as f32,
                y: 0.0,
                z: 0.0,
            }),
            ..Default::default()
        });
    }
    let start = DriveSessionRequest {
        session_uuid: uuid.clone(),
        random_seed: request.seed,
        debug_info: Some(DebugInfo {
            scene_id: request.scene_id.to_string(),
        }),
        rollout_spec: Some(RolloutSpec {
            vehicle: Some(VehicleDefinition {
                available_cameras: declared,
            }),
        }),
    };
    let ego = RolloutEgoTrajectory {
        session_uuid: uuid.clone(),
        trajectory: Some(super::wire::common::Trajectory { poses }),
        dynamic_states: states,
    };
    let drive = DriveRequest {
        session_uuid: uuid,
        time_now_us: T0_US,
        time_query_us: wire_time(HORIZON_S),
        renderer_data: Vec::new(),
    };
    Ok(Session {
        start,
        cameras,
        ego,
        drive,
    })
}

/// A camera as `start_session` declares it: pinhole intrinsics, resolution, the
/// PhysicalAI name (its logical id), and the optical frame's pose in the rig (revision 2).
pub fn declare_camera(c: &CameraCalib) -> AvailableCamera {
    let name = c.id.name().to_string();
    let q = quat_from_matrix(camera_rotation(c, CameraFrame::Optical));
    AvailableCamera {
        intrinsics: Some(CameraSpec {
            camera_param: Some(CameraParam::OpencvPinholeParam(OpenCvPinholeCameraParam {
                principal_point_x: c.cx,
                principal_point_y: c.cy,
                focal_length_x: c.fx,
                focal_length_y: c.fy,
                ..Default::default()
            })),
            logical_id: name.clone(),
            resolution_h: c.height,
            resolution_w: c.width,
            shutter_type: ShutterType::Global as i32,
            ..Default::default()
        }),
        rig_to_camera: Some(wire_pose(c.x_m, c.y_m, c.z_m, q)),
        logical_id: name,
    }
}

fn with_timeout<T>(message: T, timeout: Duration) -> tonic::Request<T> {
    let mut r = tonic::Request::new(message);
    r.set_timeout(timeout);
    r
}

/// Runs one RPC under `timeout` and maps its failure.
async fn call<T>(
    rpc: &'static str,
    timeout: Duration,
    fut: impl Future<Output = Result<tonic::Response<T>, Status>>,
) -> Result<T, PlanFailure> {
    match tokio::time::timeout(timeout, fut).await {
        Err(_) => Err(PlanFailure::new(
            FailureKind::Timeout,
            format!(
                "egodriver {rpc}: no answer within {:.3} s",
                timeout.as_secs_f64()
            ),
        )),
        Ok(Err(status)) => {
            let mut failure = status_failure(rpc, &status);
            if timed_out(&status) {
                failure.message = format!(
                    "egodriver {rpc}: no answer within {:.3} s",
                    timeout.as_secs_f64()
                );
            }
            Err(failure)
        }
        Ok(Ok(r)) => Ok(r.into_inner()),
    }
}

/// The status message and, when tonic kept one, its deepest cause (transport errors).
fn detail(status: &Status) -> String {
    let mut out = status.message().to_string();
    let mut deepest = None;
    let mut source = std::error::Error::source(status);
    while let Some(e) = source {
        deepest = Some(e.to_string());
        source = e.source();
    }
    if let Some(cause) = deepest
        && !cause.is_empty()
        && !out.contains(&cause)
    {
        out.push_str(": ");
        out.push_str(&cause);
    }
    out
}

/// Maps a gRPC status to a failure kind (see `docs/remote.md`).
pub(crate) fn status_failure(rpc: &str, status: &Status) -> PlanFailure {
    let detail = detail(status);
    let (kind, text) = match status.code() {
        _ if timed_out(status) => (
            FailureKind::Timeout,
            format!("egodriver {rpc}: no answer within the time limit: {detail}"),
        ),
        Code::DeadlineExceeded => (
            FailureKind::Timeout,
            format!("egodriver {rpc}: deadline exceeded: {detail}"),
        ),
        Code::Unavailable | Code::Cancelled => (
            FailureKind::Unavailable,
            format!("egodriver {rpc}: endpoint unavailable: {detail}"),
        ),
        Code::Internal | Code::Unknown if is_decode_failure(&detail) => (
            FailureKind::InvalidAnswer,
            format!("egodriver {rpc}: the answer cannot be decoded: {detail}"),
        ),
        Code::Internal | Code::Unknown if is_transport_failure(status, &detail) => (
            FailureKind::Unavailable,
            format!("egodriver {rpc}: the connection failed: {detail}"),
        ),
        code => (
            FailureKind::Remote,
            format!("egodriver {rpc} failed with status {code:?}: {detail}"),
        ),
    };
    PlanFailure::new(kind, text)
}

/// Whether the client's own deadline (the `grpc-timeout` it sent) expired.
fn timed_out(status: &Status) -> bool {
    // tonic turns its expired deadline into a plain `Cancelled` status.
    if status.code() == Code::Cancelled && status.message().contains("Timeout expired") {
        return true;
    }
    let mut source = std::error::Error::source(status);
    while let Some(e) = source {
        if e.is::<tonic::TimeoutExpired>() {
            return true;
        }
        source = e.source();
    }
    false
}

fn is_decode_failure(detail: &str) -> bool {
    let d = detail.to_ascii_lowercase();
    d.contains("failed to decode")
        || d.contains("protocol error")
        || d.contains("invalid compression flag")
        || d.contains("invalid content type")
        || d.contains("malformed")
        || d.contains("frame with invalid size")
}

fn is_transport_failure(status: &Status, detail: &str) -> bool {
    if std::error::Error::source(status).is_some() {
        return true;
    }
    let d = detail.to_ascii_lowercase();
    d.contains("connection") || d.contains("broken pipe") || d.contains("transport error")
}

fn invalid(m: String) -> PlanFailure {
    PlanFailure::new(FailureKind::InvalidAnswer, m)
}

/// Reads a `drive` answer: resamples the trajectory (local frame = rig frame at `t0`)
/// onto the 64 waypoint times, and extracts the explanation.
pub(crate) fn read_answer(
    answer: &DriveResponse,
    explanation_fields: &[String],
) -> Result<PlannerOutput, PlanFailure> {
    let poses = answer
        .trajectory
        .as_ref()
        .map(|t| t.poses.as_slice())
        .unwrap_or_default();
    if poses.is_empty() {
        let why = if answer.terminate_session {
            " (the policy asked to end the session)"
        } else {
            ""
        };
        return Err(invalid(format!(
            "egodriver drive: the trajectory is empty{why}"
        )));
    }
    let mut samples = Vec::with_capacity(poses.len() + 1);
    for (k, p) in poses.iter().enumerate() {
        let Some(v) = p.pose.as_ref().and_then(|p| p.vec.as_ref()) else {
            return Err(invalid(format!(
                "egodriver drive: trajectory pose {k} has no position"
            )));
        };
        let (x, y) = (f64::from(v.x), f64::from(v.y));
        if !(x.is_finite() && y.is_finite()) {
            return Err(invalid(format!(
                "egodriver drive: trajectory pose {k} is not finite ({x}, {y})"
            )));
        }
        let t = (p.timestamp_us as i128 - T0_US as i128) as f64 / 1e6;
        samples.push((t, x, y));
    }
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    samples.dedup_by(|later, earlier| later.0 == earlier.0);
    // The plan starts where the ego is at t0: the origin of the local frame.
    if samples[0].0 > 0.0 {
        samples.insert(0, (0.0, 0.0, 0.0));
    }
    let Some(&(end, _, _)) = samples.last() else {
        return Err(invalid("egodriver drive: the trajectory is empty".into()));
    };
    if end < HORIZON_S - COVER_TOLERANCE_S {
        return Err(invalid(format!(
            "egodriver drive: the trajectory covers only {:.2} s of the {HORIZON_S:.1} s horizon",
            end.max(0.0)
        )));
    }
    let trajectory = Trajectory {
        xy: (1..=HORIZON)
            .map(|k| interpolate(&samples, k as f64 * DT_S))
            .collect(),
    };
    trajectory
        .validate()
        .map_err(|e| invalid(format!("egodriver drive: {e}")))?;
    let debug = answer
        .debug_info
        .as_ref()
        .map(|d| d.unstructured_debug_info.as_slice())
        .unwrap_or_default();
    let (explanation, decision) = explanation(debug, explanation_fields);
    Ok(PlannerOutput {
        trajectory,
        explanation,
        decision,
    })
}

/// Linear interpolation of `(t, x, y)` samples (sorted by `t`) at `t`; clamps at the ends.
fn interpolate(samples: &[(f64, f64, f64)], t: f64) -> [f64; 2] {
    let i = samples.partition_point(|s| s.0 < t);
    if i == 0 {
        return [samples[0].1, samples[0].2];
    }
    if i == samples.len() {
        let s = samples[samples.len() - 1];
        return [s.1, s.2];
    }
    let (a, b) = (samples[i - 1], samples[i]);
    let w = (t - a.0) / (b.0 - a.0);
    [a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2)]
}

/// The explanation (and a decision, when one is named) in `unstructured_debug_info`:
/// a JSON object gives its first string field among `fields`; other UTF-8 text is the
/// explanation itself; anything else (a protobuf, a pickle) gives none.
pub(crate) fn explanation(bytes: &[u8], fields: &[String]) -> (String, Option<Decision>) {
    let Ok(text) = std::str::from_utf8(bytes) else {
        return (String::new(), None);
    };
    let text = text.trim();
    if text.starts_with('{')
        && let Ok(serde_json::Value::Object(obj)) = serde_json::from_str(text)
    {
        let found = fields
            .iter()
            .find_map(|f| obj.get(f).and_then(|v| v.as_str()))
            .unwrap_or_default()
            .trim()
            .to_string();
        let decision = obj
            .get("decision")
            .and_then(|v| v.as_str())
            .and_then(Decision::parse);
        return (found, decision);
    }
    // Binary payloads are often valid UTF-8 by chance; text has no control characters.
    if text
        .chars()
        .any(|c| c.is_control() && !matches!(c, '\n' | '\r' | '\t'))
    {
        return (String::new(), None);
    }
    (text.to_string(), None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::egodriver::wire::common::Trajectory as WireTrajectory;
    use crate::egodriver::wire::egodriver::drive_response::DebugInfo as AnswerDebug;

    fn fields() -> Vec<String> {
        DEFAULT_EXPLANATION_FIELDS
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    fn answer(points: &[(f64, f64, f64)], debug: &[u8]) -> DriveResponse {
        DriveResponse {
            trajectory: Some(WireTrajectory {
                poses: points
                    .iter()
                    .map(|&(t, x, y)| PoseAtTime {
                        pose: Some(wire_pose(x, y, 0.0, [1.0, 0.0, 0.0, 0.0])),
                        timestamp_us: wire_time(t),
                    })
                    .collect(),
            }),
            debug_info: Some(AnswerDebug {
                unstructured_debug_info: debug.to_vec(),
                sampled_trajectories: vec![],
            }),
            terminate_session: false,
        }
    }

    #[test]
    fn resamples_a_coarse_trajectory_by_time() {
        // 0.2 s steps at 5 m/s, starting at the anchor.
        let pts: Vec<_> = (0..=32).map(|k| (k as f64 * 0.2, k as f64, 0.0)).collect();
        let out = read_answer(&answer(&pts, b"Keep the lane."), &fields()).expect("valid");
        assert_eq!(out.trajectory.xy.len(), HORIZON);
        assert!((out.trajectory.xy[0][0] - 0.5).abs() < 1e-4);
        assert!((out.trajectory.xy[63][0] - 32.0).abs() < 1e-4);
        assert_eq!(out.explanation, "Keep the lane.");
    }

    #[test]
    fn short_empty_and_nan_answers_are_invalid() {
        let short: Vec<_> = (1..=10).map(|k| (k as f64 * 0.1, k as f64, 0.0)).collect();
        let e = read_answer(&answer(&short, b""), &fields()).unwrap_err();
        assert_eq!(e.kind, FailureKind::InvalidAnswer);
        assert!(e.message.contains("covers only 1.00 s"), "{e}");
        let e = read_answer(&answer(&[], b""), &fields()).unwrap_err();
        assert!(e.message.contains("empty"));
        let mut nan: Vec<_> = (1..=64).map(|k| (k as f64 * 0.1, k as f64, 0.0)).collect();
        nan[5].1 = f64::NAN;
        let e = read_answer(&answer(&nan, b""), &fields()).unwrap_err();
        assert_eq!(e.kind, FailureKind::InvalidAnswer);
    }

    #[test]
    fn explanations_from_json_text_and_binary() {
        let f = fields();
        let (e, d) = explanation(
            br#"{"reasoning": "Stop at the sign.", "decision": "stop_for_sign"}"#,
            &f,
        );
        assert_eq!(e, "Stop at the sign.");
        assert_eq!(d, Some(Decision::StopForSign));
        let (e, _) = explanation(br#"{"coc": "A", "reasoning": "B"}"#, &f);
        assert_eq!(e, "A");
        let (e, _) = explanation(b"  Nudge left.\n", &f);
        assert_eq!(e, "Nudge left.");
        // A protobuf (CarlaDriveDebugInfo-like): field 1 string, field 2 float.
        let (e, _) = explanation(b"\x0a\x0eroute_follower\x15\x00\x00\x80\x3f", &f);
        assert_eq!(e, "");
        let (e, _) = explanation(&[0xff, 0xfe, 0x00], &f);
        assert_eq!(e, "");
    }
}
