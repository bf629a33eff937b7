//! `fogline serve`: the reference planner behind an endpoint, over AlpaSim's egodriver gRPC
//! contract or fogline's HTTP/JSON protocol (see `docs/remote.md`).

use std::io::Write as _;
use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use fogline_campaign::BuiltinPlanner;
use fogline_remote::{Limits, Planner, egodriver, http};

/// The protocol to serve.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Protocol {
    /// AlpaSim's egodriver.EgodriverService over gRPC (default address 127.0.0.1:50051).
    Egodriver,
    /// fogline's HTTP/JSON protocol: POST /v1/plan, GET /v1/health (default 127.0.0.1:8080).
    Http,
}

/// Arguments of `fogline serve`.
#[derive(Args)]
pub struct ServeArgs {
    /// The protocol.
    #[arg(value_enum)]
    protocol: Protocol,
    /// Address to listen on (port 0 picks a free port; the line `listening on ADDR (PROTOCOL)`
    /// on stdout names it).
    #[arg(long)]
    addr: Option<SocketAddr>,
    /// egodriver only: the fogline camera a declared camera stands for, by logical id
    /// (repeatable), e.g. `--camera-map front=camera_front_wide_120fov`. PhysicalAI camera
    /// names need no mapping; without a front-wide camera the widest forward camera stands in.
    #[arg(long = "camera-map", value_name = "LOGICAL=CAMERA")]
    camera_map: Vec<String>,
    /// egodriver only: let the `shut_down` RPC stop the server (AlpaSim's runtime calls it at
    /// the end of a run). Off by default: the call is unauthenticated.
    #[arg(long)]
    allow_remote_shutdown: bool,
    /// Connections held open at once; more are closed as they arrive.
    #[arg(long, default_value_t = Limits::default().max_connections)]
    max_connections: usize,
    /// Seconds a connection may send nothing before it is closed.
    #[arg(long, default_value_t = Limits::default().idle_timeout.as_secs())]
    idle_timeout: u64,
    /// Requests read, decoded and planned at once; more wait their turn.
    #[arg(long, default_value_t = Limits::default().max_concurrent_requests)]
    max_concurrent: usize,
    /// Pixels (frames x width x height) one request, or one egodriver session, may carry.
    #[arg(long, default_value_t = Limits::default().max_request_pixels)]
    max_pixels: u64,
}

fn limits(a: &ServeArgs) -> Result<Limits> {
    let l = Limits {
        max_connections: a.max_connections,
        idle_timeout: std::time::Duration::from_secs(a.idle_timeout),
        max_concurrent_requests: a.max_concurrent,
        max_request_pixels: a.max_pixels,
        ..Limits::default()
    };
    l.validate().map_err(anyhow::Error::msg)?;
    Ok(l)
}

/// Runs `fogline serve …` until Ctrl-C or SIGTERM (or, for egodriver, a `shut_down` call).
pub fn serve(a: ServeArgs) -> Result<ExitCode> {
    let planner: Arc<dyn Planner> = Arc::new(BuiltinPlanner::new());
    let (name, default_addr) = match a.protocol {
        Protocol::Egodriver => ("egodriver", "127.0.0.1:50051"),
        Protocol::Http => ("http", "127.0.0.1:8080"),
    };
    let addr = match a.addr {
        Some(addr) => addr,
        None => default_addr.parse().context("the default address")?,
    };
    if a.protocol == Protocol::Http && (!a.camera_map.is_empty() || a.allow_remote_shutdown) {
        bail!("--camera-map and --allow-remote-shutdown apply to `fogline serve egodriver` only");
    }
    let limits = limits(&a)?;
    let handle = match a.protocol {
        Protocol::Egodriver => egodriver::serve(
            addr,
            planner,
            egodriver::ServeOptions {
                camera_map: egodriver::parse_camera_map(&a.camera_map)
                    .map_err(anyhow::Error::msg)?,
                allow_shut_down: a.allow_remote_shutdown,
                limits,
                ..egodriver::ServeOptions::default()
            },
        ),
        Protocol::Http => http::serve(
            addr,
            planner,
            http::ServeOptions {
                limits,
                ..http::ServeOptions::default()
            },
        ),
    }
    .with_context(|| format!("cannot serve {name} on {addr}"))?;
    {
        let mut out = std::io::stdout().lock();
        writeln!(out, "listening on {} ({name})", handle.local_addr())?;
        out.flush()?;
    }
    handle
        .wait_for_signal()
        .with_context(|| format!("the {name} server failed"))?;
    log::info!("{name} server stopped");
    Ok(ExitCode::SUCCESS)
}
