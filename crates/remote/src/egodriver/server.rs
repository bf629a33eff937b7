//! The egodriver server: any [`Planner`] behind the contract.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use fogline_types::clip::{
    CameraCalib, CameraId, CameraInput, DT_S, EgoPose, FRAMES, HISTORY, PlannerInput, PlannerOutput,
};
use tonic::metadata::MetadataValue;
use tonic::{Request, Response, Status};

use super::wire::common::version_id::ApiVersion;
use super::wire::common::{Empty, PoseAtTime, SessionRequestStatus, Trajectory, VersionId};
use super::wire::egodriver::drive_response::DebugInfo;
use super::wire::egodriver::egodriver_service_server::{EgodriverService, EgodriverServiceServer};
use super::wire::egodriver::{
    DriveRequest, DriveResponse, DriveSessionCloseRequest, DriveSessionRequest, GroundTruthRequest,
    RolloutCameraImage, RolloutEgoTrajectory, RouteRequest,
};
use super::wire::nre::grpc::protos::sensorsim::available_cameras_return::AvailableCamera;
use super::wire::nre::grpc::protos::sensorsim::camera_spec::CameraParam;
use super::{ALPASIM_API_VERSION, CONTRACT_METADATA_KEY, CONTRACT_REVISION, MAX_MESSAGE_BYTES};
use crate::geom::{CameraFrame, camera_angles, matrix, wrap, yaw_of};
use crate::serving::{Limits, StopFlag, accept_guarded, server_runtime, stop_flag, stopped};
use crate::{FailureKind, PlanRequest, Planner, ServerHandle, codec};

/// Sessions kept at once; beyond this the least recently used one is dropped.
const MAX_SESSIONS: usize = 256;
/// How far off the optical axis of a camera may point from the rig's x axis to stand in
/// for the front-wide camera, degrees.
const FORWARD_CONE_DEG: f64 = 20.0;
/// Frames stamped up to this long after `time_now_us` still count as available, µs.
const FRAME_SLACK_US: u64 = 50_000;

/// Settings of an egodriver server.
#[derive(Debug, Clone, PartialEq)]
pub struct ServeOptions {
    /// Which fogline camera a declared camera (by its logical id) is. A PhysicalAI camera
    /// name (`camera_front_wide_120fov`, …) needs no entry; an entry overrides it.
    pub camera_map: BTreeMap<String, CameraId>,
    /// Whether the `shut_down` RPC stops the server (AlpaSim's runtime calls it at the end
    /// of a run). Off by default: the call is unauthenticated, so any local peer could stop
    /// the server.
    pub allow_shut_down: bool,
    /// Connections, timeouts, concurrent calls and decoded pixels ([`Limits`]; the pixel
    /// limit bounds a session's declared cameras × frames).
    pub limits: Limits,
    /// The decoded frames all sessions may hold together, bytes (default 320 MiB); a new
    /// session that would pass it closes the least recently used ones.
    pub max_stored_bytes: u64,
}

impl Default for ServeOptions {
    fn default() -> Self {
        Self {
            camera_map: BTreeMap::new(),
            allow_shut_down: false,
            limits: Limits::default(),
            max_stored_bytes: 320 << 20,
        }
    }
}

/// Parses camera-map entries `LOGICAL=CAMERA` (as `fogline serve egodriver --camera-map`
/// takes them) into [`ServeOptions::camera_map`]; the error names the entry and what was
/// expected.
pub fn parse_camera_map(entries: &[String]) -> Result<BTreeMap<String, CameraId>, String> {
    let mut map = BTreeMap::new();
    for e in entries {
        let Some((logical, camera)) = e.split_once('=') else {
            return Err(format!(
                "--camera-map {e:?}: expected LOGICAL=CAMERA, e.g. front=camera_front_wide_120fov"
            ));
        };
        let Some(id) = CameraId::parse(camera.trim()) else {
            let names: Vec<&str> = CameraId::ALL.iter().map(|c| c.name()).collect();
            return Err(format!(
                "--camera-map {e:?}: {camera:?} is not a camera name (one of {})",
                names.join(", ")
            ));
        };
        if map.insert(logical.trim().to_string(), id).is_some() {
            return Err(format!("--camera-map: {logical:?} is mapped twice"));
        }
    }
    Ok(map)
}

