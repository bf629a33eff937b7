//! Scoring a backend's hazard inference and planning on labelled deficit clips
//! (DriveLM-Deficit, the paper's section 5 and figure 6): the label vocabulary, the reading
//! of a free-text answer into it, and [`DeficitEval`], the one typed definition of an
//! evaluation's result (what `fogline rco eval` writes as `eval.json` and any reader — the
//! HTML report, a notebook — reads back).
//!
//! Two prompts are scored per sample, as the controller asks them: hazard inference (object,
//! motion and strategy in one answer) and then the short-term motion planner's prompt for
//! the strategy it chose (`move_plan` or `stop_observe_move_plan`); the plan's strategy is
//! what the controller would do with it at once ([`SampleAnswer::plan_strategy`]).
//!
//! The evaluation itself (reading samples, asking the backend, the confidence intervals)
//! runs in `fogline-dataset`; this module holds only data and the answer reading, so that
//! every crate that can see the controller can also read its scores.
//!
//! ```
//! use fogline_rco::deficit_eval::{HiddenClass, MotionLabel};
//!
//! assert_eq!(HiddenClass::classify("a Stop sign"), Some(HiddenClass::TrafficSign));
//! assert_eq!(HiddenClass::classify("cyclist"), Some(HiddenClass::Bicycle));
//! assert_eq!(
//!     MotionLabel::classify("crossing paths with the ego vehicle"),
//!     Some(MotionLabel::Crossing)
//! );
//! assert_eq!(MotionLabel::classify("approaching the ego vehicle"), Some(MotionLabel::Oncoming));
//! ```

use serde::{Deserialize, Serialize};

use crate::action::Strategy;

/// The object class a deficit hides (the paper's four).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HiddenClass {
    /// A traffic light (its head).
    TrafficLight,
    /// A traffic sign (a stop sign's face).
    TrafficSign,
    /// A pedestrian.
    Pedestrian,
    /// A bicycle with its rider.
    Bicycle,
}

impl HiddenClass {
    /// All four, in the paper's order.
    pub const ALL: [HiddenClass; 4] = [
        HiddenClass::TrafficLight,
        HiddenClass::TrafficSign,
        HiddenClass::Pedestrian,
        HiddenClass::Bicycle,
    ];

    /// The snake-case name (`traffic_light`).
    pub fn name(self) -> &'static str {
        match self {
            HiddenClass::TrafficLight => "traffic_light",
            HiddenClass::TrafficSign => "traffic_sign",
            HiddenClass::Pedestrian => "pedestrian",
            HiddenClass::Bicycle => "bicycle",
        }
    }

    /// Plain words (`traffic light`), as an answer would say it.
    pub fn phrase(self) -> &'static str {
        match self {
            HiddenClass::TrafficLight => "traffic light",
            HiddenClass::TrafficSign => "traffic sign",
            HiddenClass::Pedestrian => "pedestrian",
            HiddenClass::Bicycle => "bicycle",
        }
    }

    /// Parses [`HiddenClass::name`].
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == s.trim())
    }

    /// Reads a free-text object answer: `light`/`signal` → traffic light, `sign` → traffic
    /// sign, `pedestrian`/`person`/`walker`/`people` → pedestrian, `bicycle`/`bike`/`cyclist`
    /// → bicycle; `None` for anything else (a vehicle, `unknown object`) or for an answer
    /// naming two classes.
    pub fn classify(answer: &str) -> Option<Self> {
        let a = answer.to_ascii_lowercase().replace(['_', '-'], " ");
        let has = |words: &[&str]| words.iter().any(|w| a.contains(w));
        let found: Vec<HiddenClass> = [
            (HiddenClass::TrafficLight, has(&["light", "signal"])),
            (
                HiddenClass::TrafficSign,
                has(&["sign"]) && !has(&["signal"]),
            ),
            (
                HiddenClass::Pedestrian,
                has(&["pedestrian", "person", "walker", "people", "child"]),
            ),
            (
                HiddenClass::Bicycle,
                has(&["bicycle", "bike", "cyclist", "rider"]),
            ),
        ]
        .into_iter()
        .filter_map(|(c, hit)| hit.then_some(c))
        .collect();
        match found.as_slice() {
            [one] => Some(*one),
            _ => None,
        }
    }
}

/// How the hidden object moves relative to the ego (at the last frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionLabel {
    /// Crossing the ego's road.
    Crossing,
    /// Coming towards the ego (the opposite lane, the far sidewalk).
    Oncoming,
    /// Ahead, going the ego's way.
    Leading,
    /// Not moving.
    Static,
}

