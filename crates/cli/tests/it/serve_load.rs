//! `fogline serve` under load, as a separate process on 127.0.0.1 with its default limits:
//! 2,000 idle connections (half of them with half a request sent), then 16 concurrent
//! requests at the documented size caps, then a normal request. The server must answer the
//! normal request, and its peak resident memory (`VmHWM`) must stay within 1 GB. The figures
//! are printed (`cargo nextest run -p fogline-cli serve_load --no-capture`). The same load
//! goes through `fogline guard` in front of `fogline serve egodriver` (issue 20): 16
//! concurrent sessions through the guard, which must answer every one and the normal request,
//! within the same memory bound.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use fogline_remote::{PlanRequest, Planner, egodriver, http};
use fogline_types::clip::{CameraCalib, CameraId, CameraInput, EgoPose, FRAMES, PlannerInput};
use fogline_world::{WorldConfig, generate_clip};

const IDLE: usize = 2000;
const CONCURRENT: usize = 16;
/// The documented defaults (`fogline_remote::Limits`, `http::SERVE_BODY_BYTES`).
const MAX_PIXELS: u64 = 36_000_000;
const MAX_BODY: usize = 96 * 1024 * 1024;
const RSS_BOUND_MB: f64 = 1024.0;

/// A `fogline serve` child, killed when dropped.
struct Server {
    child: Child,
    addr: SocketAddr,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start(protocol: &str) -> Server {
    spawn(Command::new(env!("CARGO_BIN_EXE_fogline")).args([
        "-q",
        "serve",
        protocol,
        "--addr",
        "127.0.0.1:0",
    ]))
}

/// `fogline guard` in front of the egodriver driver at `driver`, with a permissive
/// `odd.json` in `dir`.
fn start_guard(driver: SocketAddr, dir: &std::path::Path) -> Server {
    let odd = crate::interop::guard_odd(dir);
    spawn(
        Command::new(env!("CARGO_BIN_EXE_fogline"))
            .args(["-q", "guard", "--addr", "127.0.0.1:0", "--scenario"])
            .arg("LANE_KEEPING")
            .arg("--driver")
            .arg(format!("http://{driver}"))
            .arg("--odd")
            .arg(odd)
            .args(["--driver-timeout-ms", "120000"]),
    )
}

fn spawn(command: &mut Command) -> Server {
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    // "listening on ADDR (PROTOCOL)"
    let addr = line
        .split_whitespace()
        .nth(2)
        .and_then(|a| a.parse().ok())
        .unwrap_or_else(|| panic!("no address in {line:?}"));
    Server { child, addr }
}

/// The server's peak resident set, MB (Linux: `VmHWM` in `/proc/PID/status`).
fn peak_rss_mb(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}

/// The test's own open-file limit raised to its hard limit (it holds 2,000 sockets); the
/// number of idle connections it can hold (2,000 unless the hard limit is lower).
fn raise_fd_limit() -> usize {
    #[cfg(unix)]
    {
        use rustix::process::{Resource, getrlimit, setrlimit};
        let mut lim = getrlimit(Resource::Nofile);
        if let (Some(cur), Some(max)) = (lim.current, lim.maximum.or(Some(65_536))) {
            let want = max.min(65_536);
            if want > cur {
                lim.current = Some(want);
                let _ = setrlimit(Resource::Nofile, lim);
            }
            let now = getrlimit(Resource::Nofile).current.unwrap_or(want);
            return IDLE.min(usize::try_from(now.saturating_sub(256)).unwrap_or(IDLE));
        }
    }
    IDLE
}

/// `n` connections that send nothing, or half a request line and headers.
fn idle_connections(addr: SocketAddr, n: usize) -> Vec<TcpStream> {
    (0..n)
        .map(|i| {
            let mut s = TcpStream::connect(addr).unwrap();
            if i % 2 == 1 {
                let _ = s.write_all(b"POST /v1/plan HTTP/1.1\r\nHost: x\r\nContent-Le");
            }
            s
        })
        .collect()
}

/// A normal request: a clip of the built-in world at 576 × 320.
fn normal_clip() -> fogline_world::Clip {
    let cfg = WorldConfig {
        width: 576,
        height: 320,
        depth: false,
        ..WorldConfig::default()
    };
    generate_clip(&cfg, 3).unwrap()
}

/// Four cameras × four frames of `side × side` pixels: the pixel cap exactly when
/// `side` = 1,500. The frames are smooth, so their PNGs are small (the attack the caps
/// answer: a small request that decodes to many pixels).
fn cap_frames(side: u32) -> (Vec<CameraCalib>, Vec<u8>) {
    let calibs = CameraId::ALL
        .iter()
        .map(|&id| CameraCalib::standard(id, side, side))
        .collect();
    let frame = (0..side * side)
        .flat_map(|i| {
            let (x, y) = (i % side, i / side);
            [(x / 8 % 256) as u8, (y / 8 % 256) as u8, 90]
        })
        .collect();
    (calibs, frame)
}

fn plan_with(
    planner: &dyn Planner,
    calibs: &[CameraCalib],
    frame: &[u8],
    history: &[EgoPose],
) -> Result<(), String> {
    let input = PlannerInput {
        cameras: calibs
            .iter()
            .map(|c| CameraInput {
                calib: *c,
                frames: vec![frame; FRAMES],
            })
            .collect(),
        ego_history: history,
    };
    planner
        .plan(&PlanRequest {
            scene_id: "load",
            seed: 1,
            input,
        })
        .map(|_| ())
        .map_err(|e| e.message)
}

/// POSTs a body of exactly the server's limit (junk, so it is refused once read): the
/// status code, or 0 when the connection failed.
fn post_max_body(addr: SocketAddr, body: &[u8]) -> u16 {
    let Ok(mut s) = TcpStream::connect(addr) else {
        return 0;
    };
    let head = format!(
        "POST /v1/plan HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    if s.write_all(head.as_bytes()).is_err() || s.write_all(body).is_err() {
        return 0;
    }
    let mut reply = Vec::new();
    let _ = s.read_to_end(&mut reply);
    String::from_utf8_lossy(&reply)
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0)
}

