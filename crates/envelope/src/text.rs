//! Text conventions for Chain-of-Causation (CoC) explanations.
//!
//! - **Changed**: two CoC texts are the same when their whitespace-normalised forms are equal
//!   (runs of Unicode whitespace collapsed to one space, leading and trailing whitespace
//!   removed); the comparison is case-sensitive and keeps punctuation.
//! - **Tokens**: maximal runs of Unicode alphanumeric characters, lower-cased. Punctuation and
//!   whitespace separate tokens; an apostrophe splits (`don't` → `don`, `t`).
//! - **Jaccard**: |A ∩ B| / |A ∪ B| over the token *sets*; two texts without tokens have
//!   Jaccard 1.
//! - **Action**: see [`ActionRules`].

use std::path::Path;

use serde::Deserialize;

use crate::error::{EnvelopeError, Result};

/// Whether two CoC texts differ after whitespace normalisation.
pub fn coc_changed(clean: &str, attacked: &str) -> bool {
    !clean.split_whitespace().eq(attacked.split_whitespace())
}

/// The sorted, de-duplicated lower-case token set of a text (see the module docs).
pub fn token_set(text: &str) -> Vec<String> {
    let mut tokens: Vec<String> = text
        .split(|c: char| !c.is_alphanumeric())
        .filter(|t| !t.is_empty())
        .map(str::to_lowercase)
        .collect();
    tokens.sort_unstable();
    tokens.dedup();
    tokens
}

/// Jaccard similarity of two sorted, de-duplicated token sets.
pub fn jaccard_sets(a: &[String], b: &[String]) -> f64 {
    jaccard_slices(a, b)
}

/// Token Jaccard similarity of two texts.
pub fn jaccard(a: &str, b: &str) -> f64 {
    jaccard_sets(&token_set(a), &token_set(b))
}

/// The label of a CoC text that matches no rule.
pub const UNMATCHED_ACTION: &str = "UNCLASSIFIED";

/// One action and the keyword phrases that identify it.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
pub struct ActionRule {
    /// Action label (e.g. `STOP`).
    pub name: String,
    /// Phrases, matched as whole token sequences of the lower-cased text (`slow down`).
    pub keywords: Vec<String>,
}

/// Keyword rules that map a CoC text to its action.
///
/// The action of a text is decided on its *leading clause*: the text up to the first of
/// ` because `, ` due to `, ` since `, ` as `, ` so that `, `;` or `,` (the reason that
/// follows names objects — "the stop sign", "the slower vehicle" — not what the car does).
/// If the leading clause matches no rule, the whole text is tried. Rules are tried in order;
/// the first rule with a keyword phrase present (as a whole-token sequence) wins; a text that
/// matches none is [`UNMATCHED_ACTION`].
///
/// Override with a TOML file of `[[action]]` tables (`name`, `keywords`), in priority order.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ActionRules {
    /// The rules, in priority order.
    pub rules: Vec<ActionRule>,
    #[serde(skip)]
    compiled: Vec<Vec<Vec<String>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RulesFile {
    action: Vec<ActionRule>,
}

const DEFAULT_RULES: &[(&str, &[&str])] = &[
    (
        "STOP",
        &[
            "stop",
            "stopping",
            "halt",
            "come to a stop",
            "remain stopped",
            "stay stopped",
            "wait",
        ],
    ),
    ("YIELD", &["yield", "yielding", "give way"]),
    (
        "SLOW_DOWN",
        &[
            "slow",
            "slow down",
            "slowing",
            "decelerate",
            "decelerating",
            "brake",
            "braking",
            "reduce speed",
            "ease off",
        ],
    ),
    ("TURN_LEFT", &["turn left", "turning left", "left turn"]),
    ("TURN_RIGHT", &["turn right", "turning right", "right turn"]),
    (
        "LANE_CHANGE",
        &[
            "change lane",
            "change lanes",
            "changing lanes",
            "lane change",
            "overtake",
            "overtaking",
            "pass",
            "passing",
            "merge",
            "merging",
        ],
    ),
    (
        "NUDGE",
        &[
            "nudge",
            "nudging",
            "shift",
            "offset",
            "swerve",
            "steer around",
            "veer",
        ],
    ),
    (
        "FOLLOW",
        &[
            "follow",
            "following",
            "keep distance",
            "keep a safe distance",
            "maintain distance",
            "match speed",
        ],
    ),
    (
        "ACCELERATE",
        &[
            "accelerate",
            "accelerating",
            "speed up",
            "proceed",
            "proceeding",
            "go",
            "resume",
            "start moving",
        ],
    ),
    (
        "KEEP_LANE",
        &[
            "keep lane",
            "stay in lane",
            "keep the lane",
            "continue",
            "continuing",
            "maintain",
            "maintaining",
            "cruise",
            "cruising",
            "go straight",
            "drive straight",
            "keep straight",
        ],
    ),
];

