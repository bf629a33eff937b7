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
