//! The `cargo fuzz` corpora (`fuzz/corpus/<target>/`) and crash inputs
//! (`fuzz/regressions/<target>/`) replayed on stable Rust, with the same checks as the fuzz
//! targets (`aeris_hub::testing::fuzz_check_bytes`, `aeris_llm::view::fuzz_check_text` with
//! `aeris_hub::testing::fuzz_check_model_decision`,
//! `aeris_roles::controller::testing::fuzz_check_mavlink`)
//! and the limits of the built-in default flight.
//!
//! The seed inputs are written by the ignored test `write_seed_corpus`:
//! `cargo test -p aeris-roles --test fuzz_corpus -- --ignored write_seed_corpus`.

use aeris_hub::DecisionGate;
use aeris_hub::testing::{fuzz_check_bytes, fuzz_check_model_decision, fuzz_decision_to_bytes};
use aeris_llm::DecisionView;
use aeris_llm::view::fuzz_check_text;
use aeris_mavlink::px4::PX4_MAIN_MODE_OFFBOARD;
use aeris_orchestrator::workflow::Workflow;
use aeris_roles::controller::TrackerConfig;
use aeris_roles::controller::testing::fuzz_check_mavlink;
use aeris_runtime::RoleSpec;
use aeris_schemas::{ActionMode, Decision, OCCUPANCY_SIDE};
use mavlink::MavHeader;
use mavlink::dialects::common::{
    ATTITUDE_DATA, COMMAND_ACK_DATA, EXTENDED_SYS_STATE_DATA, HEARTBEAT_DATA,
    LOCAL_POSITION_NED_DATA, MavAutopilot, MavCmd, MavLandedState, MavMessage, MavModeFlag,
    MavResult, MavState, MavType, MavVtolState,
};
use std::path::{Path, PathBuf};

/// The controller's spec in the built-in default flight (as `fuzz/src/lib.rs` builds it).
fn default_spec() -> RoleSpec {
    let w = Workflow::builtin_default().expect("the built-in default flight is valid");
    RoleSpec {
        flight: "fuzz".into(),
        name: "controller".into(),
        kind: aeris_schemas::RoleKind::Controller,
        variant: "mavlink".into(),
        cpus: String::new(),
        timing: w.timing,
        camera: w.camera,
        mission: w.mission,
        params: Default::default(),
        instance: 0,
        remote: None,
        heartbeat_pid: None,
        flight_clock_offset_ns: 0,
        accelerator: None,
        vehicle: None,
        clock: Default::default(),
    }
}

fn default_gate() -> DecisionGate {
    DecisionGate::new(default_spec().mission.decision_limits()).expect("coherent limits")
}

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
}

/// Every input of `target`: its corpus and its crash regressions, sorted by path.
fn inputs(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    for dir in ["corpus", "regressions"] {
        let Ok(entries) = std::fs::read_dir(fuzz_dir().join(dir).join(target)) else {
            continue;
        };
        for e in entries {
            let path = e.expect("directory entry").path();
            if path.is_file() {
                let bytes = std::fs::read(&path).expect("readable corpus file");
                out.push((path, bytes));
            }
        }
    }
    out.sort();
    assert!(
        out.iter()
            .any(|(p, _)| p.to_string_lossy().contains("seed-")),
        "no seed inputs for `{target}` under {}",
        fuzz_dir().display()
    );
    out
}

/// Run `check` on every input, naming the input that panics.
fn replay(target: &str, mut check: impl FnMut(&[u8])) -> usize {
    let inputs = inputs(target);
    for (path, bytes) in &inputs {
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| check(bytes)));
        assert!(r.is_ok(), "{target}: {} broke a check", path.display());
    }
    println!("{target}: {} inputs replayed", inputs.len());
    inputs.len()
}

