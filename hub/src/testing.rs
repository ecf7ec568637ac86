//! The gate's promises as executable checks, shared by the `cargo fuzz` targets in `fuzz/`
//! (`gate_bytes`, `gate_json`) and the corpus replay tests (`roles/tests/fuzz_corpus.rs`), so
//! that both check exactly the same things.
//!
//! Every check panics on a broken promise: that is how a fuzzer sees a failure, and why
//! this module is test support, not API for flight code (nothing in a role calls it).
//! What the checks hold the gate to is the [`crate::gate`] module documentation: only a
//! decision that passes Valid(D_t) is admitted, in its own mode; what comes out is flyable,
//! inside the geofence and the altitude band, bound as the binding table says, flagged
//! `clamped` whenever anything differs from that table, and clear of every obstacle by the
//! clearance, or, without occupancy, moving only at the conservative altitude; and any
//! finite position can be held.

use crate::gate::{DecisionGate, GateError, obstacle, obstacle_top};
use aeris_schemas::{
    ActionMode, BLIND_CLIMB_SLACK_M, BLIND_MOVE_M, BoundSetpoint, Decision, DecisionLimits,
    OCCUPANCY_CELLS, OCCUPANCY_SIDE, OCCUPANCY_UNKNOWN, OccupancyGrid, OccupancyStatus, all_finite,
};

/// Size of a [`Decision`] in shared memory: every byte belongs to a field (no padding), so
/// any byte pattern is a `Decision` a misbehaving publisher could write.
pub const FUZZ_DECISION_BYTES: usize = core::mem::size_of::<Decision>();

const _: () = assert!(FUZZ_DECISION_BYTES == 6 * 8 + 8 * 4 + 2 + 1 + 1 + 4);

/// The [`Decision`] whose in-memory (`repr(C)`, native-endian) bytes start with `bytes`;
/// missing bytes read as zero, extra bytes are ignored.
pub fn fuzz_decision_from_bytes(bytes: &[u8]) -> Decision {
    use core::mem::offset_of;
    let mut raw = [0u8; FUZZ_DECISION_BYTES];
    let n = bytes.len().min(raw.len());
    raw[..n].copy_from_slice(&bytes[..n]);
    let at = |o: usize| -> [u8; 8] {
        let mut w = [0u8; 8];
        let end = (o + 8).min(raw.len());
        w[..end - o].copy_from_slice(&raw[o..end]);
        w
    };
    let u64_at = |o: usize| u64::from_ne_bytes(at(o));
    let f32_at = |o: usize| {
        let w = at(o);
        f32::from_ne_bytes([w[0], w[1], w[2], w[3]])
    };
    let target = offset_of!(Decision, target);
    let step = at(offset_of!(Decision, step));
    let source = at(offset_of!(Decision, source));
    Decision {
        seq: u64_at(offset_of!(Decision, seq)),
        cycle: u64_at(offset_of!(Decision, cycle)),
        cycle_start_ns: u64_at(offset_of!(Decision, cycle_start_ns)),
        state_stamp_ns: u64_at(offset_of!(Decision, state_stamp_ns)),
        reasoning_start_ns: u64_at(offset_of!(Decision, reasoning_start_ns)),
        publish_ns: u64_at(offset_of!(Decision, publish_ns)),
        target: [f32_at(target), f32_at(target + 4), f32_at(target + 8)],
        yaw: f32_at(offset_of!(Decision, yaw)),
        speed: f32_at(offset_of!(Decision, speed)),
        altitude: f32_at(offset_of!(Decision, altitude)),
        acceptance_radius: f32_at(offset_of!(Decision, acceptance_radius)),
        confidence: f32_at(offset_of!(Decision, confidence)),
        step: u16::from_ne_bytes([step[0], step[1]]),
        action: raw[offset_of!(Decision, action)],
        reserved: raw[offset_of!(Decision, reserved)],
        source: u32::from_ne_bytes([source[0], source[1], source[2], source[3]]),
    }
}