impl Default for ActionRules {
    fn default() -> Self {
        Self::new(
            DEFAULT_RULES
                .iter()
                .map(|(n, k)| ActionRule {
                    name: n.to_string(),
                    keywords: k.iter().map(|s| s.to_string()).collect(),
                })
                .collect(),
        )
    }
}

impl ActionRules {
    /// Rules from a list, in priority order.
    pub fn new(rules: Vec<ActionRule>) -> Self {
        let compiled = rules
            .iter()
            .map(|r| {
                r.keywords
                    .iter()
                    .map(|k| token_seq(k))
                    .filter(|k| !k.is_empty())
                    .collect()
            })
            .collect();
        Self { rules, compiled }
    }

    /// Reads rules from a TOML file (`[[action]]` tables with `name` and `keywords`).
    pub fn from_toml_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| EnvelopeError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text).map_err(|detail| EnvelopeError::ActionRules {
            path: path.to_path_buf(),
            detail,
        })
    }

    /// Parses rules from TOML text; the error is a message for the user.
    pub fn from_toml_str(text: &str) -> std::result::Result<Self, String> {
        let file: RulesFile = toml::from_str(text).map_err(|e| e.to_string())?;
        if file.action.is_empty() {
            return Err("no [[action]] tables".into());
        }
        for (i, r) in file.action.iter().enumerate() {
            if r.name.trim().is_empty() {
                return Err(format!("action #{} has an empty name", i + 1));
            }
            if r.name == UNMATCHED_ACTION {
                return Err(format!("action name {UNMATCHED_ACTION} is reserved"));
            }
            if r.keywords.iter().all(|k| token_seq(k).is_empty()) {
                return Err(format!("action {:?} has no usable keyword", r.name));
            }
            if file.action[..i].iter().any(|o| o.name == r.name) {
                return Err(format!("action {:?} is defined twice", r.name));
            }
        }
        Ok(Self::new(file.action))
    }

    /// All action labels, rule order, then [`UNMATCHED_ACTION`].
    pub fn labels(&self) -> Vec<String> {
        let mut v: Vec<String> = self.rules.iter().map(|r| r.name.clone()).collect();
        v.push(UNMATCHED_ACTION.to_string());
        v
    }

    /// The index into [`labels`](Self::labels) of a text's action.
    pub fn classify(&self, text: &str) -> usize {
        self.classify_lower(&text.to_lowercase())
    }

    /// [`classify`](Self::classify) for a text that is already lower-cased.
    pub fn classify_lower(&self, lower: &str) -> usize {
        let clause = leading_clause(lower);
        if let Some(i) = self.first_match(clause) {
            return i;
        }
        if clause.len() != lower.len()
            && let Some(i) = self.first_match(lower)
        {
            return i;
        }
        self.rules.len()
    }

    fn first_match(&self, lower: &str) -> Option<usize> {
        let tokens: Vec<&str> = tokens_of(lower).collect();
        self.compiled.iter().position(|phrases| {
            phrases.iter().any(|p| {
                tokens
                    .windows(p.len())
                    .any(|w| w.iter().zip(p).all(|(a, b)| *a == b))
            })
        })
    }
}

fn tokens_of(text: &str) -> impl Iterator<Item = &str> {
    text.split(|c: char| !c.is_alphanumeric())
        .filter(|t| !t.is_empty())
}

fn token_seq(text: &str) -> Vec<String> {
    tokens_of(text).map(str::to_lowercase).collect()
}

/// Per-row text features of a (clean, perturbed) CoC pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextFeatures {
    /// Whether the texts differ (whitespace-normalised, case-sensitive).
    pub changed: bool,
    /// Token Jaccard similarity.
    pub jaccard: f64,
    /// Action index of the clean text (into [`ActionRules::labels`]).
    pub action_clean: usize,
    /// Action index of the perturbed text.
    pub action_attacked: usize,
}

/// Reusable buffers for [`TextFeatures::compute`], so rows cost no allocation, and the
/// action of the last clean text (a clip's rows share one clean text).
#[derive(Debug, Default)]
pub struct TextScratch {
    lower_a: String,
    lower_b: String,
    cached_clean: Option<(String, usize)>,
}

