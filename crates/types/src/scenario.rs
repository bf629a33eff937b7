//! Scenario labels and taxonomies.
//!
//! A scenario is the planning decision a clip requires (LANE_KEEPING, STOP_SIGNAL, …). Any
//! label set works; the envelope paper's seven classes plus `OTHER` are the default
//! [`Taxonomy`]. Labels outside the taxonomy's classes are treated like its "other" label:
//! kept in aggregates, left out of per-scenario analysis.

use serde::{Deserialize, Serialize};

/// The seven scenario classes of the envelope paper, in complexity-rank order (1 = simplest).
pub const PAPER_CLASSES: [&str; 7] = [
    "LANE_KEEPING",
    "NUDGE_RIGHT",
    "FOLLOW_VEHICLE",
    "PASSING",
    "TURN_RIGHT",
    "STOP_SIGNAL",
    "INTERSECTION",
];

/// The label of clips that belong to no classified scenario.
pub const OTHER: &str = "OTHER";

/// An ordered set of classified scenario labels plus the label of unclassified clips.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Taxonomy {
    /// Classified scenario labels, in complexity-rank order (rank = index + 1).
    pub classes: Vec<String>,
    /// The label of unclassified clips (kept in aggregates, left out per scenario).
    pub other: String,
}

impl Default for Taxonomy {
    fn default() -> Self {
        Self::paper()
    }
}

impl Taxonomy {
    /// The envelope paper's seven classes plus `OTHER`.
    pub fn paper() -> Self {
        Self {
            classes: PAPER_CLASSES.iter().map(|s| s.to_string()).collect(),
            other: OTHER.to_string(),
        }
    }

    /// A taxonomy made of the labels found in the data, sorted, with `other` excluded.
    pub fn from_labels<'a>(labels: impl IntoIterator<Item = &'a str>, other: &str) -> Self {
        let mut classes: Vec<String> = labels
            .into_iter()
            .filter(|l| *l != other)
            .map(str::to_string)
            .collect();
        classes.sort();
        classes.dedup();
        Self {
            classes,
            other: other.to_string(),
        }
    }

    /// Whether `label` is one of the classified scenarios.
    pub fn is_classified(&self, label: &str) -> bool {
        self.classes.iter().any(|c| c == label)
    }

    /// The complexity rank (1-based) of a classified label.
    pub fn rank(&self, label: &str) -> Option<usize> {
        self.classes.iter().position(|c| c == label).map(|i| i + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_taxonomy_ranks() {
        let t = Taxonomy::paper();
        assert_eq!(t.rank("LANE_KEEPING"), Some(1));
        assert_eq!(t.rank("INTERSECTION"), Some(7));
        assert_eq!(t.rank("OTHER"), None);
        assert!(!t.is_classified("OTHER"));
    }

    #[test]
    fn taxonomy_from_labels_sorts_and_drops_other() {
        let t = Taxonomy::from_labels(["b", "OTHER", "a", "b"], "OTHER");
        assert_eq!(t.classes, vec!["a", "b"]);
    }
}
