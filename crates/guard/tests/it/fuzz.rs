//! The guard in the fuzz suite: the mutated messages of `fogline-remote`'s egodriver test
//! (`mutated_messages_get_answers_and_leave_the_server_serving`) sent to the guard in front
//! of a live driver. Every call must be answered (a gRPC error is fine), the guard must keep
//! serving, and a clean session must still be driven by the driver through it.

use std::collections::BTreeMap;

use fogline_guard::session::{LoopSession, connect};
use fogline_remote::egodriver::declare_camera;
use fogline_remote::egodriver::wire::common::{Empty, Pose, PoseAtTime, Quat, Trajectory, Vec3};
use fogline_remote::egodriver::wire::egodriver::drive_session_request::RolloutSpec;
use fogline_remote::egodriver::wire::egodriver::drive_session_request::rollout_spec::VehicleDefinition;
use fogline_remote::egodriver::wire::egodriver::rollout_camera_image::CameraImage;
use fogline_remote::egodriver::wire::egodriver::{
    DriveRequest, DriveSessionCloseRequest, DriveSessionRequest, RolloutCameraImage,
    RolloutEgoTrajectory,
};
use tonic::Code;

use crate::handback::live_frames;
use crate::*;

/// One to three random edits of `bytes` (SplitMix64 from `state`), as in `fogline-remote`.
fn mutate(bytes: &[u8], state: &mut u64) -> Vec<u8> {
    let mut next = || {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut v = bytes.to_vec();
    for _ in 0..1 + next() % 3 {
        let at = (next() as usize) % (v.len() + 1);
        match next() % 4 {
            0 if !v.is_empty() => {
                let i = at.min(v.len() - 1);
                v[i] = next() as u8;
            }
            1 => v
                .splice(at..at, (0..1 + next() % 6).map(|k| (next() >> k) as u8))
                .for_each(drop),
            2 => {
                let end = (at + 1 + (next() as usize) % 12).min(v.len());
                v.drain(at.min(end)..end);
            }
            _ => v.truncate(at),
        }
    }
    v
}

fn yaw_quat(yaw: f64) -> Quat {
    Quat {
        w: (yaw / 2.0).cos() as f32,
        x: 0.0,
        y: 0.0,
        z: (yaw / 2.0).sin() as f32,
    }
}

fn start(uuid: &str) -> DriveSessionRequest {
    DriveSessionRequest {
        session_uuid: uuid.into(),
        rollout_spec: Some(RolloutSpec {
            vehicle: Some(VehicleDefinition {
                available_cameras: vec![declare_camera(&front())],
            }),
        }),
        ..Default::default()
    }
}

fn image(uuid: &str, bytes: Vec<u8>) -> RolloutCameraImage {
    RolloutCameraImage {
        session_uuid: uuid.into(),
        camera_image: Some(CameraImage {
            frame_start_us: 1_000_000,
            frame_end_us: 1_000_000,
            image_bytes: bytes,
            logical_id: declare_camera(&front()).logical_id,
        }),
    }
}

fn code_name<T>(r: &Result<T, tonic::Status>) -> String {
    match r {
        Ok(_) => "ok".into(),
        Err(e) => format!("{:?}", e.code()),
    }
}

#[test]
fn r20_mutated_messages_through_the_guard_get_answers_and_leave_it_serving() {
    use prost::Message as _;
    let frames = live_frames(8, 0..0);
    let driver = driver();
    let log = MemLog::default();
    let guard = guard(driver.local_addr(), &log);
    let addr = guard.local_addr();
    let img = image("m", frames[0].clone());
    let poses: Vec<PoseAtTime> = (0..20)
        .map(|i| PoseAtTime {
            pose: Some(Pose {
                vec: Some(Vec3 {
                    x: i as f32 * 0.5,
                    y: 0.0,
                    z: 0.3,
                }),
                quat: Some(yaw_quat(0.0)),
            }),
            timestamp_us: 100_000 * (i + 1),
        })
        .collect();
    let ego = RolloutEgoTrajectory {
        session_uuid: "m".into(),
        trajectory: Some(Trajectory { poses }),
        dynamic_states: Vec::new(),
    };
    let drive = DriveRequest {
        session_uuid: "m".into(),
        time_now_us: 2_000_000,
        time_query_us: 2_100_000,
        ..Default::default()
    };
    let mut state = 0x00E6_0D81_u64;
    let mut sent = 0;
    let mut codes: BTreeMap<String, usize> = BTreeMap::new();
    let rt = runtime();
    rt.block_on(async {
        let mut rpc = connect(addr).await.unwrap();
        // Bad messages, each refused with the gRPC error that says why.
        let e = rpc.start_session(start("")).await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{e}");
        let e = rpc.drive(DriveRequest::default()).await.unwrap_err();
        assert_eq!(e.code(), Code::NotFound, "{e}");
        rpc.start_session(start("bad")).await.unwrap();
        let e = rpc
            .submit_image_observation(image("bad", b"\x89PNG\r\n\x1a\nnot a png".to_vec()))
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{e}");
        // A PNG whose header claims 100,000 × 100,000 pixels: refused from the header.
        let mut huge = frames[1].clone();
        huge[16..20].copy_from_slice(&100_000u32.to_be_bytes());
        huge[20..24].copy_from_slice(&100_000u32.to_be_bytes());
        let e = rpc
            .submit_image_observation(image("bad", huge))
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{e}");
        let mut nan = ego.clone();
        nan.session_uuid = "bad".into();
        if let Some(p) = nan
            .trajectory
            .as_mut()
            .and_then(|t| t.poses[3].pose.as_mut())
        {
            p.vec = Some(Vec3 {
                x: f32::NAN,
                y: 0.0,
                z: 0.0,
            });
        }
        let e = rpc.submit_egomotion_observation(nan).await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{e}");
        let e = rpc
            .drive(DriveRequest {
                session_uuid: "bad".into(),
                time_now_us: 2_000_000,
                ..Default::default()
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::FailedPrecondition, "{e}");
        let e = rpc.shut_down(Empty {}).await.unwrap_err();
        assert_eq!(e.code(), Code::PermissionDenied, "{e}");

        for round in 0..150 {
            let _ = rpc.start_session(start("m")).await;
            if let Ok(m) =
                DriveSessionRequest::decode(&*mutate(&start("m").encode_to_vec(), &mut state))
            {
                let r = rpc.start_session(m).await;
                *codes.entry(format!("start {}", code_name(&r))).or_default() += 1;
                sent += 1;
            }
            if let Ok(m) = RolloutCameraImage::decode(&*mutate(&img.encode_to_vec(), &mut state)) {
                let r = rpc.submit_image_observation(m).await;
                *codes.entry(format!("image {}", code_name(&r))).or_default() += 1;
                sent += 1;
            }
            if let Ok(m) = RolloutEgoTrajectory::decode(&*mutate(&ego.encode_to_vec(), &mut state))
            {
                let r = rpc.submit_egomotion_observation(m).await;
                *codes.entry(format!("ego {}", code_name(&r))).or_default() += 1;
                sent += 1;
            }
            if let Ok(m) = DriveRequest::decode(&*mutate(&drive.encode_to_vec(), &mut state)) {
                let r = rpc.drive(m).await;
                *codes.entry(format!("drive {}", code_name(&r))).or_default() += 1;
                sent += 1;
            }
            // Well-formed messages with hostile values: non-finite and out-of-order poses,
            // any time.
            let mut r = || {
                mutate(&[0; 8], &mut state)
                    .iter()
                    .fold(0u64, |a, &b| a.wrapping_mul(31).wrapping_add(u64::from(b)))
            };
            let wild = [f32::NAN, f32::INFINITY, -1e30, 0.0, 5.0];
            let poses: Vec<PoseAtTime> = (0..1 + r() % 30)
                .map(|_| PoseAtTime {
                    pose: Some(Pose {
                        vec: Some(Vec3 {
                            x: wild[(r() % 5) as usize],
                            y: wild[(r() % 5) as usize],
                            z: 0.0,
                        }),
                        quat: Some(yaw_quat((r() % 7) as f64)),
                    }),
                    timestamp_us: r() % 5_000_000,
                })
                .collect();
            let _ = rpc
                .submit_egomotion_observation(RolloutEgoTrajectory {
                    session_uuid: "m".into(),
                    trajectory: Some(Trajectory { poses }),
                    dynamic_states: Vec::new(),
                })
                .await;
            let r = rpc
                .drive(DriveRequest {
                    session_uuid: "m".into(),
                    time_now_us: r(),
                    time_query_us: r(),
                    ..Default::default()
                })
                .await;
            *codes.entry(format!("drive {}", code_name(&r))).or_default() += 1;
            let _ = rpc
                .close_session(DriveSessionCloseRequest {
                    session_uuid: "m".into(),
                })
                .await;
            assert!(rpc.get_version(Empty {}).await.is_ok(), "round {round}");
        }
    });
    println!("{sent} decodable mutants sent through the guard; answers: {codes:?}");
    assert!(sent >= 40, "only {sent} mutants decoded");
    // The guard still guards: a clean session on live frames is driven by the driver.
    let before = log.records().len();
    rt.block_on(async {
        let rpc = connect(addr).await.unwrap();
        let mut s = LoopSession::start(rpc, "clean", &front(), 8.0)
            .await
            .unwrap();
        for f in frames {
            let step = s.step(f).await.unwrap();
            assert!(step.response.trajectory.is_some_and(|t| t.poses.len() > 1));
        }
        s.close().await.unwrap();
    });
    let clean: Vec<String> = log.records()[before..]
        .iter()
        .filter(|r| r.session == "clean")
        .map(|r| r.source.clone())
        .collect();
    assert_eq!(clean.len(), 8);
    assert!(clean.iter().all(|s| s == "driver"), "{clean:?}");
    guard.shutdown().unwrap();
    driver.shutdown().unwrap();
}