impl TextFeatures {
    /// Computes the features of one pair of texts.
    pub fn compute(
        clean: &str,
        attacked: &str,
        rules: &ActionRules,
        scratch: &mut TextScratch,
    ) -> Self {
        let action_clean = match &scratch.cached_clean {
            Some((text, action)) if text == clean => *action,
            _ => {
                let action = rules.classify(clean);
                scratch.cached_clean = Some((clean.to_string(), action));
                action
            }
        };
        if clean == attacked {
            // Identical texts: unchanged, the same token set (Jaccard 1), the same action.
            return Self {
                changed: false,
                jaccard: 1.0,
                action_clean,
                action_attacked: action_clean,
            };
        }
        lower_into(clean, &mut scratch.lower_a);
        lower_into(attacked, &mut scratch.lower_b);
        let (a, b) = (scratch.lower_a.as_str(), scratch.lower_b.as_str());
        let jaccard = if clean.is_ascii() && attacked.is_ascii() {
            // ASCII: lower-casing the text and then splitting equals splitting and then
            // lower-casing each token, so slices of the lower-cased buffer are the tokens.
            let mut ta: Vec<&str> = tokens_of(a).collect();
            let mut tb: Vec<&str> = tokens_of(b).collect();
            ta.sort_unstable();
            ta.dedup();
            tb.sort_unstable();
            tb.dedup();
            jaccard_slices(&ta, &tb)
        } else {
            jaccard(clean, attacked)
        };
        Self {
            changed: coc_changed(clean, attacked),
            jaccard,
            action_clean,
            action_attacked: rules.classify_lower(b),
        }
    }
}

fn lower_into(text: &str, out: &mut String) {
    out.clear();
    if text.is_ascii() {
        out.push_str(text);
        out.make_ascii_lowercase();
    } else {
        out.push_str(&text.to_lowercase());
    }
}

fn jaccard_slices<T: Ord>(a: &[T], b: &[T]) -> f64 {
    if a.is_empty() && b.is_empty() {
        return 1.0;
    }
    let (mut i, mut j, mut inter) = (0, 0, 0usize);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                inter += 1;
                i += 1;
                j += 1;
            }
        }
    }
    inter as f64 / (a.len() + b.len() - inter) as f64
}

fn leading_clause(lower: &str) -> &str {
    const SEPARATORS: [&str; 7] = [
        " because ",
        " due to ",
        " since ",
        " as ",
        " so that ",
        ";",
        ",",
    ];
    let end = SEPARATORS
        .iter()
        .filter_map(|s| lower.find(s))
        .min()
        .unwrap_or(lower.len());
    &lower[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whitespace_only_differences_are_not_changes() {
        assert!(!coc_changed("Slow  down\tnow. ", " Slow down now."));
        assert!(coc_changed("Slow down now.", "slow down now."));
        assert!(coc_changed("Stop.", "Stop!"));
    }

    #[test]
    fn jaccard_on_token_sets() {
        assert_eq!(jaccard("a b c", "a b c c"), 1.0);
        assert_eq!(jaccard("a b", "c d"), 0.0);
        assert!(
            (jaccard("Slow down, lead car", "slow down for the car") - 3.0 / 6.0).abs() < 1e-15
        );
        assert_eq!(jaccard("", "..."), 1.0);
        assert_eq!(jaccard("", "go"), 0.0);
    }

    #[test]
    fn actions_use_the_leading_clause() {
        let r = ActionRules::default();
        let label = |t: &str| r.labels()[r.classify(t)].clone();
        assert_eq!(
            label("Slow down because the lead vehicle is braking ahead."),
            "SLOW_DOWN"
        );
        assert_eq!(label("Stop because of the red light."), "STOP");
        assert_eq!(
            label("Keep lane since the stop sign is far away."),
            "KEEP_LANE"
        );
        assert_eq!(
            label("Nudge left to increase clearance from the parked vehicle."),
            "NUDGE"
        );
        assert_eq!(label("Pass the slower truck on the left."), "LANE_CHANGE");
        assert_eq!(label("Turn right at the junction."), "TURN_RIGHT");
        assert_eq!(label("Hmm."), UNMATCHED_ACTION);
        // "stop sign" in the reason does not make a lane-keeping sentence a stop.
        assert_eq!(
            label("Continue, the stop sign is for the other road."),
            "KEEP_LANE"
        );
    }

    #[test]
    fn features_match_the_plain_functions() {
        let r = ActionRules::default();
        let mut sc = TextScratch::default();
        for (a, b) in [
            ("Slow down, lead car", "SLOW down for the car"),
            ("", ""),
            ("Über Straße", "über STRASSE"),
        ] {
            let f = TextFeatures::compute(a, b, &r, &mut sc);
            assert_eq!(f.changed, coc_changed(a, b));
            assert_eq!(f.jaccard, jaccard(a, b));
            assert_eq!(f.action_clean, r.classify(a));
        }
    }

    #[test]
    fn rules_from_toml() {
        let r = ActionRules::from_toml_str(
            "[[action]]\nname = \"BRAKE\"\nkeywords = [\"brake\", \"stop\"]\n",
        )
        .unwrap();
        assert_eq!(r.labels(), vec!["BRAKE", UNMATCHED_ACTION]);
        assert_eq!(r.classify("Stop now"), 0);
        assert!(ActionRules::from_toml_str("[[action]]\nname = \"\"\nkeywords = [\"x\"]").is_err());
        assert!(
            ActionRules::from_toml_str("[[action]]\nname = \"A\"\nkeywords = [\"--\"]").is_err()
        );
        assert!(ActionRules::from_toml_str("action = 3").is_err());
    }
}
