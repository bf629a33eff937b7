//! Hand-over and hand-back on live frames (issue 20, item 3): world frames that change every
//! step, clean (the driver drives), then with Gaussian noise σ 50 beyond the entry's σ* 20
//! (the guard overrides), then clean again (the guard hands back after the monitor's
//! hysteresis and minimum dwell). Who answered each call is read from the guard's log.

use fogline_guard::session::{LoopSession, connect};
use fogline_perturb::{FrameInput, FrameKey, Perturbation};
use fogline_types::clip::CameraId;
use fogline_world::{WorldConfig, generate_clip_cameras};

use crate::*;

const CLEAN_BEFORE: usize = 15;
const NOISY: usize = 20;
const CLEAN_AFTER: usize = 25;

/// `n` distinct front-wide frames (four per world clip), PNG-encoded, the ones in `noisy`
/// with Gaussian noise σ 50 (a fresh draw per frame).
pub(crate) fn live_frames(n: usize, noisy: std::ops::Range<usize>) -> Vec<Vec<u8>> {
    let cfg = WorldConfig {
        depth: false,
        ..WorldConfig::default()
    };
    let noise = Perturbation::parse("noise_50").unwrap().prepare(7).unwrap();
    let mut out = Vec::with_capacity(n);
    let mut clip = 0;
    while out.len() < n {
        let c = generate_clip_cameras(&cfg, clip, &[CameraId::FrontWide]).unwrap();
        for f in &c.cameras[0].frames {
            let k = out.len();
            if k == n {
                break;
            }
            let frame = if noisy.contains(&k) {
                let key = FrameKey::new(clip as u64, 0, k as u64);
                noise.apply(&FrameInput::new(&f.image, key)).unwrap().frame
            } else {
                f.image.clone()
            };
            out.push(
                fogline_io::encode(
                    frame.data(),
                    frame.width(),
                    frame.height(),
                    fogline_io::ImageFormat::Png,
                )
                .unwrap(),
            );
        }
        clip += 1;
    }
    out
}

/// Runs of equal sources: `[("driver", 15), ("override", 22), …]`.
fn runs(sources: &[String]) -> Vec<(String, usize)> {
    let mut out: Vec<(String, usize)> = Vec::new();
    for s in sources {
        match out.last_mut() {
            Some((last, n)) if last == s => *n += 1,
            _ => out.push((s.clone(), 1)),
        }
    }
    out
}

#[test]
fn r20_the_guard_takes_over_on_degraded_live_frames_and_hands_back() {
    let n = CLEAN_BEFORE + NOISY + CLEAN_AFTER;
    let frames = live_frames(n, CLEAN_BEFORE..CLEAN_BEFORE + NOISY);
    let driver = driver();
    let log = MemLog::default();
    let guard = guard(driver.local_addr(), &log);
    let debug: Vec<serde_json::Value> = runtime().block_on(async {
        let rpc = connect(guard.local_addr()).await.unwrap();
        let mut s = LoopSession::start(rpc, "live", &front(), 8.0)
            .await
            .unwrap();
        let mut debug = Vec::new();
        for f in frames {
            let step = s.step(f).await.unwrap();
            let answer = step.response;
            assert!(answer.trajectory.is_some_and(|t| t.poses.len() > 1));
            let info = answer
                .debug_info
                .map(|d| d.unstructured_debug_info)
                .unwrap_or_default();
            debug.push(serde_json::from_slice(&info).unwrap_or(serde_json::Value::Null));
        }
        s.close().await.unwrap();
        debug
    });
    let records = log.records();
    assert_eq!(records.len(), n, "one record per drive call");
    let sources: Vec<String> = records.iter().map(|r| r.source.clone()).collect();
    let runs = runs(&sources);
    let noise_at = |k: usize| {
        records[k]
            .monitor
            .as_ref()
            .and_then(|m| m.axes.iter().find(|a| a.axis == "gaussian_noise"))
            .map_or(f64::NAN, |a| a.bound)
    };
    println!("who answered (runs): {runs:?}");
    for (k, r) in records.iter().enumerate() {
        if k % 5 == 0 || r.monitor.as_ref().is_some_and(|m| m.switched) {
            println!(
                "  call {k:>2}  {:<8}  σ bound {:>5.1}  {}",
                r.source,
                noise_at(k),
                r.reason.as_deref().unwrap_or("")
            );
        }
    }
    // Clean: the driver drives.
    assert!(
        sources[..CLEAN_BEFORE].iter().all(|s| s == "driver"),
        "{runs:?}"
    );
    // Degraded: the guard takes over within a few frames (the moving average's lag) and
    // answers with the RCO's plan.
    let first_override = sources.iter().position(|s| s == "override").unwrap();
    assert!(
        (CLEAN_BEFORE..CLEAN_BEFORE + 4).contains(&first_override),
        "override from call {first_override}: {runs:?}"
    );
    // Handed back once the frames are clean again, after the hysteresis and dwell.
    assert_eq!(
        runs.iter().map(|r| r.0.as_str()).collect::<Vec<_>>(),
        ["driver", "override", "driver"],
        "{runs:?}"
    );
    let back = first_override + runs[1].1;
    assert!(
        back > CLEAN_BEFORE + NOISY && back < n - 10,
        "handed back at call {back}: {runs:?}"
    );
    // The answers say who gave them: the guard marks its own.
    for (k, d) in debug.iter().enumerate() {
        let by_guard = d.get("guard").and_then(|g| g.as_str());
        if sources[k] == "override" {
            assert_eq!(by_guard, Some("override"), "call {k}: {d}");
            let t = records[k].takeover.as_ref().unwrap();
            assert!(t.brake >= 0.0 && t.throttle <= 1.0, "{t:?}");
        } else {
            assert_eq!(by_guard, None, "call {k}: {d}");
        }
    }
    println!(
        "live frames: {n} calls; driver {CLEAN_BEFORE} clean, override from call \
         {first_override} (noise from {CLEAN_BEFORE}), handed back at call {back} (clean from {})",
        CLEAN_BEFORE + NOISY
    );
    guard.shutdown().unwrap();
    driver.shutdown().unwrap();
}
