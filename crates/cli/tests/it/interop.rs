//! Interoperability with an independent implementation of AlpaSim's egodriver contract:
//! the PyPI package carla-driver-interface 2.3.1 (install it with `scripts/python-peers.sh`).
//!
//! - A: `fogline serve egodriver` driven by carla-driver-interface's CARLA-free client loop
//!   (`carla-driver-interface demo`).
//! - B: carla-driver-interface's server (`serve --policy route_follower`) driven by
//!   `fogline_remote::egodriver::Client` on a generated clip.

use std::io::{BufRead as _, BufReader, Read as _};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use fogline_remote::egodriver::{Client, ClientOptions};
use fogline_remote::{PlanRequest, Planner};
use fogline_types::clip::{CameraInput, DT_S, HORIZON, PlannerInput};
use fogline_world::{WorldConfig, generate_clip};

/// A child process, killed and reaped when dropped (whatever the test did).
pub struct ChildGuard {
    child: Child,
    what: String,
}

impl ChildGuard {
    /// Starts `cmd`.
    pub fn spawn(cmd: &mut Command, what: &str) -> Self {
        let child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {what}: {e}"));
        Self {
            child,
            what: what.to_string(),
        }
    }

    /// Panics if the process has already exited (with its status).
    pub fn assert_running(&mut self) {
        if let Some(status) = self.child.try_wait().unwrap() {
            panic!("{} exited early: {status}", self.what);
        }
    }

