//! What to generate: resolution, seed and the scenario mix of a corpus.

use crate::error::WorldError;
use fogline_types::scenario::{OTHER, PAPER_CLASSES};
use serde::{Deserialize, Serialize};

/// The clip counts of the envelope paper's 1,996-clip corpus, in [`SCENARIOS`] order.
pub const PAPER_COUNTS: [usize; 8] = [213, 7, 475, 177, 40, 302, 344, 438];

/// The scenario labels the world can generate: the paper's seven classes, then `OTHER`.
pub const SCENARIOS: [&str; 8] = [
    PAPER_CLASSES[0],
    PAPER_CLASSES[1],
    PAPER_CLASSES[2],
    PAPER_CLASSES[3],
    PAPER_CLASSES[4],
    PAPER_CLASSES[5],
    PAPER_CLASSES[6],
    OTHER,
];

/// Largest image size the renderer accepts.
pub const MAX_WIDTH: u32 = 1920;
/// Largest image size the renderer accepts.
pub const MAX_HEIGHT: u32 = 1080;

/// How many clips of each scenario a corpus holds.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ScenarioMix {
    /// `(scenario, count)`, in generation order.
    pub counts: Vec<(String, usize)>,
}

impl ScenarioMix {
    /// The paper's mix: 213 / 7 / 475 / 177 / 40 / 302 / 344 / 438 (1,996 clips).
    pub fn paper() -> Self {
        Self {
            counts: SCENARIOS
                .iter()
                .zip(PAPER_COUNTS)
                .map(|(s, n)| (s.to_string(), n))
                .collect(),
        }
    }

    /// The paper's proportions scaled to `total` clips (largest remainder; every scenario
    /// gets at least one clip when `total >= 8`).
    pub fn paper_scaled(total: usize) -> Self {
        let sum: usize = PAPER_COUNTS.iter().sum();
        let mut counts: Vec<usize> = PAPER_COUNTS.iter().map(|n| n * total / sum).collect();
        if total >= SCENARIOS.len() {
            for c in counts.iter_mut() {
                *c = (*c).max(1);
            }
        }
        // Hand out (or take back) the remainder by the largest fractional parts.
        let mut order: Vec<usize> = (0..SCENARIOS.len()).collect();
        order.sort_by_key(|&i| std::cmp::Reverse((PAPER_COUNTS[i] * total) % sum));
        let mut assigned: usize = counts.iter().sum();
        let mut k = 0;
        while assigned < total {
            counts[order[k % order.len()]] += 1;
            assigned += 1;
            k += 1;
        }
        let mut k = 0;
        while assigned > total {
            let i = order[order.len() - 1 - (k % order.len())];
            if counts[i] > 1 {
                counts[i] -= 1;
                assigned -= 1;
            }
            k += 1;
        }
        Self {
            counts: SCENARIOS
                .iter()
                .zip(counts)
                .map(|(s, n)| (s.to_string(), n))
                .collect(),
        }
    }

    /// `n` clips of each scenario.
    pub fn uniform(n: usize) -> Self {
        Self {
            counts: SCENARIOS.iter().map(|s| (s.to_string(), n)).collect(),
        }
    }

    /// Only `scenario`, `n` clips.
    pub fn only(scenario: &str, n: usize) -> Result<Self, WorldError> {
        check_scenario(scenario)?;
        Ok(Self {
            counts: vec![(scenario.to_string(), n)],
        })
    }

    /// `total` clips spread evenly over the eight scenarios (the first ones get the
    /// remainder): the CLI's `--mix uniform`.
    pub fn spread(total: usize) -> Self {
        let n = SCENARIOS.len();
        Self {
            counts: SCENARIOS
                .iter()
                .enumerate()
                .map(|(i, s)| (s.to_string(), total / n + usize::from(i < total % n)))
                .collect(),
        }
    }

    /// Total clips.
    pub fn total(&self) -> usize {
        self.counts.iter().map(|(_, n)| n).sum()
    }

    /// The scenario of clip `index` (clips are numbered through the mix in order).
    pub fn scenario_of(&self, index: usize) -> Option<&str> {
        let mut i = index;
        for (s, n) in &self.counts {
            if i < *n {
                return Some(s);
            }
            i -= n;
        }
        None
    }

    /// Checks every label is one the world can generate.
    pub fn validate(&self) -> Result<(), WorldError> {
        self.counts.iter().try_for_each(|(s, _)| check_scenario(s))
    }
}

fn check_scenario(s: &str) -> Result<(), WorldError> {
    if SCENARIOS.contains(&s) {
        Ok(())
    } else {
        Err(WorldError::invalid(
            "scenario",
            s,
            format!("one of {}", SCENARIOS.join(", ")),
        ))
    }
}

/// A corpus to generate: the seed, the image size and the scenario mix.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldConfig {
    /// The corpus seed: clip `i` draws everything from `child(seed, [i])`.
    pub seed: u64,
    /// Image width of every camera, px (default 576).
    pub width: u32,
    /// Image height of every camera, px (default 320).
    pub height: u32,
    /// Render depth maps (default true; fog by Koschmieder's law needs them).
    pub depth: bool,
    /// The scenario mix.
    pub mix: ScenarioMix,
}

impl Default for WorldConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            width: 576,
            height: 320,
            depth: true,
            mix: ScenarioMix::paper(),
        }
    }
}

impl WorldConfig {
    /// Checks the image size (16×16 up to 1920×1080) and the mix.
    pub fn validate(&self) -> Result<(), WorldError> {
        if !(16..=MAX_WIDTH).contains(&self.width) {
            return Err(WorldError::invalid(
                "width",
                self.width,
                format!("16..={MAX_WIDTH} pixels"),
            ));
        }
        if !(16..=MAX_HEIGHT).contains(&self.height) {
            return Err(WorldError::invalid(
                "height",
                self.height,
                format!("16..={MAX_HEIGHT} pixels"),
            ));
        }
        self.mix.validate()
    }

    /// The id of clip `index`: `<scenario in lower case>_<index, 5 digits>`.
    pub fn clip_id(&self, index: usize) -> Option<String> {
        self.mix
            .scenario_of(index)
            .map(|s| format!("{}_{index:05}", s.to_ascii_lowercase()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_mix_sums_to_1996_and_scales() {
        assert_eq!(ScenarioMix::paper().total(), 1996);
        for n in [8, 9, 50, 200, 1996, 5000] {
            let m = ScenarioMix::paper_scaled(n);
            assert_eq!(m.total(), n, "{n}");
            assert!(m.counts.iter().all(|(_, c)| *c >= 1));
        }
        assert_eq!(ScenarioMix::paper_scaled(1996), ScenarioMix::paper());
        let m = ScenarioMix::paper();
        assert_eq!(m.scenario_of(0), Some("LANE_KEEPING"));
        assert_eq!(m.scenario_of(213), Some("NUDGE_RIGHT"));
        assert_eq!(m.scenario_of(1995), Some("OTHER"));
        assert_eq!(m.scenario_of(1996), None);
    }

    #[test]
    fn bad_config_is_refused() {
        let c = WorldConfig {
            width: 4000,
            ..WorldConfig::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("width"));
        assert!(ScenarioMix::only("PARKING", 3).is_err());
    }
}