/// Serves `planner` over the egodriver contract on `addr` (port 0 picks a free port; see
/// [`ServerHandle::local_addr`]). The socket is bound before this returns.
pub fn serve(
    addr: SocketAddr,
    planner: Arc<dyn Planner>,
    opts: ServeOptions,
) -> io::Result<ServerHandle> {
    opts.limits.validate().map_err(io::Error::other)?;
    let runtime = server_runtime("fogline-egodriver")?;
    let listener = runtime.block_on(tokio::net::TcpListener::bind(addr))?;
    let stop = stop_flag();
    let describe = planner.describe();
    let limits = opts.limits.clone();
    let service = Service {
        shared: Arc::new(Shared {
            planner,
            opts,
            sessions: Mutex::new(HashMap::new()),
            stop: stop.clone(),
            said: Mutex::new(HashSet::new()),
            evicted: Mutex::new(std::collections::VecDeque::new()),
            plans: Arc::new(tokio::sync::Semaphore::new(limits.max_concurrent_requests)),
        }),
    };
    serve_service(runtime, listener, service, &limits, &describe, stop)
}

/// Serves any implementation of the contract (e.g. `fogline-guard`'s proxy) on `addr`
/// under `limits`, as [`serve`] serves a planner: the same connection guard, timeouts and
/// message sizes. The socket is bound before this returns.
pub fn serve_contract<S: EgodriverService>(
    addr: SocketAddr,
    service: S,
    limits: &Limits,
    describe: &str,
) -> io::Result<ServerHandle> {
    limits.validate().map_err(io::Error::other)?;
    let runtime = server_runtime("fogline-egodriver")?;
    let listener = runtime.block_on(tokio::net::TcpListener::bind(addr))?;
    serve_service(runtime, listener, service, limits, describe, stop_flag())
}

fn serve_service<S: EgodriverService>(
    runtime: tokio::runtime::Runtime,
    listener: tokio::net::TcpListener,
    service: S,
    limits: &Limits,
    describe: &str,
    stop: StopFlag,
) -> io::Result<ServerHandle> {
    let local = listener.local_addr()?;
    let limits = limits.clone();
    let server = EgodriverServiceServer::new(service)
        .max_decoding_message_size(MAX_MESSAGE_BYTES)
        .max_encoding_message_size(MAX_MESSAGE_BYTES);
    let task = {
        let _guard = runtime.enter();
        let incoming = tokio_stream::wrappers::ReceiverStream::new(accept_guarded(
            listener,
            &limits,
            stop.clone(),
            "egodriver",
        ));
        let signal = stopped(stop.clone());
        runtime.spawn(async move {
            tonic::transport::Server::builder()
                .timeout(limits.request_timeout)
                .max_concurrent_streams(Some(32))
                // Calls beyond the cap wait before their messages are decoded: four per
                // plan slot, so images and session calls keep flowing while plans run.
                .layer(tower::limit::GlobalConcurrencyLimitLayer::new(
                    4 * limits.max_concurrent_requests,
                ))
                .serve_with_incoming_shutdown(server, incoming, signal)
                .await
                .map_err(io::Error::other)
        })
    };
    log::info!("egodriver: serving {describe} on {local}");
    Ok(ServerHandle::new(local, "egodriver", stop, task, runtime))
}

struct Shared {
    planner: Arc<dyn Planner>,
    opts: ServeOptions,
    sessions: Mutex<HashMap<String, Arc<Mutex<Session>>>>,
    stop: StopFlag,
    /// Notes already logged at info level (later repeats go to debug).
    said: Mutex<HashSet<String>>,
    /// Sessions recently closed to make room (the newest 1,024), so their calls are told why.
    evicted: Mutex<std::collections::VecDeque<String>>,
    /// One permit per plan being computed.
    plans: Arc<tokio::sync::Semaphore>,
}

