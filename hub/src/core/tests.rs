//! HubCore's unit tests: ordering, deadline, reuse accounting, sources, the committed
//! setpoint and its hold, ATT.

use super::*;
use crate::att::{AttentionPrior, LexicalScorer};
use aeris_schemas::{ActionMode, DecisionLimits, OCCUPANCY_CELLS, OccupancyStatus, clamp};

const S: u64 = 1_000_000_000;
const TEXTS: [&str; 3] = [
    "take off from the helipad",
    "fly to the red tower",
    "land on the blue roof",
];

fn limits() -> DecisionLimits {
    DecisionLimits {
        v_max: 8.0,
        h_min: 0.0,
        h_max: 60.0,
        r_max: 10.0,
        geofence_min: [-100.0, -100.0, 0.0],
        geofence_max: [100.0, 100.0, 60.0],
        obstacle_clearance_m: 3.0,
        subgoals: 3,
    }
}

fn hub_with(no_att: bool) -> HubCore {
    let attention = Attention::new(
        Box::new(LexicalScorer::new(&TEXTS)),
        3,
        0.5,
        AttentionPrior::default(),
        64,
    )
    .unwrap();
    HubCore::new(
        DecisionGate::new(limits()).unwrap(),
        attention,
        HubConfig {
            heartbeat_period_ns: 2 * S,
            decision_deadline_ns: 2 * S,
            no_att,
        },
        [0.0; 3],
    )
    .unwrap()
}

fn hub() -> HubCore {
    hub_with(false)
}

/// A valid goto of cycle `cycle` with sequence `seq`, started at `start_ns`.
fn goto(seq: u64, cycle: u64, start_ns: u64, target: [f32; 3]) -> Decision {
    Decision {
        seq,
        cycle,
        cycle_start_ns: start_ns,
        state_stamp_ns: start_ns,
        reasoning_start_ns: start_ns,
        publish_ns: start_ns,
        target,
        yaw: 0.5,
        speed: 4.0,
        altitude: target[2],
        acceptance_radius: 2.0,
        confidence: 0.9,
        step: 2,
        action: ActionMode::Goto as u8,
        reserved: 0,
        source: 0,
    }
}

fn state(summary: &str) -> PerceptionState {
    let mut s = PerceptionState::default();
    s.summary.set(summary);
    s
}

/// A grid of 1 m cells centred on the origin, free but for a wall `top` m high across
/// it at N in `[north, north + 1)`.
fn wall_north(north: i32, top: u8) -> OccupancyGrid {
    let mut g = OccupancyGrid {
        cells: [0; OCCUPANCY_CELLS],
        ..OccupancyGrid::observed([0.0, 0.0], 1.0)
    };
    let row = (north + 32) as usize;
    g.cells[row * 64..(row + 1) * 64].fill(top);
    g
}

/// Feed `h` an S_t whose present grid shows all free ground (the hub is blind before).
fn sees_free_ground(h: &mut HubCore, now_ns: u64) {
    let mut s = state("open ground");
    s.occupancy = wall_north(0, 0);
    h.on_state(&s, now_ns).unwrap();
}

fn committed(v: DecisionVerdict) -> (BoundSetpoint, HubReport) {
    match v {
        DecisionVerdict::Committed { setpoint, report } => (setpoint, report),
        other => panic!("expected a commit, got {other:?}"),
    }
}

