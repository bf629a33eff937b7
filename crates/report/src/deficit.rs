//! The DriveLM-Deficit evaluation's section (`fogline rco eval`, the LLM-RCO paper's figure
//! 6): the tables of `eval.md` — the hazard inference prompt's object, motion and strategy
//! accuracy per hidden class, motion label and expert strategy; the strategy the planning
//! prompt's answer carries out; the latency per prompt — and a small gallery of samples:
//! their frames inline (PNG `data:` URLs, `fogline_io::encode` and `fogline_io::data_url`,
//! as the frames go to a language model), the expert's labels and the backend's answers.
//!
//! The result is read through its one typed definition,
//! [`fogline_rco::deficit_eval::DeficitEval`] ([`deficit_eval_from_json`] names the field at
//! fault), and checked ([`check_deficit_eval`]). The gallery's frames are handed in as
//! pixels ([`GalleryFrame`]); which samples to show is [`pick_gallery`]'s deterministic
//! choice. [`section`] gives the `<section>` (the envelope report includes it when given one,
//! [`crate::ReportInput::with_deficit`]); [`render_page`] a page of its own.
//!
//! ```
//! use fogline_report::deficit::{DeficitSection, pick_gallery, render_page};
//! # fn eval() -> fogline_report::deficit::DeficitEval {
//! #     serde_json::from_str(include_str!("../tests/data/deficit_eval.json")).unwrap()
//! # }
//! let e = eval(); // serde_json::from_str(&std::fs::read_to_string("eval/eval.json")?)?
//! assert!(pick_gallery(&e, 4).len() <= 4);
//! let page = render_page(&DeficitSection::new(e, Vec::new()).unwrap(), None).unwrap();
//! assert!(page.contains("id=\"table-deficit-class\""));
//! ```

use std::fmt::Write as _;

use fogline_rco::Strategy;
pub use fogline_rco::deficit_eval::{
    DeficitEval, EvalRow, HiddenClass, Latency, Rate, SampleAnswer,
};

use crate::draw::{esc, fixed};
use crate::error::{ReportError, Result};
use crate::tables::Table;

/// One frame of a gallery sample: RGB8 pixels, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct GalleryFrame {
    /// The camera (`cross_left`, `front_wide`, `cross_right`).
    pub camera: String,
    /// Its time relative to the sample's last frame, s (`-4` … `0`).
    pub t_s: f64,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// `width × height × 3` bytes.
    pub rgb: Vec<u8>,
}

/// A sample shown in the gallery: its frames and the expert's rationale; its labels and
/// the backend's answers come from the evaluation's answer of the same `id`.
#[derive(Debug, Clone, PartialEq)]
pub struct GallerySample {
    /// The sample's id (an answer of the evaluation).
    pub id: String,
    /// The expert's strategy rationale, if known.
    pub expert_rationale: Option<String>,
    /// Its frames, in the order shown: grouped by camera, oldest first.
    pub frames: Vec<GalleryFrame>,
}

/// What the section shows: the evaluation and the gallery.
#[derive(Debug, Clone, PartialEq)]
pub struct DeficitSection {
    /// The evaluation (`eval.json`).
    pub eval: DeficitEval,
    /// The samples of the gallery (possibly none).
    pub gallery: Vec<GallerySample>,
}

impl DeficitSection {
    /// Checks the evaluation ([`check_deficit_eval`]) and the gallery: every sample is one
    /// of the evaluation's answers, every frame's pixel count matches its size.
    pub fn new(eval: DeficitEval, gallery: Vec<GallerySample>) -> Result<Self> {
        check_deficit_eval(&eval)?;
        for g in &gallery {
            if !eval.answers.iter().any(|a| a.id == g.id) {
                return Err(ReportError::Invalid {
                    what: format!("gallery sample {}", g.id),
                    reason: "not among the evaluation's answers".into(),
                });
            }
            for f in &g.frames {
                let want = f.width as usize * f.height as usize * 3;
                if f.width == 0 || f.height == 0 || f.rgb.len() != want || !f.t_s.is_finite() {
                    return Err(ReportError::Invalid {
                        what: format!("gallery sample {} frame {} t={} s", g.id, f.camera, f.t_s),
                        reason: format!(
                            "{} bytes for {}x{} px, expected {want} (RGB8) and a finite time",
                            f.rgb.len(),
                            f.width,
                            f.height
                        ),
                    });
                }
            }
        }
        Ok(Self { eval, gallery })
    }
}

