//! The egodriver server against hand-made wire messages: what an AlpaSim runtime or a
//! carla-driver-interface client sends.

use std::collections::BTreeMap;
use std::f64::consts::FRAC_PI_2;
use std::time::Duration;

use fogline_remote::egodriver::wire::common::{
    DynamicState, Empty, Pose, PoseAtTime, Quat, Trajectory, Vec3,
};
use fogline_remote::egodriver::wire::egodriver::drive_session_request::rollout_spec::VehicleDefinition;
use fogline_remote::egodriver::wire::egodriver::drive_session_request::{DebugInfo, RolloutSpec};
use fogline_remote::egodriver::wire::egodriver::egodriver_service_client::EgodriverServiceClient;
use fogline_remote::egodriver::wire::egodriver::rollout_camera_image::CameraImage;
use fogline_remote::egodriver::wire::egodriver::{
    DriveRequest, DriveSessionCloseRequest, DriveSessionRequest, RolloutCameraImage,
    RolloutEgoTrajectory,
};
use fogline_remote::egodriver::wire::nre::grpc::protos::sensorsim::available_cameras_return::AvailableCamera;
use fogline_remote::egodriver::wire::nre::grpc::protos::sensorsim::camera_spec::CameraParam;
use fogline_remote::egodriver::wire::nre::grpc::protos::sensorsim::{
    CameraSpec, OpenCvPinholeCameraParam,
};
use fogline_remote::egodriver::{self, CONTRACT_METADATA_KEY, ServeOptions};
use fogline_types::clip::CameraId;
use tonic::Code;
use tonic::transport::Channel;

use crate::*;

type Rpc = EgodriverServiceClient<Channel>;

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
}

async fn connect(addr: std::net::SocketAddr) -> Rpc {
    EgodriverServiceClient::connect(format!("http://{addr}"))
        .await
        .unwrap()
}

/// Rotation quaternion `[w, x, y, z]` of a 3×3 matrix with columns `cols`.
fn quat_of_columns(cols: [[f64; 3]; 3]) -> Quat {
    let m = |i: usize, j: usize| cols[j][i];
    let tr = m(0, 0) + m(1, 1) + m(2, 2);
    // Good enough for the rotations used here (trace > −1).
    let w = (1.0 + tr).sqrt() / 2.0;
    Quat {
        w: w as f32,
        x: ((m(2, 1) - m(1, 2)) / (4.0 * w)) as f32,
        y: ((m(0, 2) - m(2, 0)) / (4.0 * w)) as f32,
        z: ((m(1, 0) - m(0, 1)) / (4.0 * w)) as f32,
    }
}

/// A pinhole camera 640×360 with `hfov_deg`, at (2, 0, 1.5) m, turned `yaw` left and
/// `pitch` down, declared in revision `rev` (1: body frame, 2: optical frame).
fn camera(id: &str, hfov_deg: f64, yaw: f64, pitch: f64, rev: u32) -> AvailableCamera {
    let (sy, cy) = yaw.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let fwd = [cy * cp, sy * cp, -sp];
    let right = [sy, -cy, 0.0];
    let down = [-sp * cy, -sp * sy, -cp];
    let neg = |v: [f64; 3]| [-v[0], -v[1], -v[2]];
    let cols = if rev == 1 {
        [fwd, neg(right), neg(down)]
    } else {
        [right, down, fwd]
    };
    let f = 320.0 / (hfov_deg.to_radians() / 2.0).tan();
    AvailableCamera {
        intrinsics: Some(CameraSpec {
            camera_param: Some(CameraParam::OpencvPinholeParam(OpenCvPinholeCameraParam {
                principal_point_x: 320.0,
                principal_point_y: 180.0,
                focal_length_x: f,
                focal_length_y: f,
                ..Default::default()
            })),
            logical_id: id.into(),
            resolution_w: 640,
            resolution_h: 360,
            ..Default::default()
        }),
        rig_to_camera: Some(Pose {
            vec: Some(Vec3 {
                x: 2.0,
                y: 0.0,
                z: 1.5,
            }),
            quat: Some(quat_of_columns(cols)),
        }),
        logical_id: id.into(),
    }
}

