//! `fogline serve`: the reference planner behind an endpoint, over AlpaSim's egodriver gRPC
//! contract or fogline's HTTP/JSON protocol (see `docs/remote.md`).

use std::collections::BTreeMap;
use std::io::Write as _;
use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use fogline_campaign::BuiltinPlanner;
use fogline_remote::{Planner, egodriver, http};
use fogline_types::clip::CameraId;

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
    /// egodriver only: refuse the `shut_down` RPC (by default it stops the server).
    #[arg(long)]
    no_remote_shutdown: bool,
}

fn camera_map(entries: &[String]) -> Result<BTreeMap<String, CameraId>> {
    let mut map = BTreeMap::new();
    for e in entries {
        let Some((logical, camera)) = e.split_once('=') else {
            bail!(
                "--camera-map {e:?}: expected LOGICAL=CAMERA, e.g. front=camera_front_wide_120fov"
            );
        };
        let Some(id) = CameraId::parse(camera.trim()) else {
            let names: Vec<&str> = CameraId::ALL.iter().map(|c| c.name()).collect();
            bail!(
                "--camera-map {e:?}: {camera:?} is not a camera name (one of {})",
                names.join(", ")
            );
        };
        if map.insert(logical.trim().to_string(), id).is_some() {
            bail!("--camera-map: {logical:?} is mapped twice");
        }
    }
    Ok(map)
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
    if a.protocol == Protocol::Http && (!a.camera_map.is_empty() || a.no_remote_shutdown) {
        bail!("--camera-map and --no-remote-shutdown apply to `fogline serve egodriver` only");
    }
    let handle = match a.protocol {
        Protocol::Egodriver => egodriver::serve(
            addr,
            planner,
            egodriver::ServeOptions {
                camera_map: camera_map(&a.camera_map)?,
                allow_shut_down: !a.no_remote_shutdown,
            },
        ),
        Protocol::Http => http::serve(addr, planner, http::ServeOptions::default()),
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