impl MotionLabel {
    /// All four.
    pub const ALL: [MotionLabel; 4] = [
        MotionLabel::Crossing,
        MotionLabel::Oncoming,
        MotionLabel::Leading,
        MotionLabel::Static,
    ];

    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            MotionLabel::Crossing => "crossing",
            MotionLabel::Oncoming => "oncoming",
            MotionLabel::Leading => "leading",
            MotionLabel::Static => "static",
        }
    }

    /// Parses [`MotionLabel::name`].
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == s.trim())
    }

    /// Reads a free-text motion answer: `cross` → crossing; `oncoming`, `approach`,
    /// `opposite`, `towards` → oncoming; `leading`, `ahead in`, `same direction`, `away` →
    /// leading; `static`, `stationary`, `standing`, `parked`, `not moving`, `stopped` →
    /// static; `None` otherwise (`unknown`).
    pub fn classify(answer: &str) -> Option<Self> {
        let a = answer.to_ascii_lowercase().replace(['_', '-'], " ");
        let has = |words: &[&str]| words.iter().any(|w| a.contains(w));
        if has(&["cross"]) {
            Some(MotionLabel::Crossing)
        } else if has(&[
            "static",
            "stationary",
            "standing",
            "parked",
            "not moving",
            "stopped",
            "still",
        ]) {
            Some(MotionLabel::Static)
        } else if has(&["oncoming", "approach", "opposite", "towards", "toward"]) {
            Some(MotionLabel::Oncoming)
        } else if has(&[
            "leading",
            "same direction",
            "away",
            "ahead of the ego",
            "in front",
        ]) {
            Some(MotionLabel::Leading)
        } else {
            None
        }
    }
}

/// A proportion with its 95 % Wilson interval (`None` when the cell has no sample).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Rate {
    /// Successes.
    pub hits: u64,
    /// Trials.
    pub n: u64,
    /// `hits / n`.
    pub value: Option<f64>,
    /// Lower bound of the 95 % interval.
    pub ci_low: Option<f64>,
    /// Upper bound of the 95 % interval.
    pub ci_high: Option<f64>,
}

/// One row of the figure-6 table: a class, a motion label, a strategy or all samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalRow {
    /// What the row groups (`traffic_light`, `crossing`, `all`, …).
    pub group: String,
    /// Samples in the row.
    pub samples: u64,
    /// Object inference accuracy (figure 6a).
    pub object: Rate,
    /// Motion inference accuracy.
    pub motion: Rate,
    /// Strategy accuracy (figure 6b).
    pub strategy: Rate,
    /// Recall of `move` (samples labelled `move` answered `move`).
    pub move_recall: Rate,
    /// Recall of `stop-observe-move`.
    pub som_recall: Rate,
    /// Share of invalid answers (no answer, or one the controller's validation rejects).
    pub invalid: Rate,
    /// Accuracy of the strategy the planning prompt's answer carries out
    /// ([`SampleAnswer::plan_strategy`]; no valid plan counts as wrong). Version 2.
    #[serde(default)]
    pub plan_strategy: Rate,
    /// Recall of `move` by the plan.
    #[serde(default)]
    pub plan_move_recall: Rate,
    /// Recall of `stop-observe-move` by the plan.
    #[serde(default)]
    pub plan_som_recall: Rate,
    /// Share of samples without a valid plan (no hazard inference to plan from, no answer,
    /// an answer the controller's validation rejects, or a first step its verifier refuses).
    #[serde(default)]
    pub plan_invalid: Rate,
}

/// Latency of the backend calls, ms.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Latency {
    /// Calls timed.
    pub calls: u64,
    /// Mean, ms.
    pub mean_ms: f64,
    /// Lower bound of the 95 % interval of the mean (normal approximation), ms.
    pub ci_low_ms: f64,
    /// Upper bound, ms.
    pub ci_high_ms: f64,
    /// Median, ms.
    pub p50_ms: f64,
    /// 95th percentile, ms.
    pub p95_ms: f64,
    /// Largest, ms.
    pub max_ms: f64,
}

/// The latency of one prompt's calls.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PromptLatency {
    /// The prompt (`hazard_inference`, `move_plan`, `stop_observe_move_plan`: the
    /// controller's task names).
    pub prompt: String,
    /// Its calls' latency (`calls` 0: never asked).
    pub latency: Latency,
}