/// The in-memory bytes of `d` (the inverse of [`fuzz_decision_from_bytes`]), for seeds.
pub fn fuzz_decision_to_bytes(d: &Decision) -> [u8; FUZZ_DECISION_BYTES] {
    use core::mem::offset_of;
    let mut raw = [0u8; FUZZ_DECISION_BYTES];
    let mut put = |o: usize, b: &[u8]| raw[o..o + b.len()].copy_from_slice(b);
    put(offset_of!(Decision, seq), &d.seq.to_ne_bytes());
    put(offset_of!(Decision, cycle), &d.cycle.to_ne_bytes());
    put(
        offset_of!(Decision, cycle_start_ns),
        &d.cycle_start_ns.to_ne_bytes(),
    );
    put(
        offset_of!(Decision, state_stamp_ns),
        &d.state_stamp_ns.to_ne_bytes(),
    );
    put(
        offset_of!(Decision, reasoning_start_ns),
        &d.reasoning_start_ns.to_ne_bytes(),
    );
    put(
        offset_of!(Decision, publish_ns),
        &d.publish_ns.to_ne_bytes(),
    );
    for (i, v) in d.target.iter().enumerate() {
        put(offset_of!(Decision, target) + 4 * i, &v.to_ne_bytes());
    }
    put(offset_of!(Decision, yaw), &d.yaw.to_ne_bytes());
    put(offset_of!(Decision, speed), &d.speed.to_ne_bytes());
    put(offset_of!(Decision, altitude), &d.altitude.to_ne_bytes());
    put(
        offset_of!(Decision, acceptance_radius),
        &d.acceptance_radius.to_ne_bytes(),
    );
    put(
        offset_of!(Decision, confidence),
        &d.confidence.to_ne_bytes(),
    );
    put(offset_of!(Decision, step), &d.step.to_ne_bytes());
    put(offset_of!(Decision, action), &[d.action]);
    put(offset_of!(Decision, reserved), &[d.reserved]);
    put(offset_of!(Decision, source), &d.source.to_ne_bytes());
    raw
}

/// Reads fuzz bytes front to back; past the end everything reads as zero.
struct FuzzBytes<'a>(&'a [u8]);

impl FuzzBytes<'_> {
    fn u8(&mut self) -> u8 {
        let (&b, rest) = self.0.split_first().unwrap_or((&0, &[]));
        self.0 = rest;
        b
    }

    fn bits32(&mut self) -> [u8; 4] {
        [self.u8(), self.u8(), self.u8(), self.u8()]
    }

    /// Any f32 bit pattern (NaN, inf, huge, subnormal) when `wild`, else a plausible
    /// coordinate: a whole centimetre in [-327.68, 327.67] m.
    fn coordinate(&mut self, wild: bool) -> f32 {
        if wild {
            f32::from_ne_bytes(self.bits32())
        } else {
            i16::from_le_bytes([self.u8(), self.u8()]) as f32 * 0.01
        }
    }
}

/// Replay `data` as the gate's input: the first [`FUZZ_DECISION_BYTES`] bytes are a
/// [`Decision`] exactly as it would lie in shared memory (see
/// [`fuzz_decision_from_bytes`]); the rest chooses the vehicle position and the occupancy
/// grid (see [`fuzz_check_decision`]). Panics when the gate breaks one of its promises.
pub fn fuzz_check_bytes(gate: &DecisionGate, data: &[u8]) -> Option<BoundSetpoint> {
    let (head, aux) = data.split_at(data.len().min(FUZZ_DECISION_BYTES));
    fuzz_check_decision(gate, &fuzz_decision_from_bytes(head), aux)
}

/// Run `d` through the gate for the vehicle position and occupancy grid that `aux` encodes,
/// and check every promise of the module documentation; the admitted setpoint, if any.
///
/// `aux`: a flags byte (bit 0: a grid is present; bit 1: its cells start unknown instead of
/// free; bit 2: raw f32 bit patterns for the position and grid geometry instead of whole
/// centimetres; bit 3: the grid's resolution is raw too; bit 4: the grid's status is a raw
/// byte instead of present), the position `[N, E, U]`, the grid's origin `[N, E]`, its
/// resolution byte (`(b + 1) / 16` m), its status byte (with bit 4), then `(index lo, index
/// hi, top)` triples that set cells. Missing bytes read as zero.
pub fn fuzz_check_decision(gate: &DecisionGate, d: &Decision, aux: &[u8]) -> Option<BoundSetpoint> {
    let mut r = FuzzBytes(aux);
    let flags = r.u8();
    let wild = flags & 4 != 0;
    let position = [r.coordinate(wild), r.coordinate(wild), r.coordinate(wild)];
    let grid = (flags & 1 != 0).then(|| {
        let origin = [r.coordinate(wild), r.coordinate(wild)];
        let resolution_m = if flags & 8 != 0 {
            f32::from_ne_bytes(r.bits32())
        } else {
            (r.u8() as f32 + 1.0) / 16.0
        };
        let fill = if flags & 2 != 0 { OCCUPANCY_UNKNOWN } else { 0 };
        let mut g = OccupancyGrid::observed(origin, resolution_m);
        g.cells.fill(fill);
        if flags & 16 != 0 {
            g.status = r.u8();
        }
        while r.0.len() >= 3 {
            let i = u16::from_le_bytes([r.u8(), r.u8()]) as usize % OCCUPANCY_CELLS;
            g.cells[i] = r.u8();
        }
        g
    });
    fuzz_check_admission(gate, d, position, grid.as_ref())
}

