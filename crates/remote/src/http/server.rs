//! The HTTP/JSON server: any [`Planner`] behind `POST /v1/plan`.

use std::convert::Infallible;
use std::io;
use std::net::SocketAddr;
use std::sync::Arc;

use base64::Engine as _;
use base64::alphabet;
use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
use bytes::Bytes;
use fogline_types::clip::{CameraCalib, CameraId, CameraInput, PlannerInput, PlannerOutput};
use http_body_util::{BodyExt as _, Full, LengthLimitError, Limited};
use hyper::body::Incoming;
use hyper::header::{ALLOW, CONTENT_TYPE};
use hyper::service::service_fn;
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::sync::Semaphore;
use tokio::task::JoinSet;

use super::types::{AnswerBody, ErrorBody, PlanBody};
use super::{HEALTH_PATH, PLAN_PATH};
use crate::serving::{
    Guarded, Limits, StopFlag, accept_guarded, server_runtime, stop_flag, stopped,
};
use crate::{FailureKind, PlanRequest, Planner, ServerHandle, codec};

/// Settings of an HTTP server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServeOptions {
    /// The largest request body accepted, bytes (default 96 MiB: sixteen 1080p PNG camera
    /// frames in base64 fit).
    pub max_body_bytes: usize,
    /// Connections, timeouts, concurrent requests and decoded pixels ([`Limits`]).
    pub limits: Limits,
}

impl Default for ServeOptions {
    fn default() -> Self {
        Self {
            max_body_bytes: SERVE_BODY_BYTES,
            limits: Limits::default(),
        }
    }
}

/// The default request body limit of the server.
pub const SERVE_BODY_BYTES: usize = 96 * 1024 * 1024;

/// Serves `planner` over the HTTP/JSON protocol on `addr` (port 0 picks a free port; see
/// [`ServerHandle::local_addr`]). The socket is bound before this returns.
pub fn serve(
    addr: SocketAddr,
    planner: Arc<dyn Planner>,
    opts: ServeOptions,
) -> io::Result<ServerHandle> {
    opts.limits.validate().map_err(io::Error::other)?;
    if opts.max_body_bytes == 0 {
        return Err(io::Error::other("max_body_bytes must be positive"));
    }
    let runtime = server_runtime("fogline-http")?;
    let listener = runtime.block_on(tokio::net::TcpListener::bind(addr))?;
    let local = listener.local_addr()?;
    let stop = stop_flag();
    log::info!("http: serving {} on {local}", planner.describe());
    let requests = Arc::new(Semaphore::new(opts.limits.max_concurrent_requests));
    let shared = Arc::new(Shared {
        planner,
        opts,
        requests,
    });
    let task = runtime.spawn(accept_loop(listener, shared, stop.clone()));
    Ok(ServerHandle::new(local, "http", stop, task, runtime))
}

struct Shared {
    planner: Arc<dyn Planner>,
    opts: ServeOptions,
    /// One permit per request being read, decoded and planned.
    requests: Arc<Semaphore>,
}