struct Service {
    shared: Arc<Shared>,
}

struct Session {
    /// The bytes its decoded frames may take (declared cameras × frames kept × 3 bytes).
    reserved: u64,
    scene_id: String,
    seed: u64,
    cameras: Vec<Slot>,
    ego: Vec<EgoSample>,
    last_used: Instant,
}

struct Slot {
    logical_id: String,
    role: Role,
}

enum Role {
    Camera {
        calib: CameraCalib,
        frames: Vec<Frame>,
    },
    Ignored(String),
}

struct Frame {
    t_us: u64,
    rgb: Arc<Vec<u8>>,
}

#[derive(Clone, Copy)]
struct EgoSample {
    t_us: u64,
    x: f64,
    y: f64,
    z: f64,
    yaw: f64,
    speed: Option<f64>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Shared {
    fn session(&self, uuid: &str) -> Result<Arc<Mutex<Session>>, Status> {
        let found = lock(&self.sessions).get(uuid).cloned();
        let s = found.ok_or_else(|| {
            if lock(&self.evicted).iter().any(|e| e == uuid) {
                Status::resource_exhausted(format!(
                    "session {uuid:?} was closed to make room for newer ones (this server keeps \
                     at most {MAX_SESSIONS} sessions and {} bytes of frames)",
                    self.opts.max_stored_bytes
                ))
            } else {
                Status::not_found(format!("unknown session {uuid:?}"))
            }
        })?;
        lock(&s).last_used = Instant::now();
        Ok(s)
    }

    /// Logs `note` at info level the first time, at debug level afterwards.
    fn note(&self, note: String) {
        if lock(&self.said).insert(note.clone()) {
            log::info!("egodriver: {note}");
        } else {
            log::debug!("egodriver: {note}");
        }
    }
}

#[tonic::async_trait]
impl EgodriverService for Service {
    async fn start_session(
        &self,
        request: Request<DriveSessionRequest>,
    ) -> Result<Response<SessionRequestStatus>, Status> {
        let frame = match request.metadata().get(CONTRACT_METADATA_KEY) {
            None => CameraFrame::Optical,
            Some(v) => match v.to_str().ok().map(str::trim) {
                Some("1") => CameraFrame::Body,
                Some("2") => CameraFrame::Optical,
                other => {
                    return Err(Status::failed_precondition(format!(
                        "{CONTRACT_METADATA_KEY}={other:?} is not a contract revision this \
                         server speaks (1 or 2)"
                    )));
                }
            },
        };
        let msg = request.into_inner();
        let uuid = msg.session_uuid;
        if uuid.is_empty() {
            return Err(Status::invalid_argument(
                "start_session: session_uuid is empty",
            ));
        }
        let declared = msg
            .rollout_spec
            .and_then(|r| r.vehicle)
            .map(|v| v.available_cameras)
            .unwrap_or_default();
        let cameras = map_cameras(&declared, frame, &self.shared);
        let summary: Vec<String> = cameras
            .iter()
            .map(|s| match &s.role {
                Role::Camera { calib, .. } => format!("{} → {}", s.logical_id, calib.id),
                Role::Ignored(why) => format!("{} ignored ({why})", s.logical_id),
            })
            .collect();
        let scene_id = msg.debug_info.map(|d| d.scene_id).unwrap_or_default();
        log::debug!(
            "egodriver: start_session {uuid} scene {scene_id:?} seed {}: {}",
            msg.random_seed,
            summary.join(", ")
        );
        let pixels: u64 = cameras
            .iter()
            .map(|s| match &s.role {
                Role::Camera { calib, .. } => u64::from(calib.width) * u64::from(calib.height),
                Role::Ignored(_) => 0,
            })
            .sum::<u64>()
            * FRAMES as u64;
        let cap = self.shared.opts.limits.max_request_pixels;
        if pixels > cap {
            return Err(Status::resource_exhausted(format!(
                "start_session: the declared cameras hold {pixels} pixels over {FRAMES} frames, \
                 more than this server's limit of {cap}"
            )));
        }
        let reserved = pixels * 3;
        let budget = self.shared.opts.max_stored_bytes;
        if reserved > budget {
            return Err(Status::resource_exhausted(format!(
                "start_session: the session's frames need {reserved} bytes, more than this \
                 server's store of {budget}"
            )));
        }
        let session = Session {
            reserved,
            scene_id,
            seed: msg.random_seed,
            cameras,
            ego: Vec::new(),
            last_used: Instant::now(),
        };
        let mut sessions = lock(&self.shared.sessions);
        if sessions.contains_key(&uuid) {
            return Err(Status::already_exists(format!(
                "session {uuid:?} already exists"
            )));
        }
        // Room by count and by the frames' bytes: the least recently used sessions go.
        loop {
            let held: u64 = sessions.values().map(|s| lock(s).reserved).sum();
            if sessions.len() < MAX_SESSIONS && held + reserved <= budget {
                break;
            }
            let oldest = sessions
                .iter()
                .min_by_key(|(_, s)| lock(s).last_used)
                .map(|(k, _)| k.clone());
            let Some(k) = oldest else { break };
            log::warn!(
                "egodriver: {} sessions hold {held} bytes of frames; dropping {k}, the least \
                 recently used",
                sessions.len()
            );
            sessions.remove(&k);
            let mut evicted = lock(&self.shared.evicted);
            if evicted.len() >= 1024 {
                evicted.pop_front();
            }
            evicted.push_back(k);
        }
        sessions.insert(uuid, Arc::new(Mutex::new(session)));
        Ok(Response::new(SessionRequestStatus {}))
    }

