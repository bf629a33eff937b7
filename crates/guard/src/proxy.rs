//! The proxy: the egodriver service the simulator calls, forwarding to the driver.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use fogline_monitor::{Monitor, MonitorRecord};
use fogline_rco::{Rco, RcoParams};
use fogline_remote::egodriver::wire::common::version_id::ApiVersion;
use fogline_remote::egodriver::wire::common::{
    Empty, Pose, PoseAtTime, Quat, SessionRequestStatus, Trajectory, Vec3, VersionId,
};
use fogline_remote::egodriver::wire::egodriver::drive_response::DebugInfo;
use fogline_remote::egodriver::wire::egodriver::egodriver_service_client::EgodriverServiceClient;
use fogline_remote::egodriver::wire::egodriver::egodriver_service_server::EgodriverService;
use fogline_remote::egodriver::wire::egodriver::{
    DriveRequest, DriveResponse, DriveSessionCloseRequest, DriveSessionRequest, GroundTruthRequest,
    RolloutCameraImage, RolloutEgoTrajectory, RouteRequest,
};
use fogline_remote::egodriver::{
    ALPASIM_API_VERSION, CONTRACT_METADATA_KEY, CONTRACT_REVISION, MAX_MESSAGE_BYTES,
};
use fogline_types::odd::OddSpec;
use tonic::metadata::MetadataValue;
use tonic::transport::Channel;
use tonic::{Request, Response, Status};

use crate::takeover::{self, EgoNow, TakeoverAnswer};
use crate::{GuardError, GuardLog, GuardParams, GuardRecord};

/// Sessions kept at once; beyond this the least recently used one is dropped.
const MAX_SESSIONS: usize = 256;

/// The guard's egodriver service (see the crate documentation).
pub struct Guard {
    shared: Arc<Shared>,
}

struct Shared {
    odd: OddSpec,
    params: GuardParams,
    log: Option<GuardLog>,
    /// Checks the driver's certificate when its address is `https://`.
    tls: fogline_io::http::Tls,
    /// Made on first use, inside the server's runtime (a lazy channel needs one).
    client: std::sync::OnceLock<EgodriverServiceClient<Channel>>,
    sessions: Mutex<HashMap<String, Arc<Mutex<Session>>>>,
}

struct Session {
    start: DriveSessionRequest,
    revision: Option<String>,
    camera: String,
    monitor: Monitor,
    last: Option<MonitorRecord>,
    size: (u32, u32),
    rco: Rco,
    /// The newest ego poses (t_us, x, y, z, yaw), local frame.
    ego: Vec<(u64, f64, f64, f64, f64)>,
    speed_mps: Option<f64>,
    target: Option<[f64; 2]>,
    calls: u64,
    /// Calls left before the driver is tried again (0: healthy).
    driver_down: u64,
    /// The driver's session must be re-opened before the next forward.
    reopen: bool,
    /// The latest driver fault, in words (`start_session: Unavailable: …`).
    last_fault: Option<String>,
    last_used: Instant,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Whether a driver's error is a fault of the driver (it is down, slow or broken, or lost a
/// session the guard holds open) rather than its refusal of a bad message.
fn is_fault(s: &Status) -> bool {
    use tonic::Code;
    matches!(
        s.code(),
        Code::Unavailable
            | Code::NotFound
            | Code::DeadlineExceeded
            | Code::Unknown
            | Code::Internal
            | Code::Cancelled
            | Code::Aborted
            | Code::Unimplemented
    )
}

impl Guard {
    /// The service over `odd` (the scenario and monitor are checked here).
    pub fn new(
        odd: OddSpec,
        params: GuardParams,
        log: Option<GuardLog>,
    ) -> Result<Self, GuardError> {
        params.validate()?;
        Monitor::new(&odd, &params.scenario, params.monitor.clone()).map_err(|source| {
            GuardError::Monitor {
                scenario: params.scenario.clone(),
                source,
            }
        })?;
        Rco::with_rules(RcoParams::default()).map_err(GuardError::Rco)?;
        fogline_remote::egodriver::endpoint_url(&params.driver).map_err(|e| {
            GuardError::Params {
                what: "driver",
                expected: format!("an address http://HOST:PORT or https://HOST[:PORT] ({e})"),
            }
        })?;
        let tls = match &params.ca_cert {
            Some(path) => fogline_io::http::Tls::new(Some(path.as_path())),
            None => fogline_io::http::Tls::process_default(),
        }
        .map_err(|e| GuardError::Params {
            what: "ca_cert",
            expected: format!("a readable PEM file of CA certificates ({e})"),
        })?;
        Ok(Self {
            shared: Arc::new(Shared {
                odd,
                params,
                log,
                tls,
                client: std::sync::OnceLock::new(),
                sessions: Mutex::new(HashMap::new()),
            }),
        })
    }

