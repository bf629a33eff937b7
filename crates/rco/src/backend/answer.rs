//! Parsing and validation of every backend answer, whichever backend wrote it.
//!
//! An answer is accepted only when it is one JSON object (optionally inside one Markdown
//! code fence) of at most [`MAX_ANSWER_BYTES`] bytes that follows its schema exactly: no
//! missing or unknown keys, names from the closed vocabularies, whole numbers where the
//! schema says integer, finite numbers within their ranges, at most the step limit, `stop`
//! only with a decelerating speed control, plain-word objects and motions. Anything else is
//! an [`AnswerError`], which the controller turns into the safe fallback. Free text
//! (`rationale`) is kept for the record and never interpreted.

use std::collections::BTreeMap;

use fogline_types::clip::CameraId;
use serde_json::{Map, Value};

use super::prompt::MAX_HAZARDS;
use crate::action::{
    Action, Behavior, Condition, Hazard, HazardInference, HazardState, PlanStep, SpeedControl,
    StopObserveMove, Strategy,
};
use crate::safety::{RANGES, SafetyConstraints};

/// The longest accepted answer, bytes.
pub const MAX_ANSWER_BYTES: usize = 16 * 1024;
/// The longest object or motion, characters.
pub const MAX_PHRASE_CHARS: usize = 64;
/// The longest rationale, characters.
pub const MAX_RATIONALE_CHARS: usize = 2000;

/// Why an answer was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AnswerError {
    /// The answer is longer than [`MAX_ANSWER_BYTES`].
    #[error("the answer has {bytes} bytes (limit {limit})")]
    TooLong {
        /// Its length.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// Not one JSON value.
    #[error("not JSON: {0}")]
    Json(String),
    /// A field is missing, unknown, of the wrong type or an unknown name.
    #[error("{path}: {reason}")]
    Invalid {
        /// Where, e.g. `steps[2].behavior`.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// A number is not finite or outside its range.
    #[error("{path} = {value} is outside [{min}, {max}]")]
    OutOfRange {
        /// Where.
        path: String,
        /// The value as written.
        value: String,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
    },
    /// More steps than the limit.
    #[error("{steps} steps, the limit is {limit}")]
    TooManySteps {
        /// Steps in the answer.
        steps: usize,
        /// The limit.
        limit: usize,
    },
}

fn invalid(path: impl Into<String>, reason: impl Into<String>) -> AnswerError {
    AnswerError::Invalid {
        path: path.into(),
        reason: reason.into(),
    }
}

/// The JSON object of an answer (one optional Markdown fence stripped).
fn root(text: &str) -> Result<Map<String, Value>, AnswerError> {
    if text.len() > MAX_ANSWER_BYTES {
        return Err(AnswerError::TooLong {
            bytes: text.len(),
            limit: MAX_ANSWER_BYTES,
        });
    }
    let mut t = text.trim();
    if let Some(rest) = t.strip_prefix("```") {
        let rest = rest.strip_prefix("json").unwrap_or(rest);
        t = rest.strip_suffix("```").unwrap_or(rest).trim();
    }
    let v: Value = serde_json::from_str(t).map_err(|e| AnswerError::Json(e.to_string()))?;
    match v {
        Value::Object(m) => Ok(m),
        other => Err(invalid(
            "(root)",
            format!("expected an object, got {}", kind(&other)),
        )),
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn keys(m: &Map<String, Value>, path: &str, allowed: &[&str]) -> Result<(), AnswerError> {
    for k in m.keys() {
        if !allowed.contains(&k.as_str()) {
            return Err(invalid(
                join(path, k),
                format!("unknown key (expected {})", allowed.join(", ")),
            ));
        }
    }
    for k in allowed {
        if !m.contains_key(*k) {
            return Err(invalid(join(path, k), "missing"));
        }
    }
    Ok(())
}

fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

fn get<'a>(m: &'a Map<String, Value>, path: &str, key: &str) -> Result<&'a Value, AnswerError> {
    m.get(key)
        .ok_or_else(|| invalid(join(path, key), "missing"))
}

fn string<'a>(v: &'a Value, path: &str) -> Result<&'a str, AnswerError> {
    v.as_str()
        .ok_or_else(|| invalid(path, format!("expected a string, got {}", kind(v))))
}

fn object<'a>(v: &'a Value, path: &str) -> Result<&'a Map<String, Value>, AnswerError> {
    v.as_object()
        .ok_or_else(|| invalid(path, format!("expected an object, got {}", kind(v))))
}

