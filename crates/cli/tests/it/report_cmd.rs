//! `fogline report`, and the report that `fogline envelope` writes beside its outputs.

use std::path::Path;

use crate::{fogline, text};

/// pairs.csv (a synthetic corpus) and `fogline envelope`'s outputs in `dir/envelope`.
fn envelope_dir(dir: &Path, seed: u64) {
    let pairs = dir.join("pairs.csv");
    let mut f = std::fs::File::create(&pairs).unwrap();
    fogline_envelope::synthetic::write_csv(
        &fogline_envelope::synthetic::SyntheticParams { n_clips: 90, seed },
        &mut f,
    )
    .unwrap();
    let o = fogline(&[
        "envelope",
        pairs.to_str().unwrap(),
        "--out",
        dir.join("envelope").to_str().unwrap(),
        "--bootstrap",
        "60",
        "--restarts",
        "2",
        "--k-max",
        "4",
    ]);
    assert!(
        o.status.code() == Some(0) || o.status.code() == Some(1),
        "{}",
        text(&o)
    );
}

#[test]
fn envelope_writes_the_report_and_fogline_report_rebuilds_it() {
    let tmp = tempfile::tempdir().unwrap();
    envelope_dir(tmp.path(), 3);
    let envdir = tmp.path().join("envelope");
    let written = std::fs::read_to_string(envdir.join("report.html")).unwrap();
    assert!(
        written.contains("class=\"hist\""),
        "the histogram uses the pairs table"
    );
    // `fogline report` finds the pairs table at the envelope's input path: the same page.
    let out = tmp.path().join("page.html");
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), written);
    // No temporary file is left behind.
    for e in std::fs::read_dir(tmp.path()).unwrap() {
        let n = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!n.contains(".tmp-"), "{n}");
    }
    // --no-pairs: no histogram, and a note saying so; the title is escaped.
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--no-pairs",
        "--title",
        "T <1>",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(envdir.join("report.html")).unwrap();
    assert!(!html.contains("class=\"hist\"") && html.contains("No histogram"));
    assert!(html.contains("<title>T &lt;1&gt;</title>"));
}

#[test]
fn report_with_closed_loop_and_its_errors() {
    let tmp = tempfile::tempdir().unwrap();
    envelope_dir(tmp.path(), 3);
    let envdir = tmp.path().join("envelope");
    let sim = tmp.path().join("sim");
    std::fs::create_dir_all(&sim).unwrap();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../report/tests/data/closed_loop.json"),
        sim.join("closed_loop.json"),
    )
    .unwrap();
    let out = tmp.path().join("r.html");
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--sim",
        sim.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        std::fs::read_to_string(&out)
            .unwrap()
            .contains("id=\"fig-5\" data-drawn=\"true\"")
    );
    // A missing closed-loop file, a foreign pairs table and a missing envelope are errors.
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--sim",
        tmp.path().to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("closed_loop.json"), "{}", text(&o));
    let other = tmp.path().join("other.csv");
    let mut f = std::fs::File::create(&other).unwrap();
    fogline_envelope::synthetic::write_csv(
        &fogline_envelope::synthetic::SyntheticParams {
            n_clips: 90,
            seed: 4,
        },
        &mut f,
    )
    .unwrap();
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--pairs",
        other.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("is not the envelope's input"),
        "{}",
        text(&o)
    );
    let o = fogline(&["report", tmp.path().to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("envelope.json"), "{}", text(&o));
}

#[test]
fn report_with_the_deficit_evaluation_and_its_errors() {
    let tmp = tempfile::tempdir().unwrap();
    envelope_dir(tmp.path(), 3);
    let envdir = tmp.path().join("envelope");
    let data = tmp.path().join("deficit");
    let data_s = data.to_str().unwrap();
    let o = fogline(&[
        "-q",
        "dataset",
        "deficit",
        "--samples",
        "8",
        "--seed",
        "7",
        "--out",
        data_s,
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = fogline(&[
        "-q",
        "rco",
        "eval",
        "--data",
        data_s,
        "--split",
        "all",
        "--gallery",
        "2",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let eval_dir = data.join("eval");
    // `rco eval` wrote its own page: the tables and two samples' 15 frames each.
    let own = std::fs::read_to_string(eval_dir.join("report.html")).unwrap();
    assert!(
        own.contains("id=\"table-deficit-class\"") && own.contains("id=\"table-deficit-plan\"")
    );
    assert_eq!(own.matches("<img src=\"data:image/png;base64,").count(), 30);
    // `fogline report --deficit`: the envelope report gains the section, with the gallery.
    let out = tmp.path().join("r.html");
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--deficit",
        eval_dir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(&out).unwrap();
    assert!(html.contains("<section id=\"deficit\">") && html.contains("id=\"fig-1\""));
    let shown = html.matches("<img src=\"data:image/png;base64,").count();
    assert!(shown > 30 && shown.is_multiple_of(15), "{shown} frames");
    // The data set moved with its eval/: the gallery comes from the directory around it.
    let moved = tmp.path().join("moved");
    std::fs::rename(&data, &moved).unwrap();
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--deficit",
        moved.join("eval").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let again = std::fs::read_to_string(&out).unwrap();
    assert_eq!(
        again.matches("<img src=\"data:image/png;base64,").count(),
        shown
    );
    // eval.json alone, its data set nowhere: the section without a gallery, a note saying so.
    let alone = tmp.path().join("alone");
    std::fs::create_dir_all(&alone).unwrap();
    std::fs::copy(moved.join("eval/eval.json"), alone.join("eval.json")).unwrap();
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--deficit",
        alone.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(&out).unwrap();
    assert!(html.contains("No sample frames were given") && !html.contains("<img "));
    assert!(html.contains("id=\"table-deficit-class\""));
    // A broken eval.json or none: exit 2, the file and the field named.
    let bad = tmp.path().join("bad");
    std::fs::create_dir_all(&bad).unwrap();
    let text_of = std::fs::read_to_string(moved.join("eval/eval.json")).unwrap();
    std::fs::write(
        bad.join("eval.json"),
        text_of.replacen("\"samples\": 8", "\"samples\": \"eight\"", 1),
    )
    .unwrap();
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--deficit",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("eval.json") && text(&o).contains("`samples`"),
        "{}",
        text(&o)
    );
    let o = fogline(&[
        "report",
        envdir.to_str().unwrap(),
        "--deficit",
        tmp.path().to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("eval.json"), "{}", text(&o));
}