    /// `fogline-guard in front of <driver> (scenario …)`.
    pub fn describe(&self) -> String {
        format!(
            "fogline-guard in front of {} (scenario {})",
            self.shared.params.driver, self.shared.params.scenario
        )
    }
}

impl Shared {
    /// A handle on the driver's channel (reconnected as needed).
    fn driver(&self) -> Result<EgodriverServiceClient<Channel>, Status> {
        if let Some(c) = self.client.get() {
            return Ok(c.clone());
        }
        let timeout = Duration::from_millis(self.params.driver_timeout_ms);
        let channel = fogline_remote::egodriver::channel(
            &self.params.driver,
            self.tls.clone(),
            timeout,
            Some(timeout),
        )
        .map_err(Status::unavailable)?;
        let client = EgodriverServiceClient::new(channel)
            .max_decoding_message_size(MAX_MESSAGE_BYTES)
            .max_encoding_message_size(MAX_MESSAGE_BYTES);
        Ok(self.client.get_or_init(|| client).clone())
    }

    fn session(&self, uuid: &str) -> Result<Arc<Mutex<Session>>, Status> {
        let s = lock(&self.sessions)
            .get(uuid)
            .cloned()
            .ok_or_else(|| Status::not_found(format!("unknown session {uuid:?}")))?;
        lock(&s).last_used = Instant::now();
        Ok(s)
    }

    fn timeout(&self) -> Duration {
        Duration::from_millis(self.params.driver_timeout_ms)
    }

    fn write(&self, r: &GuardRecord) {
        let Some(log) = &self.log else { return };
        match serde_json::to_string(r) {
            Ok(line) => {
                let mut w = lock(log);
                if let Err(e) = writeln!(w, "{line}").and_then(|()| w.flush()) {
                    log::warn!("guard: cannot write the log: {e}");
                }
            }
            Err(e) => log::warn!("guard: cannot serialise a record: {e}"),
        }
    }

    /// Whether the session's calls go to the driver now (re-opening its session first
    /// when a retry is due).
    async fn driver_ready(&self, s: &Arc<Mutex<Session>>) -> bool {
        let (reopen, start, revision) = {
            let g = lock(s);
            if g.driver_down > 0 {
                return false;
            }
            (g.reopen, g.start.clone(), g.revision.clone())
        };
        if !reopen {
            return true;
        }
        let r = self.forward_start(start, revision.as_deref()).await;
        let mut g = lock(s);
        match r {
            Ok(()) => {
                g.reopen = false;
                log::info!(
                    "guard: the driver is back (session {:?})",
                    g.start.session_uuid
                );
                true
            }
            Err(e) => {
                g.driver_down = self.params.fault_retry_calls;
                g.last_fault = Some(format!("start_session: {:?}: {}", e.code(), e.message()));
                log::warn!("guard: the driver is still down: {e}");
                false
            }
        }
    }