    async fn close_session(
        &self,
        request: Request<DriveSessionCloseRequest>,
    ) -> Result<Response<Empty>, Status> {
        let uuid = request.into_inner().session_uuid;
        if lock(&self.shared.sessions).remove(&uuid).is_none() {
            log::debug!("egodriver: close_session for unknown session {uuid:?}");
        }
        Ok(Response::new(Empty {}))
    }

    async fn submit_image_observation(
        &self,
        request: Request<RolloutCameraImage>,
    ) -> Result<Response<Empty>, Status> {
        let msg = request.into_inner();
        let session = self.shared.session(&msg.session_uuid)?;
        let image = msg
            .camera_image
            .ok_or_else(|| Status::invalid_argument("submit_image_observation: no camera_image"))?;
        let id = image.logical_id;
        let (width, height) = {
            let s = lock(&session);
            let Some(slot) = s.cameras.iter().find(|c| c.logical_id == id) else {
                let known: Vec<&str> = s.cameras.iter().map(|c| c.logical_id.as_str()).collect();
                return Err(Status::invalid_argument(format!(
                    "camera {id:?} was not declared in start_session (declared: {known:?})"
                )));
            };
            match &slot.role {
                Role::Ignored(_) => return Ok(Response::new(Empty {})),
                Role::Camera { calib, .. } => (calib.width, calib.height),
            }
        };
        let bytes = image.image_bytes;
        let decoded = tokio::task::spawn_blocking(move || {
            codec::decode_sized(&bytes, width, height, "start_session")
        })
        .await
        .map_err(|e| Status::internal(format!("decoding failed: {e}")))?
        .map_err(|e| Status::invalid_argument(format!("camera {id:?}: {e}")))?;
        let t_us = if image.frame_end_us > 0 {
            image.frame_end_us
        } else {
            image.frame_start_us
        };
        let mut s = lock(&session);
        if let Some(Slot {
            role: Role::Camera { frames, .. },
            ..
        }) = s.cameras.iter_mut().find(|c| c.logical_id == id)
        {
            let frame = Frame {
                t_us,
                rgb: Arc::new(decoded.rgb),
            };
            match frames.binary_search_by_key(&t_us, |f| f.t_us) {
                Ok(i) => frames[i] = frame,
                Err(i) => frames.insert(i, frame),
            }
            let excess = frames.len().saturating_sub(FRAMES);
            frames.drain(..excess);
        }
        Ok(Response::new(Empty {}))
    }

