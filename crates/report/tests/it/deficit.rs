//! The DriveLM-Deficit section: the figure-6 tables and the gallery on the page (its frames
//! inline, the expert's labels and the backend's answers), in a page of its own and inside
//! the envelope report; bad input is refused with the field named.
//!
//! `tests/data/deficit_eval.json` is the `eval.json` of `fogline dataset deficit --samples 8
//! --seed 7` and `fogline rco eval --split all` (rules backend), with `data` set to
//! `deficit`.

use base64::Engine as _;
use fogline_report::deficit::{
    DeficitEval, DeficitSection, GalleryFrame, GallerySample, deficit_eval_from_json, pick_gallery,
    render_page,
};
use fogline_report::{ReportError, ReportParams, render};

use crate::fixture::{crate_dir, fixture};

fn eval_text() -> String {
    std::fs::read_to_string(crate_dir().join("tests/data/deficit_eval.json")).unwrap()
}

fn eval() -> DeficitEval {
    deficit_eval_from_json(&eval_text(), "deficit_eval.json").unwrap()
}

/// A frame whose pixels say which sample, camera and time it is.
fn frame(sample: u8, camera: &str, k: u8, w: u32, h: u32) -> GalleryFrame {
    let rgb = (0..w * h)
        .flat_map(|i| [sample * 40, k * 50, (i % 251) as u8])
        .collect();
    GalleryFrame {
        camera: camera.into(),
        t_s: f64::from(k) - 4.0,
        width: w,
        height: h,
        rgb,
    }
}

fn sample(e: &DeficitEval, i: usize) -> GallerySample {
    let mut frames = Vec::new();
    for (cam, w, h) in [
        ("cross_left", 6, 4),
        ("front_wide", 12, 8),
        ("cross_right", 6, 4),
    ] {
        for k in 0..5 {
            frames.push(frame(i as u8, cam, k, w, h));
        }
    }
    GallerySample {
        id: e.answers[i].id.clone(),
        expert_rationale: Some(format!("expert says <{i}>")),
        frames,
    }
}

/// Every `data:` image of the page, decoded.
fn images(html: &str) -> Vec<fogline_io::DecodedRgb> {
    html.split("<img src=\"data:image/png;base64,")
        .skip(1)
        .map(|rest| {
            let b64 = &rest[..rest.find('"').unwrap()];
            let png = base64::engine::general_purpose::STANDARD
                .decode(b64)
                .unwrap();
            fogline_io::decode_rgb(&png).unwrap()
        })
        .collect()
}

#[test]
fn the_gallery_picks_a_wrong_then_a_right_answer_per_class() {
    let e = eval();
    // Answers 0 (light), 1 (sign) and 3 (bicycle) are wrong somewhere, 2 and 5 right on all;
    // no light and no bicycle is right on all four tasks, no pedestrian wrong.
    assert_eq!(pick_gallery(&e, 8), [0, 1, 3, 5, 2]);
    assert_eq!(pick_gallery(&e, 2), [0, 1]);
    assert!(pick_gallery(&e, 0).is_empty());
}

#[test]
fn the_page_holds_the_figure_6_tables_and_the_gallerys_frames() {
    let e = eval();
    let picks = pick_gallery(&e, 4);
    let gallery: Vec<GallerySample> = picks.iter().map(|&i| sample(&e, i)).collect();
    let d = DeficitSection::new(e.clone(), gallery.clone()).unwrap();
    let html = render_page(&d, None).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>") && html.ends_with("</html>\n"));
    for id in [
        "table-deficit-class",
        "table-deficit-motion",
        "table-deficit-strategy",
        "table-deficit-plan",
        "table-deficit-latency",
        "deficit-gallery",
    ] {
        assert!(html.contains(&format!("id=\"{id}\"")), "missing {id}");
    }
    // Figure 6's rows: every class and `all`, with the numbers of eval.json.
    for r in e.by_class.iter().chain([&e.overall]) {
        let v = r.object.value.unwrap() * 100.0;
        let row = format!(
            "<tr><th scope=\"row\">{}</th><td class=\"num\">{}</td><td class=\"num\">{v:.1}&nbsp;",
            r.group, r.samples
        );
        assert!(html.contains(&row), "{row}");
    }
    for prompt in ["hazard_inference", "move_plan", "stop_observe_move_plan"] {
        assert!(html.contains(&format!("<code>{prompt}</code>")), "{prompt}");
    }
    // The gallery: every frame inline, as PNG data URLs carrying exactly its pixels, in order.
    let shown = images(&html);
    let given: Vec<&GalleryFrame> = gallery.iter().flat_map(|g| &g.frames).collect();
    assert_eq!(shown.len(), given.len());
    assert_eq!(shown.len(), 4 * 15);
    for (s, g) in shown.iter().zip(&given) {
        assert_eq!((s.width, s.height, &s.rgb), (g.width, g.height, &g.rgb));
    }
    // Each sample with the expert's labels and the backend's answers, marked right or wrong.
    for g in &gallery {
        let a = e.answers.iter().find(|a| a.id == g.id).unwrap();
        let fig = &html[html.find(&format!("id=\"sample-{}\"", g.id)).unwrap()..];
        let fig = &fig[..fig.find("</figure>").unwrap()];
        assert!(fig.contains(a.class.name()), "{}", g.id);
        assert!(fig.contains(a.motion.name()), "{}", g.id);
        assert!(
            fig.contains(a.answer_object.as_deref().unwrap()),
            "{}",
            g.id
        );
        let summary = a.plan_summary.as_deref().unwrap().replace('&', "&amp;");
        assert!(fig.contains(&summary), "{}: {summary}", g.id);
        // The rationale is text, never markup.
        assert!(fig.contains("expert says &lt;"), "{}", g.id);
        let wrong = fig.matches("title=\"wrong\"").count();
        let expected = [!a.object_ok, !a.motion_ok, !a.strategy_ok, !a.plan_ok]
            .iter()
            .filter(|w| **w)
            .count();
        assert_eq!(wrong, expected, "{}", g.id);
    }
    assert!(!html.contains("NaN") && !html.contains("<script"));
    // Deterministic.
    assert_eq!(render_page(&d, None).unwrap(), html);
}