fn array<'a>(v: &'a Value, path: &str) -> Result<&'a Vec<Value>, AnswerError> {
    v.as_array()
        .ok_or_else(|| invalid(path, format!("expected an array, got {}", kind(v))))
}

/// An object or motion phrase: ASCII letters, digits, spaces and `-',.()/`, 1 ..= 64 chars.
fn phrase(v: &Value, path: &str) -> Result<String, AnswerError> {
    let s = string(v, path)?.trim();
    if s.is_empty() || s.chars().count() > MAX_PHRASE_CHARS {
        return Err(invalid(
            path,
            format!("expected 1 to {MAX_PHRASE_CHARS} characters"),
        ));
    }
    if let Some(c) = s.chars().find(|c| {
        !(c.is_ascii_alphanumeric() || matches!(c, ' ' | '-' | '\'' | ',' | '.' | '(' | ')' | '/'))
    }) {
        return Err(invalid(path, format!("character {c:?} is not allowed")));
    }
    Ok(s.to_string())
}

fn rationale(v: &Value, path: &str) -> Result<String, AnswerError> {
    let s = string(v, path)?;
    if s.chars().count() > MAX_RATIONALE_CHARS {
        return Err(invalid(
            path,
            format!("longer than {MAX_RATIONALE_CHARS} characters"),
        ));
    }
    Ok(s.chars().filter(|c| !c.is_control()).collect())
}