    async fn submit_egomotion_observation(
        &self,
        request: Request<RolloutEgoTrajectory>,
    ) -> Result<Response<Empty>, Status> {
        let msg = request.into_inner();
        let session = self.shared.session(&msg.session_uuid)?;
        let poses = msg.trajectory.map(|t| t.poses).unwrap_or_default();
        let states = msg.dynamic_states;
        if !states.is_empty() && states.len() != poses.len() {
            return Err(Status::invalid_argument(format!(
                "submit_egomotion_observation: {} dynamic_states for {} poses",
                states.len(),
                poses.len()
            )));
        }
        let mut s = lock(&session);
        for (i, p) in poses.iter().enumerate() {
            if s.ego.last().is_some_and(|last| p.timestamp_us <= last.t_us) {
                // A resent or older pose: the history only moves forward.
                continue;
            }
            let pose = p.pose.unwrap_or_default();
            let v = pose.vec.unwrap_or_default();
            let q = pose.quat.unwrap_or_default();
            let q = [q.w, q.x, q.y, q.z].map(f64::from);
            let sample = EgoSample {
                t_us: p.timestamp_us,
                x: f64::from(v.x),
                y: f64::from(v.y),
                z: f64::from(v.z),
                yaw: yaw_of(q),
                speed: states
                    .get(i)
                    .and_then(|d| d.linear_velocity)
                    .map(|lv| f64::from(lv.x).hypot(f64::from(lv.y))),
            };
            if ![sample.x, sample.y, sample.z, sample.yaw]
                .iter()
                .all(|v| v.is_finite())
            {
                return Err(Status::invalid_argument(format!(
                    "submit_egomotion_observation: pose {i} is not finite"
                )));
            }
            s.ego.push(sample);
        }
        let excess = s.ego.len().saturating_sub(HISTORY + 1);
        s.ego.drain(..excess);
        Ok(Response::new(Empty {}))
    }

    async fn submit_route(
        &self,
        request: Request<RouteRequest>,
    ) -> Result<Response<Empty>, Status> {
        // Camera planners do not use a route; the session must exist all the same.
        self.shared.session(&request.into_inner().session_uuid)?;
        Ok(Response::new(Empty {}))
    }

    async fn submit_recording_ground_truth(
        &self,
        request: Request<GroundTruthRequest>,
    ) -> Result<Response<Empty>, Status> {
        self.shared.session(&request.into_inner().session_uuid)?;
        Ok(Response::new(Empty {}))
    }

    async fn drive(
        &self,
        request: Request<DriveRequest>,
    ) -> Result<Response<DriveResponse>, Status> {
        let msg = request.into_inner();
        let uuid = msg.session_uuid;
        let now = msg.time_now_us;
        let session = self.shared.session(&uuid)?;
        let snapshot = snapshot(&lock(&session), &uuid, now)?;
        let planner = Arc::clone(&self.shared.planner);
        let Snapshot {
            scene_id,
            seed,
            cameras,
            history,
            anchor,
        } = snapshot;
        // At most `max_concurrent_requests` plans at once; the permit lives as long as the
        // planner runs, even when the caller has given up.
        let slot = Arc::clone(&self.shared.plans)
            .acquire_owned()
            .await
            .map_err(|_| Status::unavailable("the server is stopping"))?;
        let result = tokio::task::spawn_blocking(move || {
            let _slot = slot;
            let input = PlannerInput {
                cameras: cameras
                    .iter()
                    .map(|(calib, frames)| CameraInput {
                        calib: *calib,
                        frames: frames.iter().map(|f| f.as_slice()).collect(),
                    })
                    .collect(),
                ego_history: &history,
            };
            planner.plan(&PlanRequest {
                scene_id: &scene_id,
                seed,
                input,
            })
        })
        .await
        .map_err(|e| Status::internal(format!("the planner did not finish: {e}")))?;
        let describe = self.shared.planner.describe();
        let out = result.map_err(|e| {
            let text = format!("{describe}: {e}");
            if e.kind == FailureKind::Input {
                Status::failed_precondition(text)
            } else {
                Status::internal(text)
            }
        })?;
        if let Err(e) = out.trajectory.validate() {
            // Passed on as it is: judging the answer is the caller's business.
            log::warn!("egodriver: session {uuid}: {describe} answered an invalid trajectory: {e}");
        }
        Ok(Response::new(answer(&out, &anchor, now, &describe)))
    }