#[test]
fn a_swapped_in_reasoner_takes_over_with_its_first_timely_decision_and_costs_no_slot() {
    let mut h = hub();
    let from = |source: u32, seq: u64, start: u64| Decision {
        source,
        ..goto(seq, seq, start, [10.0, 0.0, 10.0])
    };
    // the old instance 3 has been deciding every heartbeat
    for k in 1..=5u64 {
        committed(h.on_decision(&from(3, 40 + k, 2 * k * S), 2 * k * S + 1));
    }
    // a candidate's first decision arrives late (it was still warming up): rejected,
    // but it neither takes over nor costs the running reasoner its slot
    let v = h.on_decision(&from(7, 1, 8 * S), 11 * S);
    assert!(
        matches!(v, DecisionVerdict::Late { report: None, .. }),
        "{v:?}"
    );
    assert_eq!(h.decision_source(), Some(3));
    assert_eq!(h.counters().decisions_reused, 0);
    // its next one is in time: it takes over, its own numbering (1, 2) accepted
    let (_, r) = committed(h.on_decision(&from(7, 2, 12 * S), 12 * S + 1));
    assert_eq!((r.decision_source, r.counts.source_switches), (7, 1));
    // the old one, not stopped yet, is ignored without costing a slot
    let v = h.on_decision(&from(3, 46, 12 * S + 5), 12 * S + 6);
    assert_eq!(
        v,
        DecisionVerdict::Superseded {
            source: 3,
            active: 7
        }
    );
    committed(h.on_decision(&from(7, 3, 14 * S), 14 * S + 1));
    let c = h.counters();
    assert_eq!(
        (
            c.decisions_committed,
            c.decisions_rejected,
            c.decisions_reused,
            c.decisions_superseded,
            c.sequence_reorders
        ),
        (7, 1, 0, 1, 0)
    );
    // the new one falls silent (rolled back, died): after a whole slot the old
    // instance's next decision is taken again
    committed(h.on_decision(&from(3, 47, 19 * S), 19 * S + 1));
    assert_eq!(h.decision_source(), Some(3));
    assert_eq!(h.counters().source_switches, 2);
}

#[test]
fn no_setpoint_before_the_first_valid_decision() {
    let mut h = hub();
    assert_eq!(h.on_tick(S), TickOutput::default());
    let mut bad = goto(1, 1, S, [10.0, 0.0, 10.0]);
    bad.speed = f32::NAN;
    let v = h.on_decision(&bad, S + 1);
    assert!(matches!(
        v,
        DecisionVerdict::Rejected {
            reason: RejectReason::Gate(GateError::Invalid(_)),
            report: None
        }
    ));
    assert_eq!(h.on_tick(100 * S), TickOutput::default());
    let c = h.counters();
    assert_eq!(
        (
            c.decisions_received,
            c.decisions_rejected,
            c.decisions_reused
        ),
        (1, 1, 0)
    );
}

#[test]
fn a_garbage_decision_leaves_the_last_valid_one_in_force() {
    let mut h = hub();
    h.on_telemetry([1.0, 1.0, 10.0]);
    let good = goto(1, 1, S, [30.0, 10.0, 12.0]);
    let (fresh, report) = committed(h.on_decision(&good, S + S / 2));
    assert_eq!((report.committed, report.reused, report.cycle), (1, 0, 1));
    let before = h.on_tick(S + S / 2 + 1).setpoint.unwrap();
    assert_eq!(before.reused, 0);
    assert_eq!(before.position, fresh.position);

    let mut garbage = goto(2, 2, 2 * S, [30.0, 10.0, 12.0]);
    garbage.target[0] = f32::INFINITY;
    garbage.action = 0xEE;
    match h.on_decision(&garbage, 2 * S + 1) {
        DecisionVerdict::Rejected {
            report: Some(r), ..
        } => {
            assert_eq!(
                (r.reused, r.committed, r.counts.decisions_reused),
                (1, 0, 1)
            );
            assert_eq!(r.validate(), Ok(()));
        }
        other => panic!("{other:?}"),
    }
    let after = h.on_tick(2 * S + 2).setpoint.unwrap();
    let expected = h.gate().admit(&good, [1.0, 1.0, 10.0], None).unwrap();
    assert_eq!(after.position, expected.position);
    assert_eq!(
        (after.decision_seq, after.mode),
        (1, ActionMode::Goto as u8)
    );
    assert_eq!((after.reused, after.seq), (1, before.seq + 1));
    // a second garbage decision in the same slot: rejected, but no second reuse
    let mut again = garbage;
    again.seq = 3;
    assert!(matches!(
        h.on_decision(&again, 2 * S + 3),
        DecisionVerdict::Rejected { report: None, .. }
    ));
    let c = h.counters();
    assert_eq!((c.decisions_rejected, c.decisions_reused), (2, 1));
}