    async fn forward_start(
        &self,
        msg: DriveSessionRequest,
        revision: Option<&str>,
    ) -> Result<(), Status> {
        let mut req = Request::new(msg);
        if let Some(v) = revision.and_then(|v| MetadataValue::try_from(v).ok()) {
            req.metadata_mut().insert(CONTRACT_METADATA_KEY, v);
        }
        let mut c = self.driver()?;
        match tokio::time::timeout(self.timeout(), c.start_session(req)).await {
            Ok(Ok(_)) => Ok(()),
            Ok(Err(e)) if e.code() == tonic::Code::AlreadyExists => Ok(()),
            Ok(Err(e)) => Err(e),
            Err(_) => Err(Status::deadline_exceeded(
                "the driver did not answer in time",
            )),
        }
    }

    /// Marks the driver down after a fault seen on `what`.
    fn fault(&self, s: &Arc<Mutex<Session>>, what: &str, e: &Status) {
        let mut g = lock(s);
        if g.driver_down == 0 {
            log::warn!(
                "guard: session {:?}: the driver failed on {what} ({:?}: {}); answering in its place",
                g.start.session_uuid,
                e.code(),
                e.message()
            );
        }
        g.driver_down = self.params.fault_retry_calls;
        g.reopen = true;
        g.last_fault = Some(format!("{what}: {:?}: {}", e.code(), e.message()));
    }

    /// Forwards one observation call; a driver fault is absorbed (the driver is marked
    /// down), a refusal of the message is passed back.
    async fn forward<F, Fut>(
        &self,
        s: &Arc<Mutex<Session>>,
        what: &str,
        call: F,
    ) -> Result<(), Status>
    where
        F: FnOnce(EgodriverServiceClient<Channel>) -> Fut,
        Fut: std::future::Future<Output = Result<Response<Empty>, Status>>,
    {
        if !self.driver_ready(s).await {
            return Ok(());
        }
        let c = match self.driver() {
            Ok(c) => c,
            Err(e) => {
                self.fault(s, what, &e);
                return Ok(());
            }
        };
        match tokio::time::timeout(self.timeout(), call(c)).await {
            Ok(Ok(_)) => Ok(()),
            Ok(Err(e)) if !is_fault(&e) => Err(e),
            Ok(Err(e)) => {
                self.fault(s, what, &e);
                Ok(())
            }
            Err(_) => {
                self.fault(s, what, &Status::deadline_exceeded("no answer in time"));
                Ok(())
            }
        }
    }
}

fn yaw_of(q: &Quat) -> f64 {
    let (w, x, y, z) = (
        f64::from(q.w),
        f64::from(q.x),
        f64::from(q.y),
        f64::from(q.z),
    );
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    (a + std::f64::consts::PI).rem_euclid(t) - std::f64::consts::PI
}

#[tonic::async_trait]
impl EgodriverService for Guard {
    async fn start_session(
        &self,
        request: Request<DriveSessionRequest>,
    ) -> Result<Response<SessionRequestStatus>, Status> {
        let revision = request
            .metadata()
            .get(CONTRACT_METADATA_KEY)
            .and_then(|v| v.to_str().ok())
            .map(str::to_string);
        let msg = request.into_inner();
        let uuid = msg.session_uuid.clone();
        if uuid.is_empty() {
            return Err(Status::invalid_argument(
                "start_session: session_uuid is empty",
            ));
        }
        let declared: Vec<String> = msg
            .rollout_spec
            .as_ref()
            .and_then(|r| r.vehicle.as_ref())
            .map(|v| {
                v.available_cameras
                    .iter()
                    .map(|c| {
                        if c.logical_id.is_empty() {
                            c.intrinsics
                                .as_ref()
                                .map(|i| i.logical_id.clone())
                                .unwrap_or_default()
                        } else {
                            c.logical_id.clone()
                        }
                    })
                    .collect()
            })
            .unwrap_or_default();
        let p = &self.shared.params;
        let camera = match &p.camera {
            Some(c) if declared.iter().any(|d| d == c) => c.clone(),
            Some(c) => {
                return Err(Status::failed_precondition(format!(
                    "start_session: the guard monitors camera {c:?}, which the session does not declare (declared: {declared:?})"
                )));
            }
            None => match declared
                .iter()
                .find(|d| d.contains("front_wide"))
                .or_else(|| declared.first())
            {
                Some(c) => c.clone(),
                None => {
                    return Err(Status::invalid_argument(
                        "start_session: no camera declared (the guard monitors one)",
                    ));
                }
            },
        };
        let monitor = Monitor::new(&self.shared.odd, &p.scenario, p.monitor.clone())
            .map_err(|e| Status::internal(format!("the monitor cannot start: {e}")))?;
        let rco = Rco::with_rules(RcoParams::default())
            .map_err(|e| Status::internal(format!("the RCO cannot start: {e}")))?;
        {
            let mut sessions = lock(&self.shared.sessions);
            if sessions.contains_key(&uuid) {
                return Err(Status::already_exists(format!(
                    "session {uuid:?} already exists"
                )));
            }
            while sessions.len() >= MAX_SESSIONS {
                let oldest = sessions
                    .iter()
                    .min_by_key(|(_, s)| lock(s).last_used)
                    .map(|(k, _)| k.clone());
                let Some(k) = oldest else { break };
                log::warn!(
                    "guard: {MAX_SESSIONS} sessions open; dropping {k}, the least recently used"
                );
                sessions.remove(&k);
            }
            sessions.insert(
                uuid.clone(),
                Arc::new(Mutex::new(Session {
                    start: msg.clone(),
                    revision: revision.clone(),
                    camera: camera.clone(),
                    monitor,
                    last: None,
                    size: (0, 0),
                    rco,
                    ego: Vec::new(),
                    speed_mps: None,
                    target: None,
                    calls: 0,
                    driver_down: 0,
                    reopen: false,
                    last_fault: None,
                    last_used: Instant::now(),
                })),
            );
        }
        log::info!(
            "guard: session {uuid}: monitoring camera {camera:?}, scenario {}",
            p.scenario
        );
        let s = self.shared.session(&uuid)?;
        match self.shared.forward_start(msg, revision.as_deref()).await {
            Ok(()) => {}
            Err(e) if !is_fault(&e) => {
                lock(&self.shared.sessions).remove(&uuid);
                return Err(e);
            }
            Err(e) => self.shared.fault(&s, "start_session", &e),
        }
        Ok(Response::new(SessionRequestStatus {}))
    }

