//! The recorded observations of the replay example.

use fogline_rco::verifier::{Inconsistency, Refusal};
use fogline_rco::{HazardState, Rco, RcoParams, ReplanReason, Source, Strategy, replay, synth};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/observations.jsonl");

/// The committed file is the story (`FOGLINE_RCO_WRITE_DATA=1` rewrites it).
#[test]
fn committed_observations_are_the_story() {
    let text = replay::to_jsonl(&synth::story());
    if std::env::var_os("FOGLINE_RCO_WRITE_DATA").is_some() {
        std::fs::write(DATA, &text).unwrap();
    }
    let committed = std::fs::read_to_string(DATA).unwrap();
    assert!(
        committed == text,
        "regenerate with FOGLINE_RCO_WRITE_DATA=1"
    );
    let obs = replay::read_observations(committed.as_bytes()).unwrap();
    assert!(
        obs == synth::story(),
        "the file does not read back as the story"
    );
}

#[test]
fn replaying_the_story_with_the_rules() {
    let mut rco = Rco::with_rules(RcoParams::default()).unwrap();
    let decisions: Vec<_> = synth::story().iter().map(|o| rco.step(o)).collect();
    for d in &decisions {
        eprintln!("{}", d.summary());
    }
    assert!(decisions.iter().all(|d| d.fallback.is_none()));
    // Clean start: move.
    assert_eq!(decisions[0].strategy, Some(Strategy::Move));
    // The pedestrian vanishes at tick 10: a new plan, and the ego stops and observes.
    assert!(decisions[10].replanned);
    assert_eq!(decisions[10].strategy, Some(Strategy::StopObserveMove));
    assert!(
        decisions[10]
            .hazards
            .iter()
            .any(|h| h.object == "pedestrian")
    );
    assert_eq!(decisions[11].source, Source::Wait);
    // The pedestrian reappears at tick 25: the deficit disappeared, the plan is refused.
    assert_eq!(decisions[25].replan_reason, Some(ReplanReason::Refused));
    assert!(matches!(
        decisions[25].refusal,
        Some(Refusal::Inconsistent {
            change: Inconsistency::Disappeared { .. }
        })
    ));
    // The masked traffic light from tick 32: approached with care (rule S4: the driving
    // stack stops at its line as at an all-way stop), no stop where it is first seen.
    assert_eq!(decisions[32].strategy, Some(Strategy::Move));
    assert_ne!(decisions[32].action.behavior, fogline_rco::Behavior::Stop);
    assert!(
        decisions[32]
            .hazards
            .iter()
            .any(|h| h.object == "traffic light")
    );
    // A move trigger held at some point and the ego moved on.
    assert!(
        decisions
            .iter()
            .any(|d| d.replan_reason == Some(ReplanReason::TriggerHeld))
    );
    // The lane change is taken while the left view is clear.
    assert!(
        decisions[64..=72]
            .iter()
            .any(|d| d.action.behavior == fogline_rco::Behavior::ChangeLaneToLeft)
    );
    // Dirt on the right camera: a count change, then an immediate hazard there.
    assert!(matches!(
        decisions[60].refusal,
        Some(Refusal::Inconsistent {
            change: Inconsistency::CountChanged { .. }
        })
    ));
    assert_eq!(
        decisions[61].observed[2].state,
        HazardState::ImmediateHazard
    );
    // The camera dropout forces a stop; its return does not cut the wait short (standing
    // still needs no consistency check).
    assert_eq!(decisions[75].strategy, Some(Strategy::StopObserveMove));
    assert_eq!(decisions[77].source, Source::Wait);
    assert_eq!(decisions[77].refusal, None);
}