#[test]
fn gate_bytes_corpus_holds() {
    let gate = default_gate();
    let mut admitted = 0;
    let n = replay("gate_bytes", |b| {
        admitted += fuzz_check_bytes(&gate, b).is_some() as usize
    });
    assert!(admitted > 0 && admitted < n, "{admitted} of {n} admitted");
    // the seeds do what their names say
    let seed = |name: &str| {
        let b = std::fs::read(fuzz_dir().join("corpus/gate_bytes").join(name)).expect("seed");
        fuzz_check_bytes(&gate, &b)
    };
    let takeoff = seed("seed-takeoff").expect("takeoff admitted");
    assert_eq!((takeoff.position, takeoff.clamped), ([0.0, 0.0, 12.0], 0));
    let wall = seed("seed-goto-east-wall").expect("pulled back before the wall");
    assert_eq!(wall.clamped, 1);
    assert!((wall.position[1] - 52.0).abs() < 1e-3, "{wall:?}");
    let roof = seed("seed-ascend-over-roof").expect("raised over the roof");
    assert_eq!((roof.position[2], roof.clamped), (18.0, 1));
    assert!(seed("seed-land").is_some());
    for rejected in [
        "seed-land-on-sign",
        "seed-nan-speed",
        "seed-outside-fence",
        "seed-step-0",
    ] {
        assert!(seed(rejected).is_none(), "{rejected} admitted");
    }
}

#[test]
fn gate_json_corpus_holds() {
    let gate = default_gate();
    let mut admitted = 0;
    let n = replay("gate_json", |b| {
        let text = String::from_utf8_lossy(b);
        fuzz_check_text(&text, |d| {
            let ok = fuzz_check_model_decision(&gate, d).is_some();
            admitted += ok as usize;
            ok
        });
    });
    assert!(admitted > 0 && admitted < n, "{admitted} of {n} admitted");
}

#[test]
fn controller_mavlink_corpus_holds() {
    let cfg = TrackerConfig::from_spec(&default_spec());
    replay("controller_mavlink", |b| fuzz_check_mavlink(cfg, b));
}

// --- seeds -------------------------------------------------------------------------------

fn decision(step: u16, action: ActionMode, target: [f32; 3], altitude: f32) -> Decision {
    Decision {
        seq: 7,
        cycle: 7,
        target,
        yaw: 0.0,
        speed: 5.0,
        altitude,
        acceptance_radius: 3.0,
        confidence: 0.9,
        step,
        action: action as u8,
        source: 1,
        ..Decision::default()
    }
}

/// The bytes after the decision (see `aeris_hub::testing::fuzz_check_decision`): tame
/// coordinates, a 1 m grid centred on `origin` when given, `cells` as `(row, col, top)`.
/// A seed grid: origin `[N, E]`, unknown (not free) cells, cells set as `(row, col, top)`.
type SeedGrid<'a> = ([f32; 2], bool, &'a [(usize, usize, u8)]);

fn aux(position: [f32; 3], grid: Option<SeedGrid<'_>>) -> Vec<u8> {
    let cm = |v: f32| ((v * 100.0).round() as i16).to_le_bytes();
    let flags = match grid {
        None => 0u8,
        Some((_, unknown, _)) => 1 | if unknown { 2 } else { 0 },
    };
    let mut out = vec![flags];
    for v in position {
        out.extend(cm(v));
    }
    if let Some((origin, _, cells)) = grid {
        out.extend(cm(origin[0]));
        out.extend(cm(origin[1]));
        out.push(15); // (15 + 1) / 16 = 1 m
        for &(r, c, top) in cells {
            out.extend(((r * OCCUPANCY_SIDE + c) as u16).to_le_bytes());
            out.push(top);
        }
    }
    out
}