/// Reads an `eval.json` through its one typed definition and checks it; `what` names the
/// document in errors, which name the field at fault.
pub fn deficit_eval_from_json(text: &str, what: &str) -> Result<DeficitEval> {
    let de = &mut serde_json::Deserializer::from_str(text);
    let e: DeficitEval = serde_path_to_error::deserialize(de).map_err(|e| ReportError::Schema {
        what: what.to_string(),
        path: e.path().to_string(),
        source: e.into_inner(),
    })?;
    check_deficit_eval(&e).map_err(|err| match err {
        ReportError::Invalid {
            what: field,
            reason,
        } => ReportError::Invalid {
            what: format!("{what}: {field}"),
            reason,
        },
        other => other,
    })?;
    Ok(e)
}

/// What the section relies on: the format tag, a version it reads, proportions within
/// [0, 1] with `hits ≤ n`, finite non-negative latencies, one answer per sample.
pub fn check_deficit_eval(e: &DeficitEval) -> Result<()> {
    let bad = |what: String, reason: String| Err(ReportError::Invalid { what, reason });
    if e.format != DeficitEval::FORMAT {
        return bad(
            "format".into(),
            format!("expected {:?}, got {:?}", DeficitEval::FORMAT, e.format),
        );
    }
    if !(1..=DeficitEval::VERSION).contains(&e.version) {
        return bad(
            "version".into(),
            format!(
                "version {} is not supported (this report reads 1 to {})",
                e.version,
                DeficitEval::VERSION
            ),
        );
    }
    if e.answers.len() as u64 != e.samples {
        return bad(
            "answers".into(),
            format!("{} answers for {} samples", e.answers.len(), e.samples),
        );
    }
    let groups = [
        ("by_class", &e.by_class),
        ("by_motion", &e.by_motion),
        ("by_strategy", &e.by_strategy),
    ];
    let rows = std::iter::once(("overall".to_string(), &e.overall)).chain(groups.iter().flat_map(
        |(name, rows)| {
            rows.iter()
                .enumerate()
                .map(move |(i, r)| (format!("{name}[{i}]"), r))
        },
    ));
    for (path, r) in rows {
        for (field, rate) in rate_fields(r) {
            let unit = |v: Option<f64>| v.is_none_or(|v| v.is_finite() && (0.0..=1.0).contains(&v));
            let ordered = match (rate.ci_low, rate.value, rate.ci_high) {
                (Some(lo), Some(v), Some(hi)) => lo <= v + 1e-12 && v <= hi + 1e-12,
                _ => true,
            };
            if rate.hits > rate.n
                || !unit(rate.value)
                || !unit(rate.ci_low)
                || !unit(rate.ci_high)
                || !ordered
            {
                return bad(
                    format!("{path}.{field}"),
                    format!(
                        "expected hits ≤ n and low ≤ value ≤ high within [0, 1], got {} of {}, {:?} [{:?}, {:?}]",
                        rate.hits, rate.n, rate.value, rate.ci_low, rate.ci_high
                    ),
                );
            }
        }
    }
    let lat = std::iter::once(("latency".to_string(), &e.latency)).chain(
        e.plan_latency
            .iter()
            .enumerate()
            .map(|(i, p)| (format!("plan_latency[{i}].latency"), &p.latency)),
    );
    for (path, l) in lat {
        let ms = [
            l.mean_ms,
            l.ci_low_ms,
            l.ci_high_ms,
            l.p50_ms,
            l.p95_ms,
            l.max_ms,
        ];
        if ms.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return bad(path, "expected finite, non-negative times in ms".into());
        }
    }
    if !(e.elapsed_s.is_finite() && e.elapsed_s >= 0.0) {
        return bad(
            "elapsed_s".into(),
            format!("expected a finite time >= 0, got {}", e.elapsed_s),
        );
    }
    Ok(())
}