    async fn close_session(
        &self,
        request: Request<DriveSessionCloseRequest>,
    ) -> Result<Response<Empty>, Status> {
        let msg = request.into_inner();
        let removed = lock(&self.shared.sessions).remove(&msg.session_uuid);
        if let Some(s) = removed
            && lock(&s).driver_down == 0
            && let Ok(mut c) = self.shared.driver()
        {
            let _ = tokio::time::timeout(self.shared.timeout(), c.close_session(msg)).await;
        }
        Ok(Response::new(Empty {}))
    }

    async fn submit_image_observation(
        &self,
        request: Request<RolloutCameraImage>,
    ) -> Result<Response<Empty>, Status> {
        let msg = request.into_inner();
        let s = self.shared.session(&msg.session_uuid)?;
        let image = msg
            .camera_image
            .as_ref()
            .ok_or_else(|| Status::invalid_argument("submit_image_observation: no camera_image"))?;
        let monitored = lock(&s).camera == image.logical_id;
        if monitored {
            let bytes = image.image_bytes.clone();
            let cap = self.shared.params.limits.max_request_pixels;
            let decoded =
                tokio::task::spawn_blocking(move || fogline_remote::decode_frame(&bytes, cap))
                    .await
                    .map_err(|e| Status::internal(format!("decoding failed: {e}")))?
                    .map_err(|e| {
                        Status::invalid_argument(format!("camera {:?}: {e}", image.logical_id))
                    })?;
            let mut g = lock(&s);
            let record = g
                .monitor
                .step_frame(
                    &decoded.rgb,
                    decoded.width as usize,
                    decoded.height as usize,
                )
                .map_err(|e| {
                    Status::invalid_argument(format!("camera {:?}: {e}", image.logical_id))
                })?;
            if record.switched {
                log::info!(
                    "guard: session {:?}: {} the envelope: {}",
                    msg.session_uuid,
                    if record.in_envelope {
                        "back inside"
                    } else {
                        "out of"
                    },
                    record.reason
                );
            }
            g.size = (decoded.width, decoded.height);
            g.last = Some(record);
        }
        let sh = &self.shared;
        sh.forward(&s, "submit_image_observation", |mut c| async move {
            c.submit_image_observation(msg).await
        })
        .await?;
        Ok(Response::new(Empty {}))
    }

