//! Leaderboard 1.0 scoring through the public API: the golden cases of
//! `../shared/reference/leaderboard.md` and every termination rule.

use fogline_sim::score::{
    BlockedMonitor, DenseRoute, Event, EventKind, GlobalScore, RouteCompletion,
    RouteDeviationMonitor, RouteScore, ScoringParams, TimeLimits, route_timeout_s,
};

fn ev(kind: EventKind) -> Event {
    Event::new(kind, 0.0, 0.0, 0.0)
}

#[test]
fn golden_cases_of_the_reference() {
    let p = ScoringParams::default();
    // Completed route, no events: RC 100, IS 1.0, DS 100.
    let s = RouteScore::of(100.0, &[], &p);
    assert_eq!(
        (s.route_completion, s.infraction_score, s.driving_score),
        (100.0, 1.0, 100.0)
    );
    // One vehicle collision + one red light: IS 0.42, DS 42.
    let s = RouteScore::of(
        100.0,
        &[ev(EventKind::CollisionVehicle), ev(EventKind::RedLight)],
        &p,
    );
    assert!((s.infraction_score - 0.42).abs() < 1e-12 && (s.driving_score - 42.0).abs() < 1e-9);
    // Two pedestrian collisions: IS 0.25.
    let s = RouteScore::of(
        100.0,
        &[
            ev(EventKind::CollisionPedestrian),
            ev(EventKind::CollisionPedestrian),
        ],
        &p,
    );
    assert!((s.infraction_score - 0.25).abs() < 1e-12);
    // Timeout at 60 %: RC 60, IS 1.0, DS 60.
    let s = RouteScore::of(60.0, &[ev(EventKind::Timeout)], &p);
    assert_eq!(
        (s.route_completion, s.infraction_score, s.driving_score),
        (60.0, 1.0, 60.0)
    );
    // Global: (100, 0.5) and (50, 1.0) give DS 50 and 50, global DS 50 (not 56.25).
    let a = RouteScore::of(100.0, &[ev(EventKind::CollisionPedestrian)], &p);
    let b = RouteScore::of(50.0, &[], &p);
    let g = GlobalScore::of(&[a, b]).unwrap();
    assert!((g.driving_score.mean - 50.0).abs() < 1e-12);
    assert!((g.route_completion.mean * g.infraction_score.mean - 56.25).abs() < 1e-12);
}

#[test]
fn termination_rules() {
    let route = DenseRoute::new((0..=200).map(|i| [i as f64, 0.0]).collect()).unwrap();
    // Agent blocked: more than 180 s below 0.1 m/s.
    let mut b = BlockedMonitor::default();
    assert!(!b.update(0.0, 0.05));
    assert!(!b.update(180.0, 0.05));
    assert!(b.update(180.05, 0.05));
    // Route deviation: 30 m away at once.
    let mut d = RouteDeviationMonitor::new();
    assert!(!d.update(&route, [3.0, 29.9]));
    assert!(d.update(&route, [3.0, 30.0]));
    // Timeout: int(0.8 · length + 5) s of game time.
    let limits = TimeLimits {
        route_timeout_s: route_timeout_s(route.length_m()),
        game_time_limit_s: Some(120.0),
        system_time_limit_s: Some(100.0),
    };
    assert_eq!(limits.route_timeout_s, 165.0);
    // System time (game time + LLM latency) can end a run before its game time does.
    assert_eq!(limits.check(90.0, 100.5), Some(EventKind::SystemTimeLimit));
    assert_eq!(limits.check(120.5, 120.5), Some(EventKind::GameTimeLimit));
    assert_eq!(limits.check(165.5, 0.0), Some(EventKind::Timeout));
    // Route completion: completed within 10 m of the end above 99 %.
    let mut rc = RouteCompletion::new();
    for i in 0..=200 {
        rc.update(&route, [i as f64 + 0.5, 0.0]);
    }
    assert!(rc.completed() && rc.percent() == 100.0);
}

#[test]
fn the_paired_bootstrap_interval() {
    use fogline_sim::experiment::paired_bootstrap;
    // A constant difference: a degenerate interval at it.
    let (m, ci) = paired_bootstrap(&[4.0; 12], 2000, 1).unwrap();
    assert_eq!((m, ci), (4.0, [4.0, 4.0]));
    assert!(paired_bootstrap(&[], 2000, 1).is_none());
    // 36 differences: the interval holds the mean, is seeded (same seed, same interval), and
    // is close to the normal-theory one, mean ± 1.96 sd / sqrt(n) (the mean of 36 draws
    // is nearly normal).
    let d: Vec<f64> = (0..36)
        .map(|i| {
            let u =
                ((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11) as f64 / (1u64 << 53) as f64;
            20.0 * (u - 0.5) + 3.0
        })
        .collect();
    let (m, ci) = paired_bootstrap(&d, 10_000, 7).unwrap();
    assert_eq!(paired_bootstrap(&d, 10_000, 7).unwrap(), (m, ci));
    assert_ne!(paired_bootstrap(&d, 10_000, 8).unwrap().1, ci);
    assert!(ci[0] < m && m < ci[1], "{ci:?} {m}");
    let n = d.len() as f64;
    let sd = (d.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0)).sqrt();
    let half = 1.96 * sd / n.sqrt();
    for (got, want) in [(ci[0], m - half), (ci[1], m + half)] {
        assert!((got - want).abs() < 0.12 * half, "{got} vs {want}");
    }
}
