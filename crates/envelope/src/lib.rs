//! The envelope analysis of fogline: from a pairs table to the two-dimensional safety
//! envelope of the paper *When and How Severely: Scenario-Specific Safety Envelopes for
//! Driving VLAs* (sections 3–7, tables 1–5).
//!
//! Use it when you have one row per (clip, perturbed condition) — from `fogline campaign
//! export` or from your own logs — and want per-scenario thresholds σ*(s) with bootstrap
//! confidence, GMM severity bands, high-severity shares, the two-dimensional ODD entry and
//! every statistic the paper reports.
//!
//! ```
//! use fogline_envelope::{analyze, synthetic, EnvelopeParams};
//!
//! let table = synthetic::corpus(&synthetic::SyntheticParams { n_clips: 120, seed: 7, ..Default::default() });
//! let params = EnvelopeParams { bootstrap: 200, restarts: 2, ..EnvelopeParams::default() };
//! let env = analyze(&table, &params).unwrap();
//! assert_eq!(env.schema_version, fogline_envelope::model::SCHEMA_VERSION);
//! assert!(!env.thresholds.is_empty());
//! ```

mod analyze;
mod assurance;
pub mod error;
pub mod input;
pub mod markdown;
pub mod model;
pub mod params;
mod statistics;
pub mod synthetic;
pub mod text;
mod threshold;

use std::collections::BTreeMap;

pub use analyze::analyze;
pub use error::{EnvelopeError, Result};
pub use input::{PairTable, ReadOptions, read_pairs, read_pairs_arrow, read_pairs_bytes};
pub use model::Envelope;
pub use params::{Bands, BootstrapMethod, EnvelopeParams, TaxonomyChoice, ThresholdRule};

/// Every convention the paper leaves open, as fogline chooses it (recorded in the output).
pub fn conventions(p: &EnvelopeParams) -> BTreeMap<String, String> {
    let mut c = BTreeMap::new();
    let mut put = |k: &str, v: String| {
        c.insert(k.to_string(), v);
    };
    put("coc_changed", "whitespace-normalised exact comparison: runs of Unicode whitespace collapse to one space, ends trimmed; case and punctuation count".into());
    put("tokens", "maximal runs of Unicode alphanumeric characters, lower-cased; Jaccard over token sets; two token-less texts have Jaccard 1".into());
    put("threshold_rule", match p.rule {
        ThresholdRule::FirstViolation => "first-violation: the largest level before the first level at which mean ADE_attacked >= (1+b) * mean ADE_clean; none when the smallest level fails; right-censored when no level fails".into(),
        ThresholdRule::MaxPassing => "max-passing: the largest level at which mean ADE_attacked < (1+b) * mean ADE_clean; none when no level passes; right-censored when the largest passes".into(),
    });
    put("level_means", "per group and level, means over the group's pairs at that level; the clean mean is over the same pairs (paired)".into());
    put("axes", "one ordered axis per family; brightness splits into darken (gain < 1, more severe as the gain falls) and brighten (gain > 1); other families ascend by level; identity levels are not perturbations".into());
    put(
        "aggregates",
        format!(
            "{} pools the classified scenarios, {} pools every clip; a scenario's threshold is compared with {}",
            model::AGG_CLASSIFIED,
            model::AGG_ALL,
            model::AGG_ALL
        ),
    );
    put(
        "bootstrap_method",
        format!(
            "multinomial (n clips drawn with replacement per scenario) by default; with `auto`, corpora of more than {} clips use the Poisson bootstrap (independent Poisson(1) clip weights, weighted means), which has the same large-sample behaviour and streams clips in order; the method used is in `bootstrap_method`",
            p.poisson_min_clips
        ),
    );
    put("bootstrap", "clips resampled with replacement within each scenario label, each clip with all its conditions; aggregates are sums of their strata (stratified); ΔADE intervals are numpy-linear percentiles; σ* intervals are inverse-CDF quantiles on the ordinal scale none < levels (ties: the smaller level)".into());
    put(
        "pilot",
        format!(
            "a scenario with fewer than {} clips is a pilot",
            p.min_clips
        ),
    );
    put(
        "gmm",
        format!(
            "1-D Gaussian mixture on L2 of changed pairs: k-means initialisation, {} starts per fit keeping the best lower bound, reg_covar 1e-6, tol 1e-3, max_iter 200; BIC = -2 n loglik + (3k-1) ln n",
            p.n_init
        ),
    );
    put("final_model", "k = the modal BIC-optimal k over the restart seeds (ties: the smaller k); the model is the lowest-BIC fit at that k".into());
    put("bands", "components sorted by mean: C0 lowest; each changed pair assigned to the band of maximum posterior".into());
    put(
        "high_severity",
        format!(
            "the top {} bands (at most k-1); P(high | changed, s) = high pairs / changed pairs of s",
            p.high_bands
        ),
    );
    put(
        "severity_group",
        format!(
            "mild if P(high|s) <= P(high) of all changed pairs; severe if >= {} x that; moderate between",
            p.severe_factor
        ),
    );
    put("acceptance", "with --pi-star: s passes iff sigma_op <= sigma*(s) and P(high|s) <= pi*; sigma_op defaults to the all-clips aggregate threshold".into());
    put(
        "mann_whitney",
        format!(
            "two-sided, asymptotic, tie-corrected, continuity-corrected; complete rewrites J < {} vs mid-range edits {} <= J <= {}; Cohen's d = (low - mid) / pooled sd; power: normal approximation of a two-sided two-sample test at alpha {}",
            p.jaccard_low, p.jaccard_low, p.jaccard_high, p.alpha
        ),
    );
    put("semantic_similarity", "coc_cosine: cosine of the two CoC texts' sentence embeddings (all-MiniLM-L6-v2: BERT-uncased WordPiece, mean pooling, L2-normalised, as sentence-transformers; fogline-embed), as the pairs table gives it; cosine_l2 correlates it with L2 on changed pairs that have it, cosine_l2_mid_jaccard on those of the mid-range Jaccard band".into());
    put("icc", "ICC(2,1) and ICC(3,1) (Shrout & Fleiss) of the 0/1 flip flags, clips as targets and conditions as raters, complete clips only".into());
    put("chi2", "Pearson chi-square without Yates correction on the classified scenario x band counts, empty rows and columns dropped; Cramer's V = sqrt(chi2 / (n (min(r,c)-1)))".into());
    put("actions", "keyword rules on the leading clause (see the action rules); transitions count changed pairs of classified scenarios".into());
    put("l2_aggregation", p.l2_aggregation.clone());
    c
}