    /// Waits for the process to exit, at most `limit`; kills it and panics after that.
    pub fn wait_for(&mut self, limit: Duration) -> ExitStatus {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!("{} did not finish within {limit:?}", self.what);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The Python with carla-driver-interface: `FOGLINE_TEST_PYTHON`, else
/// `<workspace>/target/pyenv/bin/python`. Fails (never skips) when it is missing.
pub fn python() -> PathBuf {
    let advice = "run scripts/python-peers.sh (it installs carla-driver-interface 2.3.1 into \
                  target/pyenv), or point FOGLINE_TEST_PYTHON at a Python that has it";
    let python = std::env::var_os("FOGLINE_TEST_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("target/pyenv/bin/python"));
    assert!(
        python.exists(),
        "the interoperability peer's Python {} does not exist: {advice}",
        python.display()
    );
    let probe = Command::new(&python)
        .args(["-c", "import carla_driver_interface"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}; {advice}", python.display()));
    assert!(
        probe.status.success(),
        "{} cannot import carla_driver_interface ({}): {advice}",
        python.display(),
        String::from_utf8_lossy(&probe.stderr).trim()
    );
    python
}

/// A loopback port nobody listens on (yet).
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Waits until something accepts connections on `addr`.
pub fn wait_until_listening(addr: SocketAddr, server: &mut ChildGuard, limit: Duration) {
    let start = Instant::now();
    while TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_err() {
        server.assert_running();
        assert!(
            start.elapsed() < limit,
            "nothing listens on {addr} after {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Starts `fogline serve PROTOCOL` on a free port and returns it with its address (read
/// from its `listening on …` line).
pub fn fogline_serve(protocol: &str) -> (ChildGuard, SocketAddr) {
    let what = format!("fogline serve {protocol}");
    let mut server = ChildGuard::spawn(
        Command::new(env!("CARGO_BIN_EXE_fogline"))
            .args(["serve", protocol, "--addr", "127.0.0.1:0"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit()),
        &what,
    );
    let stdout = server.child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(Duration::from_secs(60))
        .unwrap_or_else(|_| panic!("{what} printed no `listening on` line within 60 s"));
    let suffix = format!(" ({protocol})\n");
    let addr = line
        .strip_prefix("listening on ")
        .and_then(|rest| rest.strip_suffix(suffix.as_str()))
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"));
    (server, addr.parse().unwrap())
}

#[test]
fn carla_driver_interface_demo_drives_fogline_serve() {
    let python = python();
    let (mut server, addr) = fogline_serve("egodriver");
    let mut demo = ChildGuard::spawn(
        Command::new(&python)
            .args(["-m", "carla_driver_interface.cli", "demo", "--driver"])
            .arg(addr.to_string())
            .args(["--steps", "30"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
        "carla-driver-interface demo",
    );
    let mut out = String::new();
    let mut err = String::new();
    let mut stdout = demo.child.stdout.take().unwrap();
    let mut stderr = demo.child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut e = String::new();
        let _ = stderr.read_to_string(&mut e);
        e
    });
    stdout.read_to_string(&mut out).unwrap();
    let status = demo.wait_for(Duration::from_secs(180));
    err.push_str(&reader.join().unwrap());
    assert!(status.success(), "demo failed ({status}):\n{out}\n{err}");
    let steps = out
        .lines()
        .find(|l| l.starts_with("steps"))
        .unwrap_or_else(|| panic!("no steps line:\n{out}"));
    assert_eq!(steps.split(':').nth(1).map(str::trim), Some("30"), "{out}");
    server.assert_running();
}

/// carla-driver-interface's policy server with its `route_follower` policy over a 6.4 s
/// horizon, on a free loopback port, once it accepts connections.
fn route_follower_server() -> (ChildGuard, SocketAddr) {
    let port = free_port();
    let addr: SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
    let mut server = ChildGuard::spawn(
        Command::new(python())
            .args([
                "-m",
                "carla_driver_interface.cli",
                "--log-level",
                "WARNING",
                "serve",
            ])
            .args(["--host", "127.0.0.1", "--port"])
            .arg(port.to_string())
            .args([
                "--policy",
                "route_follower",
                "--policy-arg",
                "horizon_s=6.4",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit()),
        "carla-driver-interface serve",
    );
    wait_until_listening(addr, &mut server, Duration::from_secs(60));
    (server, addr)
}

#[test]
fn fogline_client_drives_the_carla_driver_interface_server() {
    let (mut server, addr) = route_follower_server();

    let cfg = WorldConfig {
        width: 288,
        height: 160,
        depth: false,
        ..WorldConfig::default()
    };
    let clip = generate_clip(&cfg, 3).unwrap();
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
    let client = Client::new(ClientOptions {
        endpoint: addr.to_string(),
        timeout: Duration::from_secs(30),
        ..ClientOptions::default()
    })
    .unwrap();
    let request = PlanRequest {
        scene_id: &clip.id,
        seed: 11,
        input,
    };
    let out = client.plan(&request).unwrap();
    out.trajectory.validate().unwrap();
    assert_eq!(out.trajectory.xy.len(), HORIZON);
    // With no route the policy holds its heading and brakes to a stop at 4 m/s²: a
    // straight path along x, each step `speed · 0.1 s` with the speed falling by 0.4 m/s.
    let v0 = clip.ego_history.last().unwrap().speed_mps;
    assert!(v0 > 1.0, "clip 3 is a moving one (v0 = {v0})");
    let mut v = v0;
    let mut x = 0.0;
    for (k, p) in out.trajectory.xy.iter().enumerate() {
        v = (v - 4.0 * DT_S).max(0.0);
        x += v * DT_S;
        assert!(
            (p[0] - x).abs() < 0.02,
            "waypoint {k}: {p:?}, expected x = {x} (v0 = {v0})"
        );
        assert!(p[1].abs() < 0.02, "waypoint {k}: {p:?}");
    }
    // Its debug payload is a protobuf, not text: no explanation.
    assert_eq!(out.explanation, "");
    // Sessions are independent: the same request gives the same plan.
    let again = client.plan(&request).unwrap();
    assert_eq!(again.trajectory, out.trajectory);
    server.assert_running();
}

#[test]
fn fogline_serve_answers_as_the_in_process_planner_does() {
    use fogline_campaign::BuiltinPlanner;
    let cfg = WorldConfig {
        width: 288,
        height: 160,
        depth: false,
        ..WorldConfig::default()
    };
    let clips: Vec<_> = [0, 7, 40]
        .iter()
        .map(|&i| generate_clip(&cfg, i).unwrap())
        .collect();
    let local = BuiltinPlanner::new();
    for protocol in ["egodriver", "http"] {
        let (mut server, addr) = fogline_serve(protocol);
        let timeout = Duration::from_secs(30);
        let client: Box<dyn Planner> = match protocol {
            "egodriver" => Box::new(
                Client::new(ClientOptions {
                    endpoint: addr.to_string(),
                    timeout,
                    ..ClientOptions::default()
                })
                .unwrap(),
            ),
            _ => Box::new(
                fogline_remote::http::Client::new(fogline_remote::http::ClientOptions {
                    url: format!("http://{addr}"),
                    timeout,
                    ..fogline_remote::http::ClientOptions::default()
                })
                .unwrap(),
            ),
        };
        for clip in &clips {
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
            let request = PlanRequest {
                scene_id: &clip.id,
                seed: 3,
                input,
            };
            let expected = Planner::plan(&local, &request).unwrap();
            let got = client.plan(&request).unwrap();
            assert_eq!(got.decision, expected.decision, "{protocol} {}", clip.id);
            assert_eq!(
                got.explanation, expected.explanation,
                "{protocol} {}",
                clip.id
            );
            // gRPC carries single-precision floats.
            let ade = got.trajectory.ade(&expected.trajectory);
            assert!(ade < 1e-3, "{protocol} {}: ADE {ade} m", clip.id);
        }
        server.assert_running();
    }
}

#[test]
fn fogline_campaign_drives_the_carla_driver_interface_server() {
    let (_server, addr) = route_follower_server();
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("remote.toml");
    std::fs::write(
        &cfg,
        format!(
            "[clips]\ncount = 4\nseed = 2\nwidth = 288\nheight = 160\n\
             [conditions]\nnames = [\"noise_30\", \"fog_07\"]\n\
             [planner]\nkind = \"egodriver\"\nendpoint = \"{addr}\"\nimage_format = \"jpeg\"\n\
             [run]\nconcurrency = 3\ntimeout_s = 30\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_fogline"))
        .args(["campaign", "run"])
        .arg(&cfg)
        .arg("--export")
        .arg(&out)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "{text}");
    assert!(text.contains("ran 12 runs"), "{text}");
    assert!(text.contains("12 ok, 0 failed"), "{text}");
    assert!(text.contains("pairs (seed 0): 8"), "{text}");
    let pairs = std::fs::read_to_string(out.join("pairs.csv")).unwrap();
    assert_eq!(pairs.lines().count(), 9, "{pairs}");
}

/// A stand-in for a driving model that launches from rest: the reference planner's
/// decision, with a speed profile that speeds up (4 m/s², to 30 m/s, in the planner's own
/// time) whenever it decides to go on. The reference planner itself holds its speed — a
/// clip predictor — so from rest it stands.
struct Launcher(fogline_planner::ReferencePlanner);

impl Planner for Launcher {
    fn describe(&self) -> String {
        "launcher".into()
    }

    fn plan(
        &self,
        request: &PlanRequest<'_>,
    ) -> Result<fogline_types::clip::PlannerOutput, fogline_types::planner::PlanFailure> {
        use fogline_types::clip::Decision;
        let mut out = Planner::plan(&self.0, request)?;
        let go = matches!(
            out.decision,
            Some(Decision::KeepLane | Decision::ProceedOnGreen | Decision::TurnRight)
        );
        if go {
            let mut v = request
                .input
                .ego_history
                .last()
                .map_or(0.0, |p| p.speed_mps);
            let mut x = 0.0;
            for q in &mut out.trajectory.xy {
                v = (v + 4.0 * DT_S).min(30.0);
                x += v * DT_S;
                *q = [x, 0.0];
            }
        }
        Ok(out)
    }
}

/// A closed-loop record without what the wall clock measures.
fn comparable(mut v: serde_json::Value) -> serde_json::Value {
    let o = v.as_object_mut().unwrap();
    for wall in ["wall_s", "wall_parts_s", "system_time_s", "timeline"] {
        o.remove(wall);
    }
    v
}

/// `fogline sim run --planner`: a planner behind an endpoint drives the closed loop exactly
/// as the same planner does in process (frames travel as PNG, numbers as JSON written to
/// round-trip), through the library and through the CLI, over either protocol.
#[test]
fn fogline_sim_run_is_driven_by_a_planner_behind_an_endpoint() {
    use fogline_sim::experiment::{ExperimentParams, run_experiment_with};
    use std::sync::Arc;
    let params = ExperimentParams {
        suite: fogline_sim::suite::SuiteParams::quick(),
        seeds: vec![0],
        configs: vec![fogline_sim::config::Config::no_deficit()],
        run: fogline_sim::run::RunParams::default(),
        system_time_limit_s: 1800.0,
        llm_latency_ms: Some(1000.0),
        routes: Some(vec![0]),
    };
    let launcher = || Arc::new(Launcher(fogline_planner::ReferencePlanner::new()));
    let drive = |p: Arc<dyn Planner>| {
        let r = run_experiment_with(&params, Some(p), 1, &|_, _| {}).unwrap();
        comparable(serde_json::to_value(&r.records[0]).unwrap())
    };
    let local = drive(launcher());
    assert_eq!(local["plan_errors"], 0, "{local}");
    assert!(
        local["score"]["route_completion"].as_f64().unwrap() > 50.0,
        "{local}"
    );
    let loopback: SocketAddr = "127.0.0.1:0".parse().unwrap();
    let http = fogline_remote::http::serve(loopback, launcher(), Default::default()).unwrap();
    let url = format!("http://{}", http.local_addr());
    assert_eq!(
        drive(fogline_api::sim::planner_at(&url, 60.0).unwrap()),
        local
    );
    // The CLI, as a user runs it.
    let dir = tempfile::tempdir().unwrap();
    let cli = |planner: &str, name: &str| {
        let out = dir.path().join(name);
        let args = [
            "sim",
            "run",
            "--quick",
            "--deficits",
            "none",
            "--routes",
            "0",
        ];
        let o = super::fogline(
            &[
                &args[..],
                &["--planner", planner, "--out", out.to_str().unwrap()],
            ]
            .concat(),
        );
        (o, out)
    };
    let (o, out) = cli(&url, "http");
    assert!(o.status.success(), "{}", super::text(&o));
    let records = std::fs::read_to_string(out.join("records.jsonl")).unwrap();
    assert_eq!(
        comparable(serde_json::from_str(records.trim()).unwrap()),
        local
    );
    let tables = std::fs::read_to_string(out.join("tables.md")).unwrap();
    assert!(tables.contains("driven by http planner at"), "{tables}");
    let grpc = fogline_remote::egodriver::serve(loopback, launcher(), Default::default()).unwrap();
    let (o, out) = cli(&format!("egodriver://{}", grpc.local_addr()), "egodriver");
    assert!(o.status.success(), "{}", super::text(&o));
    let records = std::fs::read_to_string(out.join("records.jsonl")).unwrap();
    let remote: serde_json::Value = serde_json::from_str(records.trim()).unwrap();
    assert_eq!(remote["plan_errors"], 0, "{remote}");
    assert!(
        remote["score"]["route_completion"].as_f64().unwrap() > 50.0,
        "{remote}"
    );
    // A planner nobody serves: every call fails, the car brakes, the summary says so.
    let (o, _) = cli(&format!("http://127.0.0.1:{}", free_port()), "nobody");
    let t = super::text(&o);
    assert!(
        o.status.success() && t.contains("planner calls failed"),
        "{t}"
    );
    // A malformed spec fails at start-up naming the flag.
    let (o, _) = cli("ftp://x", "bad");
    assert_eq!(o.status.code(), Some(2), "{}", super::text(&o));
    assert!(super::text(&o).contains("--planner"), "{}", super::text(&o));
}

/// A permissive `odd.json` with one LANE_KEEPING entry (σ* 70, darken 0.4, brighten 1.6,
/// fog 0.7).
pub(crate) fn guard_odd(dir: &std::path::Path) -> PathBuf {
    let axis = |name: &str, sigma: f64, descending: bool, identity: f64| {
        serde_json::json!({
            "axis": name, "family": if name == "darken" || name == "brighten" { "brightness" } else { name },
            "descending": descending, "identity_level": identity, "levels": [], "sigma_star": sigma,
            "right_censored": false, "ci95": null, "threshold_group": "match",
        })
    };
    let odd = serde_json::json!({
        "schema_version": 1, "kind": "fogline.odd", "generated_by": "test", "input_sha256": "00",
        "axis": "gaussian_noise", "budget": 0.15, "rule": "first-violation", "high_bands": [],
        "pi_star": null, "sigma_op": null,
        "entries": [{
            "scenario": "LANE_KEEPING", "rank": 1, "n_clips": 40, "n_changed": 5, "pilot": false,
            "axis": "gaussian_noise", "budget": 0.15, "sigma_star": 70.0,
            "right_censored": false, "ci95": null, "p_high": 0.2, "threshold_group": "match",
            "severity_group": "mild", "quadrant": "match + mild", "accepted": null,
            "acceptance_reason": null,
            "thresholds": [axis("gaussian_noise", 70.0, false, 0.0), axis("darken", 0.4, true, 1.0),
                           axis("brighten", 1.6, false, 1.0), axis("fog", 0.7, false, 0.0)],
        }],
    });
    let path = dir.join("odd.json");
    std::fs::write(&path, serde_json::to_vec(&odd).unwrap()).unwrap();
    path
}

/// Issue 20, item 3: carla-driver-interface's client loop drives `fogline guard` in front
/// of `fogline serve egodriver`; the driver is killed mid-route and the guard keeps
/// answering every `drive` (a safe stop or the RCO's override), then the route completes.
#[test]
#[allow(clippy::print_stdout)] // the run's counts, for the log of the test
fn r20_carla_driver_interface_drives_through_fogline_guard_and_survives_the_driver() {
    let python = python();
    let dir = std::env::temp_dir().join(format!("fogline-guard-it-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let odd = guard_odd(&dir);
    let log = dir.join("guard.jsonl");
    let (mut driver, driver_addr) = fogline_serve("egodriver");
    let mut guard = ChildGuard::spawn(
        Command::new(env!("CARGO_BIN_EXE_fogline"))
            .args([
                "guard",
                "--addr",
                "127.0.0.1:0",
                "--scenario",
                "LANE_KEEPING",
            ])
            .arg("--driver")
            .arg(format!("http://{driver_addr}"))
            .arg("--odd")
            .arg(&odd)
            .arg("--log")
            .arg(&log)
            .args(["--driver-timeout-ms", "500"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit()),
        "fogline guard",
    );
    let stdout = guard.child.stdout.take().unwrap();
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).unwrap();
    let guard_addr: SocketAddr = line
        .strip_prefix("listening on ")
        .and_then(|r| r.strip_suffix(" (guard)\n"))
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
        .parse()
        .unwrap();
    let steps = 60;
    let mut demo = ChildGuard::spawn(
        Command::new(&python)
            .args(["-m", "carla_driver_interface.cli", "demo", "--driver"])
            .arg(guard_addr.to_string())
            .args(["--steps", &steps.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
        "carla-driver-interface demo",
    );
    // Kill the driver once the guard has passed on some of its answers.
    let count = |log: &std::path::Path| {
        std::fs::read_to_string(log)
            .map(|t| t.lines().count())
            .unwrap_or(0)
    };
    let start = Instant::now();
    while count(&log) < 15 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the guard logged no drive calls"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = driver.child.kill();
    let _ = driver.child.wait();
    let killed_at = count(&log);
    let mut out = String::new();
    let mut stdout = demo.child.stdout.take().unwrap();
    let mut stderr = demo.child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut e = String::new();
        let _ = stderr.read_to_string(&mut e);
        e
    });
    stdout.read_to_string(&mut out).unwrap();
    let status = demo.wait_for(Duration::from_secs(180));
    let err = reader.join().unwrap();
    assert!(status.success(), "demo failed ({status}):\n{out}\n{err}");
    let done = out
        .lines()
        .find(|l| l.starts_with("steps"))
        .unwrap_or_else(|| panic!("no steps line:\n{out}"));
    assert_eq!(done.split(':').nth(1).map(str::trim), Some("60"), "{out}");
    guard.assert_running();
    let records: Vec<serde_json::Value> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(records.len(), steps, "one record per drive call");
    let source = |r: &serde_json::Value| r["source"].as_str().unwrap().to_string();
    assert!(
        records[..killed_at.saturating_sub(1)]
            .iter()
            .any(|r| source(r) == "driver"),
        "the driver answered before it was killed"
    );
    let after: Vec<String> = records[killed_at + 1..].iter().map(source).collect();
    assert!(
        !after.is_empty() && after.iter().all(|s| s == "safe_stop" || s == "override"),
        "after the kill the guard answers: {after:?}"
    );
    println!(
        "guard: {} drive calls, {} by the driver before the kill, then {} by the guard ({})",
        records.len(),
        records.iter().filter(|r| source(r) == "driver").count(),
        after.len(),
        after.first().cloned().unwrap_or_default()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// fogline's JPEG encoder against an independent decoder: Pillow (libjpeg-turbo), in the
/// peers' Python. World frames at qualities 50 and 95 decode there to the pixels the `image`
/// crate's decoder (zune-jpeg) gives, within the two decoders' rounding, and close to the
/// source.
#[test]
fn fogline_jpeg_frames_decode_with_pillow_as_with_the_image_crate() {
    let python = python();
    let clip = generate_clip(&WorldConfig::default(), 5).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (k, (cam, quality)) in [(0usize, 95u8), (1, 50), (2, 95)].into_iter().enumerate() {
        let camera = &clip.cameras[cam];
        let frame = &camera.frames.last().unwrap().image;
        let (w, h) = (frame.width(), frame.height());
        let src = frame.data();
        let jpeg =
            fogline_io::encode(src, w, h, fogline_io::ImageFormat::Jpeg { quality }).unwrap();
        let path = dir.path().join(format!("{k}.jpg"));
        std::fs::write(&path, &jpeg).unwrap();
        let o = Command::new(&python)
            .args([
                "-c",
                "import sys; from PIL import Image; \
                 sys.stdout.buffer.write(Image.open(sys.argv[1]).convert('RGB').tobytes())",
            ])
            .arg(&path)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let pillow = o.stdout;
        let zune = image::load_from_memory(&jpeg)
            .unwrap()
            .into_rgb8()
            .into_raw();
        assert_eq!(pillow.len(), src.len(), "{w}x{h}");
        let max_diff = pillow
            .iter()
            .zip(&zune)
            .map(|(&a, &b)| a.abs_diff(b))
            .max()
            .unwrap();
        assert!(
            max_diff <= 3,
            "q{quality}: Pillow and zune-jpeg differ by {max_diff}"
        );
        let mse = src
            .iter()
            .zip(&pillow)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum::<f64>()
            / src.len() as f64;
        let psnr = 10.0 * (255.0f64 * 255.0 / mse.max(1e-9)).log10();
        let floor = if quality == 95 { 38.0 } else { 30.0 };
        assert!(psnr > floor, "q{quality}: PSNR {psnr:.1} dB through Pillow");
    }
}
