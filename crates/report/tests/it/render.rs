//! The public API: determinism, the in-memory and on-disk paths agree, errors are useful.

use fogline_report::{ReportError, ReportInput, ReportParams, render};

use crate::fixture::{edited, fixture, quick_params};

#[test]
fn same_input_same_bytes() {
    let input = fixture();
    let a = render(&input, &ReportParams::default()).unwrap();
    let b = render(&input, &ReportParams::default()).unwrap();
    assert_eq!(a.html, b.html);
    assert!(a.html.starts_with("<!DOCTYPE html>"));
    assert!(a.html.ends_with("</html>\n"));
    // FOGLINE_REPORT_DUMP=page.html keeps the fixture's page for a look.
    if let Some(path) = std::env::var_os("FOGLINE_REPORT_DUMP") {
        std::fs::write(path, &a.html).unwrap();
    }
}

#[test]
fn page_is_self_contained() {
    let html = render(&fixture(), &ReportParams::default()).unwrap().html;
    for needle in [
        "<script",
        "<link",
        "<img",
        "<iframe",
        "@import",
        "url(http",
        "src=",
        "href=\"http",
    ] {
        assert!(!html.contains(needle), "the page contains {needle:?}");
    }
    for needle in ["NaN", "inf ", "Infinity", "undefined%"] {
        assert!(!html.contains(needle), "the page contains {needle:?}");
    }
    // Every SVG is an accessible image with a title and a description.
    let svgs = html.matches("<svg ").count();
    assert_eq!(svgs, html.matches("role=\"img\"").count());
    assert_eq!(svgs, html.matches("<desc id=").count());
    assert!(svgs >= 6);
}

#[test]
fn every_figure_and_table_is_on_the_page() {
    let r = render(&fixture(), &ReportParams::default()).unwrap();
    let ids: Vec<&str> = r.figures.iter().map(|f| f.id.as_str()).collect();
    assert_eq!(
        ids,
        ["fig-1", "fig-4", "fig-2a", "fig-2b", "fig-3", "fig-5"]
    );
    assert!(r.figures.iter().all(|f| f.drawn), "{:?}", r.figures);
    for id in [
        "table-1",
        "table-2",
        "table-2-budgets",
        "table-2-families",
        "table-3",
        "table-bic",
        "table-4",
        "table-5",
        "table-5-a1",
        "table-statistics",
        "table-input",
        "table-parameters",
        "table-closed-loop",
        "table-dose",
        "conventions-list",
    ] {
        assert!(r.html.contains(&format!("id=\"{id}\"")), "missing {id}");
    }
    let input = fixture();
    // The checksum, every parameter and every convention are shown.
    for (k, v) in &input.envelope.conventions {
        assert!(
            r.html.contains(&format!("<code>{k}</code>")),
            "convention {k}"
        );
        let escaped = v
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
            .replace('\'', "&#39;");
        assert!(r.html.contains(&escaped), "convention text {k}");
    }
    let params = serde_json::to_value(&input.envelope.parameters).unwrap();
    for k in params.as_object().unwrap().keys() {
        assert!(
            r.html.contains(&format!("<code>{k}</code>")),
            "parameter {k}"
        );
    }
}

#[test]
fn summary_names_looser_tighter_severe_and_acceptance() {
    let r = render(&fixture(), &ReportParams::default()).unwrap();
    let summary = &r.fragments.iter().find(|(k, _)| k == "summary").unwrap().1;
    assert!(summary.contains("<strong>When.</strong>"));
    assert!(summary.contains("<strong>How severely.</strong>"));
    assert!(
        summary.contains("Acceptance against π* = 8.0%"),
        "{summary}"
    );
    let env = fixture().envelope;
    for o in &env.odd {
        if o.severity_group == "severe" {
            assert!(
                summary.contains(&o.scenario),
                "{} is severe but not named",
                o.scenario
            );
        }
    }
}

