//! The fixed input of the snapshot and browser tests, and corpora built on purpose.

use std::path::PathBuf;

use fogline_envelope::input::{ReadOptions, RowRef, table_from_rows};
use fogline_envelope::synthetic::{self, SyntheticParams};
use fogline_envelope::{Envelope, EnvelopeParams, PairTable, analyze};
use fogline_report::{ClosedLoop, ReportInput};

/// The crate's directory.
pub fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `tests/data/report_input.json`: an envelope of a 400-clip synthetic corpus (400 bootstrap
/// resamples, π* = 8 %), its changed pairs' L2 and an illustrative closed-loop table. It is
/// committed so that the snapshots depend on the report code only; regenerate it with
/// `FOGLINE_REGENERATE_FIXTURE=1 cargo nextest run -p fogline-report fixture`.
pub fn fixture() -> ReportInput {
    let text = std::fs::read_to_string(crate_dir().join("tests/data/report_input.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Builds the fixture from scratch.
pub fn make_fixture() -> ReportInput {
    let table = synthetic::corpus(&SyntheticParams {
        n_clips: 400,
        seed: 11,
    });
    let env = analyze(
        &table,
        &EnvelopeParams {
            bootstrap: 400,
            restarts: 6,
            seed: 11,
            pi_star: Some(0.08),
            ..EnvelopeParams::default()
        },
    )
    .unwrap();
    ReportInput::from_envelope(&env)
        .unwrap()
        .with_pairs(&table)
        .unwrap()
        .with_closed_loop(closed_loop())
        .unwrap()
}

/// `tests/data/closed_loop.json`: illustrative numbers in the closed-loop contract.
pub fn closed_loop() -> ClosedLoop {
    let text = std::fs::read_to_string(crate_dir().join("tests/data/closed_loop.json")).unwrap();
    fogline_report::closed_loop_from_json(&text, "closed_loop.json").unwrap()
}

/// Small analysis parameters for corpora built on purpose.
pub fn quick_params() -> EnvelopeParams {
    EnvelopeParams {
        bootstrap: 60,
        restarts: 2,
        k_max: 4,
        n_init: 1,
        cv_folds: 0,
        per_scenario_k_max: 3,
        ..EnvelopeParams::default()
    }
}

/// A synthetic corpus with every row passed through `edit` (scenario, condition, ade_clean,
/// ade_attacked, l2, coc_clean, coc_attacked), analysed with `params`.
pub fn edited(
    n_clips: usize,
    params: &EnvelopeParams,
    edit: impl Fn(&str, &str, &mut f64, &mut f64, &mut f64, &str, &mut String),
) -> (PairTable, Envelope) {
    let mut rows = Vec::new();
    synthetic::for_each_row(&SyntheticParams { n_clips, seed: 5 }, |r| {
        let (mut clean, mut attacked, mut l2) = (r.ade_clean, r.ade_attacked, r.l2);
        let mut coc = r.coc_attacked.to_string();
        edit(
            r.scenario,
            r.condition,
            &mut clean,
            &mut attacked,
            &mut l2,
            r.coc_clean,
            &mut coc,
        );
        rows.push((
            format!("c{:05}", r.clip),
            r.scenario.to_string(),
            r.condition,
            clean,
            attacked,
            l2,
            r.coc_clean,
            coc,
        ));
    });
    let table = table_from_rows(
        "edited.csv",
        &ReadOptions::default(),
        rows.iter().map(|r| RowRef {
            clip_id: &r.0,
            scenario: &r.1,
            condition: r.2,
            ade_clean: r.3,
            ade_attacked: r.4,
            l2: r.5,
            coc_clean: r.6,
            coc_attacked: &r.7,
        }),
    )
    .unwrap();
    let env = analyze(&table, params).unwrap();
    (table, env)
}

#[test]
fn fixture_is_readable_and_regenerates_on_request() {
    let path = crate_dir().join("tests/data/report_input.json");
    if std::env::var_os("FOGLINE_REGENERATE_FIXTURE").is_some() {
        let input = make_fixture();
        let text = serde_json::to_string_pretty(&input).unwrap();
        std::fs::write(&path, text + "\n").unwrap();
    }
    let input = fixture();
    assert_eq!(input.envelope.schema_version, 1);
    assert!(
        input
            .changed_l2_m
            .as_ref()
            .is_some_and(|v| v.len() == input.envelope.severity.n_changed)
    );
    assert!(input.closed_loop.is_some());
}
