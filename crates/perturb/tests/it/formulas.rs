//! Deterministic families against their formulas, pixel by pixel.
//!
//! Expected values are computed here in exact integer arithmetic where the parameters are
//! decimal (gain, homogeneous fog), so the check does not share the implementation's
//! floating-point path.

use fogline_perturb::{
    DepthMap, Frame, FrameInput, FrameKey, ObjectBox, Perturbation, PixelRect, Step,
    params::{FogModel, FogParams},
};

use crate::{apply, ramp};

fn check(name: &str, expect: impl Fn(u32) -> u32) {
    let src = ramp(97, 61);
    let out = apply(name, 0, &src, FrameKey::default());
    for (i, (&o, &j)) in out.data().iter().zip(src.data()).enumerate() {
        assert_eq!(
            u32::from(o),
            expect(u32::from(j)),
            "{name}: sample {i}, J = {j}"
        );
    }
}

#[test]
fn gain_is_round_half_up_of_g_times_j_clipped() {
    // ⌊0.4·J + ½⌋ = ⌊(4J + 5) / 10⌋
    check("dark", |j| (4 * j + 5) / 10);
    check("bright", |j| ((16 * j + 5) / 10).min(255));
    check("gain_1.25", |j| ((125 * j + 50) / 100).min(255));
}

#[test]
fn homogeneous_fog_is_the_blend_with_airlight_204() {
    // ⌊(1 − α)·J + α·204 + ½⌋ with α = 3/10 and 7/10
    check("fog_03", |j| (7 * j + 3 * 204 + 5) / 10);
    check("fog_07", |j| (3 * j + 7 * 204 + 5) / 10);
    check("fog_10", |_| 204);
    check("fog_0.25", |j| (75 * j + 25 * 204 + 50) / 100);
}

#[test]
fn contrast_quantize_saturation_glare_follow_their_formulas() {
    let src = ramp(64, 40);
    let n = src.data().len() as f64;
    let m = src.data().iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let out = apply("contrast_0.4", 0, &src, FrameKey::default());
    for (&o, &j) in out.data().iter().zip(src.data()) {
        let want = (m + 0.4 * (f64::from(j) - m) + 0.5).floor();
        assert_eq!(f64::from(o), want, "J = {j}");
    }
    // 2 bits: levels 0, 85, 170, 255
    let out = apply("quantize_2", 0, &src, FrameKey::default());
    for (&o, &j) in out.data().iter().zip(src.data()) {
        let level = (u32::from(j) * 3 + 127) / 255;
        assert_eq!(u32::from(o), level * 85, "J = {j}");
    }
    let out = apply("saturation_0", 0, &src, FrameKey::default());
    for (o, j) in out.data().chunks(3).zip(src.data().chunks(3)) {
        let l = 0.299 * f64::from(j[0]) + 0.587 * f64::from(j[1]) + 0.114 * f64::from(j[2]);
        let want = (l + 0.5 + 1e-9).floor() as u8;
        assert_eq!(o, [want, want, want], "{j:?}");
    }
    let out = apply("glare_1", 0, &src, FrameKey::default());
    for (i, (o, j)) in out.data().chunks(3).zip(src.data().chunks(3)).enumerate() {
        let (x, y) = ((i % 64) as f64 + 0.5, (i / 64) as f64 + 0.5);
        let rho = 0.15 * (64f64 * 64.0 + 40.0 * 40.0).sqrt();
        let w = (-((x - 0.7 * 64.0).powi(2) + (y - 0.3 * 40.0).powi(2)) / (2.0 * rho * rho)).exp();
        for c in 0..3 {
            let jj = f64::from(j[c]);
            let want = jj + (255.0 - jj) * w + 0.5;
            // exact except within 1e-9 of a rounding boundary (separable evaluation order)
            if (want - want.round()).abs() > 1e-9 {
                assert_eq!(f64::from(o[c]), want.floor().min(255.0), "pixel {i}");
            }
        }
    }
}