    async fn submit_egomotion_observation(
        &self,
        request: Request<RolloutEgoTrajectory>,
    ) -> Result<Response<Empty>, Status> {
        let msg = request.into_inner();
        let s = self.shared.session(&msg.session_uuid)?;
        let poses = msg
            .trajectory
            .as_ref()
            .map(|t| t.poses.as_slice())
            .unwrap_or_default();
        if !msg.dynamic_states.is_empty() && msg.dynamic_states.len() != poses.len() {
            return Err(Status::invalid_argument(format!(
                "submit_egomotion_observation: {} dynamic_states for {} poses",
                msg.dynamic_states.len(),
                poses.len()
            )));
        }
        {
            let mut g = lock(&s);
            for (i, p) in poses.iter().enumerate() {
                let pose = p.pose.unwrap_or_default();
                let v = pose.vec.unwrap_or_default();
                let yaw = yaw_of(&pose.quat.unwrap_or_default());
                let e = (
                    p.timestamp_us,
                    f64::from(v.x),
                    f64::from(v.y),
                    f64::from(v.z),
                    yaw,
                );
                if ![e.1, e.2, e.3, e.4].iter().all(|x| x.is_finite()) {
                    return Err(Status::invalid_argument(format!(
                        "submit_egomotion_observation: pose {i} is not finite"
                    )));
                }
                if g.ego.last().is_some_and(|l| e.0 <= l.0) {
                    continue;
                }
                g.ego.push(e);
                if let Some(lv) = msg.dynamic_states.get(i).and_then(|d| d.linear_velocity) {
                    let sp = f64::from(lv.x).hypot(f64::from(lv.y));
                    g.speed_mps = sp.is_finite().then_some(sp);
                }
            }
            let excess = g.ego.len().saturating_sub(8);
            g.ego.drain(..excess);
        }
        let sh = &self.shared;
        sh.forward(&s, "submit_egomotion_observation", |mut c| async move {
            c.submit_egomotion_observation(msg).await
        })
        .await?;
        Ok(Response::new(Empty {}))
    }

    async fn submit_route(
        &self,
        request: Request<RouteRequest>,
    ) -> Result<Response<Empty>, Status> {
        let msg = request.into_inner();
        let s = self.shared.session(&msg.session_uuid)?;
        let target = msg.route.as_ref().and_then(|r| {
            r.waypoints
                .iter()
                .map(|w| [f64::from(w.x), f64::from(w.y)])
                .find(|w| w[0].is_finite() && w[1].is_finite() && w[0].hypot(w[1]) >= 5.0)
        });
        lock(&s).target = target;
        let sh = &self.shared;
        sh.forward(&s, "submit_route", |mut c| async move {
            c.submit_route(msg).await
        })
        .await?;
        Ok(Response::new(Empty {}))
    }