fn gate_bytes_seeds() -> Vec<(&'static str, Vec<u8>)> {
    use ActionMode::*;
    let seed = |d: Decision, aux: Vec<u8>| {
        let mut b = fuzz_decision_to_bytes(&d).to_vec();
        b.extend(aux);
        b
    };
    // the default grid cell of [N, E] for a grid centred on `origin` (1 m cells)
    let rc = |origin: [f32; 2], n: f32, e: f32| {
        let half = (OCCUPANCY_SIDE / 2) as f32;
        (
            (n - origin[0] + half) as usize,
            (e - origin[1] + half) as usize,
        )
    };
    // a wall 20 m high across the road east at E = 55
    let o = [62.0, 64.0];
    let wall: Vec<_> = (0..OCCUPANCY_SIDE)
        .map(|r| (r, rc(o, 0.0, 55.0).1, 20))
        .collect();
    let (ur, uc) = rc([62.0, 64.0], 62.0, 64.0);
    let under = [(ur, uc, 15u8)];
    let (lr, lc) = rc([42.0, 88.0], 42.0, 88.0);
    let sign = [(lr, lc, 2u8)];
    let mut nan_speed = decision(2, Goto, [62.0, 0.0, 12.0], 12.0);
    nan_speed.speed = f32::NAN;
    let mut wild = aux([0.0; 3], None);
    wild[0] = 4 | 8 | 1; // raw f32 position and grid geometry
    vec![
        (
            "takeoff",
            seed(
                decision(1, Takeoff, [0.0, 0.0, 12.0], 12.0),
                aux([0.0; 3], None),
            ),
        ),
        (
            "goto-north",
            seed(
                decision(2, Goto, [62.0, 0.0, 12.0], 12.0),
                aux([0.0, 0.0, 12.0], None),
            ),
        ),
        (
            "goto-east-wall",
            seed(
                decision(3, Goto, [62.0, 64.0, 12.0], 12.0),
                aux([62.0, 40.0, 12.0], Some((o, false, &wall))),
            ),
        ),
        (
            "goto-over-wall",
            seed(
                decision(3, Goto, [62.0, 100.0, 30.0], 30.0),
                aux([62.0, 40.0, 30.0], Some((o, true, &wall))),
            ),
        ),
        (
            "land",
            seed(
                decision(4, Land, [42.0, 88.0, 0.0], 12.0),
                aux([62.0, 64.0, 12.0], Some(([42.0, 88.0], true, &[]))),
            ),
        ),
        (
            "land-on-sign",
            seed(
                decision(4, Land, [42.0, 88.0, 0.0], 12.0),
                aux([62.0, 64.0, 12.0], Some(([42.0, 88.0], false, &sign))),
            ),
        ),
        (
            "ascend-over-roof",
            seed(
                decision(3, Ascend, [62.0, 64.0, 10.0], 10.0),
                aux([62.0, 64.0, 10.0], Some((o, false, &under))),
            ),
        ),
        (
            "hover",
            seed(
                decision(2, Hover, [30.0, 0.0, 12.0], 12.0),
                aux([30.0, 0.0, 12.0], None),
            ),
        ),
        (
            "turn",
            seed(
                decision(3, Turn, [62.0, 0.0, 12.0], 12.0),
                aux([62.0, 0.0, 12.0], None),
            ),
        ),
        (
            "descend",
            seed(
                decision(4, Descend, [0.0; 3], 5.0),
                aux([42.0, 88.0, 12.0], None),
            ),
        ),
        (
            "stop",
            seed(
                decision(4, Stop, [42.0, 88.0, 0.0], 12.0),
                aux([42.0, 88.0, 0.0], None),
            ),
        ),
        (
            "outside-fence",
            seed(
                decision(2, Goto, [500.0, 0.0, 12.0], 12.0),
                aux([0.0; 3], None),
            ),
        ),
        (
            "vehicle-outside",
            seed(
                decision(1, Takeoff, [0.0; 3], 12.0),
                aux([-50.0, 200.0, 0.0], None),
            ),
        ),
        ("nan-speed", seed(nan_speed, aux([0.0; 3], None))),
        (
            "step-0",
            seed(
                decision(0, Goto, [62.0, 0.0, 12.0], 12.0),
                aux([0.0; 3], None),
            ),
        ),
        (
            "wild-geometry",
            seed(decision(2, Goto, [62.0, 0.0, 12.0], 12.0), wild),
        ),
    ]
}