fn png(width: u32, height: u32, shade: u8) -> Vec<u8> {
    let img = image::RgbImage::from_fn(width, height, |x, y| {
        image::Rgb([shade, (x % 256) as u8, (y % 256) as u8])
    });
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn start_request(
    uuid: &str,
    cameras: Vec<AvailableCamera>,
    rev: Option<u32>,
) -> tonic::Request<DriveSessionRequest> {
    let mut r = tonic::Request::new(DriveSessionRequest {
        session_uuid: uuid.into(),
        random_seed: 99,
        debug_info: Some(DebugInfo {
            scene_id: "wire".into(),
        }),
        rollout_spec: Some(RolloutSpec {
            vehicle: Some(VehicleDefinition {
                available_cameras: cameras,
            }),
        }),
    });
    if let Some(rev) = rev {
        r.metadata_mut()
            .insert(CONTRACT_METADATA_KEY, rev.to_string().parse().unwrap());
    }
    r
}

async fn image(rpc: &mut Rpc, uuid: &str, id: &str, t_us: u64, shade: u8) {
    rpc.submit_image_observation(RolloutCameraImage {
        session_uuid: uuid.into(),
        camera_image: Some(CameraImage {
            frame_start_us: t_us,
            frame_end_us: t_us,
            image_bytes: png(640, 360, shade),
            logical_id: id.into(),
        }),
    })
    .await
    .unwrap();
}

fn yaw_quat(yaw: f64) -> Quat {
    Quat {
        w: (yaw / 2.0).cos() as f32,
        x: 0.0,
        y: 0.0,
        z: (yaw / 2.0).sin() as f32,
    }
}

#[test]
fn get_version_declares_revision_2_and_unknown_sessions_are_not_found() {
    let server = egodriver::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions::default(),
    )
    .unwrap();
    let addr = server.local_addr();
    runtime().block_on(async {
        let mut rpc = connect(addr).await;
        let v = rpc.get_version(Empty {}).await.unwrap();
        let rev = v
            .metadata()
            .get(CONTRACT_METADATA_KEY)
            .unwrap()
            .to_str()
            .unwrap();
        assert_eq!(rev, "2");
        assert!(v.get_ref().version_id.contains("fake planner"));
        assert!(v.get_ref().grpc_api_version.is_some());

        let e = rpc
            .drive(DriveRequest {
                session_uuid: "nope".into(),
                ..Default::default()
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::NotFound);

        // A session without frames cannot drive, and says why.
        rpc.start_session(start_request(
            "s0",
            vec![camera("camera_front_wide_120fov", 120.0, 0.0, 0.0, 2)],
            Some(2),
        ))
        .await
        .unwrap();
        let e = rpc
            .start_session(start_request("s0", vec![], Some(2)))
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::AlreadyExists);
        rpc.submit_egomotion_observation(RolloutEgoTrajectory {
            session_uuid: "s0".into(),
            trajectory: Some(Trajectory {
                poses: vec![PoseAtTime {
                    pose: Some(Pose::default()),
                    timestamp_us: 1_000,
                }],
            }),
            dynamic_states: vec![],
        })
        .await
        .unwrap();
        let e = rpc
            .drive(DriveRequest {
                session_uuid: "s0".into(),
                time_now_us: 1_000,
                time_query_us: 101_000,
                ..Default::default()
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::FailedPrecondition);
        assert!(e.message().contains("no frame"), "{}", e.message());
        // Undeclared cameras are refused.
        let e = rpc
            .submit_image_observation(RolloutCameraImage {
                session_uuid: "s0".into(),
                camera_image: Some(CameraImage {
                    logical_id: "camera_rear".into(),
                    image_bytes: png(8, 8, 0),
                    ..Default::default()
                }),
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument);

        // Other services are not implemented (carla-driver-interface's demo relies on it).
        let mut grpc = tonic::client::Grpc::new(
            Channel::from_shared(format!("http://{addr}"))
                .unwrap()
                .connect()
                .await
                .unwrap(),
        );
        grpc.ready().await.unwrap();
        let path = tonic::codegen::http::uri::PathAndQuery::from_static(
            "/carla_driver.v0.CarlaVehicleService/get_vehicle_command",
        );
        let codec = tonic_prost::ProstCodec::<Empty, Empty>::default();
        let e = grpc
            .unary(tonic::Request::new(Empty {}), path, codec)
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::Unimplemented);
    });
    server.shutdown().unwrap();
}

/// Declares cameras, sends frames and a history in a local frame that is not the rig
/// frame, drives, and returns what the planner saw and the wire answer.
fn drive_session(
    opts: ServeOptions,
    cameras: Vec<AvailableCamera>,
    rev: Option<u32>,
    frames: &[(&str, u64)],
) -> (
    Seen,
    fogline_remote::egodriver::wire::egodriver::DriveResponse,
) {
    let fake = Fake::new(Behaviour::Straight);
    let server = egodriver::serve(loopback(), fake.clone(), opts).unwrap();
    let addr = server.local_addr();
    let answer = runtime().block_on(async {
        let mut rpc = connect(addr).await;
        rpc.start_session(start_request("s1", cameras, rev))
            .await
            .unwrap();
        for (k, &(id, t)) in frames.iter().enumerate() {
            image(&mut rpc, "s1", id, t, k as u8).await;
        }
        // The ego drives north (local yaw 90°) at 5 m/s and is at (100, 50) at t = 2 s.
        let poses: Vec<PoseAtTime> = (0..20)
            .map(|i| {
                let t_us = 100_000 * (i + 1) as u64;
                let dt = (t_us as f64 - 2e6) / 1e6;
                PoseAtTime {
                    pose: Some(Pose {
                        vec: Some(Vec3 {
                            x: 100.0,
                            y: (50.0 + 5.0 * dt) as f32,
                            z: 0.3,
                        }),
                        quat: Some(yaw_quat(FRAC_PI_2)),
                    }),
                    timestamp_us: t_us,
                }
            })
            .collect();
        let states = (0..20)
            .map(|_| DynamicState {
                linear_velocity: Some(Vec3 {
                    x: 5.0,
                    y: 0.0,
                    z: 0.0,
                }),
                ..Default::default()
            })
            .collect();
        rpc.submit_egomotion_observation(RolloutEgoTrajectory {
            session_uuid: "s1".into(),
            trajectory: Some(Trajectory { poses }),
            dynamic_states: states,
        })
        .await
        .unwrap();
        let answer = rpc
            .drive(DriveRequest {
                session_uuid: "s1".into(),
                time_now_us: 2_000_000,
                time_query_us: 2_100_000,
                ..Default::default()
            })
            .await
            .unwrap()
            .into_inner();
        rpc.close_session(DriveSessionCloseRequest {
            session_uuid: "s1".into(),
        })
        .await
        .unwrap();
        answer
    });
    server.shutdown().unwrap();
    (fake.last(), answer)
}

#[test]
fn a_session_in_a_foreign_local_frame_is_planned_in_the_rig_frame() {
    let (seen, answer) = drive_session(
        ServeOptions::default(),
        vec![camera("camera_front_wide_120fov", 120.0, 0.0, 0.0, 2)],
        Some(2),
        &[
            ("camera_front_wide_120fov", 1_800_000),
            ("camera_front_wide_120fov", 1_900_000),
            ("camera_front_wide_120fov", 2_000_000),
        ],
    );
    assert_eq!(seen.scene_id, "wire");
    assert_eq!(seen.seed, 99);
    // The history: the last 16 poses, ending at the origin, driving along +x.
    assert_eq!(seen.history.len(), 16);
    let last = seen.history.last().unwrap();
    close(last.t_s, 0.0, 1e-9, "t0");
    close(last.x_m, 0.0, 1e-4, "x0");
    close(last.y_m, 0.0, 1e-4, "y0");
    let first = seen.history[0];
    close(first.t_s, -1.5, 1e-9, "t first");
    close(first.x_m, -7.5, 1e-3, "x first");
    close(first.y_m, 0.0, 1e-3, "y first");
    close(first.yaw_rad, 0.0, 1e-6, "yaw first");
    close(first.speed_mps, 5.0, 1e-6, "speed");
    assert_eq!(seen.cameras[0].1.len(), 3);

    // The answer: the anchor then 64 poses, 0.1 s apart, in the local frame (rig x is
    // local +y here), heading along the path.
    let poses = answer.trajectory.unwrap().poses;
    assert_eq!(poses.len(), 65);
    let expected = straight(99);
    for (k, p) in poses.iter().enumerate() {
        assert_eq!(p.timestamp_us, 2_000_000 + 100_000 * k as u64);
        let v = p.pose.as_ref().unwrap().vec.unwrap();
        let (rx, ry) = if k == 0 {
            (0.0, 0.0)
        } else {
            (expected[k - 1][0], expected[k - 1][1])
        };
        close(f64::from(v.x), 100.0 - ry, 1e-3, "local x");
        close(f64::from(v.y), 50.0 + rx, 1e-3, "local y");
        close(f64::from(v.z), 0.3, 1e-6, "local z");
    }
    let q = poses[10].pose.as_ref().unwrap().quat.unwrap();
    let yaw = (2.0 * f64::from(q.w * q.z)).atan2(1.0 - 2.0 * f64::from(q.z * q.z));
    close(yaw, FRAC_PI_2, 1e-3, "heading");
    let debug = answer.debug_info.unwrap().unstructured_debug_info;
    let json: serde_json::Value = serde_json::from_slice(&debug).unwrap();
    assert_eq!(json["coc"], EXPLANATION);
    assert_eq!(json["decision"], "keep_lane");
    assert_eq!(json["planner"], "fake planner");
}

#[test]
fn cameras_map_by_name_by_option_or_as_the_widest_forward_camera() {
    let opts = ServeOptions {
        camera_map: BTreeMap::from([("side".to_string(), CameraId::CrossLeft)]),
        ..ServeOptions::default()
    };
    for rev in [Some(1), Some(2), None] {
        let declared_rev = rev.unwrap_or(2);
        let cameras = vec![
            camera("narrow", 30.0, 0.0, 0.0, declared_rev),
            camera("wide", 100.0, 0.1, 0.05, declared_rev),
            camera("side", 120.0, 1.0, 0.0, declared_rev),
            camera("behind", 120.0, 3.1, 0.0, declared_rev),
        ];
        let frames = [
            ("wide", 1_900_000),
            ("wide", 2_000_000),
            ("side", 1_700_000),
            ("side", 1_800_000),
            ("side", 1_900_000),
            ("narrow", 2_000_000),
            ("behind", 2_000_000),
        ];
        let (seen, _) = drive_session(opts.clone(), cameras, rev, &frames);
        let ids: Vec<CameraId> = seen.cameras.iter().map(|c| c.0.id).collect();
        assert_eq!(
            ids,
            vec![CameraId::CrossLeft, CameraId::FrontWide],
            "rev {rev:?}"
        );
        let (wide, wide_frames) = &seen.cameras[1];
        close(wide.yaw_rad, 0.1, 1e-5, "wide yaw");
        close(wide.pitch_rad, 0.05, 1e-5, "wide pitch");
        close(wide.x_m, 2.0, 1e-6, "x");
        close(wide.z_m, 1.5, 1e-6, "z");
        close(wide.fx, 320.0 / (50f64.to_radians()).tan(), 1e-9, "fx");
        let (side, side_frames) = &seen.cameras[0];
        close(side.yaw_rad, 1.0, 1e-5, "side yaw");
        // Trimmed to the same count: the newest two of each.
        assert_eq!(wide_frames.len(), 2);
        assert_eq!(side_frames.len(), 2);
        // Frame k was drawn with shade k: side's newest two are frames 3 and 4.
        assert_eq!(side_frames[0][0], 3);
        assert_eq!(side_frames[1][0], 4);
        assert_eq!(wide_frames[1][0], 1);
    }
}

#[test]
fn shut_down_is_refused_by_default_and_stops_the_server_when_allowed() {
    // Off by default: any local peer could call it.
    let server = egodriver::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions::default(),
    )
    .unwrap();
    let addr = server.local_addr();
    runtime().block_on(async {
        let mut rpc = connect(addr).await;
        let e = rpc.shut_down(Empty {}).await.unwrap_err();
        assert_eq!(e.code(), tonic::Code::PermissionDenied, "{e}");
        // Still serving.
        rpc.get_version(Empty {}).await.unwrap();
    });
    server.shutdown().unwrap();

    let server = egodriver::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions {
            allow_shut_down: true,
            ..ServeOptions::default()
        },
    )
    .unwrap();
    let addr = server.local_addr();
    let waiter = std::thread::spawn(move || server.wait());
    runtime().block_on(async {
        let mut rpc = connect(addr).await;
        rpc.shut_down(Empty {}).await.unwrap();
    });
    let t = std::time::Instant::now();
    while !waiter.is_finished() {
        assert!(
            t.elapsed() < Duration::from_secs(10),
            "the server did not stop"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    waiter.join().unwrap().unwrap();
}

#[test]
fn a_session_declaring_more_pixels_than_the_cap_is_refused() {
    // One 640 × 360 camera × 4 frames is 921,600 pixels: a cap one below refuses it.
    let server = egodriver::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions {
            limits: fogline_remote::Limits {
                max_request_pixels: 640 * 360 * 4 - 1,
                ..fogline_remote::Limits::default()
            },
            ..ServeOptions::default()
        },
    )
    .unwrap();
    let addr = server.local_addr();
    runtime().block_on(async {
        let mut rpc = connect(addr).await;
        let cam = camera("front", 120.0, 0.0, 0.0, 2);
        let e = rpc
            .start_session(start_request("s1", vec![cam], Some(2)))
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::ResourceExhausted, "{e}");
        assert!(e.message().contains("921600 pixels"), "{}", e.message());
    });
    server.shutdown().unwrap();
}

