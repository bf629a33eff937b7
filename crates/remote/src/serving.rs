//! What both servers share: their tokio runtime, the handle that stops them, and the limits
//! that keep a server answering under load (a connection cap, an idle timeout, a bound on
//! concurrent requests and on the pixels one request may make the server decode).

use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::runtime::Runtime;
use tokio::sync::{OwnedSemaphorePermit, Semaphore, mpsc, watch};
use tokio::task::JoinHandle;
use tokio::time::{Instant, Sleep};

/// The limits of a server (both protocols; `docs/security.md` explains each default). With
/// the defaults a server's memory stays under 1 GB however it is loaded: at most
/// `max_concurrent_requests` requests are read and decoded at once, each bounded in bytes
/// and in decoded pixels, and idle connections cost a few kilobytes each until they time out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Limits {
    /// Connections held open at once; beyond it new ones are closed as they arrive (default
    /// 4,096; lowered to what the process's file-descriptor limit allows).
    pub max_connections: usize,
    /// A connection that sends nothing for this long is closed (default 60 s).
    pub idle_timeout: Duration,
    /// HTTP: the request line and headers must arrive within this (default 10 s).
    pub header_timeout: Duration,
    /// HTTP: the whole body must arrive within this; gRPC: the whole call (default 60 s).
    pub request_timeout: Duration,
    /// Plans computed at once (default 2, the cores a planner can use). HTTP requests beyond
    /// it wait before their body is read; egodriver calls in flight are capped at four times
    /// it, waiting before their messages are decoded.
    pub max_concurrent_requests: usize,
    /// Pixels one request may make the server decode: the frames × width × height of an
    /// HTTP request, of an egodriver session's declared cameras (default 36 M: four cameras
    /// × four 1920 × 1080 frames fit).
    pub max_request_pixels: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_connections: 4096,
            idle_timeout: Duration::from_secs(60),
            header_timeout: Duration::from_secs(10),
            request_timeout: Duration::from_secs(60),
            max_concurrent_requests: 2,
            max_request_pixels: 36_000_000,
        }
    }
}

impl Limits {
    /// Checks the limits are usable (every one positive).
    pub fn validate(&self) -> Result<(), String> {
        let zero = [
            ("max_connections", self.max_connections == 0),
            ("idle_timeout", self.idle_timeout.is_zero()),
            ("header_timeout", self.header_timeout.is_zero()),
            ("request_timeout", self.request_timeout.is_zero()),
            ("max_concurrent_requests", self.max_concurrent_requests == 0),
            ("max_request_pixels", self.max_request_pixels == 0),
        ];
        match zero.iter().find(|(_, z)| *z) {
            Some((name, _)) => Err(format!("server limit {name} must be positive")),
            None => Ok(()),
        }
    }
}

/// Raises the process's soft limit on open files to its hard limit (at most 65,536), as
/// servers do, and returns the soft limit now in force (`None` where it cannot be read).
fn raise_fd_limit() -> Option<u64> {
    #[cfg(unix)]
    {
        use rustix::process::{Resource, getrlimit, setrlimit};
        let mut lim = getrlimit(Resource::Nofile);
        let cur = lim.current?;
        let want = lim.maximum.unwrap_or(65_536).min(65_536);
        if want > cur {
            lim.current = Some(want);
            if setrlimit(Resource::Nofile, lim).is_ok() {
                return Some(want);
            }
        }
        Some(cur)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Accepts connections on `listener` until `stop`, each wrapped in a [`Guarded`] stream (the
/// connection cap and the idle timeout), and sends them on the returned channel.
pub(crate) fn accept_guarded(
    listener: tokio::net::TcpListener,
    limits: &Limits,
    stop: StopFlag,
    name: &'static str,
) -> mpsc::Receiver<io::Result<Guarded>> {
    let fds = raise_fd_limit();
    // Descriptors for everything else the process holds (files, the runtime, logs).
    let cap = match fds {
        Some(n) => limits
            .max_connections
            .min(usize::try_from(n.saturating_sub(128)).unwrap_or(usize::MAX))
            .max(1),
        None => limits.max_connections,
    };
    if cap < limits.max_connections {
        log::info!(
            "{name}: at most {cap} connections (the open-file limit is {})",
            fds.unwrap_or(0)
        );
    }
    let slots = Arc::new(Semaphore::new(cap));
    let idle = limits.idle_timeout;
    let (tx, rx) = mpsc::channel(64);
    tokio::spawn(async move {
        let halt = stopped(stop);
        tokio::pin!(halt);
        let mut shed: u64 = 0;
        loop {
            let accepted = tokio::select! {
                _ = &mut halt => break,
                a = listener.accept() => a,
            };
            match accepted {
                Ok((stream, _peer)) => {
                    let _ = stream.set_nodelay(true);
                    let Ok(permit) = Arc::clone(&slots).try_acquire_owned() else {
                        // Full: close it now rather than let the backlog fill.
                        shed += 1;
                        if shed.is_power_of_two() {
                            log::warn!(
                                "{name}: {cap} connections open; {shed} new ones closed so far"
                            );
                        }
                        drop(stream);
                        continue;
                    };
                    if tx
                        .send(Ok(Guarded::new(stream, permit, idle)))
                        .await
                        .is_err()
                    {
                        break;
                    }
                }
                Err(e) => {
                    // Out of descriptors and the like: back off rather than spin.
                    log::warn!("{name}: accept failed: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            }
        }
    });
    rx
}

/// A server's connection: it holds one of the server's connection slots while open, and
/// fails its reads once the peer has sent nothing for the idle timeout (the server then
/// closes it).
pub(crate) struct Guarded {
    inner: tokio::net::TcpStream,
    _slot: OwnedSemaphorePermit,
    idle: Duration,
    deadline: Pin<Box<Sleep>>,
}

impl Guarded {
    fn new(inner: tokio::net::TcpStream, slot: OwnedSemaphorePermit, idle: Duration) -> Self {
        Self {
            inner,
            _slot: slot,
            idle,
            deadline: Box::pin(tokio::time::sleep(idle)),
        }
    }

    fn touch(&mut self) {
        self.deadline.as_mut().reset(Instant::now() + self.idle);
    }
}

impl AsyncRead for Guarded {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        match Pin::new(&mut self.inner).poll_read(cx, buf) {
            Poll::Ready(r) => {
                if buf.filled().len() > before {
                    self.touch();
                }
                Poll::Ready(r)
            }
            Poll::Pending => match self.deadline.as_mut().poll(cx) {
                Poll::Ready(()) => Poll::Ready(Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    "the peer sent nothing for the idle timeout",
                ))),
                Poll::Pending => Poll::Pending,
            },
        }
    }
}

impl AsyncWrite for Guarded {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.inner).poll_write(cx, buf);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            self.touch();
        }
        r
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.inner).poll_write_vectored(cx, bufs);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            self.touch();
        }
        r
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }
}

impl tonic::transport::server::Connected for Guarded {
    type ConnectInfo = tonic::transport::server::TcpConnectInfo;

    fn connect_info(&self) -> Self::ConnectInfo {
        self.inner.connect_info()
    }
}

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