#[test]
fn late_and_future_decisions_are_rejected() {
    let mut h = hub();
    sees_free_ground(&mut h, 0);
    let (first, _) = committed(h.on_decision(&goto(1, 1, 10 * S, [20.0, 0.0, 10.0]), 11 * S));
    // 2.5 s after its cycle start: late
    let late = goto(2, 2, 12 * S, [-20.0, 0.0, 10.0]);
    match h.on_decision(&late, 14 * S + S / 2) {
        DecisionVerdict::Late { age_ns, report } => {
            assert_eq!(age_ns, 2 * S + S / 2);
            assert_eq!(report.map(|r| r.counts.decisions_late), Some(1));
        }
        other => panic!("{other:?}"),
    }
    // exactly at the deadline is on time
    let on_time = goto(3, 3, 13 * S, [-20.0, 0.0, 10.0]);
    let (sp, _) = committed(h.on_decision(&on_time, 15 * S));
    assert_ne!(sp.position, first.position);
    let future = goto(4, 4, 20 * S, [5.0, 0.0, 10.0]);
    assert!(matches!(
        h.on_decision(&future, 16 * S),
        DecisionVerdict::Rejected {
            reason: RejectReason::FutureTimestamp { .. },
            ..
        }
    ));
    let tick = h.on_tick(16 * S).setpoint.unwrap();
    assert_eq!((tick.decision_seq, tick.position), (3, sp.position));
    let c = h.counters();
    assert_eq!(
        (
            c.decisions_late,
            c.decisions_rejected,
            c.decisions_committed
        ),
        (1, 2, 2)
    );
}

#[test]
fn each_missed_heartbeat_counts_one_reuse() {
    let mut h = hub();
    committed(h.on_decision(&goto(1, 7, 0, [20.0, 0.0, 10.0]), S));
    // the next cycle is due by 0 + 2 s period + 2 s deadline
    let t = h.on_tick(4 * S);
    assert_eq!((t.report, t.setpoint.unwrap().reused), (None, 0));
    let t = h.on_tick(4 * S + 1);
    let r = t.report.unwrap();
    assert_eq!((r.reused, r.cycle, r.counts.decisions_reused), (1, 8, 1));
    assert_eq!(t.setpoint.unwrap().reused, 1);
    assert_eq!(h.on_tick(5 * S).report, None);
    let r = h.on_tick(6 * S + 1).report.unwrap();
    assert_eq!((r.cycle, r.counts.decisions_reused), (9, 2));
    // a stall over three more periods: three reuses, one report
    let r = h.on_tick(12 * S + 1).report.unwrap();
    assert_eq!(r.counts.decisions_reused, 5);
    assert_eq!(h.on_tick(12 * S + 2).report, None);
    // a fresh decision ends the reuse
    let (_, r) = committed(h.on_decision(&goto(2, 13, 12 * S, [0.0, 20.0, 10.0]), 13 * S));
    assert_eq!(
        (r.committed, r.reused, r.counts.decisions_reused),
        (1, 0, 5)
    );
    assert_eq!(h.on_tick(13 * S).setpoint.unwrap().reused, 0);
    assert_eq!(h.counters().decisions_reused, 5);
}

#[test]
fn a_rejection_counts_its_slot_once() {
    let mut h = hub();
    committed(h.on_decision(&goto(1, 1, 0, [20.0, 0.0, 10.0]), S));
    let mut bad = goto(2, 2, 2 * S, [20.0, 0.0, 10.0]);
    bad.step = 99;
    assert!(matches!(
        h.on_decision(&bad, 3 * S),
        DecisionVerdict::Rejected {
            report: Some(_),
            ..
        }
    ));
    // the slot that the rejection already counted closes without a second reuse
    assert_eq!(h.on_tick(4 * S + 1).report, None);
    assert_eq!(h.counters().decisions_reused, 1);
    // the next one does count
    assert!(h.on_tick(6 * S + 1).report.is_some());
    assert_eq!(h.counters().decisions_reused, 2);
}

#[test]
fn stages_and_cycle_time_of_a_commit() {
    let mut h = hub();
    let mut d = goto(1, 4, 1_000, [10.0, 0.0, 10.0]);
    d.state_stamp_ns = 1_500;
    d.reasoning_start_ns = 1_600;
    d.publish_ns = 1_800;
    let (sp, r) = committed(h.on_decision_timed(&d, 2_000, || 2_100));
    assert_eq!(r.stage_ns, [500, 300, 200, 100]);
    assert_eq!((r.ct_ns, r.cycle, r.publish_ns), (1_100, 4, 2_100));
    assert_eq!(sp.publish_ns, 2_100);
    assert_eq!(r.stage_ns.iter().sum::<u64>(), r.ct_ns);
}