/// [`fuzz_check_decision`] for a decision parsed from a language model's text: the vehicle
/// on the ground at the origin with no occupancy, then in the air with a grid holding a
/// wall across its way north, then there again with that grid stale. The first admitted
/// setpoint, if any.
pub fn fuzz_check_model_decision(gate: &DecisionGate, d: &Decision) -> Option<BoundSetpoint> {
    let on_ground = fuzz_check_admission(gate, d, [0.0; 3], None);
    let mut g = OccupancyGrid::observed([20.0, 0.0], 1.0);
    g.cells.fill(0);
    // a wall 20 m high at N in [30, 31), and an unobserved strip beside it
    for c in 0..OCCUPANCY_SIDE {
        g.cells[(OCCUPANCY_SIDE / 2 + 10) * OCCUPANCY_SIDE + c] = 20;
        g.cells[(OCCUPANCY_SIDE / 2 + 12) * OCCUPANCY_SIDE + c] = OCCUPANCY_UNKNOWN;
    }
    let airborne = fuzz_check_admission(gate, d, [10.0, 5.0, 12.0], Some(&g));
    g.status = OccupancyStatus::Stale as u8;
    let stale = fuzz_check_admission(gate, d, [10.0, 5.0, 12.0], Some(&g));
    on_ground.or(airborne).or(stale)
}

/// The checks behind [`fuzz_check_decision`].
fn fuzz_check_admission(
    gate: &DecisionGate,
    d: &Decision,
    position: [f32; 3],
    grid: Option<&OccupancyGrid>,
) -> Option<BoundSetpoint> {
    let l = *gate.limits();
    let (lo, hi) = gate.altitude_band();
    let c = gate.clearance_m();
    let pi = core::f32::consts::PI;
    let admitted = gate.admit(d, position, grid);
    // admit is exactly validate -> feasible -> bind (Debug: NaN-carrying errors compare)
    let chained = gate
        .validate(d)
        .and_then(|m| gate.feasible(d, m, position, grid))
        .and_then(|f| gate.bind(d, &f));
    assert_eq!(
        format!("{admitted:?}"),
        format!("{chained:?}"),
        "admit != chain"
    );

    // the hub's fallback: any finite position can be held
    let held = gate.hold(d, position);
    if all_finite(&position) {
        let h = held.unwrap_or_else(|e| panic!("hold({position:?}) failed: {e}"));
        assert_eq!(h.validate(&l), Ok(ActionMode::Hover), "hold: {h:?}");
        assert!(all_finite(&h.position) && all_finite(&[h.yaw, h.speed, h.acceptance_radius]));
        assert!(
            inside_fence_ne(&l, h.position),
            "hold outside the fence: {h:?}"
        );
        assert_eq!(h.position[2], position[2].min(hi), "hold altitude: {h:?}");
        assert!(h.acceptance_radius >= 0.0 && h.acceptance_radius <= l.r_max);
        assert_eq!(h.clamped, 1);
    } else {
        assert!(matches!(held, Err(GateError::BadPosition(_))), "{held:?}");
    }

    let sp = admitted.ok()?;
    // what the hub commits, it keeps flying while the way stays as the gate saw it
    assert_eq!(
        gate.check_way(&sp, position, grid),
        Ok(()),
        "a setpoint just bound fails its way check: {sp:?}"
    );
    // only a decision that passes Valid(D_t) is admitted, in its own mode
    let mode = d
        .validate(&l)
        .unwrap_or_else(|e| panic!("admitted an invalid decision ({e}): {d:?}"));
    assert_eq!(sp.mode, mode as u8);
    assert_eq!(
        sp.validate(&l),
        Ok(mode),
        "admitted an unflyable setpoint: {sp:?}"
    );
    assert!(all_finite(&sp.position), "{sp:?}");
    assert!(
        all_finite(&[sp.yaw, sp.speed, sp.acceptance_radius]),
        "{sp:?}"
    );
    assert!(
        inside_fence_ne(&l, sp.position),
        "outside the geofence: {sp:?}"
    );
    if mode == ActionMode::Land {
        assert_eq!(sp.position[2], 0.0, "land not at the ground: {sp:?}");
    } else {
        assert!(
            sp.position[2] >= lo && sp.position[2] <= hi,
            "outside the band: {sp:?}"
        );
    }
    assert!(sp.speed >= 0.0 && sp.speed <= l.v_max, "{sp:?}");
    assert!(sp.yaw >= -pi && sp.yaw <= pi, "{sp:?}");
    assert!(sp.acceptance_radius >= 0.0 && sp.acceptance_radius <= l.r_max);
    assert_eq!(
        (
            sp.yaw,
            sp.acceptance_radius,
            sp.decision_seq,
            sp.active_step
        ),
        (d.yaw, d.acceptance_radius, d.seq, d.step)
    );
    assert_eq!(
        (sp.seq, sp.publish_ns, sp.reused, sp.reserved),
        (0, 0, 0, [0; 3])
    );
    // the binding table, and `clamped` set whenever anything differs from it
    let here = [
        position[0].clamp(l.geofence_min[0], l.geofence_max[0]),
        position[1].clamp(l.geofence_min[1], l.geofence_max[1]),
    ];
    let h = d.altitude.clamp(lo, hi);
    let unclamped = match mode {
        ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn => {
            [position[0], position[1], d.altitude]
        }
        ActionMode::Goto | ActionMode::Hover | ActionMode::Stop => {
            [d.target[0], d.target[1], d.altitude]
        }
        ActionMode::Land => [d.target[0], d.target[1], 0.0],
    };
    if sp.clamped == 0 {
        assert_eq!(
            (sp.position, sp.speed),
            (unclamped, d.speed),
            "unflagged change: {sp:?}"
        );
    } else {
        assert_eq!(sp.clamped, 1);
    }
    // without occupancy: horizontal moves only at the conservative altitude, in place
    // never below it (or the vehicle's altitude, when lower)
    let present = grid.filter(|g| g.is_present());
    if present.is_none() {
        let b = l.blind_altitude();
        let p = sp.position;
        let away = (f64::from(p[0]) - f64::from(here[0]))
            .hypot(f64::from(p[1]) - f64::from(here[1])) as f32;
        let in_place = matches!(
            mode,
            ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn
        );
        if !in_place && away > BLIND_MOVE_M {
            assert!(
                position[2] >= b - BLIND_CLIMB_SLACK_M,
                "a move of {away} m from {position:?} below the conservative altitude {b}: {sp:?}"
            );
            if mode != ActionMode::Land {
                assert!(
                    p[2] >= b,
                    "a move below the conservative altitude {b}: {sp:?}"
                );
            }
        } else if mode != ActionMode::Land {
            assert!(
                p[2] >= b.min(position[2]),
                "blind descent below {b}: {sp:?}"
            );
        }
    }
    // obstacles, as the module documentation states them
    if let Some(g) = present {
        let p = sp.position;
        match mode {
            ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn => {
                assert_eq!([p[0], p[1]], here);
                if let Some(top) = obstacle_top(g, here) {
                    assert!(top <= p[2] - c + 1e-3, "{top} m obstacle under {sp:?}");
                }
            }
            ActionMode::Goto | ActionMode::Hover | ActionMode::Stop => {
                fuzz_assert_clear(g, here, [p[0], p[1]], p[2] - c, &sp);
            }
            ActionMode::Land => {
                fuzz_assert_clear(g, here, [p[0], p[1]], h.min(position[2]) - c, &sp);
                assert!(
                    obstacle_top(g, [p[0], p[1]]).is_none(),
                    "landed on an obstacle: {sp:?}"
                );
            }
        }
    }
    Some(sp)
}

