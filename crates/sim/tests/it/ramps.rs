//! Condition ramps in the closed loop (issue 20, item 4): the guard hands the car to the
//! override while the condition is outside the envelope and back once it clears.

use fogline_sim::config::{BackendSetup, ConfigSet, configs};
use fogline_sim::experiment::run_experiment;
use fogline_sim::ramp::{GuardMode, Ramp};

use crate::{experiment, tiny_suite};

#[test]
fn the_guard_hands_over_while_the_condition_is_out_and_hands_back_after() {
    let seed = 4;
    let c = configs(&[ConfigSet::Ramps], &[], &BackendSetup::Rules);
    assert_eq!(
        c.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
        GuardMode::ALL.map(GuardMode::config_name)
    );
    let params = experiment(tiny_suite(3, 420.0), c, seed);
    let res = run_experiment(&params, 2, &|_, _| {}).unwrap();
    assert_eq!(res.records.len(), 12);
    let get = |mode: GuardMode, route: usize| {
        res.records
            .iter()
            .find(|r| r.config == mode.config_name() && r.route == route)
            .unwrap()
    };
    for route in 0..3 {
        let ramp = Ramp::for_route(seed, route);
        let none = get(GuardMode::None, route);
        let oracle = get(GuardMode::Oracle, route);
        let guard = get(GuardMode::Monitor, route);
        let always = get(GuardMode::Always, route);
        for r in [none, oracle, guard, always] {
            assert_eq!(r.ramp, Some(ramp), "route {route}");
        }
        // Without a guard nobody takes over; the true condition left the envelope.
        assert_eq!(none.takeover_s, 0.0);
        assert!(
            oracle.deficit_s > 10.0,
            "route {route}: {}",
            oracle.deficit_s
        );
        // The oracle hands over exactly while the true condition is out (to an agent step).
        assert!(
            (oracle.takeover_s - oracle.deficit_s).abs() <= 0.5,
            "route {route}: override {} s, out {} s",
            oracle.takeover_s,
            oracle.deficit_s
        );
        // The monitor, from the frames alone, hands over too, and back: the run ends
        // with the car driving again, not held until the blocked rule.
        assert!(
            guard.takeover_s > 5.0,
            "route {route}: {}",
            guard.takeover_s
        );
        assert!(
            guard.takeover_s < guard.game_time_s - 30.0,
            "route {route}: in override {} of {} s",
            guard.takeover_s,
            guard.game_time_s
        );
        assert!(
            guard.takeover_s <= ramp.end_s() - ramp.start_s + 30.0,
            "route {route}: {} s in override, ramp {ramp:?}",
            guard.takeover_s
        );
        assert_ne!(
            guard.termination,
            fogline_sim::run::Termination::AgentBlocked,
            "route {route}"
        );
        // Always on: the override drives for the whole ramp (and no longer).
        assert!(
            always.takeover_s >= oracle.takeover_s - 0.5,
            "route {route}"
        );
        assert!(
            always.takeover_s <= ramp.end_s() - ramp.start_s + 0.5,
            "route {route}"
        );
    }
    let r = res.summary.ramps.as_ref().unwrap();
    assert_eq!(r.paired.len(), 3);
    assert!(r.paired.iter().all(|p| p.pairs == 3));
    assert_eq!(r.routes.len(), 3);
    let md = fogline_sim::output::markdown(&res);
    assert!(md.contains("## Condition ramps"), "{md}");
    assert!(md.contains("| ramps/guard | 3 |"), "{md}");
    assert!(md.contains("of the oracle hand-over's"), "{md}");
}