#[test]
fn gaps_and_reorders_are_counted_and_reorders_rejected() {
    let mut h = hub();
    let t = 10 * S;
    for seq in [1, 2, 5] {
        committed(h.on_decision(&goto(seq, seq, t, [10.0, 0.0, 10.0]), t + seq));
    }
    for seq in [4, 5, 0] {
        assert!(matches!(
            h.on_decision(&goto(seq, seq, t, [10.0, 0.0, 10.0]), t + 9),
            DecisionVerdict::Rejected {
                reason: RejectReason::Sequence { .. },
                ..
            }
        ));
    }
    let c = h.counters();
    assert_eq!((c.sequence_gaps, c.sequence_reorders), (1, 3));
    assert_eq!((c.decisions_received, c.decisions_rejected), (6, 3));
    assert_eq!(h.last_valid().map(|d| d.seq), Some(5));
    assert_eq!(h.sequence().missing(), 2);
    // a restarted reasoner starts over at 1, with a newer cycle start: accepted
    committed(h.on_decision(&goto(1, 1, t + S, [10.0, 0.0, 10.0]), t + S));
    assert_eq!(h.sequence().restarts(), 1);
    committed(h.on_decision(&goto(2, 2, t + S, [10.0, 0.0, 10.0]), t + S));
}

#[test]
fn an_infeasible_decision_becomes_a_latched_hold() {
    let mut h = hub();
    h.on_telemetry([0.0, 0.0, 10.0]);
    sees_free_ground(&mut h, 0);
    committed(h.on_decision(&goto(1, 1, S, [30.0, 0.0, 10.0]), S));
    assert_eq!(h.on_tick(S).setpoint.unwrap().position, [30.0, 0.0, 10.0]);
    // a wall appears 2 m ahead: pulling back leaves no motion
    let mut s = state("a wall");
    s.position = [0.0, 0.0, 10.0];
    s.occupancy = wall_north(2, 40);
    h.on_state(&s, S).unwrap();
    h.on_telemetry([0.4, 0.1, 10.2]);
    let sp = h.on_tick(S + 1).setpoint.unwrap();
    assert_eq!(
        (sp.mode, sp.position),
        (ActionMode::Hover as u8, [0.4, 0.1, 10.2])
    );
    assert_eq!(sp.validate(&limits()), Ok(ActionMode::Hover));
    // the hold stays where it was latched while the vehicle drifts
    h.on_telemetry([0.9, -0.3, 10.0]);
    assert_eq!(
        h.on_tick(S + 2).setpoint.unwrap().position,
        [0.4, 0.1, 10.2]
    );
    // the wall is gone: the decision is flown again
    s.occupancy.cells = [0; OCCUPANCY_CELLS];
    h.on_state(&s, S).unwrap();
    let sp = h.on_tick(S + 3).setpoint.unwrap();
    assert_eq!(
        (sp.mode, sp.position),
        (ActionMode::Goto as u8, [30.0, 0.0, 10.0])
    );
}

