//! Bad input: invalid suite files, an unreachable LLM endpoint.

use std::io::Write as _;

use fogline_rco::OpenAiParams;
use fogline_sim::SimError;
use fogline_sim::config::{BackendSetup, Config, RcoSetup};
use fogline_sim::experiment::run_experiment;
use fogline_sim::output::markdown;
use fogline_sim::sense::DeficitKind;
use fogline_sim::suite::SuiteParams;

use super::{experiment, tiny_suite};

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.path().join(name);
    let mut f = std::fs::File::create(&p).unwrap();
    f.write_all(text.as_bytes()).unwrap();
    p
}

#[test]
fn invalid_suite_files_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "unknown.toml",
            "towns = 2\nroute_count = 5\n",
            "route_count",
        ),
        ("range.toml", "min_route_m = 50.0\n", "min_route_m"),
        ("zero.toml", "routes_per_town = 0\n", "routes_per_town"),
        (
            "route.toml",
            "towns = 1\n[[routes]]\ntown = 3\nlength_m = 500.0\nweather = \"wet\"\ndaylight = \"noon\"\n",
            "routes[0].town",
        ),
        (
            "weather.toml",
            "[[routes]]\ntown = 0\nlength_m = 500.0\nweather = \"sunny\"\ndaylight = \"noon\"\n",
            "sunny",
        ),
        ("broken.json", "{\"towns\": ", "EOF"),
    ];
    for (name, text, needle) in cases {
        let p = write(&dir, name, text);
        let e = SuiteParams::read(&p).unwrap_err();
        assert!(matches!(e, SimError::Suite { .. }), "{name}: {e}");
        let msg = e.to_string();
        assert!(msg.contains(name), "{name}: {msg}");
        assert!(msg.contains(needle), "{name}: {msg}");
    }
    let missing = dir.path().join("missing.toml");
    let e = SuiteParams::read(&missing).unwrap_err().to_string();
    assert!(
        e.contains("missing.toml") && e.contains("cannot read"),
        "{e}"
    );
    // A valid file reads.
    let ok = write(
        &dir,
        "ok.toml",
        "name = \"mine\"\ntowns = 1\nroutes_per_town = 2\n",
    );
    let p = SuiteParams::read(&ok).unwrap();
    assert_eq!(p.n_routes(), 2);
}

#[test]
fn an_unreachable_llm_endpoint_falls_back_safely_and_says_so() {
    // Port 1 on the loopback: nothing listens there.
    let backend = BackendSetup::Openai(OpenAiParams {
        base_url: "http://127.0.0.1:1".into(),
        timeout_ms: 500,
        ..OpenAiParams::default()
    });
    let config = Config::with_rco(
        DeficitKind::TrafficLight,
        RcoSetup {
            backend,
            ..RcoSetup::default()
        },
    );
    let params = experiment(tiny_suite(1, 150.0), vec![config], 3);
    let results = run_experiment(&params, 1, &|_, _| {}).unwrap();
    assert!(
        results.warnings.iter().any(|w| w.contains("unreachable")),
        "{:?}",
        results.warnings
    );
    let r = &results.records[0];
    let rco = r.rco.as_ref().unwrap();
    assert!(r.takeover_s > 0.0, "the deficit must hand control to RCO");
    assert!(rco.fallbacks_total() > 0, "{rco:?}");
    assert!(rco.first_fallback.is_some());
    let md = markdown(&results);
    assert!(
        md.contains("unreachable") && md.contains("fell back"),
        "{md}"
    );
}