fn gate_json_seeds() -> Vec<(&'static str, Vec<u8>)> {
    let view = |step: u16, action: &str, n: f32, e: f32, alt: f32, yaw: f32| DecisionView {
        step,
        action: action.into(),
        north: n,
        east: e,
        altitude: alt,
        yaw_deg: yaw,
        speed: 5.0,
        radius: 3.0,
        confidence: 0.9,
    };
    let mut out: Vec<(&'static str, String)> = vec![
        ("takeoff", view(1, "takeoff", 0.0, 0.0, 12.0, 0.0).to_json()),
        (
            "goto-north",
            view(2, "goto", 62.0, 0.0, 12.0, 0.0).to_json(),
        ),
        (
            "goto-east",
            view(3, "goto", 62.0, 64.0, 12.0, 90.0).to_json(),
        ),
        ("land", view(4, "land", 42.0, 88.0, 12.0, 90.0).to_json()),
        (
            "turn-half",
            view(3, "turn", 62.0, 0.0, 12.0, -180.0).to_json(),
        ),
        ("hover", view(2, "hover", 30.0, 0.0, 12.0, 0.0).to_json()),
        (
            "unknown-action",
            view(2, "loop", 30.0, 0.0, 12.0, 0.0).to_json(),
        ),
        (
            "outside-fence",
            view(2, "goto", 400.0, 0.0, 12.0, 0.0).to_json(),
        ),
    ];
    out.extend([
        (
            "spaced-floats",
            "  {\"step\": 2, \"action\": \"goto\", \"north\": 61.5, \"east\": -0.25, \
             \"altitude\": 12.0, \"yaw_deg\": 1e1, \"speed\": 4.5, \"radius\": 2.5, \
             \"confidence\": 0.95}\n"
                .to_string(),
        ),
        (
            "overflow",
            "{\"step\":2,\"action\":\"goto\",\"north\":1e39,\"east\":0,\"altitude\":12,\
             \"yaw_deg\":0,\"speed\":5,\"radius\":3,\"confidence\":0.9}"
                .to_string(),
        ),
        (
            "extra-key",
            "{\"step\":1,\"action\":\"takeoff\",\"north\":0,\"east\":0,\"altitude\":12,\
             \"yaw_deg\":0,\"speed\":5,\"radius\":3,\"confidence\":0.9,\"why\":\"go\"}"
                .to_string(),
        ),
        (
            "truncated",
            "{\"step\":1,\"action\":\"takeoff\",\"north\":0,\"ea".to_string(),
        ),
        ("prose", "I will take off now.".to_string()),
    ]);
    out.into_iter().map(|(n, s)| (n, s.into_bytes())).collect()
}