/// The setpoint a decision was committed to is the one flown: the vehicle moving (with
/// or without a new S_t whose grid leaves its way clear) does not make the hub run the
/// gate again and bind it elsewhere, though a fresh admission would.
#[test]
fn a_decision_is_gated_once_and_its_setpoint_kept_while_the_vehicle_moves() {
    let mut h = hub();
    h.on_telemetry([0.0, 0.0, 10.0]);
    // a wall 20 m high across the way at N in [10, 11)
    let mut s = state("a wall ahead");
    s.occupancy = wall_north(10, 20);
    h.on_state(&s, S).unwrap();
    let d = goto(1, 1, S, [25.0, 0.0, 10.0]);
    let (committed, _) = self::committed(h.on_decision(&d, S));
    // pulled back 3 m before the wall
    assert_eq!(
        (committed.position, committed.clamped),
        ([7.0, 0.0, 10.0], 1)
    );
    let first = h.on_tick(S + 1).setpoint.unwrap();
    assert_eq!((first.position, first.clamped), (committed.position, 1));
    // the vehicle moves east: from there the gate would pull the goal back elsewhere
    let moved = [2.0, 6.0, 10.0];
    h.on_telemetry(moved);
    let again = h.gate().admit(&d, moved, Some(&s.occupancy)).unwrap();
    assert_ne!(again.position, committed.position);
    let sp = h.on_tick(S + 2).setpoint.unwrap();
    assert_eq!(
        (sp.position, sp.mode, sp.clamped, sp.decision_seq),
        (committed.position, ActionMode::Goto as u8, 1, 1)
    );
    assert_eq!(sp.seq, first.seq + 1);
    // a new S_t with the same wall: the way to the committed setpoint is still clear
    h.on_state(&s, S + 3).unwrap();
    let sp = h.on_tick(S + 4).setpoint.unwrap();
    assert_eq!(
        (sp.position, sp.mode),
        (committed.position, ActionMode::Goto as u8)
    );
}

/// Without occupancy (none yet, absent, stale) unknown space is not free: a move is held
/// until the vehicle is at the conservative altitude (the band's top, 60 m here), and the
/// reports say so; a present grid in which nothing was seen is flown as before.
#[test]
fn without_occupancy_moves_wait_for_the_conservative_altitude_and_reports_say_so() {
    let d = |seq| goto(seq, seq, seq * S, [30.0, 0.0, 10.0]);
    for status in [
        None,
        Some(OccupancyStatus::Absent),
        Some(OccupancyStatus::Stale),
    ] {
        let mut h = hub();
        h.on_telemetry([0.0, 0.0, 10.0]);
        if let Some(status) = status {
            let mut s = state("no depth");
            s.occupancy = wall_north(0, 0);
            s.occupancy.status = status as u8;
            h.on_state(&s, 0).unwrap();
        }
        let (sp, r) = committed(h.on_decision(&d(1), S));
        // climb where it is first
        assert_eq!(
            (sp.position, sp.clamped),
            ([0.0, 0.0, 60.0], 1),
            "{status:?}"
        );
        assert_eq!(r.clamp_reasons, clamp::NO_OCCUPANCY, "{status:?}");
        let want = status.unwrap_or(OccupancyStatus::Absent);
        assert_eq!(r.occupancy_status(), Some(want));
        assert_eq!(r.validate(), Ok(()));
        // up there: the move is flown, at that altitude
        h.on_telemetry([0.0, 0.0, 59.5]);
        let (sp, r) = committed(h.on_decision(&d(2), 2 * S));
        assert_eq!(sp.position, [30.0, 0.0, 60.0], "{status:?}");
        assert_eq!(r.clamp_reasons, clamp::NO_OCCUPANCY);
    }
    // present and empty (nothing observed yet): as before, unknown cells do not block
    let mut h = hub();
    h.on_telemetry([0.0, 0.0, 10.0]);
    let mut s = state("nothing seen");
    s.occupancy = aeris_schemas::OccupancyGrid::observed([0.0, 0.0], 2.0);
    h.on_state(&s, 0).unwrap();
    let (sp, r) = committed(h.on_decision(&d(1), S));
    assert_eq!((sp.position, sp.clamped), ([30.0, 0.0, 10.0], 0));
    assert_eq!(
        (r.clamp_reasons, r.occupancy_status()),
        (0, Some(OccupancyStatus::Present))
    );
}

/// A committed move below the conservative altitude becomes a hold when an S_t without
/// occupancy arrives, and is flown again once occupancy is back.
#[test]
fn losing_occupancy_holds_a_low_move_until_it_is_back() {
    let mut h = hub();
    h.on_telemetry([0.0, 0.0, 10.0]);
    sees_free_ground(&mut h, 0);
    let (_, r) = committed(h.on_decision(&goto(1, 1, S, [30.0, 0.0, 10.0]), S));
    assert_eq!(r.occupancy_status(), Some(OccupancyStatus::Present));
    h.on_telemetry([2.0, 0.0, 10.0]);
    h.on_state(&state("depth lost"), S + 1).unwrap();
    let sp = h.on_tick(S + 2).setpoint.unwrap();
    assert_eq!(
        (sp.mode, sp.position),
        (ActionMode::Hover as u8, [2.0, 0.0, 10.0])
    );
    sees_free_ground(&mut h, S + 3);
    let sp = h.on_tick(S + 4).setpoint.unwrap();
    assert_eq!(
        (sp.mode, sp.position),
        (ActionMode::Goto as u8, [30.0, 0.0, 10.0])
    );
}