    async fn submit_recording_ground_truth(
        &self,
        request: Request<GroundTruthRequest>,
    ) -> Result<Response<Empty>, Status> {
        let msg = request.into_inner();
        let s = self.shared.session(&msg.session_uuid)?;
        let sh = &self.shared;
        sh.forward(&s, "submit_recording_ground_truth", |mut c| async move {
            c.submit_recording_ground_truth(msg).await
        })
        .await?;
        Ok(Response::new(Empty {}))
    }

    async fn drive(
        &self,
        request: Request<DriveRequest>,
    ) -> Result<Response<DriveResponse>, Status> {
        let msg = request.into_inner();
        let uuid = msg.session_uuid.clone();
        let now = msg.time_now_us;
        let s = self.shared.session(&uuid)?;
        let (in_env, call) = {
            let mut g = lock(&s);
            if g.driver_down > 0 {
                g.driver_down -= 1;
            }
            let call = g.calls;
            g.calls += 1;
            (g.last.as_ref().is_none_or(|r| r.in_envelope), call)
        };
        let mut driver_ms = None;
        let mut reason = None;
        if in_env && self.shared.driver_ready(&s).await {
            let t = Instant::now();
            let r = match self.shared.driver() {
                Ok(mut c) => {
                    tokio::time::timeout(self.shared.timeout(), c.drive(msg.clone())).await
                }
                Err(e) => Ok(Err(e)),
            };
            let ms = t.elapsed().as_secs_f64() * 1e3;
            match r {
                Ok(Ok(resp)) => {
                    let monitor = lock(&s).last.clone();
                    self.shared.write(&GuardRecord {
                        session: uuid,
                        call,
                        time_now_us: now,
                        source: "driver".into(),
                        reason: None,
                        in_envelope: true,
                        driver_ms: Some(ms),
                        takeover: None,
                        monitor,
                    });
                    return Ok(resp);
                }
                Ok(Err(e)) if !is_fault(&e) => {
                    // The driver refused the simulator's message: its answer, passed back.
                    let monitor = lock(&s).last.clone();
                    self.shared.write(&GuardRecord {
                        session: uuid,
                        call,
                        time_now_us: now,
                        source: "refused".into(),
                        reason: Some(format!("driver refused {:?}: {}", e.code(), e.message())),
                        in_envelope: true,
                        driver_ms: Some(ms),
                        takeover: None,
                        monitor,
                    });
                    return Err(e);
                }
                Ok(Err(e)) => {
                    driver_ms = Some(ms);
                    reason = Some(format!("driver error {:?}: {}", e.code(), e.message()));
                    self.shared.fault(&s, "drive", &e);
                }
                Err(_) => {
                    reason = Some(format!(
                        "driver timeout: no answer within {} ms",
                        self.shared.params.driver_timeout_ms
                    ));
                    self.shared
                        .fault(&s, "drive", &Status::deadline_exceeded("timeout"));
                }
            }
        } else if in_env {
            let last = lock(&s).last_fault.clone().unwrap_or_default();
            reason = Some(format!("driver down since an earlier fault ({last})"));
        }
        let (answer, anchor, monitor) = {
            let mut g = lock(&s);
            let known: Vec<_> = g.ego.iter().copied().filter(|e| e.0 <= now).collect();
            let anchor = known.last().copied();
            let ego = ego_now(&known, g.speed_mps);
            let v = &self.shared.params.vehicle;
            let answer = if in_env {
                takeover::safe_stop(&ego, v)
            } else {
                let degraded: Vec<String> = g
                    .last
                    .as_ref()
                    .map(|r| {
                        r.axes
                            .iter()
                            .filter(|a| a.beyond)
                            .map(|a| a.axis.clone())
                            .collect()
                    })
                    .unwrap_or_default();
                let (w, h) = g.size;
                let obs = takeover::observation(call, w, h, &ego, g.target, &degraded);
                takeover::rco_answer(&mut g.rco, &obs, &ego, v)
            };
            if !in_env {
                reason = g.last.as_ref().map(|r| r.reason.clone());
            }
            (answer, anchor, g.last.clone())
        };
        let Some(anchor) = anchor else {
            return Err(Status::failed_precondition(format!(
                "session {uuid}: no ego pose at or before time_now_us {now} \
                 (submit_egomotion_observation comes before drive)"
            )));
        };
        let response = respond(
            &answer,
            anchor,
            now,
            self.shared.params.vehicle.dt_s,
            reason.as_deref(),
        );
        self.shared.write(&GuardRecord {
            session: uuid,
            call,
            time_now_us: now,
            source: answer.kind.clone(),
            reason,
            in_envelope: in_env,
            driver_ms,
            takeover: Some(answer),
            monitor,
        });
        Ok(Response::new(response))
    }