/// fogline's client of `protocol` for the server at `addr`, with a limit of `timeout_s`.
fn client(protocol: &str, addr: SocketAddr, timeout_s: u64) -> Box<dyn Planner> {
    let timeout = Duration::from_secs(timeout_s);
    if protocol == "http" {
        Box::new(
            http::Client::new(http::ClientOptions {
                url: format!("http://{addr}"),
                timeout,
                ..http::ClientOptions::default()
            })
            .unwrap(),
        )
    } else {
        Box::new(
            egodriver::Client::new(egodriver::ClientOptions {
                endpoint: addr.to_string(),
                timeout,
                ..egodriver::ClientOptions::default()
            })
            .unwrap(),
        )
    }
}

fn run_load(protocol: &str) {
    let server = start(protocol);
    load(protocol, &server, None);
}

/// The load of `run_load` on `server` (speaking `protocol`); `driver`, the guarded driver
/// when `server` is a guard.
fn load(protocol: &str, server: &Server, driver: Option<&Server>) {
    let n_idle = raise_fd_limit();
    assert!(
        n_idle >= 500,
        "the open-file limit leaves room for {n_idle} connections only"
    );
    let addr = server.addr;
    let clip = normal_clip();
    let history = clip.ego_history.clone();
    let t = Instant::now();
    let idle = idle_connections(addr, n_idle);
    let idle_s = t.elapsed().as_secs_f64();

    // 16 concurrent requests at the caps: each planning call carries exactly the pixel
    // cap; for HTTP four of them are instead bodies of exactly the byte cap.
    let (calibs, frame) = cap_frames(1500);
    let pixels: u64 = calibs.len() as u64 * FRAMES as u64 * 1500 * 1500;
    assert!(pixels <= MAX_PIXELS && pixels > MAX_PIXELS * 99 / 100);
    let (calibs, frame) = (Arc::new(calibs), Arc::new(frame));
    let junk = Arc::new(vec![b'x'; MAX_BODY]);
    let t = Instant::now();
    let outcomes: Vec<String> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..CONCURRENT)
            .map(|i| {
                let (calibs, frame, junk, history) = (&calibs, &frame, &junk, &history);
                s.spawn(move || -> String {
                    if protocol == "http" && i % 4 == 3 {
                        return format!("body at cap: HTTP {}", post_max_body(addr, junk));
                    }
                    let planner = client(protocol, addr, 120);
                    match plan_with(planner.as_ref(), calibs, frame, history) {
                        Ok(()) => "pixels at cap: answered".into(),
                        Err(e) => format!("pixels at cap: refused ({e})"),
                    }
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let burst_s = t.elapsed().as_secs_f64();

    // Then a normal request, the idle connections still open.
    let planner = client(protocol, addr, 60);
    let input = PlannerInput {
        cameras: clip
            .cameras
            .iter()
            .map(|c| CameraInput {
                calib: c.calib,
                frames: c.frames.iter().map(|f| f.image.data()).collect(),
            })
            .collect(),
        ego_history: &clip.ego_history,
    };
    let t = Instant::now();
    let answer = planner.plan(&PlanRequest {
        scene_id: &clip.id,
        seed: 1,
        input,
    });
    let latency_ms = t.elapsed().as_secs_f64() * 1e3;
    let rss = peak_rss_mb(server.child.id());
    let driver_rss = driver.and_then(|d| peak_rss_mb(d.child.id()));
    drop(idle);

    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    for o in &outcomes {
        let key = o.split(" (").next().unwrap_or(o).to_string();
        *counts.entry(key).or_default() += 1;
    }
    eprintln!(
        "{protocol}: {n_idle} idle connections in {idle_s:.2} s; {CONCURRENT} concurrent requests \
         at the caps in {burst_s:.1} s: {counts:?}; then a normal request answered in \
         {latency_ms:.0} ms; peak RSS {} (bound {RSS_BOUND_MB} MB){}",
        rss.map_or("unknown".into(), |r| format!("{r:.0} MB")),
        driver_rss.map_or(String::new(), |r| format!(
            "; the guarded driver's peak RSS {r:.0} MB"
        ))
    );
    if let Some(first) = outcomes.iter().find(|o| o.contains("refused")) {
        eprintln!("{protocol}: e.g. {first}");
    }
    answer.unwrap_or_else(|e| panic!("{protocol}: the normal request failed: {}", e.message));
    if let Some(rss) = rss {
        assert!(
            rss <= RSS_BOUND_MB,
            "{protocol}: peak RSS {rss:.0} MB over the {RSS_BOUND_MB} MB bound"
        );
    }
}

#[test]
fn the_http_server_keeps_answering_under_load_within_its_memory_bound() {
    run_load("http");
}

#[test]
fn the_egodriver_server_keeps_answering_under_load_within_its_memory_bound() {
    run_load("egodriver");
}

#[test]
fn r20_the_guard_keeps_answering_under_load_within_its_memory_bound() {
    let dir = std::env::temp_dir().join(format!("fogline-guard-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let driver = start("egodriver");
    let guard = start_guard(driver.addr, &dir);
    load("egodriver through fogline guard", &guard, Some(&driver));
    // The guard is still up after the load.
    let mut g = guard;
    assert!(g.child.try_wait().unwrap().is_none(), "the guard exited");
    drop(g);
    let _ = std::fs::remove_dir_all(&dir);
}