    async fn get_version(&self, _request: Request<Empty>) -> Result<Response<VersionId>, Status> {
        let (major, minor, patch) = ALPASIM_API_VERSION;
        let mut response = Response::new(VersionId {
            version_id: format!(
                "fogline-remote {} serving {}",
                env!("CARGO_PKG_VERSION"),
                self.shared.planner.describe()
            ),
            git_hash: String::new(),
            grpc_api_version: Some(ApiVersion {
                major,
                minor,
                patch,
            }),
        });
        response.metadata_mut().insert(
            CONTRACT_METADATA_KEY,
            MetadataValue::from(CONTRACT_REVISION),
        );
        Ok(response)
    }

    async fn shut_down(&self, _request: Request<Empty>) -> Result<Response<Empty>, Status> {
        if !self.shared.opts.allow_shut_down {
            return Err(Status::permission_denied(
                "shut_down is disabled on this server (fogline serve egodriver --allow-remote-shutdown enables it)",
            ));
        }
        log::info!("egodriver: shut_down requested");
        self.shared.stop.send_replace(true);
        Ok(Response::new(Empty {}))
    }
}

/// What one `drive` needs from a session, copied out of its lock.
struct Snapshot {
    scene_id: String,
    seed: u64,
    cameras: Vec<(CameraCalib, Vec<Arc<Vec<u8>>>)>,
    history: Vec<EgoPose>,
    anchor: EgoSample,
}

fn snapshot(s: &Session, uuid: &str, now: u64) -> Result<Snapshot, Status> {
    let known: Vec<EgoSample> = s.ego.iter().copied().filter(|e| e.t_us <= now).collect();
    let Some(&anchor) = known.last() else {
        return Err(Status::failed_precondition(format!(
            "session {uuid}: no ego pose at or before time_now_us {now} \
             (submit_egomotion_observation comes before drive)"
        )));
    };
    let window = &known[known.len().saturating_sub(HISTORY)..];
    let (sy, cy) = anchor.yaw.sin_cos();
    let history = window
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let (dx, dy) = (e.x - anchor.x, e.y - anchor.y);
            EgoPose {
                t_s: (e.t_us as i128 - now as i128) as f64 / 1e6,
                x_m: cy * dx + sy * dy,
                y_m: -sy * dx + cy * dy,
                yaw_rad: wrap(e.yaw - anchor.yaw),
                speed_mps: e.speed.unwrap_or_else(|| finite_speed(window, i)),
            }
        })
        .collect();
    let mut cameras: Vec<(CameraCalib, Vec<Arc<Vec<u8>>>)> = Vec::new();
    for slot in &s.cameras {
        if let Role::Camera { calib, frames } = &slot.role {
            let ready: Vec<Arc<Vec<u8>>> = frames
                .iter()
                .filter(|f| f.t_us <= now.saturating_add(FRAME_SLACK_US))
                .map(|f| Arc::clone(&f.rgb))
                .collect();
            if !ready.is_empty() {
                cameras.push((*calib, ready));
            }
        }
    }
    if cameras.is_empty() {
        let declared: Vec<String> = s
            .cameras
            .iter()
            .map(|c| match &c.role {
                Role::Camera { calib, .. } => {
                    format!("{} → {} (no frame yet)", c.logical_id, calib.id)
                }
                Role::Ignored(why) => format!("{}: ignored, {why}", c.logical_id),
            })
            .collect();
        return Err(Status::failed_precondition(format!(
            "session {uuid}: no frame from a usable camera at or before time_now_us {now}; \
             cameras: [{}]",
            declared.join("; ")
        )));
    }
    // Every camera gets the same number of frames: the newest ones.
    let n = cameras.iter().map(|c| c.1.len()).min().unwrap_or(0);
    for (_, frames) in &mut cameras {
        let excess = frames.len() - n;
        frames.drain(..excess);
    }
    cameras.sort_by_key(|c| c.0.id);
    Ok(Snapshot {
        scene_id: s.scene_id.clone(),
        seed: s.seed,
        cameras,
        history,
        anchor,
    })
}

