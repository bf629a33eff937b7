//! Integration tests of fogline-types.

#![allow(clippy::unwrap_used)]

use fogline_types::{Condition, Family, Taxonomy};

#[test]
fn every_paper_condition_parses_to_its_family() {
    let grid = [
        "noise_10", "noise_30", "noise_50", "noise_70", "dark", "bright", "fog_03", "fog_07",
    ];
    let fams: Vec<Family> = grid
        .iter()
        .map(|n| Condition::parse(n).unwrap().family)
        .collect();
    assert_eq!(
        fams.iter().filter(|f| **f == Family::GaussianNoise).count(),
        4
    );
    assert_eq!(fams.iter().filter(|f| **f == Family::Brightness).count(), 2);
    assert_eq!(fams.iter().filter(|f| **f == Family::Fog).count(), 2);
}

#[test]
fn default_taxonomy_is_the_papers() {
    let t = Taxonomy::default();
    assert_eq!(t.classes.len(), 7);
    assert_eq!(t.other, "OTHER");
}