#[test]
fn in_memory_and_json_paths_agree() {
    let (table, env) = edited(90, &quick_params(), |_, _, _, _, _, _, _| {});
    let json = serde_json::to_string_pretty(&env).unwrap();
    let a = ReportInput::from_envelope(&env)
        .unwrap()
        .with_pairs(&table)
        .unwrap();
    let b = ReportInput::from_envelope_json(&json, "envelope.json")
        .unwrap()
        .with_pairs(&table)
        .unwrap();
    let p = ReportParams::default();
    assert_eq!(render(&a, &p).unwrap().html, render(&b, &p).unwrap().html);
}

#[test]
fn schema_errors_name_the_field() {
    let mut v: serde_json::Value = serde_json::to_value(&fixture().envelope).unwrap();
    v["severity"]["bands"][0]["mean_m"] = serde_json::Value::Null;
    let e = ReportInput::from_envelope_json(&v.to_string(), "e/envelope.json").unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("e/envelope.json") && msg.contains("severity.bands[0].mean_m"),
        "{msg}"
    );
    // A file of another schema version is refused by the envelope's reader ...
    v["schema_version"] = 2.into();
    v["severity"]["bands"][0]["mean_m"] = 1.0.into();
    let e = ReportInput::from_envelope_json(&v.to_string(), "x/envelope.json").unwrap_err();
    assert!(matches!(e, ReportError::Envelope(_)), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("x/envelope.json") && msg.contains("schema_version 2"),
        "{msg}"
    );
    // ... and an in-memory one by the report.
    let mut input = fixture();
    input.envelope.schema_version = 2;
    let e = render(&input, &ReportParams::default()).unwrap_err();
    assert!(
        matches!(
            e,
            ReportError::SchemaVersion {
                found: 2,
                expected: 1
            }
        ),
        "{e}"
    );
}

#[test]
fn malformed_matrices_are_refused() {
    let mut input = fixture();
    input.envelope.joint.counts.pop();
    let e = render(&input, &ReportParams::default()).unwrap_err();
    assert!(e.to_string().contains("joint.counts"), "{e}");
    let json = serde_json::to_string(&input.envelope).unwrap();
    let e = ReportInput::from_envelope_json(&json, "e/envelope.json").unwrap_err();
    assert!(e.to_string().contains("joint.counts"), "{e}");
}

#[test]
fn a_foreign_pairs_table_is_refused() {
    let (table, _) = edited(60, &quick_params(), |_, _, _, _, _, _, _| {});
    let mut input = fixture();
    input.envelope.input.sha256 = "00".repeat(32);
    let mut t2 = table.clone();
    t2.input.sha256 = "11".repeat(32);
    let e = input.clone().with_pairs(&t2).unwrap_err();
    assert!(matches!(e, ReportError::PairsMismatch { .. }), "{e}");
    // Same checksum but other changed pairs: refused too.
    t2.input.sha256 = "00".repeat(32);
    let e = input.with_pairs(&t2).unwrap_err();
    assert!(e.to_string().contains("changed pairs"), "{e}");
}

#[test]
fn parameters_are_validated() {
    let p = ReportParams {
        histogram_bins: 1,
        ..ReportParams::default()
    };
    assert!(matches!(
        render(&fixture(), &p),
        Err(ReportError::InvalidParam {
            name: "histogram_bins",
            ..
        })
    ));
}

#[test]
fn labels_are_escaped() {
    // Labels are user data: they must never become markup.
    let (table, env) = edited(80, &quick_params(), |_, _, _, _, _, _, _| {});
    let mut input = ReportInput::from_envelope(&env)
        .unwrap()
        .with_pairs(&table)
        .unwrap();
    let evil = "<img src=x onerror=alert(1)>";
    input.envelope.corpus.scenarios[0].scenario = evil.into();
    input.envelope.input.path = format!("a\"b{evil}.csv");
    input.envelope.notes.push(evil.into());
    let html = render(&input, &ReportParams::default()).unwrap().html;
    assert!(!html.contains("<img"), "unescaped label");
    assert!(html.contains("&lt;img src=x onerror=alert(1)&gt;"));
}
