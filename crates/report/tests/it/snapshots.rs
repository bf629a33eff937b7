//! Snapshots of every fragment of the page for the committed fixture: byte-stable output.
//! After an intended change, review and update with
//! `UPDATE_SNAPSHOTS=1 cargo nextest run -p fogline-report snapshots`.

use fogline_report::{ReportParams, render};

use crate::fixture::{crate_dir, fixture};

#[test]
fn fragments_match_snapshots() {
    let r = render(&fixture(), &ReportParams::default()).unwrap();
    let dir = crate_dir().join("tests/snapshots");
    let update = std::env::var_os("UPDATE_SNAPSHOTS").is_some();
    let mut failures = Vec::new();
    for (id, html) in &r.fragments {
        if html.is_empty() {
            continue;
        }
        let path = dir.join(format!("{id}.html"));
        if update {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, html).unwrap();
            continue;
        }
        match std::fs::read_to_string(&path) {
            Ok(want) if &want == html => {}
            Ok(want) => {
                let line = want
                    .lines()
                    .zip(html.lines())
                    .position(|(a, b)| a != b)
                    .unwrap_or_else(|| want.lines().count().min(html.lines().count()));
                failures.push(format!(
                    "{id}: differs from {} at line {}:\n  want: {}\n  got:  {}",
                    path.display(),
                    line + 1,
                    want.lines().nth(line).unwrap_or("<end>"),
                    html.lines().nth(line).unwrap_or("<end>")
                ));
            }
            Err(_) => failures.push(format!("{id}: no snapshot at {}", path.display())),
        }
    }
    assert!(
        failures.is_empty(),
        "{}\n(review, then UPDATE_SNAPSHOTS=1 cargo nextest run -p fogline-report snapshots)",
        failures.join("\n")
    );
}