/// One to three random edits of `bytes` (SplitMix64 from `state`).
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

#[test]
fn mutated_messages_get_answers_and_leave_the_server_serving() {
    use prost::Message as _;
    // Valid messages of a whole session, encoded; each mutated 150 times, decoded, and the
    // mutants that decode sent to a live server. Every call must be answered (an error is
    // fine), the server must keep serving, and a clean session must still drive.
    let server = egodriver::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions::default(),
    )
    .unwrap();
    let addr = server.local_addr();
    let start = start_request("m", vec![camera("front", 120.0, 0.0, 0.0, 2)], None).into_inner();
    let img = RolloutCameraImage {
        session_uuid: "m".into(),
        camera_image: Some(CameraImage {
            frame_start_us: 1_000_000,
            frame_end_us: 1_000_000,
            image_bytes: png(640, 360, 7),
            logical_id: "front".into(),
        }),
    };
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
    let (mut sent, mut decoded_none) = (0, 0);
    runtime().block_on(async {
        let mut rpc = connect(addr).await;
        for round in 0..150 {
            // A session to send the mutants into (a mutated start may or may not make one).
            let _ = rpc.start_session(start.clone()).await;
            if let Ok(m) = DriveSessionRequest::decode(&*mutate(&start.encode_to_vec(), &mut state))
            {
                let _ = rpc.start_session(m).await;
                sent += 1;
            }
            match RolloutCameraImage::decode(&*mutate(&img.encode_to_vec(), &mut state)) {
                Ok(m) => {
                    let _ = rpc.submit_image_observation(m).await;
                    sent += 1;
                }
                Err(_) => decoded_none += 1,
            }
            if let Ok(m) = RolloutEgoTrajectory::decode(&*mutate(&ego.encode_to_vec(), &mut state))
            {
                let _ = rpc.submit_egomotion_observation(m).await;
                sent += 1;
            }
            if let Ok(m) = DriveRequest::decode(&*mutate(&drive.encode_to_vec(), &mut state)) {
                let _ = rpc.drive(m).await;
                sent += 1;
            }
            // Well-formed messages with hostile values: any resolution and focal length,
            // non-finite and out-of-order poses, any time.
            let mut r = || {
                mutate(&[0; 8], &mut state)
                    .iter()
                    .fold(0u64, |a, &b| a.wrapping_mul(31).wrapping_add(u64::from(b)))
            };
            let mut cam = camera("front", 120.0, 0.0, 0.0, 2);
            if let Some(spec) = cam.intrinsics.as_mut() {
                spec.resolution_w = (r() % 20_000) as u32;
                spec.resolution_h = (r() % 20_000) as u32;
                if let Some(CameraParam::OpencvPinholeParam(p)) = spec.camera_param.as_mut() {
                    p.focal_length_x = [0.0, -1.0, f64::NAN, 1e30, 300.0][(r() % 5) as usize];
                }
            }
            let _ = rpc.start_session(start_request("m", vec![cam], None)).await;
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
            let _ = rpc
                .drive(DriveRequest {
                    session_uuid: "m".into(),
                    time_now_us: r(),
                    time_query_us: r(),
                    ..Default::default()
                })
                .await;
            let _ = rpc
                .close_session(DriveSessionCloseRequest {
                    session_uuid: "m".into(),
                })
                .await;
            assert!(rpc.get_version(Empty {}).await.is_ok(), "round {round}");
        }
    });
    // Most byte-level mutants no longer decode as protobuf; enough do.
    assert!(
        sent >= 40,
        "only {sent} mutants decoded ({decoded_none} images did not)"
    );
    server.shutdown().unwrap();
    // A clean session on a fresh server drives as before.
    let (_, answer) = drive_session(
        ServeOptions::default(),
        vec![camera("front", 120.0, 0.0, 0.0, 2)],
        None,
        &[("front", 1_000_000), ("front", 1_900_000)],
    );
    assert!(!answer.trajectory.unwrap_or_default().poses.is_empty());
}