    async fn get_version(&self, _request: Request<Empty>) -> Result<Response<VersionId>, Status> {
        let (major, minor, patch) = ALPASIM_API_VERSION;
        let mut response = Response::new(VersionId {
            version_id: format!("{} {}", env!("CARGO_PKG_NAME"), env!("CARGO_PKG_VERSION")),
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
        Err(Status::permission_denied(
            "shut_down is not forwarded by the guard; stop it with a signal",
        ))
    }
}

/// Speed, acceleration and yaw rate from the newest poses (the runtime's speed if it sent
/// one).
fn ego_now(known: &[(u64, f64, f64, f64, f64)], speed: Option<f64>) -> EgoNow {
    let rate = |a: &(u64, f64, f64, f64, f64), b: &(u64, f64, f64, f64, f64)| {
        let dt = (b.0.saturating_sub(a.0)) as f64 / 1e6;
        (dt > 0.0).then(|| ((b.1 - a.1).hypot(b.2 - a.2) / dt, wrap(b.4 - a.4) / dt, dt))
    };
    let n = known.len();
    let last = if n >= 2 {
        rate(&known[n - 2], &known[n - 1])
    } else {
        None
    };
    let prev = if n >= 3 {
        rate(&known[n - 3], &known[n - 2])
    } else {
        None
    };
    let v = speed.or(last.map(|l| l.0)).unwrap_or(0.0);
    let accel = match (last, prev) {
        (Some(l), Some(p)) => (l.0 - p.0) / l.2,
        _ => 0.0,
    };
    EgoNow {
        speed_mps: v,
        accel_x_mps2: if accel.is_finite() { accel } else { 0.0 },
        yaw_rate_rps: last.map_or(0.0, |l| l.1),
    }
}

/// The guard's answer in the local frame: the anchor at `now`, then the integrated points.
fn respond(
    a: &TakeoverAnswer,
    anchor: (u64, f64, f64, f64, f64),
    now: u64,
    dt_s: f64,
    reason: Option<&str>,
) -> DriveResponse {
    let (_, ax, ay, az, ayaw) = anchor;
    let (sy, cy) = ayaw.sin_cos();
    let step_us = (dt_s * 1e6).round() as u64;
    let pose = |x: f64, y: f64, yaw: f64, k: u64| {
        let h = 0.5 * (ayaw + yaw);
        PoseAtTime {
            pose: Some(Pose {
                vec: Some(Vec3 {
                    x: (ax + cy * x - sy * y) as f32,
                    y: (ay + sy * x + cy * y) as f32,
                    z: az as f32,
                }),
                quat: Some(Quat {
                    w: h.cos() as f32,
                    x: 0.0,
                    y: 0.0,
                    z: h.sin() as f32,
                }),
            }),
            timestamp_us: now.saturating_add(k * step_us),
        }
    };
    let mut poses = vec![pose(0.0, 0.0, 0.0, 0)];
    for (k, p) in a.xy_yaw.iter().enumerate() {
        poses.push(pose(p[0], p[1], p[2], k as u64 + 1));
    }
    let debug = serde_json::json!({
        "guard": a.kind,
        "reason": reason,
        "action": a.action,
        "strategy": a.strategy,
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