fn rate_fields(r: &EvalRow) -> [(&'static str, &Rate); 10] {
    [
        ("object", &r.object),
        ("motion", &r.motion),
        ("strategy", &r.strategy),
        ("move_recall", &r.move_recall),
        ("som_recall", &r.som_recall),
        ("invalid", &r.invalid),
        ("plan_strategy", &r.plan_strategy),
        ("plan_move_recall", &r.plan_move_recall),
        ("plan_som_recall", &r.plan_som_recall),
        ("plan_invalid", &r.plan_invalid),
    ]
}

/// Whether a sample's answers are right on every task asked (object, motion, strategy and,
/// when the evaluation has the planning prompt, the plan's strategy).
fn all_right(a: &SampleAnswer, planned: bool) -> bool {
    a.object_ok && a.motion_ok && a.strategy_ok && (a.plan_ok || !planned)
}

/// The gallery's samples, as indices into `e.answers`, at most `n`: per hidden class (the
/// paper's order), first the first sample answered wrongly on some task (or invalid), then
/// the first answered right on all; round by round until `n`. Deterministic.
pub fn pick_gallery(e: &DeficitEval, n: usize) -> Vec<usize> {
    let planned = e.version >= 2;
    let mut out = Vec::new();
    for wrong in [true, false] {
        for c in HiddenClass::ALL {
            if out.len() >= n {
                return out;
            }
            if let Some(i) = e
                .answers
                .iter()
                .position(|a| a.class == c && all_right(a, planned) != wrong)
            {
                out.push(i);
            }
        }
    }
    out
}

fn cell(r: &Rate) -> String {
    match (r.value, r.ci_low, r.ci_high) {
        (Some(v), Some(lo), Some(hi)) => format!(
            "{}&nbsp;<span class=\"ci\">[{}, {}]</span>",
            fixed(v * 100.0, 1),
            fixed(lo * 100.0, 1),
            fixed(hi * 100.0, 1)
        ),
        _ => "–".into(),
    }
}

/// The row groups: per hidden class (with all samples), per motion label, per expert
/// strategy.
fn groups(e: &DeficitEval) -> [(&'static str, &'static str, Vec<&EvalRow>); 3] {
    let mut by_class: Vec<&EvalRow> = e.by_class.iter().collect();
    by_class.push(&e.overall);
    [
        (
            "class",
            "per hidden class (figure 6a: object; 6b: strategy)",
            by_class,
        ),
        ("motion", "per motion label", e.by_motion.iter().collect()),
        (
            "strategy",
            "per expert strategy",
            e.by_strategy.iter().collect(),
        ),
    ]
}

fn tables(e: &DeficitEval) -> String {
    let mut s = String::new();
    let num = [false, true, true, true, true, true, true, true];
    for (id, title, rows) in groups(e) {
        let mut t = Table::new(
            &format!("table-deficit-{id}"),
            &format!(
                "Hazard inference prompt, {}: accuracy in % [95&nbsp;% Wilson interval].",
                esc(title)
            ),
            &[
                "Group",
                "n",
                "Object",
                "Motion",
                "Strategy",
                "Move recall",
                "Stop-observe-move recall",
                "Invalid",
            ],
            &num,
        );
        for r in &rows {
            t.row(
                &[
                    esc(&r.group),
                    r.samples.to_string(),
                    cell(&r.object),
                    cell(&r.motion),
                    cell(&r.strategy),
                    cell(&r.move_recall),
                    cell(&r.som_recall),
                    cell(&r.invalid),
                ],
                &num,
            );
        }
        s.push_str(&t.finish(""));
    }
    if e.version >= 2 {
        let num = [false, true, true, true, true, true];
        let mut t = Table::new(
            "table-deficit-plan",
            "Planning prompt (the short-term motion planner's, for the strategy hazard inference chose): the strategy the plan carries out at once, in % [95&nbsp;% Wilson interval].",
            &[
                "Group",
                "n",
                "Strategy",
                "Move recall",
                "Stop-observe-move recall",
                "No valid plan",
            ],
            &num,
        );
        for (_, _, rows) in groups(e) {
            for r in rows {
                t.row(
                    &[
                        esc(&r.group),
                        r.samples.to_string(),
                        cell(&r.plan_strategy),
                        cell(&r.plan_move_recall),
                        cell(&r.plan_som_recall),
                        cell(&r.plan_invalid),
                    ],
                    &num,
                );
            }
        }
        s.push_str(&t.finish(
            "A stop-observe-move plan, or a move plan whose first step (verified against the last frame) stops the car, carries out stop-observe-move; no valid plan (no hazard inference to plan from, no answer, an answer the controller rejects, a first step its verifier refuses) counts as wrong.",
        ));
    }
    let num = [false, true, true, true, true, true];
    let mut t = Table::new(
        "table-deficit-latency",
        "Latency per call and prompt, ms.",
        &[
            "Prompt",
            "Calls",
            "Mean [95&nbsp;% CI]",
            "Median",
            "p95",
            "Max",
        ],
        &num,
    );
    let mut lat = vec![("hazard_inference", &e.latency)];
    lat.extend(
        e.plan_latency
            .iter()
            .map(|p| (p.prompt.as_str(), &p.latency)),
    );
    for (prompt, l) in lat {
        t.row(
            &[
                format!("<code>{}</code>", esc(prompt)),
                l.calls.to_string(),
                format!(
                    "{} [{}, {}]",
                    fixed(l.mean_ms, 2),
                    fixed(l.ci_low_ms, 2),
                    fixed(l.ci_high_ms, 2)
                ),
                fixed(l.p50_ms, 2),
                fixed(l.p95_ms, 2),
                fixed(l.max_ms, 2),
            ],
            &num,
        );
    }
    s.push_str(&t.finish(&format!(
        "Evaluation wall time {} s.",
        fixed(e.elapsed_s, 1)
    )));
    s
}

fn mark(ok: bool) -> &'static str {
    if ok {
        "<span class=\"ok\" title=\"right\">✓</span>"
    } else {
        "<span class=\"bad\" title=\"wrong\">✗</span>"
    }
}