#[test]
fn koschmieder_fog_matches_the_double_precision_formula() {
    let (w, h) = (211u32, 97u32);
    let src = ramp(w, h);
    let mut depth: Vec<f32> = (0..w * h)
        .map(|i| (i % 1013) as f32 * 0.37 + (i / 1013) as f32 * 1.3)
        .collect();
    depth[0] = 0.0;
    depth[1] = f32::INFINITY;
    let depth = DepthMap::new(w, h, depth).unwrap();
    let p = Perturbation::parse("fog_07").unwrap().prepare(0).unwrap();
    let input = FrameInput {
        depth: Some(&depth),
        ..FrameInput::new(&src, FrameKey::default())
    };
    let out = p.apply(&input).unwrap().frame;
    let beta = -(0.3f64).ln() / 50.0;
    let (mut near_ties, mut exact) = (0, 0);
    for (i, (&o, &j)) in out.data().iter().zip(src.data()).enumerate() {
        let d = f64::from(depth.depth_m()[i / 3]);
        let t = (-beta * d).exp();
        let v = 204.0 + (f64::from(j) - 204.0) * t;
        let want = (v + 0.5).floor();
        if (v - v.floor() - 0.5).abs() < 1e-3 {
            near_ties += 1;
            assert!((f64::from(o) - want).abs() <= 1.0, "sample {i}");
        } else {
            exact += 1;
            assert_eq!(f64::from(o), want, "sample {i}: d = {d}, J = {j}");
        }
    }
    assert!(
        exact > 60_000 && near_ties < exact / 100,
        "{exact} {near_ties}"
    );
    // Zero distance keeps the pixel; the sky is pure airlight.
    assert_eq!(out.pixel(0, 0), src.pixel(0, 0));
    assert_eq!(out.pixel(1, 0), [204, 204, 204]);
}

#[test]
fn fog_models_choose_by_depth_unless_forced() {
    let src = ramp(16, 8);
    let depth = DepthMap::new(16, 8, vec![10.0; 128]).unwrap();
    let with_depth = |name: &str| {
        Perturbation::parse(name)
            .unwrap()
            .prepare(0)
            .unwrap()
            .apply(&FrameInput {
                depth: Some(&depth),
                ..FrameInput::new(&src, FrameKey::default())
            })
            .unwrap()
            .frame
    };
    let homogeneous = apply("fog_07", 0, &src, FrameKey::default());
    assert_ne!(with_depth("fog_07"), homogeneous);
    let forced = Perturbation::from_steps(vec![Step::Fog(FogParams {
        alpha: 0.7,
        model: FogModel::Homogeneous,
        ..FogParams::default()
    })]);
    let out = forced
        .prepare(0)
        .unwrap()
        .apply(&FrameInput {
            depth: Some(&depth),
            ..FrameInput::new(&src, FrameKey::default())
        })
        .unwrap()
        .frame;
    assert_eq!(out, homogeneous);
    // Visibility V: β = 3.912 / V; at d = V the contrast left is 2 %.
    let grey = Frame::filled(16, 8, [0, 0, 0]).unwrap();
    let vis = DepthMap::new(16, 8, vec![300.0; 128]).unwrap();
    let out = Perturbation::parse("visibility_300")
        .unwrap()
        .prepare(0)
        .unwrap()
        .apply(&FrameInput {
            depth: Some(&vis),
            ..FrameInput::new(&grey, FrameKey::default())
        })
        .unwrap()
        .frame;
    assert_eq!(out.pixel(0, 0), [200, 200, 200]); // 204·(1 − 0.02) = 199.9
}

#[test]
fn deficit_masks_fill_and_outline_the_chosen_boxes() {
    let src = Frame::filled(20, 10, [90, 90, 90]).unwrap();
    let boxes = [
        ObjectBox {
            class: "pedestrian".into(),
            track_id: Some(3),
            x_px: 2.0,
            y_px: 1.0,
            width_px: 6.0,
            height_px: 5.0,
        },
        ObjectBox {
            class: "car".into(),
            track_id: Some(4),
            x_px: 12.0,
            y_px: 2.0,
            width_px: 5.0,
            height_px: 5.0,
        },
    ];
    let p = Perturbation::parse("mask_class_pedestrian")
        .unwrap()
        .prepare(0)
        .unwrap();
    let out = p
        .apply(&FrameInput {
            boxes: &boxes,
            ..FrameInput::new(&src, FrameKey::default())
        })
        .unwrap();
    assert_eq!(out.deficits.len(), 1);
    assert_eq!(
        out.deficits[0].rect,
        PixelRect {
            x0: 2,
            y0: 1,
            x1: 8,
            y1: 6
        }
    );
    assert_eq!(out.deficits[0].track_id, Some(3));
    for y in 0..10 {
        for x in 0..20 {
            let inside = (2..8).contains(&x) && (1..6).contains(&y);
            let border = inside && (!(4..6).contains(&x) || !(3..4).contains(&y));
            let want = if border {
                [255, 0, 0]
            } else if inside {
                [0, 0, 0]
            } else {
                [90, 90, 90]
            };
            assert_eq!(out.frame.pixel(x, y), want, "({x}, {y})");
        }
    }
}