#[test]
fn in_place_actions_stay_anchored() {
    let mut h = hub();
    h.on_telemetry([1.0, 2.0, 0.0]);
    let mut d = goto(1, 1, S, [1.0, 2.0, 10.0]);
    d.action = ActionMode::Takeoff as u8;
    d.step = 1;
    committed(h.on_decision(&d, S));
    h.on_telemetry([3.0, 4.0, 5.0]);
    assert_eq!(h.on_tick(S).setpoint.unwrap().position, [1.0, 2.0, 10.0]);
}

#[test]
fn bad_states_and_telemetry_are_ignored() {
    let mut h = hub();
    let mut s = state("x");
    s.cue_count = 99;
    assert!(h.on_state(&s, S).is_err());
    assert!(!h.on_telemetry([f32::NAN, 0.0, 0.0]));
    assert_eq!(h.position(), [0.0; 3]);
    let c = h.counters();
    assert_eq!((c.states_received, c.states_rejected), (1, 1));
    // before telemetry, a state's position is used
    let mut s = state("x");
    s.position = [5.0, 6.0, 7.0];
    h.on_state(&s, S).unwrap();
    assert_eq!(h.position(), [5.0, 6.0, 7.0]);
    h.on_telemetry([1.0, 1.0, 1.0]);
    h.on_state(&s, S).unwrap();
    assert_eq!(h.position(), [1.0, 1.0, 1.0]);
}

#[test]
fn att_alpha_sums_to_one_and_follows_progress() {
    let mut h = hub();
    let scenes = [
        ("helipad below, taking off", 1),
        ("open field", 1),
        ("a red tower ahead", 2),
        ("red tower close, trees", 2),
        ("a blue roof below", 3),
        // evidence for an earlier subgoal does not move ATT back
        ("a red tower behind, helipad", 3),
        ("blue roof", 3),
    ];
    let mut steps = Vec::new();
    for (i, (text, want)) in scenes.iter().enumerate() {
        h.on_state(&state(text), i as u64).unwrap();
        let a = h.attention_now();
        let sum: f32 = a.alpha[..3].iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "{sum}");
        assert!(a.alpha[3..].iter().all(|v| *v == 0.0));
        assert_eq!(h.active_step(), *want, "after {text:?}");
        steps.push(h.active_step());
    }
    let trace: Vec<usize> = h.attention().trace().map(|e| e.active).collect();
    assert_eq!(trace, vec![0, 0, 1, 1, 2, 2, 2]);
    // reports carry the attention and the active step
    let (sp, r) = committed(h.on_decision(&goto(1, 1, S, [10.0, 0.0, 10.0]), S));
    assert_eq!((sp.active_step, r.active_step, r.subgoals), (3, 3, 3));
    assert_eq!(r.validate(), Ok(()));
    assert!((r.alpha().iter().sum::<f32>() - 1.0).abs() < 1e-5);
}

#[test]
fn declared_step_pulls_att_forward_and_no_att_follows_it() {
    let mut h = hub();
    let mut d = goto(1, 1, S, [10.0, 0.0, 10.0]);
    d.step = 2;
    committed(h.on_decision(&d, S));
    h.on_state(&state("nothing in particular"), S).unwrap();
    assert_eq!(h.active_step(), 2);

    let mut h = hub_with(true);
    assert_eq!(h.active_step(), 1);
    d.step = 3;
    committed(h.on_decision(&d, S));
    h.on_state(&state("helipad"), S).unwrap();
    assert_eq!(h.active_step(), 3);
    let a = h.attention_now();
    assert_eq!(&a.alpha[..3], &[0.0, 0.0, 1.0]);
    assert_eq!(h.attention().updates(), 0);
}