fn opt(s: Option<&str>) -> String {
    s.map_or("—".into(), esc)
}

fn strategy_name(s: Option<Strategy>) -> &'static str {
    s.map_or("—", Strategy::name)
}

fn gallery_sample(g: &GallerySample, a: &SampleAnswer, planned: bool) -> Result<String> {
    let mut s = String::new();
    let _ = writeln!(s, "<figure class=\"sample\" id=\"sample-{}\">", esc(&g.id));
    // Frames: one row per camera, oldest first.
    let mut cameras: Vec<&str> = Vec::new();
    for f in &g.frames {
        if !cameras.contains(&f.camera.as_str()) {
            cameras.push(&f.camera);
        }
    }
    s.push_str("<div class=\"frames\">\n");
    if let Some(first) = cameras.first() {
        s.push_str("<div class=\"frame-row times\"><span></span>");
        for f in g.frames.iter().filter(|f| f.camera == *first) {
            let _ = write!(s, "<span>t = {} s</span>", fixed(f.t_s, 0));
        }
        s.push_str("</div>\n");
    }
    for cam in cameras {
        let _ = write!(
            s,
            "<div class=\"frame-row\"><span class=\"cam\">{}</span>",
            esc(cam)
        );
        for f in g.frames.iter().filter(|f| f.camera == cam) {
            let png = fogline_io::encode(&f.rgb, f.width, f.height, fogline_io::ImageFormat::Png)
                .map_err(|reason| ReportError::Invalid {
                what: format!("gallery sample {} frame {} t={} s", g.id, f.camera, f.t_s),
                reason,
            })?;
            let _ = write!(
                s,
                "<img src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{} camera, t = {} s\" title=\"{} camera, t = {} s\">",
                fogline_io::data_url(&png, fogline_io::ImageFormat::Png),
                f.width,
                f.height,
                esc(cam),
                fixed(f.t_s, 0),
                esc(cam),
                fixed(f.t_s, 0)
            );
        }
        s.push_str("</div>\n");
    }
    s.push_str("</div>\n");
    let _ = writeln!(
        s,
        "<figcaption>Sample <code>{}</code> (oldest frame left, the hidden object behind the black region with the red outline).</figcaption>",
        esc(&g.id)
    );
    let mut t = String::from(
        "<table class=\"answers\"><thead><tr><th scope=\"col\">Task</th><th scope=\"col\">Expert</th><th scope=\"col\">Backend</th><th scope=\"col\"></th></tr></thead>\n<tbody>\n",
    );
    let mut row = |task: &str, expert: String, backend: String, ok: bool| {
        let _ = writeln!(
            t,
            "<tr><th scope=\"row\">{task}</th><td>{expert}</td><td>{backend}</td><td>{}</td></tr>",
            mark(ok)
        );
    };
    row(
        "Object",
        esc(a.class.name()),
        opt(a.answer_object.as_deref()),
        a.object_ok,
    );
    row(
        "Motion",
        esc(a.motion.name()),
        opt(a.answer_motion.as_deref()),
        a.motion_ok,
    );
    row(
        "Strategy (hazard inference)",
        format!(
            "{}{}",
            esc(a.strategy.name()),
            g.expert_rationale
                .as_deref()
                .map_or(String::new(), |r| format!(
                    "<br><span class=\"why\">{}</span>",
                    esc(r)
                ))
        ),
        match (&a.invalid, a.answer_strategy) {
            (Some(why), _) => format!("<span class=\"bad\">invalid</span>: {}", esc(why)),
            (None, s) => format!(
                "{}{}",
                strategy_name(s),
                a.answer_rationale
                    .as_deref()
                    .map_or(String::new(), |r| format!(
                        "<br><span class=\"why\">{}</span>",
                        esc(r)
                    ))
            ),
        },
        a.strategy_ok,
    );
    if planned {
        row(
            "Strategy (planning)",
            esc(a.strategy.name()),
            match (&a.plan_invalid, a.plan_strategy) {
                (Some(why), _) => format!(
                    "{}<span class=\"bad\">no valid plan</span>: {}",
                    a.plan_prompt
                        .as_deref()
                        .map_or(String::new(), |p| format!("<code>{}</code> ", esc(p))),
                    esc(why)
                ),
                (None, s) => format!(
                    "{}{}{}",
                    strategy_name(s),
                    a.plan_prompt
                        .as_deref()
                        .map_or(String::new(), |p| format!(" (<code>{}</code>)", esc(p))),
                    a.plan_summary.as_deref().map_or(String::new(), |p| format!(
                        "<br><span class=\"why\">{}</span>",
                        esc(p)
                    ))
                ),
            },
            a.plan_ok,
        );
    }
    t.push_str("</tbody></table>\n");
    s.push_str(&t);
    let _ = writeln!(
        s,
        "<p class=\"foot\">Latency: hazard inference {} ms{}.</p>\n</figure>",
        fixed(a.latency_ms, 2),
        a.plan_latency_ms.map_or(String::new(), |ms| format!(
            ", planning {} ms",
            fixed(ms, 2)
        ))
    );
    Ok(s)
}