/// One sample's truth and answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleAnswer {
    /// The sample.
    pub id: String,
    /// The hidden class.
    pub class: HiddenClass,
    /// Its motion.
    pub motion: MotionLabel,
    /// The expert's strategy.
    pub strategy: Strategy,
    /// The object the answer names for the hidden region (`None`: invalid or no hazard).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub answer_object: Option<String>,
    /// The motion it names.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub answer_motion: Option<String>,
    /// The strategy it chose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub answer_strategy: Option<Strategy>,
    /// Its rationale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub answer_rationale: Option<String>,
    /// Why the answer was invalid, if it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub invalid: Option<String>,
    /// Object inference right.
    pub object_ok: bool,
    /// Motion inference right.
    pub motion_ok: bool,
    /// Strategy right.
    pub strategy_ok: bool,
    /// The hazard inference call's wall time, ms.
    pub latency_ms: f64,
    /// The planning prompt asked (`move_plan` or `stop_observe_move_plan`, the strategy the
    /// hazard inference chose); `None` when hazard inference gave no valid answer (the
    /// controller falls back without planning). Version 2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan_prompt: Option<String>,
    /// What the plan does at once, as the controller runs it: a stop-observe-move plan, or
    /// a move plan whose first step (verified against the last frame) stops the car
    /// (behaviour `stop` or speed `deceleration_to_zero`), is `stop-observe-move`; any
    /// other move plan is `move`. `None`: no valid plan.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan_strategy: Option<Strategy>,
    /// The plan in short (`2 steps: move_forward/deceleration, …`, `wait 10 ticks, then
    /// move when front_wide=no_immediate_hazard …`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan_summary: Option<String>,
    /// Why there is no valid plan, if there is none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan_invalid: Option<String>,
    /// The plan's strategy is the expert's.
    #[serde(default)]
    pub plan_ok: bool,
    /// The planning call's wall time, ms (`None`: not asked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan_latency_ms: Option<f64>,
}

/// The result of `fogline rco eval` (`eval.json`): figure 6's accuracies per class, motion
/// label and strategy, with 95 % intervals, invalid answers, latency per prompt, every
/// answer. Version 1 files (hazard inference only) read with the planning fields empty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeficitEval {
    /// Always [`DeficitEval::FORMAT`].
    pub format: String,
    /// Schema version.
    pub version: u32,
    /// The backend (`rules`, `openai-compatible model … at …`).
    pub backend: String,
    /// The data set directory.
    pub data: String,
    /// The split scored (`train`, `val`, `test` or `all`).
    pub split: String,
    /// Samples scored.
    pub samples: u64,
    /// All samples.
    pub overall: EvalRow,
    /// Per hidden class, in [`HiddenClass::ALL`] order (figure 6a and 6b).
    pub by_class: Vec<EvalRow>,
    /// Per motion label, in [`MotionLabel::ALL`] order.
    pub by_motion: Vec<EvalRow>,
    /// Per expert strategy (`move`, `stop-observe-move`).
    pub by_strategy: Vec<EvalRow>,
    /// Latency of the hazard inference calls.
    pub latency: Latency,
    /// Latency of the planning calls, per prompt (`move_plan`, `stop_observe_move_plan`).
    /// Version 2.
    #[serde(default)]
    pub plan_latency: Vec<PromptLatency>,
    /// Wall time of the whole evaluation, s.
    pub elapsed_s: f64,
    /// Every sample's answer, in sample order.
    pub answers: Vec<SampleAnswer>,
}

impl DeficitEval {
    /// The `format` tag.
    pub const FORMAT: &'static str = "fogline-deficit-eval";
    /// The schema version (2: the planning prompt's fields).
    pub const VERSION: u32 = 2;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_are_read_into_labels() {
        for (a, c) in [
            ("traffic light", Some(HiddenClass::TrafficLight)),
            ("traffic_signal head", Some(HiddenClass::TrafficLight)),
            ("stop sign", Some(HiddenClass::TrafficSign)),
            ("Pedestrian", Some(HiddenClass::Pedestrian)),
            ("cyclist", Some(HiddenClass::Bicycle)),
            ("vehicle", None),
            ("unknown object", None),
            ("pedestrian or cyclist", None),
        ] {
            assert_eq!(HiddenClass::classify(a), c, "{a}");
        }
        for (a, m) in [
            (
                "crossing paths with the ego vehicle",
                Some(MotionLabel::Crossing),
            ),
            (
                "approaching from the opposite lane",
                Some(MotionLabel::Oncoming),
            ),
            (
                "moving away from the ego vehicle",
                Some(MotionLabel::Leading),
            ),
            ("stationary", Some(MotionLabel::Static)),
            ("unknown", None),
        ] {
            assert_eq!(MotionLabel::classify(a), m, "{a}");
        }
        for c in HiddenClass::ALL {
            assert_eq!(HiddenClass::parse(c.name()), Some(c));
            assert_eq!(HiddenClass::classify(c.phrase()), Some(c));
        }
        for m in MotionLabel::ALL {
            assert_eq!(MotionLabel::parse(m.name()), Some(m));
            assert_eq!(MotionLabel::classify(m.name()), Some(m));
        }
    }
}