async fn accept_loop(
    listener: tokio::net::TcpListener,
    shared: Arc<Shared>,
    stop: StopFlag,
) -> io::Result<()> {
    let mut incoming = accept_guarded(listener, &shared.opts.limits, stop.clone(), "http");
    let mut connections = JoinSet::new();
    let halt = stopped(stop.clone());
    tokio::pin!(halt);
    loop {
        tokio::select! {
            _ = &mut halt => break,
            accepted = incoming.recv() => match accepted {
                Some(Ok(stream)) => {
                    connections.spawn(connection(stream, Arc::clone(&shared), stop.clone()));
                }
                Some(Err(e)) => log::warn!("http: accept failed: {e}"),
                None => break,
            },
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
    drop(incoming);
    while connections.join_next().await.is_some() {}
    Ok(())
}

async fn connection(stream: Guarded, shared: Arc<Shared>, stop: StopFlag) {
    let header_timeout = shared.opts.limits.header_timeout;
    let service = service_fn(move |req| handle(Arc::clone(&shared), req));
    let conn = hyper::server::conn::http1::Builder::new()
        .timer(TokioTimer::new())
        .header_read_timeout(header_timeout)
        .serve_connection(TokioIo::new(stream), service);
    tokio::pin!(conn);
    let result = tokio::select! {
        r = conn.as_mut() => r,
        _ = stopped(stop) => {
            conn.as_mut().graceful_shutdown();
            conn.await
        }
    };
    if let Err(e) = result {
        log::debug!("http: connection: {e}");
    }
}

fn json_response(status: StatusCode, body: Vec<u8>) -> Response<Full<Bytes>> {
    let mut r = Response::new(Full::new(Bytes::from(body)));
    *r.status_mut() = status;
    r.headers_mut().insert(
        CONTENT_TYPE,
        hyper::header::HeaderValue::from_static("application/json"),
    );
    r
}

fn error_response(
    status: StatusCode,
    error: String,
    kind: Option<FailureKind>,
) -> Response<Full<Bytes>> {
    let body = ErrorBody {
        error,
        kind: kind.map(|k| k.name().to_string()),
    };
    json_response(status, serde_json::to_vec(&body).unwrap_or_default())
}

async fn handle(
    shared: Arc<Shared>,
    req: Request<Incoming>,
) -> Result<Response<Full<Bytes>>, Infallible> {
    let path = req.uri().path().to_string();
    let response = match (req.method(), path.as_str()) {
        (&Method::GET, HEALTH_PATH) => {
            let body = serde_json::json!({"status": "ok", "planner": shared.planner.describe()});
            json_response(StatusCode::OK, body.to_string().into_bytes())
        }
        (&Method::POST, PLAN_PATH) => plan(shared, req).await,
        (_, HEALTH_PATH | PLAN_PATH) => {
            let allow = if path == HEALTH_PATH { "GET" } else { "POST" };
            let mut r = error_response(
                StatusCode::METHOD_NOT_ALLOWED,
                format!("{path} takes {allow}"),
                None,
            );
            r.headers_mut()
                .insert(ALLOW, hyper::header::HeaderValue::from_static(allow));
            r
        }
        _ => error_response(
            StatusCode::NOT_FOUND,
            format!("no endpoint {path}: POST {PLAN_PATH} or GET {HEALTH_PATH}"),
            None,
        ),
    };
    Ok(response)
}

async fn plan(shared: Arc<Shared>, req: Request<Incoming>) -> Response<Full<Bytes>> {
    // The body is read only with a permit: requests beyond the cap wait here, their bodies
    // unread, so memory stays bounded however many arrive at once.
    let Ok(permit) = Arc::clone(&shared.requests).acquire_owned().await else {
        return error_response(
            StatusCode::SERVICE_UNAVAILABLE,
            "the server is stopping".into(),
            None,
        );
    };
    let limit = shared.opts.limits.request_timeout;
    let read = Limited::new(req.into_body(), shared.opts.max_body_bytes).collect();
    let Ok(read) = tokio::time::timeout(limit, read).await else {
        return error_response(
            StatusCode::REQUEST_TIMEOUT,
            format!("the request body did not arrive within {limit:?}"),
            None,
        );
    };
    let body = match read {
        Ok(b) => b.to_bytes(),
        Err(e) if e.is::<LengthLimitError>() => {
            return error_response(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!(
                    "the request is larger than {} bytes",
                    shared.opts.max_body_bytes
                ),
                None,
            );
        }
        Err(e) => {
            return error_response(
                StatusCode::BAD_REQUEST,
                format!("cannot read the request: {e}"),
                None,
            );
        }
    };
    let worker = Arc::clone(&shared);
    // The permit lives as long as the planner runs, even when the caller has given up.
    match tokio::task::spawn_blocking(move || {
        let _permit = permit;
        run(&worker, &body)
    })
    .await
    {
        Ok(Ok(out)) => {
            let answer = AnswerBody {
                trajectory: &out.trajectory.xy,
                explanation: &out.explanation,
                decision: out.decision.map(|d| d.name()),
            };
            // Non-finite numbers become null: passed on as they are, for the caller to judge.
            json_response(
                StatusCode::OK,
                serde_json::to_vec(&answer).unwrap_or_default(),
            )
        }
        Ok(Err((status, message, kind))) => error_response(status, message, kind),
        Err(e) => error_response(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the planner did not finish: {e}"),
            None,
        ),
    }
}

type Refusal = (StatusCode, String, Option<FailureKind>);

fn bad(message: String) -> Refusal {
    (StatusCode::BAD_REQUEST, message, None)
}

/// Decodes a request and plans (on a blocking thread).
fn run(shared: &Shared, body: &[u8]) -> Result<PlannerOutput, Refusal> {
    let req: PlanBody =
        serde_json::from_slice(body).map_err(|e| bad(format!("invalid request: {e}")))?;
    let b64 = GeneralPurpose::new(
        &alphabet::STANDARD,
        GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
    );
    let mut calibs: Vec<CameraCalib> = Vec::with_capacity(req.cameras.len());
    for (i, cam) in req.cameras.iter().enumerate() {
        let id = CameraId::parse(&cam.id).ok_or_else(|| {
            bad(format!(
                "cameras[{i}].id {:?} is not a camera name (one of {})",
                cam.id,
                CameraId::ALL.map(|c| c.name()).join(", ")
            ))
        })?;
        if calibs.iter().any(|c| c.id == id) {
            return Err(bad(format!("cameras[{i}]: camera {id} appears twice")));
        }
        let k = cam.calibration;
        let calib = CameraCalib {
            id,
            width: k.width,
            height: k.height,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            x_m: k.x_m,
            y_m: k.y_m,
            z_m: k.z_m,
            yaw_rad: k.yaw_rad,
            pitch_rad: k.pitch_rad,
        };
        calib
            .validate()
            .map_err(|e| bad(format!("cameras[{i}].calibration: {e}")))?;
        calibs.push(calib);
    }
    // What decoding would cost, known from the calibrations before any image is read.
    let pixels: u64 = req
        .cameras
        .iter()
        .zip(&calibs)
        .map(|(cam, c)| cam.frames.len() as u64 * u64::from(c.width) * u64::from(c.height))
        .sum();
    let cap = shared.opts.limits.max_request_pixels;
    if pixels > cap {
        return Err((
            StatusCode::PAYLOAD_TOO_LARGE,
            format!(
                "the request's frames hold {pixels} pixels (frames x width x height), more than \
                 this server's limit of {cap}"
            ),
            None,
        ));
    }
    // Every frame, oldest first per camera, decoded on all cores.
    let mut jobs = Vec::new();
    for (i, cam) in req.cameras.iter().enumerate() {
        let mut order: Vec<usize> = (0..cam.frames.len()).collect();
        order.sort_by(|&a, &b| cam.frames[a].t_s.total_cmp(&cam.frames[b].t_s));
        jobs.extend(order.into_iter().map(|j| (i, j)));
    }
    // The work is the pixels decoded, not the bytes sent: 16 JPEG frames of 576×320 are
    // under 1 MB of base64 and 8.8 MB of pixels.
    let work = usize::try_from(pixels.saturating_mul(3)).unwrap_or(usize::MAX);
    let mut decoded = codec::par_map(&jobs, work, |&(i, j)| {
        let f = &req.cameras[i].frames[j];
        let calib = &calibs[i];
        let at = format!("cameras[{i}] ({}) frames[{j}]", calib.id);
        if !f.t_s.is_finite() || f.t_s > 1e-9 {
            return Err(bad(format!(
                "{at}: t_s must be finite and ≤ 0, got {}",
                f.t_s
            )));
        }
        let fmt = f.image_format.to_ascii_lowercase();
        if !matches!(fmt.as_str(), "png" | "jpeg" | "jpg") {
            return Err(bad(format!(
                "{at}: image_format {:?} is not png or jpeg",
                f.image_format
            )));
        }
        let bytes = b64
            .decode(f.data.as_bytes())
            .map_err(|e| bad(format!("{at}: data is not base64: {e}")))?;
        let img = codec::decode_sized(&bytes, calib.width, calib.height, "the calibration")
            .map_err(|e| bad(format!("{at}: {e}")))?;
        Ok(img.rgb)
    })
    .into_iter();
    let mut cameras: Vec<(CameraCalib, Vec<Vec<u8>>)> = Vec::with_capacity(calibs.len());
    for (calib, cam) in calibs.iter().zip(&req.cameras) {
        let frames = decoded
            .by_ref()
            .take(cam.frames.len())
            .collect::<Result<Vec<_>, Refusal>>()?;
        cameras.push((*calib, frames));
    }
    let mut history = req.ego_history;
    history.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
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
    if let Some(t0) = req.t0_us {
        log::debug!("http: plan for {} at t0 = {t0} µs", req.scene_id);
    }
    shared
        .planner
        .plan(&PlanRequest {
            scene_id: &req.scene_id,
            seed: req.seed,
            input,
        })
        .map_err(|e| {
            let status = match e.kind {
                FailureKind::Input => StatusCode::UNPROCESSABLE_ENTITY,
                _ => StatusCode::INTERNAL_SERVER_ERROR,
            };
            (
                status,
                format!("{}: {}", shared.planner.describe(), e.message),
                Some(e.kind),
            )
        })
}
