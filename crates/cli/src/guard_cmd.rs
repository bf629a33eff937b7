//! `fogline guard`: parsing and dispatch only (the job is `fogline_guard::guard`).

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result};
use fogline_guard::{GuardLog, GuardParams};
use fogline_types::odd::OddSpec;

/// What `fogline guard` runs.
#[derive(Debug, clap::Args)]
pub struct GuardArgs {
    /// The driver to guard: its egodriver address, http://HOST:PORT or https://HOST[:PORT]
    /// (TLS; a private CA with --ca-cert).
    #[arg(long)]
    driver: String,
    /// The envelope's odd.json.
    #[arg(long)]
    odd: PathBuf,
    /// The scenario whose entry the monitor uses.
    #[arg(long)]
    scenario: String,
    /// Address to listen on (port 0: any free port).
    #[arg(long, default_value = "127.0.0.1:50052")]
    addr: SocketAddr,
    /// The monitored camera's logical id (default: the first declared *front_wide*, else the first).
    #[arg(long)]
    camera: Option<String>,
    /// The longest wait for a driver call, ms.
    #[arg(long, default_value_t = 1000)]
    driver_timeout_ms: u64,
    /// JSON-lines log of every drive call (one GuardRecord each).
    #[arg(long)]
    log: Option<PathBuf>,
}

/// Runs the guard until Ctrl-C or SIGTERM.
pub fn guard(a: GuardArgs) -> Result<ExitCode> {
    let odd = OddSpec::read(&a.odd).map_err(anyhow::Error::msg)?;
    let create = |p: &PathBuf| {
        std::fs::File::create(p).with_context(|| format!("cannot create {}", p.display()))
    };
    let log: Option<GuardLog> = match a.log.as_ref().map(create).transpose()? {
        Some(f) => Some(Arc::new(Mutex::new(Box::new(std::io::BufWriter::new(f))))),
        None => None,
    };
    let params = GuardParams {
        driver: a.driver,
        scenario: a.scenario,
        camera: a.camera,
        driver_timeout_ms: a.driver_timeout_ms,
        ..GuardParams::default()
    };
    let handle = fogline_guard::guard(a.addr, odd, params, log)
        .with_context(|| format!("cannot start the guard on {} ({})", a.addr, a.odd.display()))?;
    let addr = handle.local_addr(); // stdout is line-buffered: flushed at the newline
    writeln!(std::io::stdout(), "listening on {addr} (guard)")?;
    handle.wait_for_signal().context("the guard failed")?;
    Ok(ExitCode::SUCCESS)
}
