//! A small HTTP/JSON protocol for planners, both ways round.
//!
//! - `POST /v1/plan`: the planner's input as JSON (frames as base64 PNG or JPEG) →
//!   `200 {"trajectory": [[x, y] × 64], "explanation": "…", "decision": "…" | null}`;
//!   errors are 4xx/5xx with `{"error": "…"}`.
//! - `GET /v1/health`: `200 {"status": "ok", "planner": "…"}`.
//!
//! [`Client`] is a planner behind this protocol as a [`Planner`](crate::Planner);
//! [`serve`] puts any [`Planner`](crate::Planner) behind it. The schema is
//! `docs/http-planner.openapi.yaml`; `docs/remote.md` has the prose.

mod client;
mod server;
mod types;

pub use client::{Client, ClientOptions};
pub use server::{SERVE_BODY_BYTES, ServeOptions, serve};

pub use crate::{ImageFormat, Limits, ServerHandle};

/// The path of the planning call.
pub const PLAN_PATH: &str = "/v1/plan";
/// The path of the health check.
pub const HEALTH_PATH: &str = "/v1/health";
/// The largest answer body the client accepts (256 MiB; the server's request limit is
/// [`ServeOptions::max_body_bytes`]).
pub const MAX_BODY_BYTES: usize = 256 * 1024 * 1024;
