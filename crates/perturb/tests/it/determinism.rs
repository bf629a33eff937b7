//! Bit-identical output across runs, thread counts and processing orders.

use fogline_perturb::{Frame, FrameInput, FrameKey, Perturbation, Prepared};

use crate::{apply, ramp};

const CONDITIONS: [&str; 8] = [
    "noise_30",
    "noise_70+jpeg_40",
    "shot_4",
    "impulse_0.05",
    "dead_0.01",
    "dirt_5",
    "fog_03+noise_10",
    "glare_0.5+defocus_2",
];

fn keys() -> Vec<FrameKey> {
    let mut k = Vec::new();
    for clip in [0u64, 7] {
        for camera in 0..2 {
            for frame in 0..3 {
                k.push(FrameKey::new(clip, camera, frame));
            }
        }
    }
    k
}

fn run_all(prepared: &[Prepared], frame: &Frame, order: &[(usize, usize)]) -> Vec<Vec<u8>> {
    let ks = keys();
    let mut out = vec![Vec::new(); prepared.len() * ks.len()];
    for &(c, k) in order {
        let f = prepared[c].apply(&FrameInput::new(frame, ks[k])).unwrap();
        out[c * ks.len() + k] = f.frame.into_data();
    }
    out
}

#[test]
fn one_thread_two_threads_and_any_order_give_the_same_bytes() {
    let frame = ramp(160, 90);
    let prepared: Vec<Prepared> = CONDITIONS
        .iter()
        .map(|c| Perturbation::parse(c).unwrap().prepare(42).unwrap())
        .collect();
    let n_keys = keys().len();
    let forward: Vec<(usize, usize)> = (0..CONDITIONS.len())
        .flat_map(|c| (0..n_keys).map(move |k| (c, k)))
        .collect();
    let one_thread = run_all(&prepared, &frame, &forward);

    // Reverse order, interleaved, on two threads.
    let mut backward = forward.clone();
    backward.reverse();
    let (a, b): (Vec<_>, Vec<_>) = backward.iter().enumerate().partition(|(i, _)| i % 2 == 0);
    let a: Vec<(usize, usize)> = a.into_iter().map(|(_, x)| *x).collect();
    let b: Vec<(usize, usize)> = b.into_iter().map(|(_, x)| *x).collect();
    let (ra, rb) = std::thread::scope(|s| {
        let ha = s.spawn(|| run_all(&prepared, &frame, &a));
        let hb = s.spawn(|| run_all(&prepared, &frame, &b));
        (ha.join().unwrap(), hb.join().unwrap())
    });
    for i in 0..one_thread.len() {
        let two = if ra[i].is_empty() { &rb[i] } else { &ra[i] };
        assert_eq!(&one_thread[i], two, "item {i}");
    }

    // A fresh preparation (a new run) gives the same bytes again.
    let again: Vec<Prepared> = CONDITIONS
        .iter()
        .map(|c| Perturbation::parse(c).unwrap().prepare(42).unwrap())
        .collect();
    assert_eq!(run_all(&again, &frame, &forward), one_thread);
}

#[test]
fn streams_differ_by_seed_clip_camera_frame_and_condition() {
    let frame = Frame::filled(64, 32, [128, 128, 128]).unwrap();
    let base = apply("noise_30", 1, &frame, FrameKey::new(0, 0, 0));
    for (name, seed, key) in [
        ("noise_30", 2, FrameKey::new(0, 0, 0)),
        ("noise_30", 1, FrameKey::new(1, 0, 0)),
        ("noise_30", 1, FrameKey::new(0, 1, 0)),
        ("noise_30", 1, FrameKey::new(0, 0, 1)),
        ("noise_30.0", 1, FrameKey::new(0, 0, 0)),
    ] {
        assert_ne!(
            apply(name, seed, &frame, key),
            base,
            "{name} {seed} {key:?}"
        );
    }
    // Rows are independent streams: no two rows repeat each other.
    let rows: Vec<&[u8]> = base.data().chunks(64 * 3).collect();
    for i in 1..rows.len() {
        assert_ne!(rows[i], rows[0]);
    }
}

#[test]
fn sensor_defects_stay_put_across_frames_and_move_across_cameras() {
    let frame = Frame::filled(128, 64, [200, 200, 200]).unwrap();
    for name in ["dead_0.02", "dirt_4"] {
        let f0 = apply(name, 5, &frame, FrameKey::new(3, 0, 0));
        let f9 = apply(name, 5, &frame, FrameKey::new(3, 0, 9));
        let other_camera = apply(name, 5, &frame, FrameKey::new(3, 1, 0));
        assert_eq!(f0, f9, "{name}");
        assert_ne!(f0, other_camera, "{name}");
        assert_ne!(f0, frame, "{name}");
    }
}
