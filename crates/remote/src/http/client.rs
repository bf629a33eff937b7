//! The HTTP/JSON client: a planner behind `POST /v1/plan` as a [`Planner`].

use std::time::Duration;

use base64::Engine as _;
use bytes::Bytes;
use fogline_types::clip::{DT_S, Decision, HORIZON, PlannerOutput, Trajectory};
use hyper::StatusCode;
use tokio::runtime::Runtime;

use super::types::{CalibrationBody, CameraBody, ErrorBody, FrameBody, FrameJson, PlanBody};
use super::{MAX_BODY_BYTES, PLAN_PATH};
use crate::{FailureKind, ImageFormat, PlanFailure, PlanRequest, Planner, codec};

/// Settings of an HTTP [`Client`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClientOptions {
    /// The planner's base URL, `http://host:port` or `https://host[:port]` (a path prefix is
    /// allowed: `http://host:port/planner` posts to `/planner/v1/plan`).
    pub url: String,
    /// The time limit of one call: connecting, sending, planning and answering.
    pub timeout: Duration,
    /// How frames are encoded.
    pub image_format: ImageFormat,
}

impl Default for ClientOptions {
    fn default() -> Self {
        Self {
            url: "http://127.0.0.1:8080".into(),
            timeout: Duration::from_secs(30),
            image_format: ImageFormat::Png,
        }
    }
}

/// A planner behind the HTTP/JSON protocol, as a [`Planner`].
///
/// Synchronous (an internal tokio runtime); any number of threads may call at once, each
/// call on its own connection. Do not call from inside an async runtime.
pub struct Client {
    opts: ClientOptions,
    /// Where to connect, the `Host` header and the path prefix.
    base: fogline_io::http::BaseUrl,
    /// How an `https://` planner's certificate is checked.
    tls: fogline_io::http::Tls,
    runtime: Runtime,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("http::Client")
            .field("opts", &self.opts)
            .field("tls", &self.tls)
            .finish_non_exhaustive()
    }
}

fn failure(kind: FailureKind, m: String) -> PlanFailure {
    PlanFailure::new(kind, m)
}

impl Client {
    /// A client for `opts.url`; nothing is connected until the first call. An `https://`
    /// planner's certificate is checked against the bundled roots and the process's CA
    /// certificate file (`fogline_io::http::set_default_ca_cert`, `--ca-cert`).
    pub fn new(opts: ClientOptions) -> Result<Self, PlanFailure> {
        let tls = fogline_io::http::Tls::process_default()
            .map_err(|e| failure(FailureKind::Input, format!("http client: {e}")))?;
        Self::with_tls(opts, tls)
    }

    /// A client for `opts.url` whose `https://` connections are checked by `tls`.
    pub fn with_tls(opts: ClientOptions, tls: fogline_io::http::Tls) -> Result<Self, PlanFailure> {
        let url = opts.url.trim();
        let base = fogline_io::http::BaseUrl::parse(url)
            .map_err(|e| failure(FailureKind::Input, format!("planner URL {url:?}: {e}")))?;
        if opts.timeout.is_zero() {
            return Err(failure(
                FailureKind::Input,
                "http client: the timeout must be positive".into(),
            ));
        }
        let runtime = crate::serving::client_runtime("fogline-http-client").map_err(|e| {
            failure(
                FailureKind::Input,
                format!("cannot start the http client runtime: {e}"),
            )
        })?;
        Ok(Self {
            base,
            tls,
            opts,
            runtime,
        })
    }

    /// The client's settings.
    pub fn options(&self) -> &ClientOptions {
        &self.opts
    }

    async fn post(&self, body: Vec<u8>) -> Result<(StatusCode, Bytes), PlanFailure> {
        use fogline_io::http::PostError;
        let url = &self.opts.url;
        let path = format!("{}{PLAN_PATH}", self.base.prefix);
        let (status, body) =
            fogline_io::http::post_json(&self.base, &self.tls, &path, body, None, MAX_BODY_BYTES)
                .await
                .map_err(|e| {
                    let kind = match e {
                        PostError::NotHttp(_) | PostError::Body(_) | PostError::TooLarge(_) => {
                            FailureKind::InvalidAnswer
                        }
                        PostError::Timeout(_) => FailureKind::Timeout,
                        PostError::Request(_) => FailureKind::Input,
                        // Connect, Connection, Tls (a certificate problem: no secure way there).
                        _ => FailureKind::Unavailable,
                    };
                    failure(kind, format!("http planner at {url}: {e}"))
                })?;
        let status = StatusCode::from_u16(status).map_err(|e| {
            failure(
                FailureKind::InvalidAnswer,
                format!("http planner at {url}: status {status}: {e}"),
            )
        })?;
        Ok((status, body))
    }
}

impl Planner for Client {
    fn describe(&self) -> String {
        format!("http planner at {}", self.opts.url)
    }

    fn plan(&self, request: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        let body = request_body(request, self.opts.image_format)?;
        let timeout = self.opts.timeout;
        let (status, bytes) = self.runtime.block_on(async {
            match tokio::time::timeout(timeout, self.post(body)).await {
                Ok(r) => r,
                Err(_) => Err(failure(
                    FailureKind::Timeout,
                    format!(
                        "http planner at {}: no answer within {:.3} s",
                        self.opts.url,
                        timeout.as_secs_f64()
                    ),
                )),
            }
        })?;
        read_answer(&self.opts.url, status, &bytes)
    }
}

