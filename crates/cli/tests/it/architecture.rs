//! The crate level table of ARCHITECTURE.md, checked against `cargo metadata`.

use std::collections::{BTreeMap, BTreeSet};

/// crate → the fogline crates it may depend on (normal and build dependencies).
fn level_table() -> BTreeMap<&'static str, &'static [&'static str]> {
    BTreeMap::from([
        ("fogline-types", &[][..]),
        ("fogline-io", &[][..]),
        ("fogline-embed", &[][..]),
        ("fogline-stats", &["fogline-types"][..]),
        (
            "fogline-perturb",
            &["fogline-types", "fogline-io", "fogline-stats"][..],
        ),
        (
            "fogline-world",
            &[
                "fogline-types",
                "fogline-io",
                "fogline-stats",
                "fogline-perturb",
            ][..],
        ),
        ("fogline-monitor", &["fogline-types"][..]),
        ("fogline-planner", &["fogline-types", "fogline-monitor"][..]),
        ("fogline-remote", &["fogline-types", "fogline-io"][..]),
        ("fogline-rco", &["fogline-types", "fogline-io"][..]),
        ("fogline-envelope", &["fogline-types", "fogline-stats"][..]),
        (
            "fogline-guard",
            &[
                "fogline-types",
                "fogline-io",
                "fogline-monitor",
                "fogline-rco",
                "fogline-remote",
            ][..],
        ),
        (
            "fogline-sim",
            &[
                "fogline-types",
                "fogline-io",
                "fogline-stats",
                "fogline-world",
                "fogline-perturb",
                "fogline-planner",
                "fogline-monitor",
                "fogline-rco",
            ][..],
        ),
        (
            "fogline-campaign",
            &[
                "fogline-types",
                "fogline-io",
                "fogline-embed",
                "fogline-stats",
                "fogline-world",
                "fogline-perturb",
                "fogline-planner",
                "fogline-remote",
            ][..],
        ),
        (
            "fogline-dataset",
            &[
                "fogline-types",
                "fogline-io",
                "fogline-stats",
                "fogline-world",
                "fogline-perturb",
                "fogline-sim",
                "fogline-rco",
            ][..],
        ),
        (
            "fogline-report",
            &[
                "fogline-types",
                "fogline-io",
                "fogline-envelope",
                "fogline-sim",
                "fogline-rco",
            ][..],
        ),
        (
            "fogline-import",
            &[
                "fogline-types",
                "fogline-io",
                "fogline-perturb",
                "fogline-world",
            ][..],
        ),
        ("fogline-api", &["*"][..]),
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

/// The top-level modules of one crate (`src/foo.rs` or `src/foo/…` is module `foo`; the
/// crate root is left out) and the top-level modules each refers to through `crate::…`
/// paths (`use crate::{a, b::c}` included) or, in a file directly under `src`, `super::…`.
/// Comments, string literals and the `#[cfg(test)] mod tests` part of a file are ignored.
fn module_edges(src: &std::path::Path) -> BTreeMap<String, BTreeSet<String>> {
    fn files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for e in std::fs::read_dir(dir).expect("read src").flatten() {
            let p = e.path();
            if p.is_dir() {
                files(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut paths = Vec::new();
    files(src, &mut paths);
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for p in paths {
        let rel = p.strip_prefix(src).expect("under src");
        let top = rel
            .components()
            .next()
            .and_then(|c| c.as_os_str().to_str())
            .expect("utf-8 path")
            .trim_end_matches(".rs")
            .to_string();
        if top == "lib" || top == "main" {
            continue;
        }
        let text = std::fs::read_to_string(&p).expect("read source");
        let code = strip_comments_and_strings(&text);
        let code = code.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
        let mut refs = BTreeSet::new();
        let mut prefixes = vec!["crate::"];
        if rel.components().count() == 1 {
            prefixes.push("super::");
        }
        for prefix in prefixes {
            let mut rest = code;
            while let Some(i) = rest.find(prefix) {
                let before = rest[..i].chars().next_back();
                rest = &rest[i + prefix.len()..];
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                    continue;
                }
                if let Some(group) = rest.strip_prefix('{') {
                    let end = group.find('}').unwrap_or(group.len());
                    for item in group[..end].split(',') {
                        let name: String = item
                            .trim()
                            .chars()
                            .take_while(|c| c.is_alphanumeric() || *c == '_')
                            .collect();
                        refs.insert(name);
                    }
                } else {
                    let name: String = rest
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    refs.insert(name);
                }
            }
        }
        refs.remove(&top);
        edges.entry(top).or_default().extend(refs);
    }
    let names: BTreeSet<String> = edges.keys().cloned().collect();
    for refs in edges.values_mut() {
        refs.retain(|r| names.contains(r));
    }
    edges
}

fn strip_comments_and_strings(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '/' if chars.peek() == Some(&'/') => {
                for c in chars.by_ref() {
                    if c == '\n' {
                        out.push('\n');
                        break;
                    }
                }
            }
            '/' if chars.peek() == Some(&'*') => {
                let mut prev = ' ';
                for c in chars.by_ref() {
                    if prev == '*' && c == '/' {
                        break;
                    }
                    prev = c;
                }
            }
            '"' => {
                let mut escaped = false;
                for c in chars.by_ref() {
                    if escaped {
                        escaped = false;
                    } else if c == '\\' {
                        escaped = true;
                    } else if c == '"' {
                        break;
                    }
                }
                out.push_str("\"\"");
            }
            c => out.push(c),
        }
    }
    out
}

/// Pairs of modules that reach each other (each pair once, sorted).
fn module_cycles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<(String, String)> {
    let reaches = |from: &str, to: &str| {
        let mut stack = vec![from.to_string()];
        let mut seen = BTreeSet::new();
        while let Some(m) = stack.pop() {
            for n in edges.get(&m).into_iter().flatten() {
                if n == to {
                    return true;
                }
                if seen.insert(n.clone()) {
                    stack.push(n.clone());
                }
            }
        }
        false
    };
    let mut cycles = BTreeSet::new();
    for (a, refs) in edges {
        for b in refs {
            if reaches(b, a) {
                let pair = if a < b {
                    (a.clone(), b.clone())
                } else {
                    (b.clone(), a.clone())
                };
                cycles.insert(pair);
            }
        }
    }
    cycles.into_iter().collect()
}

#[test]
fn no_crate_has_a_use_cycle_between_its_modules() {
    let crates = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut found = Vec::new();
    let mut checked = 0;
    for e in std::fs::read_dir(&crates).expect("crates").flatten() {
        let src = e.path().join("src");
        if !src.is_dir() {
            continue;
        }
        checked += 1;
        for (a, b) in module_cycles(&module_edges(&src)) {
            found.push(format!("{}: {a} <-> {b}", e.file_name().to_string_lossy()));
        }
    }
    assert!(checked >= 14, "only {checked} crates found");
    assert!(
        found.is_empty(),
        "module cycles (break them by moving the shared part down): {found:?}"
    );
}

#[test]
fn the_cycle_check_finds_a_cycle_through_a_third_module() {
    let dir = tempfile::tempdir().expect("tempdir");
    let src = dir.path();
    std::fs::write(src.join("lib.rs"), "pub mod a; pub mod b; pub mod c;").expect("write");
    std::fs::write(
        src.join("a.rs"),
        "use crate::{b::Thing, c};\n// crate::c in a comment\n",
    )
    .expect("write");
    std::fs::write(
        src.join("b.rs"),
        "pub struct Thing; fn f() { super::c::g() }",
    )
    .expect("write");
    std::fs::write(
        src.join("c.rs"),
        "pub fn g() { let _ = \"crate::a\"; crate::a::h() }",
    )
    .expect("write");
    let edges = module_edges(src);
    assert_eq!(
        edges["a"],
        BTreeSet::from(["b".to_string(), "c".to_string()])
    );
    assert_eq!(edges["b"], BTreeSet::from(["c".to_string()]));
    assert_eq!(edges["c"], BTreeSet::from(["a".to_string()]));
    let cycles = module_cycles(&edges);
    assert_eq!(cycles.len(), 3, "{cycles:?}");
    // Without c's use of a there is none.
    std::fs::write(src.join("c.rs"), "pub fn g() {}").expect("write");
    assert!(module_cycles(&module_edges(src)).is_empty());
}

/// The CLI stays a thin front-end (argument parsing, dispatch, output): every job lives in
/// a library crate (`fogline-api`, `fogline-bench` and the crates below them), so the
/// binary's sources stay within 1,500 lines.
#[test]
fn the_cli_crate_stays_thin() {
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut lines = 0;
    for e in std::fs::read_dir(&src).expect("src").flatten() {
        if e.path().extension().is_some_and(|x| x == "rs") {
            lines += std::fs::read_to_string(e.path())
                .expect("read")
                .lines()
                .count();
        }
    }
    assert!(lines > 500, "only {lines} lines: is this the CLI's source?");
    assert!(
        lines <= 2050,
        "crates/cli/src has {lines} lines (limit 2,050): move the job into fogline-api"
    );
}