/// Speed at sample `i` from its neighbours, when the runtime sent no dynamic state.
fn finite_speed(w: &[EgoSample], i: usize) -> f64 {
    let pair = if i > 0 {
        Some((w[i - 1], w[i]))
    } else {
        w.get(1).map(|&next| (w[0], next))
    };
    match pair {
        Some((a, b)) if b.t_us > a.t_us => {
            (b.x - a.x).hypot(b.y - a.y) / ((b.t_us - a.t_us) as f64 / 1e6)
        }
        _ => 0.0,
    }
}

/// The `drive` answer: the anchor at `now`, then the planner's waypoints (rig frame at
/// `now`) in the local frame, 0.1 s apart, heading along the path.
fn answer(out: &PlannerOutput, anchor: &EgoSample, now: u64, describe: &str) -> DriveResponse {
    let (sy, cy) = anchor.yaw.sin_cos();
    let step_us = (DT_S * 1e6).round() as u64;
    let to_local = |x: f64, y: f64, heading: f64, k: u64| PoseAtTime {
        pose: Some(super::wire_pose_yaw(
            anchor.x + cy * x - sy * y,
            anchor.y + sy * x + cy * y,
            anchor.z,
            anchor.yaw + heading,
        )),
        timestamp_us: now.saturating_add(k * step_us),
    };
    let mut poses = Vec::with_capacity(out.trajectory.xy.len() + 1);
    poses.push(to_local(0.0, 0.0, 0.0, 0));
    let (mut px, mut py, mut heading) = (0.0, 0.0, 0.0);
    for (k, p) in out.trajectory.xy.iter().enumerate() {
        let (dx, dy) = (p[0] - px, p[1] - py);
        if dx.hypot(dy) >= 0.01 {
            heading = dy.atan2(dx);
        }
        poses.push(to_local(p[0], p[1], heading, k as u64 + 1));
        (px, py) = (p[0], p[1]);
    }
    let debug = serde_json::json!({
        "coc": out.explanation,
        "decision": out.decision.map(|d| d.name()),
        "planner": describe,
    });
    DriveResponse {
        trajectory: Some(Trajectory { poses }),
        debug_info: Some(DebugInfo {
            unstructured_debug_info: debug.to_string().into_bytes(),
            sampled_trajectories: Vec::new(),
        }),
        terminate_session: false,
    }
}

/// A declared camera as a fogline calibration (its id still to be assigned).
fn calibration(cam: &AvailableCamera, frame: CameraFrame) -> Result<(CameraCalib, f64), String> {
    let spec = cam.intrinsics.as_ref().ok_or("no intrinsics declared")?;
    let pin = match &spec.camera_param {
        Some(CameraParam::OpencvPinholeParam(p)) => p,
        Some(CameraParam::FthetaParam(_)) => {
            return Err("an f-theta camera; only the OpenCV pinhole model is supported".into());
        }
        Some(CameraParam::OpencvFisheyeParam(_)) => {
            return Err("a fisheye camera; only the OpenCV pinhole model is supported".into());
        }
        None => return Err("no camera model declared (opencv_pinhole_param expected)".into()),
    };
    let pose = cam.rig_to_camera.unwrap_or_default();
    let v = pose.vec.unwrap_or_default();
    let q = pose.quat.unwrap_or_default();
    let m = matrix([q.w, q.x, q.y, q.z].map(f64::from));
    let (yaw, pitch, roll) = camera_angles(m, frame);
    let calib = CameraCalib {
        id: CameraId::FrontWide,
        width: spec.resolution_w,
        height: spec.resolution_h,
        fx: pin.focal_length_x,
        fy: pin.focal_length_y,
        cx: pin.principal_point_x,
        cy: pin.principal_point_y,
        x_m: f64::from(v.x),
        y_m: f64::from(v.y),
        z_m: f64::from(v.z),
        yaw_rad: yaw,
        pitch_rad: pitch,
    };
    calib.validate()?;
    Ok((calib, roll))
}