fn request_body(request: &PlanRequest<'_>, format: ImageFormat) -> Result<Vec<u8>, PlanFailure> {
    let input = |m: String| failure(FailureKind::Input, m);
    let b64 = base64::engine::general_purpose::STANDARD;
    let mut jobs = Vec::new();
    for (i, cam) in request.input.cameras.iter().enumerate() {
        cam.calib.validate().map_err(input)?;
        let n = cam.frames.len();
        jobs.extend(cam.frames.iter().enumerate().map(|(j, f)| (i, j, n, *f)));
    }
    let bytes = jobs.iter().map(|job| job.3.len()).sum();
    let mut encoded = codec::par_map(&jobs, bytes, |&(i, j, n, f)| {
        let c = &request.input.cameras[i].calib;
        let bytes = codec::encode(f, c.width, c.height, format)
            .map_err(|e| input(format!("{} frame {j}: {e}", c.id)))?;
        serde_json::value::to_raw_value(&FrameBody {
            t_s: -DT_S * (n - 1 - j) as f64,
            image_format: format.name().to_string(),
            data: b64.encode(bytes),
        })
        .map_err(|e| input(format!("cannot write the request: {e}")))
    })
    .into_iter();
    let mut cameras = Vec::with_capacity(request.input.cameras.len());
    for cam in &request.input.cameras {
        let c = &cam.calib;
        let frames = encoded
            .by_ref()
            .take(cam.frames.len())
            .collect::<Result<Vec<FrameJson>, PlanFailure>>()?;
        cameras.push(CameraBody {
            id: c.id.name().to_string(),
            calibration: CalibrationBody {
                width: c.width,
                height: c.height,
                fx: c.fx,
                fy: c.fy,
                cx: c.cx,
                cy: c.cy,
                x_m: c.x_m,
                y_m: c.y_m,
                z_m: c.z_m,
                yaw_rad: c.yaw_rad,
                pitch_rad: c.pitch_rad,
            },
            frames,
        });
    }
    for (k, p) in request.input.ego_history.iter().enumerate() {
        if ![p.t_s, p.x_m, p.y_m, p.yaw_rad, p.speed_mps]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(input(format!("ego history pose {k} is not finite")));
        }
    }
    let body = PlanBody {
        scene_id: request.scene_id.to_string(),
        seed: request.seed,
        t0_us: None,
        cameras,
        ego_history: request.input.ego_history.to_vec(),
    };
    serde_json::to_vec(&body).map_err(|e| input(format!("cannot write the request: {e}")))
}

/// The first `max` characters of a body, for error messages.
fn excerpt(bytes: &[u8], max: usize) -> String {
    let text = String::from_utf8_lossy(bytes);
    let text = text.trim();
    match text.char_indices().nth(max) {
        Some((i, _)) => format!("{}…", &text[..i]),
        None => text.to_string(),
    }
}

/// Checks an answer strictly: exactly 64 finite waypoints, an optional explanation and
/// decision.
fn read_answer(url: &str, status: StatusCode, body: &[u8]) -> Result<PlannerOutput, PlanFailure> {
    let invalid = |m: String| {
        failure(
            FailureKind::InvalidAnswer,
            format!("http planner at {url}: {m}"),
        )
    };
    if status.as_u16() >= 400 {
        let message = serde_json::from_slice::<ErrorBody>(body)
            .map(|e| e.error)
            .unwrap_or_else(|_| excerpt(body, 300));
        return Err(failure(
            FailureKind::Remote,
            format!("http planner at {url} answered {status}: {message}"),
        ));
    }
    if status != StatusCode::OK {
        return Err(invalid(format!("unexpected status {status}")));
    }
    let value: serde_json::Value = serde_json::from_slice(body).map_err(|e| {
        invalid(format!(
            "the answer is not JSON ({e}): {}",
            excerpt(body, 80)
        ))
    })?;
    let obj = value
        .as_object()
        .ok_or_else(|| invalid("the answer is not a JSON object".into()))?;
    let points = obj
        .get("trajectory")
        .and_then(|t| t.as_array())
        .ok_or_else(|| invalid("the answer has no \"trajectory\" array".into()))?;
    if points.len() != HORIZON {
        return Err(invalid(format!(
            "the trajectory has {} waypoints, expected {HORIZON}",
            points.len()
        )));
    }
    let mut xy = Vec::with_capacity(HORIZON);
    for (k, p) in points.iter().enumerate() {
        let pair = p.as_array().filter(|a| a.len() == 2).and_then(|a| {
            let x = a[0].as_f64()?;
            let y = a[1].as_f64()?;
            (x.is_finite() && y.is_finite()).then_some([x, y])
        });
        let Some(pair) = pair else {
            return Err(invalid(format!(
                "waypoint {k} is not a pair of finite numbers: {p}"
            )));
        };
        xy.push(pair);
    }
    let explanation = match obj.get("explanation") {
        None | Some(serde_json::Value::Null) => String::new(),
        Some(serde_json::Value::String(s)) => s.trim().to_string(),
        Some(other) => return Err(invalid(format!("\"explanation\" is not a string: {other}"))),
    };
    let decision = match obj.get("decision") {
        None | Some(serde_json::Value::Null) => None,
        Some(serde_json::Value::String(s)) => {
            let d = Decision::parse(s);
            if d.is_none() {
                log::debug!("http planner at {url}: decision {s:?} is not one of fogline's");
            }
            d
        }
        Some(other) => return Err(invalid(format!("\"decision\" is not a string: {other}"))),
    };
    let trajectory = Trajectory { xy };
    trajectory.validate().map_err(invalid)?;
    Ok(PlannerOutput {
        trajectory,
        explanation,
        decision,
    })
}
