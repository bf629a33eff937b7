//! What both servers share: their tokio runtime and the handle that stops them.

use std::io;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::runtime::Runtime;
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// How long a graceful shutdown waits for calls in flight before it drops them.
const GRACE: Duration = Duration::from_secs(5);

/// Builds the runtime of a server (two workers; planners run on its blocking pool).
pub(crate) fn server_runtime(name: &str) -> io::Result<Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name(name)
        .enable_all()
        .build()
}

/// Builds the runtime of a client: one worker drives the connections; callers block on
/// their own futures, so many threads can call at once.
pub(crate) fn client_runtime(name: &str) -> io::Result<Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name(name)
        .enable_all()
        .build()
}

/// The stop flag a server watches; `true` asks it to stop.
pub(crate) type StopFlag = Arc<watch::Sender<bool>>;

/// A new stop flag.
pub(crate) fn stop_flag() -> StopFlag {
    Arc::new(watch::channel(false).0)
}

/// Resolves when `flag` is raised.
pub(crate) async fn stopped(flag: StopFlag) {
    let mut rx = flag.subscribe();
    let _ = rx.wait_for(|stop| *stop).await;
}

/// A running server (gRPC or HTTP). It owns its runtime: dropping the handle stops the
/// server abruptly; [`ServerHandle::shutdown`] stops it gracefully.
///
/// The handle is for synchronous code (a CLI, tests): do not call its blocking methods
/// from inside an async runtime.
pub struct ServerHandle {
    addr: SocketAddr,
    protocol: &'static str,
    stop: StopFlag,
    task: Option<JoinHandle<io::Result<()>>>,
    runtime: Option<Runtime>,
}

impl std::fmt::Debug for ServerHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServerHandle")
            .field("addr", &self.addr)
            .field("protocol", &self.protocol)
            .finish_non_exhaustive()
    }
}

impl ServerHandle {
    pub(crate) fn new(
        addr: SocketAddr,
        protocol: &'static str,
        stop: StopFlag,
        task: JoinHandle<io::Result<()>>,
        runtime: Runtime,
    ) -> Self {
        Self {
            addr,
            protocol,
            stop,
            task: Some(task),
            runtime: Some(runtime),
        }
    }

    /// The address the server listens on (with the actual port when bound to port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// `egodriver` or `http`.
    pub fn protocol(&self) -> &'static str {
        self.protocol
    }

    /// Stops accepting connections, lets calls in flight finish (up to 5 s) and returns
    /// the server's own error, if it failed.
    pub fn shutdown(mut self) -> io::Result<()> {
        self.stop.send_replace(true);
        self.finish()
    }

    /// Blocks until the server stops by itself (an egodriver `shut_down` call) or fails.
    pub fn wait(mut self) -> io::Result<()> {
        let (Some(rt), Some(task)) = (self.runtime.as_ref(), self.task.as_mut()) else {
            return Ok(());
        };
        let result = rt.block_on(task);
        self.task = None;
        self.close_runtime();
        flatten(result)
    }

    /// Blocks until Ctrl-C or SIGTERM (then shuts down gracefully), or until the server
    /// stops by itself.
    pub fn wait_for_signal(mut self) -> io::Result<()> {
        let (Some(rt), Some(task)) = (self.runtime.as_ref(), self.task.as_mut()) else {
            return Ok(());
        };
        let ended = rt.block_on(async {
            tokio::select! {
                r = task => Ok(r),
                r = signal() => Err(r),
            }
        });
        match ended {
            Ok(result) => {
                self.task = None;
                self.close_runtime();
                flatten(result)
            }
            Err(Err(e)) => {
                self.stop.send_replace(true);
                let _ = self.finish();
                Err(io::Error::other(format!("cannot wait for signals: {e}")))
            }
            Err(Ok(())) => {
                log::info!("signal received: shutting down");
                self.stop.send_replace(true);
                self.finish()
            }
        }
    }

    fn finish(&mut self) -> io::Result<()> {
        let result = match (self.runtime.as_ref(), self.task.take()) {
            (Some(rt), Some(mut task)) => rt.block_on(async {
                match tokio::time::timeout(GRACE, &mut task).await {
                    Ok(r) => flatten(r),
                    Err(_) => {
                        log::warn!("calls still in flight after {GRACE:?}: dropping them");
                        task.abort();
                        Ok(())
                    }
                }
            }),
            _ => Ok(()),
        };
        self.close_runtime();
        result
    }

    fn close_runtime(&mut self) {
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_timeout(Duration::from_secs(1));
        }
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        self.stop.send_replace(true);
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_background();
        }
    }
}

fn flatten(r: Result<io::Result<()>, tokio::task::JoinError>) -> io::Result<()> {
    match r {
        Ok(r) => r,
        Err(e) if e.is_cancelled() => Ok(()),
        Err(e) => Err(io::Error::other(format!("the server task failed: {e}"))),
    }
}

#[cfg(unix)]
async fn signal() -> io::Result<()> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut term = signal(SignalKind::terminate())?;
    tokio::select! {
        r = tokio::signal::ctrl_c() => r,
        _ = term.recv() => Ok(()),
    }
}

#[cfg(not(unix))]
async fn signal() -> io::Result<()> {
    tokio::signal::ctrl_c().await
}