/// The section's inner HTML (no `<section>` wrapper nor heading): the summary line, the
/// tables, the gallery.
pub fn fragment(d: &DeficitSection) -> Result<String> {
    let e = &d.eval;
    // The fields are public: check what a hand-made section holds as `new` would.
    check_deficit_eval(e)?;
    let planned = e.version >= 2;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<p class=\"meta\">Backend <code>{}</code> · data <code>{}</code> · split <code>{}</code> · {} samples · schema version {}</p>",
        esc(&e.backend),
        esc(&e.data),
        esc(&e.split),
        e.samples,
        e.version
    );
    if !planned {
        s.push_str("<p class=\"note\">This evaluation predates the planning prompt (schema version 1): hazard inference only.</p>\n");
    }
    s.push_str(&tables(e));
    s.push_str("<h3 id=\"deficit-gallery\">Gallery: samples and answers</h3>\n");
    if d.gallery.is_empty() {
        s.push_str("<p class=\"note\">No sample frames were given (the data set directory was not readable, or the gallery is off).</p>\n");
    }
    s.push_str("<div class=\"gallery\">\n");
    for g in &d.gallery {
        let a = e
            .answers
            .iter()
            .find(|a| a.id == g.id)
            .ok_or_else(|| ReportError::Invalid {
                what: format!("gallery sample {}", g.id),
                reason: "not among the evaluation's answers".into(),
            })?;
        s.push_str(&gallery_sample(g, a, planned)?);
    }
    s.push_str("</div>\n");
    Ok(s)
}

/// The `<section id="deficit">` of the report, headed `heading`.
pub fn section(d: &DeficitSection, heading: &str) -> Result<String> {
    Ok(format!(
        "<section id=\"deficit\">\n<h2>{}</h2>\n{}</section>\n",
        esc(heading),
        fragment(d)?
    ))
}

/// A self-contained page of its own (the report's style, no script, no external resource):
/// what `fogline rco eval` writes as `report.html`.
pub fn render_page(d: &DeficitSection, title: Option<&str>) -> Result<String> {
    let title = title.map_or_else(
        || {
            format!(
                "Backbone evaluation on DriveLM-Deficit — {}",
                d.eval.backend
            )
        },
        String::from,
    );
    let mut h = String::with_capacity(64 * 1024);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<meta name=\"generator\" content=\"fogline-report {}\">\n<title>{}</title>\n<style>\n{}</style>\n</head>\n<body>\n<main>\n<header>\n<h1>{}</h1>\n</header>\n",
        env!("CARGO_PKG_VERSION"),
        esc(&title),
        crate::CSS,
        esc(&title)
    );
    h.push_str(&section(
        d,
        "Hazard inference and planning under perception deficits (figure 6)",
    )?);
    let _ = write!(
        h,
        "<footer>Generated by fogline-report {} from <code>eval.json</code> (format {}, version {}). Self-contained: no scripts, no external resources.</footer>\n</main>\n</body>\n</html>\n",
        env!("CARGO_PKG_VERSION"),
        esc(&d.eval.format),
        d.eval.version
    );
    Ok(h)
}