fn inside_fence_ne(l: &DecisionLimits, p: [f32; 3]) -> bool {
    (0..2).all(|i| p[i] >= l.geofence_min[i] && p[i] <= l.geofence_max[i])
}

/// No point of the segment `from -> to` (sampled finely, independent of the gate's grid
/// traversal) lies in a cell whose obstacle top is `>= threshold`.
fn fuzz_assert_clear(
    g: &OccupancyGrid,
    from: [f32; 2],
    to: [f32; 2],
    threshold: f32,
    sp: &BoundSetpoint,
) {
    const SAMPLES: usize = 1024;
    let res = g.resolution_m as f64;
    let half = (OCCUPANCY_SIDE / 2) as f64;
    let cell = |n: f64, e: f64| {
        let x = ((n - g.origin[0] as f64) / res + half).floor();
        let y = ((e - g.origin[1] as f64) / res + half).floor();
        let side = OCCUPANCY_SIDE as f64;
        (x >= 0.0 && y >= 0.0 && x < side && y < side)
            .then(|| x as usize * OCCUPANCY_SIDE + y as usize)
    };
    for k in 0..=SAMPLES {
        let t = k as f64 / SAMPLES as f64;
        let n = from[0] as f64 + (to[0] as f64 - from[0] as f64) * t;
        let e = from[1] as f64 + (to[1] as f64 - from[1] as f64) * t;
        if let Some(i) = cell(n, e)
            && let Some(top) = obstacle(g.cells[i])
        {
            assert!(
                top < threshold,
                "the way {from:?} -> {to:?} crosses a {top} m obstacle in cell {i}: {sp:?}"
            );
        }
    }
}