fn controller_seeds() -> Vec<(&'static str, Vec<u8>)> {
    let ap = MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    let other = MavHeader { system_id: 2, ..ap };
    let v2 = |out: &mut Vec<u8>, h: MavHeader, m: MavMessage| {
        mavlink::write_v2_msg(out, h, &m).expect("encodes");
    };
    let v1 = |out: &mut Vec<u8>, h: MavHeader, m: MavMessage| {
        mavlink::write_v1_msg(out, h, &m).expect("encodes");
    };
    let heartbeat = |armed: bool| {
        let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        if armed {
            base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: u32::from(PX4_MAIN_MODE_OFFBOARD) << 16,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: base,
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        })
    };
    let position = |ned: [f32; 3], v: [f32; 3]| {
        MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: 1000,
            x: ned[0],
            y: ned[1],
            z: ned[2],
            vx: v[0],
            vy: v[1],
            vz: v[2],
        })
    };
    let attitude = |yaw: f32| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: 1000,
            roll: 0.01,
            pitch: -0.02,
            yaw,
            rollspeed: 0.0,
            pitchspeed: 0.0,
            yawspeed: 0.1,
        })
    };
    let landed = |s: MavLandedState| {
        MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
            landed_state: s,
        })
    };
    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        result: MavResult::MAV_RESULT_ACCEPTED,
    });
    let scene = |mode: Option<ActionMode>, fresh: bool, any: bool| {
        mode.map_or(0, |m| m as u8) | if fresh { 0x10 } else { 0 } | if any { 0x20 } else { 0 }
    };

    let mut on_ground = vec![scene(None, false, false)];
    v2(&mut on_ground, ap, heartbeat(false));
    v2(
        &mut on_ground,
        ap,
        landed(MavLandedState::MAV_LANDED_STATE_ON_GROUND),
    );
    v2(&mut on_ground, ap, position([0.0; 3], [0.0; 3]));
    v2(&mut on_ground, ap, attitude(0.0));

    let mut takeoff = vec![scene(Some(ActionMode::Takeoff), true, false)];
    v2(&mut takeoff, ap, heartbeat(true));
    v2(&mut takeoff, ap, ack);
    for k in 0..6 {
        v2(
            &mut takeoff,
            ap,
            landed(MavLandedState::MAV_LANDED_STATE_TAKEOFF),
        );
        v2(
            &mut takeoff,
            ap,
            position([0.0, 0.0, -2.0 * k as f32], [0.0, 0.0, -2.0]),
        );
    }

    let mut goto = vec![scene(Some(ActionMode::Goto), true, false)];
    v2(&mut goto, ap, heartbeat(true));
    v2(
        &mut goto,
        ap,
        landed(MavLandedState::MAV_LANDED_STATE_IN_AIR),
    );
    for k in 0..6 {
        v2(
            &mut goto,
            ap,
            position([10.0 * k as f32, 0.0, -12.0], [5.0, 0.0, 0.0]),
        );
        v2(&mut goto, ap, attitude(0.05 * k as f32));
    }

    let mut land = vec![scene(Some(ActionMode::Land), false, false)];
    v2(&mut land, ap, heartbeat(true));
    v2(
        &mut land,
        ap,
        landed(MavLandedState::MAV_LANDED_STATE_LANDING),
    );
    for k in 0..4 {
        v2(
            &mut land,
            ap,
            position([70.0, 50.0, -3.0 + k as f32], [0.0, 0.0, 1.0]),
        );
    }
    v2(
        &mut land,
        ap,
        landed(MavLandedState::MAV_LANDED_STATE_UNDEFINED),
    );
    v2(&mut land, ap, position([70.0, 50.0, 0.0], [0.0; 3]));

    let mut mavlink1 = vec![scene(Some(ActionMode::Hover), true, true)];
    v1(&mut mavlink1, ap, heartbeat(true));
    v1(&mut mavlink1, ap, position([5.0, 5.0, -10.0], [0.0; 3]));
    v2(&mut mavlink1, ap, attitude(-3.0));

    // what must be ignored or survived: another system, garbage, a cut frame, far away
    let mut noise = vec![scene(Some(ActionMode::Turn), false, false)];
    v2(&mut noise, other, position([1e6, 0.0, -5.0], [0.0; 3]));
    noise.extend([0xFD, 0x03, 0x00, 0xFE, 0x55, 0xAA, 0x00]);
    v2(
        &mut noise,
        ap,
        position([1e30, -1e30, 1e30], [1e30, 0.0, -1e30]),
    );
    v2(&mut noise, ap, attitude(1e6));
    let mut cut = Vec::new();
    v2(&mut cut, ap, heartbeat(true));
    noise.extend(&cut[..cut.len() - 3]);

    // 25 ticks per message: the setpoint goes stale after the first, the controller holds
    let mut stale = vec![scene(Some(ActionMode::Goto), false, false) | 0xC0];
    v2(&mut stale, ap, heartbeat(true));
    v2(
        &mut stale,
        ap,
        landed(MavLandedState::MAV_LANDED_STATE_IN_AIR),
    );
    v2(&mut stale, ap, position([20.0, -10.0, -12.0], [0.0; 3]));
    v2(&mut stale, ap, attitude(2.0));

    vec![
        ("on-ground", on_ground),
        ("takeoff", takeoff),
        ("goto", goto),
        ("land", land),
        ("mavlink1", mavlink1),
        ("noise", noise),
        ("stale", stale),
    ]
}

/// Write the seed inputs into `fuzz/corpus/<target>/seed-*` (run by hand after a change of
/// the input formats; the fuzzer adds its own inputs beside them).
#[test]
#[ignore = "writes the seed corpus"]
fn write_seed_corpus() {
    for (target, seeds) in [
        ("gate_bytes", gate_bytes_seeds()),
        ("gate_json", gate_json_seeds()),
        ("controller_mavlink", controller_seeds()),
    ] {
        let dir = fuzz_dir().join("corpus").join(target);
        std::fs::create_dir_all(&dir).expect("corpus directory");
        for (name, bytes) in seeds {
            std::fs::write(dir.join(format!("seed-{name}")), bytes).expect("seed written");
        }
    }
}

/// The seeds on disk are what the generator writes (no stale or hand-edited seed).
#[test]
fn seeds_are_current() {
    for (target, seeds) in [
        ("gate_bytes", gate_bytes_seeds()),
        ("gate_json", gate_json_seeds()),
        ("controller_mavlink", controller_seeds()),
    ] {
        for (name, bytes) in seeds {
            let path = fuzz_dir()
                .join("corpus")
                .join(target)
                .join(format!("seed-{name}"));
            let on_disk = std::fs::read(&path)
                .unwrap_or_else(|e| panic!("{}: {e} (run write_seed_corpus)", path.display()));
            assert!(
                on_disk == bytes,
                "{} is stale (run write_seed_corpus)",
                path.display()
            );
        }
    }
}
