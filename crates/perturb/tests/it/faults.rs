//! Temporal faults and deficits over a clip.

use fogline_perturb::{
    Frame, FrameInput, FrameKey, FrameSource, ObjectBox, Perturbation, PixelRect,
};

use crate::ramp;

#[test]
fn temporal_faults_compose_in_order_and_spatial_steps_follow_the_source_frame() {
    let p = Perturbation::parse("latency_2+blackout_5+noise_20")
        .unwrap()
        .prepare(9)
        .unwrap();
    let plan = p.plan_clip(4, 0, 7);
    use FrameSource::{Black, Captured};
    assert_eq!(
        plan,
        [
            Captured(0),
            Captured(0),
            Captured(0),
            Captured(1),
            Captured(2),
            Black,
            Black
        ]
    );
    // The delivered frame is the captured frame perturbed under its own key, so repeats are
    // bit-identical.
    let frames: Vec<Frame> = (0..7).map(|i| ramp(32 + i, 16)).collect();
    let deliver = |i: usize| match plan[i] {
        Captured(j) => Some(
            p.apply(&FrameInput::new(&frames[j], FrameKey::new(4, 0, j as u64)))
                .unwrap()
                .frame,
        ),
        Black => None,
    };
    assert_eq!(deliver(0), deliver(2));
    assert_ne!(deliver(2), deliver(3));
    assert!(p.perturbation().is_temporal());
}

#[test]
fn frame_drop_plans_are_per_camera_and_reproducible() {
    let p = Perturbation::parse("drop_0.5").unwrap().prepare(1).unwrap();
    let a = p.plan_clip(0, 0, 200);
    assert_eq!(a, p.plan_clip(0, 0, 200));
    assert_ne!(a, p.plan_clip(0, 1, 200));
    assert_eq!(a[0], FrameSource::Captured(0));
    let freeze = Perturbation::parse("freeze_3").unwrap().prepare(1).unwrap();
    assert_eq!(freeze.plan_clip(0, 0, 5)[4], FrameSource::Captured(3));
}

#[test]
fn a_track_is_masked_in_every_frame_it_appears_in() {
    let p = Perturbation::parse("mask_track_7")
        .unwrap()
        .prepare(0)
        .unwrap();
    let frame = Frame::filled(40, 20, [50, 60, 70]).unwrap();
    for i in 0..5u32 {
        let boxes = [
            ObjectBox {
                class: "pedestrian".into(),
                track_id: Some(7),
                x_px: f64::from(2 + 5 * i),
                y_px: 4.0,
                width_px: 6.0,
                height_px: 10.0,
            },
            ObjectBox {
                class: "pedestrian".into(),
                track_id: Some(8),
                x_px: 30.0,
                y_px: 2.0,
                width_px: 6.0,
                height_px: 10.0,
            },
        ];
        let out = p
            .apply(&FrameInput {
                boxes: &boxes,
                ..FrameInput::new(&frame, FrameKey::new(0, 0, u64::from(i)))
            })
            .unwrap();
        assert_eq!(out.deficits.len(), 1);
        let x0 = 2 + 5 * i;
        assert_eq!(
            out.deficits[0].rect,
            PixelRect {
                x0,
                y0: 4,
                x1: x0 + 6,
                y1: 14
            }
        );
        assert_eq!(out.frame.pixel(x0 + 3, 9), [0, 0, 0]);
        assert_eq!(out.frame.pixel(x0, 9), [255, 0, 0]);
        assert_eq!(out.frame.pixel(33, 6), [50, 60, 70]);
    }
}

#[test]
fn outlines_are_a_parameter() {
    let mut p = Perturbation::parse("mask_all").unwrap();
    if let fogline_perturb::Step::DeficitMask(d) = &mut p.steps[0] {
        d.outline = None;
        d.fill_rgb = [9, 9, 9];
    }
    let frame = Frame::filled(10, 10, [50, 60, 70]).unwrap();
    let b = [ObjectBox {
        class: "car".into(),
        track_id: None,
        x_px: 1.0,
        y_px: 1.0,
        width_px: 4.0,
        height_px: 4.0,
    }];
    let out = p
        .prepare(0)
        .unwrap()
        .apply(&FrameInput {
            boxes: &b,
            ..FrameInput::new(&frame, FrameKey::default())
        })
        .unwrap();
    assert_eq!(out.frame.pixel(1, 1), [9, 9, 9]);
}
