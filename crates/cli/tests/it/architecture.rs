//! The crate level table of ARCHITECTURE.md, checked against `cargo metadata`.

use std::collections::{BTreeMap, BTreeSet};

/// crate → the fogline crates it may depend on (normal and build dependencies).
fn level_table() -> BTreeMap<&'static str, &'static [&'static str]> {
    BTreeMap::from([
        ("fogline-types", &[][..]),
        ("fogline-stats", &["fogline-types"][..]),
        ("fogline-perturb", &["fogline-types", "fogline-stats"][..]),
        (
            "fogline-world",
            &["fogline-types", "fogline-stats", "fogline-perturb"][..],
        ),
        ("fogline-monitor", &["fogline-types"][..]),
        ("fogline-planner", &["fogline-types", "fogline-monitor"][..]),
        ("fogline-remote", &["fogline-types"][..]),
        ("fogline-rco", &["fogline-types"][..]),
        ("fogline-envelope", &["fogline-types", "fogline-stats"][..]),
        (
            "fogline-sim",
            &[
                "fogline-types",
                "fogline-stats",
                "fogline-world",
                "fogline-perturb",
                "fogline-planner",
                "fogline-rco",
            ][..],
        ),
        (
            "fogline-campaign",
            &[
                "fogline-types",
                "fogline-stats",
                "fogline-world",
                "fogline-perturb",
                "fogline-planner",
                "fogline-remote",
            ][..],
        ),
        (
            "fogline-report",
            &["fogline-types", "fogline-envelope", "fogline-sim"][..],
        ),
        ("fogline-cli", &["*"][..]),
        ("fogline-python", &["*"][..]),
        ("fogline-bench", &["*"][..]),
    ])
}

#[test]
fn crates_depend_only_on_lower_levels() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata is JSON");
    let table = level_table();
    let mut seen = BTreeSet::new();
    let mut violations = Vec::new();
    for pkg in meta["packages"].as_array().expect("packages") {
        let name = pkg["name"].as_str().expect("name");
        if !name.starts_with("fogline-") {
            continue;
        }
        seen.insert(name.to_string());
        let allowed = table.get(name).unwrap_or_else(|| {
            panic!("{name} is not in the level table: add it to ARCHITECTURE.md and this test")
        });
        for dep in pkg["dependencies"].as_array().expect("dependencies") {
            let dname = dep["name"].as_str().expect("dep name");
            let kind = dep["kind"].as_str();
            if !dname.starts_with("fogline-") || kind == Some("dev") {
                continue;
            }
            if !allowed.contains(&"*") && !allowed.contains(&dname) {
                violations.push(format!("{name} depends on {dname}"));
            }
        }
    }
    assert!(violations.is_empty(), "level rule broken: {violations:?}");
    for must in [
        "fogline-types",
        "fogline-stats",
        "fogline-envelope",
        "fogline-cli",
    ] {
        assert!(seen.contains(must), "{must} missing from the workspace");
    }
}

#[test]
fn the_level_table_rejects_an_upward_dependency() {
    // The check above must be able to fail: stats may not use envelope.
    let table = level_table();
    assert!(!table["fogline-stats"].contains(&"fogline-envelope"));
    assert!(!table["fogline-planner"].contains(&"fogline-world"));
}
