//! Property tests: severity 0 is the identity, outputs keep their size, bad inputs are errors.

use fogline_perturb::{
    DepthMap, Frame, FrameInput, FrameKey, ObjectBox, PerturbError, Perturbation,
};
use proptest::prelude::*;

/// Every family at its identity level, plus `clean`.
const IDENTITIES: [&str; 19] = [
    "clean",
    "noise_0",
    "gain_1",
    "fog_00",
    "shot_0",
    "impulse_0",
    "contrast_1",
    "saturation_1",
    "defocus_0",
    "defocus_0.5",
    "motion_1",
    "pixelate_1",
    "quantize_8",
    "dead_0",
    "dirt_0",
    "glare_0",
    "drop_0",
    "latency_0",
    "noise_0+gain_1+fog_00",
];

fn frame_strategy() -> impl Strategy<Value = Frame> {
    (1u32..24, 1u32..24).prop_flat_map(|(w, h)| {
        proptest::collection::vec(any::<u8>(), (w * h * 3) as usize)
            .prop_map(move |d| Frame::new(w, h, d).unwrap())
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn severity_zero_is_the_identity(frame in frame_strategy(), seed in any::<u64>()) {
        for name in IDENTITIES {
            let p = Perturbation::parse(name).unwrap();
            prop_assert!(p.is_identity(), "{}", name);
            let out = p.prepare(seed).unwrap()
                .apply(&FrameInput::new(&frame, FrameKey::new(seed, 1, 2))).unwrap();
            prop_assert_eq!(&out.frame, &frame, "{}", name);
            prop_assert!(out.deficits.is_empty());
        }
    }

    #[test]
    fn every_family_keeps_the_size_and_never_panics(
        frame in frame_strategy(),
        seed in any::<u64>(),
        which in 0usize..16,
    ) {
        let name = [
            "noise_70", "bright", "fog_07", "shot_20", "impulse_0.5", "contrast_3",
            "saturation_4", "defocus_7", "motion_9", "jpeg_5", "pixelate_5", "quantize_1",
            "dead_0.5", "dirt_9", "glare_1", "mask_all",
        ][which];
        let out = Perturbation::parse(name).unwrap().prepare(seed).unwrap()
            .apply(&FrameInput::new(&frame, FrameKey::default())).unwrap();
        prop_assert_eq!((out.frame.width(), out.frame.height()), (frame.width(), frame.height()));
    }

    #[test]
    fn boxes_inside_are_accepted_and_outside_rejected(
        x in -5.0f64..30.0, y in -5.0f64..30.0, w in -3.0f64..30.0, h in -3.0f64..30.0,
    ) {
        let frame = Frame::filled(20, 20, [1, 2, 3]).unwrap();
        let b = [ObjectBox { class: "car".into(), track_id: None, x_px: x, y_px: y, width_px: w, height_px: h }];
        let p = Perturbation::parse("mask_all").unwrap().prepare(0).unwrap();
        let r = p.apply(&FrameInput { boxes: &b, ..FrameInput::new(&frame, FrameKey::default()) });
        let ok = w >= 0.0 && h >= 0.0 && x >= 0.0 && y >= 0.0 && x + w <= 20.0 && y + h <= 20.0;
        prop_assert_eq!(r.is_ok(), ok, "{:?}", r.err());
    }
}

#[test]
fn a_depth_map_of_the_wrong_size_is_an_error_naming_both_sizes() {
    let frame = Frame::filled(8, 4, [9, 9, 9]).unwrap();
    let depth = DepthMap::new(4, 8, vec![1.0; 32]).unwrap();
    let p = Perturbation::parse("fog_07").unwrap().prepare(0).unwrap();
    let e = p
        .apply(&FrameInput {
            depth: Some(&depth),
            ..FrameInput::new(&frame, FrameKey::default())
        })
        .unwrap_err();
    assert!(matches!(e, PerturbError::DepthSize { .. }));
    assert_eq!(
        e.to_string(),
        "the depth map is 4×8 pixels but the frame is 8×4"
    );
}

#[test]
fn visibility_without_depth_is_an_error() {
    let frame = Frame::filled(8, 4, [9, 9, 9]).unwrap();
    let p = Perturbation::parse("visibility_100").unwrap();
    assert!(p.needs_depth());
    let e = p
        .prepare(0)
        .unwrap()
        .apply(&FrameInput::new(&frame, FrameKey::default()))
        .unwrap_err();
    assert!(e.to_string().contains("needs a depth map"), "{e}");
}