/// Assigns fogline cameras to the declared ones (see [`ServeOptions::camera_map`]); when
/// no camera is the front-wide one, the widest camera looking forward stands in for it.
fn map_cameras(declared: &[AvailableCamera], frame: CameraFrame, shared: &Shared) -> Vec<Slot> {
    struct Candidate {
        logical_id: String,
        calib: Result<CameraCalib, String>,
        id: Option<CameraId>,
    }
    let mut cands: Vec<Candidate> = declared
        .iter()
        .map(|cam| {
            let logical_id = if cam.logical_id.is_empty() {
                cam.intrinsics
                    .as_ref()
                    .map(|s| s.logical_id.clone())
                    .unwrap_or_default()
            } else {
                cam.logical_id.clone()
            };
            let calib = calibration(cam, frame).map(|(calib, roll)| {
                if roll.to_degrees() > 2.0 {
                    shared.note(format!(
                        "camera {logical_id:?} is rolled by {:.1}°; fogline cameras have no roll, it is ignored",
                        roll.to_degrees()
                    ));
                }
                calib
            });
            let id = shared
                .opts
                .camera_map
                .get(&logical_id)
                .copied()
                .or_else(|| CameraId::parse(&logical_id));
            Candidate {
                logical_id,
                calib,
                id,
            }
        })
        .collect();
    let mut taken: HashMap<CameraId, String> = HashMap::new();
    for c in &mut cands {
        let (Ok(_), Some(id)) = (&c.calib, c.id) else {
            continue;
        };
        if let Some(first) = taken.get(&id) {
            c.calib = Err(format!("{id} is already taken by {first:?}"));
        } else {
            taken.insert(id, c.logical_id.clone());
        }
    }
    if !taken.contains_key(&CameraId::FrontWide) {
        let hfov = |c: &CameraCalib| 2.0 * (f64::from(c.width) / (2.0 * c.fx)).atan();
        let forward = |c: &CameraCalib| {
            (c.yaw_rad.cos() * c.pitch_rad.cos())
                .clamp(-1.0, 1.0)
                .acos()
                <= FORWARD_CONE_DEG.to_radians()
        };
        let best = cands
            .iter_mut()
            .filter(|c| c.id.is_none())
            .filter_map(|c| match &c.calib {
                Ok(calib) if forward(calib) => Some((hfov(calib), c)),
                _ => None,
            })
            .max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((fov, c)) = best {
            c.id = Some(CameraId::FrontWide);
            shared.note(format!(
                "no camera is {}: using {:?} ({:.0}° wide, looking forward) in its place",
                CameraId::FrontWide,
                c.logical_id,
                fov.to_degrees()
            ));
        }
    }
    cands
        .into_iter()
        .map(|c| {
            let role = match (c.calib, c.id) {
                (Err(why), _) => Role::Ignored(why),
                (Ok(_), None) => {
                    Role::Ignored("not a PhysicalAI camera name and not in the camera map".into())
                }
                (Ok(mut calib), Some(id)) => {
                    calib.id = id;
                    Role::Camera {
                        calib,
                        frames: Vec::new(),
                    }
                }
            };
            if let Role::Ignored(why) = &role {
                shared.note(format!("camera {:?} ignored: {why}", c.logical_id));
            }
            Slot {
                logical_id: c.logical_id,
                role,
            }
        })
        .collect()
}