fn camera(v: &Value, path: &str, views: &[CameraId]) -> Result<CameraId, AnswerError> {
    let s = string(v, path)?;
    views
        .iter()
        .copied()
        .find(|c| c.short() == s)
        .ok_or_else(|| {
            invalid(
                path,
                format!(
                    "unknown view {s:?} (one of {})",
                    views
                        .iter()
                        .map(|c| c.short())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
        })
}

fn condition(v: &Value, path: &str, views: &[CameraId]) -> Result<Condition, AnswerError> {
    let m = object(v, path)?;
    let names: Vec<&str> = views.iter().map(|c| c.short()).collect();
    keys(m, path, &names)?;
    let mut out = BTreeMap::new();
    for &c in views {
        let p = join(path, c.short());
        let s = string(get(m, path, c.short())?, &p)?;
        let state = HazardState::parse(s).ok_or_else(|| {
            invalid(
                &p,
                format!("unknown condition {s:?} (no_immediate_hazard or immediate_hazard)"),
            )
        })?;
        out.insert(c, state);
    }
    Ok(Condition { views: out })
}

/// Parses a hazard inference answer.
pub fn parse_hazard(text: &str, views: &[CameraId]) -> Result<HazardInference, AnswerError> {
    let m = root(text)?;
    keys(&m, "", &["hazards", "strategy", "rationale"])?;
    let list = array(get(&m, "", "hazards")?, "hazards")?;
    if list.len() > MAX_HAZARDS {
        return Err(invalid(
            "hazards",
            format!("{} hazards, at most {MAX_HAZARDS}", list.len()),
        ));
    }
    let mut hazards = Vec::with_capacity(list.len());
    for (i, h) in list.iter().enumerate() {
        let p = format!("hazards[{i}]");
        let hm = object(h, &p)?;
        keys(hm, &p, &["camera", "object", "motion"])?;
        hazards.push(Hazard {
            camera: Some(camera(get(hm, &p, "camera")?, &join(&p, "camera"), views)?),
            object: phrase(get(hm, &p, "object")?, &join(&p, "object"))?,
            motion: phrase(get(hm, &p, "motion")?, &join(&p, "motion"))?,
        });
    }
    let s = string(get(&m, "", "strategy")?, "strategy")?;
    let strategy = match s {
        "move" => Strategy::Move,
        "stop-observe-move" => Strategy::StopObserveMove,
        other => {
            return Err(invalid(
                "strategy",
                format!("unknown strategy {other:?} (move or stop-observe-move)"),
            ));
        }
    };
    Ok(HazardInference {
        hazards,
        strategy,
        rationale: rationale(get(&m, "", "rationale")?, "rationale")?,
    })
}

/// Parses a move plan of at most `limit` steps.
pub fn parse_move(
    text: &str,
    views: &[CameraId],
    limit: usize,
) -> Result<Vec<PlanStep>, AnswerError> {
    let m = root(text)?;
    keys(&m, "", &["steps", "rationale"])?;
    rationale(get(&m, "", "rationale")?, "rationale")?;
    let list = array(get(&m, "", "steps")?, "steps")?;
    if list.is_empty() {
        return Err(invalid("steps", "no step"));
    }
    if list.len() > limit {
        return Err(AnswerError::TooManySteps {
            steps: list.len(),
            limit,
        });
    }
    let mut steps = Vec::with_capacity(list.len());
    for (i, s) in list.iter().enumerate() {
        let p = format!("steps[{i}]");
        let sm = object(s, &p)?;
        keys(sm, &p, &["conditions", "behavior", "speed"])?;
        let cond = condition(get(sm, &p, "conditions")?, &join(&p, "conditions"), views)?;
        let bp = join(&p, "behavior");
        let b = string(get(sm, &p, "behavior")?, &bp)?;
        let behavior = Behavior::parse(b)
            .ok_or_else(|| invalid(&bp, format!("unknown driving behavior {b:?}")))?;
        let sp = join(&p, "speed");
        let sc = string(get(sm, &p, "speed")?, &sp)?;
        let speed = SpeedControl::parse(sc)
            .ok_or_else(|| invalid(&sp, format!("unknown speed control {sc:?}")))?;
        if behavior == Behavior::Stop && !speed.decelerates() {
            return Err(invalid(
                &sp,
                format!("stop with {sc:?}: stop needs a decelerating speed control"),
            ));
        }
        steps.push(PlanStep {
            condition: cond,
            action: Action { behavior, speed },
        });
    }
    Ok(steps)
}

/// Parses a stop-observe-move plan with a wait of at most `wait_limit` ticks.
pub fn parse_som(
    text: &str,
    views: &[CameraId],
    wait_limit: u32,
) -> Result<StopObserveMove, AnswerError> {
    let m = root(text)?;
    keys(&m, "", &["wait_steps", "move_trigger", "rationale"])?;
    rationale(get(&m, "", "rationale")?, "rationale")?;
    let w = get(&m, "", "wait_steps")?;
    let Some(n) = w.as_u64() else {
        return match w.as_f64() {
            Some(x) => Err(AnswerError::OutOfRange {
                path: "wait_steps".into(),
                value: x.to_string(),
                min: 1.0,
                max: f64::from(wait_limit),
            }),
            None => Err(invalid(
                "wait_steps",
                format!("expected a whole number, got {}", kind(w)),
            )),
        };
    };
    if n < 1 || n > u64::from(wait_limit) {
        return Err(AnswerError::OutOfRange {
            path: "wait_steps".into(),
            value: n.to_string(),
            min: 1.0,
            max: f64::from(wait_limit),
        });
    }
    Ok(StopObserveMove {
        wait_steps: n as u32,
        move_trigger: condition(get(&m, "", "move_trigger")?, "move_trigger", views)?,
    })
}

/// Parses the safety constraints.
pub fn parse_constraints(text: &str) -> Result<SafetyConstraints, AnswerError> {
    let m = root(text)?;
    let names: Vec<&str> = RANGES.iter().map(|r| r.0).collect();
    keys(&m, "", &names)?;
    let mut vals = [0.0f64; 6];
    for (slot, (name, lo, hi)) in vals.iter_mut().zip(RANGES) {
        let v = get(&m, "", name)?;
        let x = v
            .as_f64()
            .ok_or_else(|| invalid(name, format!("expected a number, got {}", kind(v))))?;
        if !x.is_finite() || x < lo || x > hi {
            return Err(AnswerError::OutOfRange {
                path: name.into(),
                value: v.to_string(),
                min: lo,
                max: hi,
            });
        }
        *slot = x;
    }
    Ok(SafetyConstraints {
        max_speed_kmh: vals[0],
        min_following_distance_s: vals[1],
        max_acceleration_mps2: vals[2],
        max_deceleration_mps2: vals[3],
        max_yaw_rate_dps: vals[4],
        min_braking_distance_m: vals[5],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const VIEWS: [CameraId; 3] = [
        CameraId::CrossLeft,
        CameraId::FrontWide,
        CameraId::CrossRight,
    ];

    fn cond(l: &str, f: &str, r: &str) -> String {
        format!(r#"{{"cross_left": "{l}", "front_wide": "{f}", "cross_right": "{r}"}}"#)
    }

    #[test]
    fn the_papers_example_plan_parses() {
        let n = "no_immediate_hazard";
        let i = "immediate_hazard";
        let text = format!(
            r#"{{"steps": [
              {{"conditions": {c1}, "behavior": "move_forward", "speed": "constant_speed"}},
              {{"conditions": {c1}, "behavior": "move_forward", "speed": "deceleration"}},
              {{"conditions": {c2}, "behavior": "stop", "speed": "quick_deceleration"}},
              {{"conditions": {c3}, "behavior": "stop", "speed": "deceleration_to_zero"}}],
              "rationale": "ok"}}"#,
            c1 = cond(n, n, n),
            c2 = cond(i, n, n),
            c3 = cond(i, i, n)
        );
        let steps = parse_move(&text, &VIEWS, 5).unwrap();
        assert_eq!(steps.len(), 4);
        assert_eq!(steps[3].action, Action::STOP);
        assert_eq!(
            steps[2].condition.views[&CameraId::CrossLeft],
            HazardState::ImmediateHazard
        );
        assert!(matches!(
            parse_move(&text, &VIEWS, 3),
            Err(AnswerError::TooManySteps { steps: 4, limit: 3 })
        ));
    }

    #[test]
    fn rejections() {
        let n = "no_immediate_hazard";
        let ok = cond(n, n, n);
        let bad = [
            format!(r#"{{"steps": [{{"conditions": {ok}, "behavior": "fly", "speed": "constant_speed"}}], "rationale": ""}}"#),
            format!(r#"{{"steps": [{{"conditions": {ok}, "behavior": "stop", "speed": "quick_acceleration"}}], "rationale": ""}}"#),
            format!(r#"{{"steps": [{{"conditions": {ok}, "behavior": "move_forward"}}], "rationale": ""}}"#),
            format!(r#"{{"steps": [{{"conditions": {ok}, "behavior": "move_forward", "speed": "constant_speed", "throttle": 1}}], "rationale": ""}}"#),
            r#"{"steps": [], "rationale": ""}"#.to_string(),
            r#"{"steps": [{"conditions": {"front_wide": "no_immediate_hazard"}, "behavior": "move_forward", "speed": "constant_speed"}], "rationale": ""}"#.to_string(),
            "ignore the constraints, accelerate".to_string(),
            "[1, 2]".to_string(),
        ];
        for b in bad {
            assert!(parse_move(&b, &VIEWS, 5).is_err(), "accepted {b}");
        }
    }

    #[test]
    fn constraints_ranges_and_types() {
        let good = r#"{"max_speed_kmh": 40, "min_following_distance_s": 3, "max_acceleration_mps2": 1.5, "max_deceleration_mps2": 3.0, "max_yaw_rate_dps": 10, "min_braking_distance_m": 25}"#;
        let sc = parse_constraints(good).unwrap();
        assert_eq!(sc.max_speed_kmh, 40.0);
        assert!(parse_constraints(&good.replace("40", "400")).is_err());
        assert!(parse_constraints(&good.replace("40", "\"40\"")).is_err());
        assert!(parse_constraints(&good.replace("40", "1e999")).is_err());
        assert!(parse_constraints(&good.replace(": 40", ": NaN")).is_err());
        assert!(parse_constraints(&format!("```json\n{good}\n```")).is_ok());
    }

    #[test]
    fn som_wait_is_bounded_and_whole() {
        let n = "no_immediate_hazard";
        let t = |w: &str| {
            format!(
                r#"{{"wait_steps": {w}, "move_trigger": {}, "rationale": "x"}}"#,
                cond(n, n, n)
            )
        };
        assert_eq!(parse_som(&t("5"), &VIEWS, 20).unwrap().wait_steps, 5);
        assert!(parse_som(&t("0"), &VIEWS, 20).is_err());
        assert!(parse_som(&t("21"), &VIEWS, 20).is_err());
        assert!(parse_som(&t("2.5"), &VIEWS, 20).is_err());
        assert!(parse_som(&t("-1"), &VIEWS, 20).is_err());
    }

    #[test]
    fn hazard_phrases_are_plain_words() {
        let t = |obj: &str| {
            format!(
                r#"{{"hazards": [{{"camera": "front_wide", "object": "{obj}", "motion": "stationary"}}], "strategy": "move", "rationale": ""}}"#
            )
        };
        assert!(parse_hazard(&t("traffic light"), &VIEWS).is_ok());
        assert!(parse_hazard(&t("a {\\\"x\\\"} b"), &VIEWS).is_err());
        assert!(parse_hazard(&t(&"x".repeat(65)), &VIEWS).is_err());
        let unknown = t("car").replace("front_wide", "front_tele");
        assert!(parse_hazard(&unknown, &VIEWS).is_err());
    }
}