#[test]
fn the_envelope_report_gains_the_section_numbered_before_the_data() {
    let e = eval();
    let d = DeficitSection::new(e.clone(), vec![sample(&e, 0)]).unwrap();
    let plain = render(&fixture(), &ReportParams::default()).unwrap();
    assert!(!plain.html.contains("id=\"deficit\""));
    assert!(plain.html.contains("<h2>7. Data behind figure 1</h2>"));
    let r = render(&fixture().with_deficit(d), &ReportParams::default()).unwrap();
    assert!(r.html.contains("<section id=\"deficit\">"));
    assert!(r.html.contains(
        "<h2>7. Hazard inference and planning under perception deficits (DriveLM-Deficit)</h2>"
    ));
    assert!(r.html.contains("<h2>8. Data behind figure 1</h2>"));
    assert!(r.html.contains("<a href=\"#deficit\">"));
    assert_eq!(images(&r.html).len(), 15);
    let frag = &r.fragments.iter().find(|(k, _)| k == "deficit").unwrap().1;
    assert!(frag.contains("id=\"table-deficit-class\""));
    // Everything else is the page without the section.
    for (k, v) in &plain.fragments {
        assert_eq!(
            &r.fragments.iter().find(|(id, _)| id == k).unwrap().1,
            v,
            "{k}"
        );
    }
}

#[test]
fn a_version_1_evaluation_has_no_planning_table() {
    let mut v: serde_json::Value = serde_json::from_str(&eval_text()).unwrap();
    v["version"] = 1.into();
    v.as_object_mut().unwrap().remove("plan_latency");
    for a in v["answers"].as_array_mut().unwrap() {
        for k in [
            "plan_prompt",
            "plan_strategy",
            "plan_summary",
            "plan_ok",
            "plan_latency_ms",
        ] {
            a.as_object_mut().unwrap().remove(k);
        }
    }
    let e = deficit_eval_from_json(&v.to_string(), "old.json").unwrap();
    let html = render_page(&DeficitSection::new(e, Vec::new()).unwrap(), None).unwrap();
    assert!(html.contains("id=\"table-deficit-class\""));
    assert!(!html.contains("id=\"table-deficit-plan\""));
    assert!(html.contains("predates the planning prompt"));
    assert!(html.contains("No sample frames were given"));
}

#[test]
fn bad_input_is_refused_with_the_field_named() {
    let good: serde_json::Value = serde_json::from_str(&eval_text()).unwrap();
    let err = |edit: &dyn Fn(&mut serde_json::Value)| -> String {
        let mut v = good.clone();
        edit(&mut v);
        anyhow_like(deficit_eval_from_json(&v.to_string(), "eval.json").unwrap_err())
    };
    let e = err(&|v| v["format"] = "something-else".into());
    assert!(
        e.contains("eval.json: format") && e.contains("fogline-deficit-eval"),
        "{e}"
    );
    let e = err(&|v| v["version"] = 9.into());
    assert!(e.contains("version 9 is not supported"), "{e}");
    let e = err(&|v| v["by_class"][2]["object"]["hits"] = 99.into());
    assert!(e.contains("by_class[2].object"), "{e}");
    let e = err(&|v| v["overall"]["plan_strategy"]["value"] = 1.5.into());
    assert!(e.contains("overall.plan_strategy"), "{e}");
    let e = err(&|v| v["by_motion"][0]["samples"] = "many".into());
    assert!(
        e.contains("eval.json") && e.contains("by_motion[0].samples"),
        "{e}"
    );
    let e = err(&|v| {
        v["answers"].as_array_mut().unwrap().pop();
    });
    assert!(e.contains("7 answers for 8 samples"), "{e}");
    let e = err(&|v| v["latency"]["mean_ms"] = (-1.0).into());
    assert!(e.contains("latency"), "{e}");
    // The gallery: a sample the evaluation does not have, pixels that do not fit the size.
    let ev = eval();
    let mut stranger = sample(&ev, 0);
    stranger.id = "c9999999".into();
    let e = DeficitSection::new(ev.clone(), vec![stranger]).unwrap_err();
    assert!(
        e.to_string()
            .contains("gallery sample c9999999: not among the evaluation's answers"),
        "{e}"
    );
    let mut short = sample(&ev, 1);
    short.frames[6].rgb.pop();
    let e = DeficitSection::new(ev, vec![short])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("gallery sample c0000001 frame front_wide t=-3 s") && e.contains("287 bytes"),
        "{e}"
    );
}

/// The error with its causes, as the CLI prints it.
fn anyhow_like(e: ReportError) -> String {
    let mut s = e.to_string();
    let mut src = std::error::Error::source(&e);
    while let Some(c) = src {
        s.push_str(": ");
        s.push_str(&c.to_string());
        src = c.source();
    }
    s
}
