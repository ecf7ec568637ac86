//! Cost per decision of the hub's gate: validate + clamp + bind
//! ([`aeris_hub::gate::DecisionGate::admit`]).
//!
//! Three mixes are timed call by call on a fixed, deterministic set of decisions:
//! `valid` (admitted, no occupancy grid), `occupancy` (a 64x64 grid with a wall the path
//! crosses: the clamp walks the cells) and `invalid` (NaN, out-of-range and unknown-action
//! decisions: rejected early). The clock's own cost is measured and reported beside them.

use crate::{BenchError, ns_to_us};
use aeris_hub::gate::DecisionGate;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::stats::percentile;
use aeris_schemas::{ActionMode, Decision, DecisionLimits, OCCUPANCY_SIDE, OccupancyGrid};
use serde::Serialize;

/// One mix of decisions.
#[derive(Debug, Clone, Serialize)]
pub struct GateRow {
    /// `valid`, `occupancy` or `invalid`.
    pub mix: &'static str,
    /// Calls timed.
    pub calls: usize,
    /// Calls admitted (the rest were rejected).
    pub admitted: usize,
    /// Median cost per call (µs).
    pub median_us: f64,
    /// 99th percentile (µs).
    pub p99_us: f64,
    /// Median cost per call in ns (finer than µs).
    pub median_ns: f64,
}

/// The gate benchmark's result.
#[derive(Debug, Clone, Serialize)]
pub struct GateReport {
    /// One row per mix.
    pub rows: Vec<GateRow>,
    /// Median cost of reading the clock twice (ns), included in every figure above.
    pub clock_overhead_ns: f64,
}

fn limits() -> DecisionLimits {
    DecisionLimits {
        v_max: 8.0,
        h_min: 0.0,
        h_max: 60.0,
        r_max: 10.0,
        geofence_min: [-200.0, -200.0, 0.0],
        geofence_max: [200.0, 200.0, 60.0],
        obstacle_clearance_m: 3.0,
        subgoals: 4,
    }
}

fn decision(i: usize) -> Decision {
    let f = i as f32;
    Decision {
        target: [10.0 + (f * 7.3) % 40.0, -20.0 + (f * 3.1) % 40.0, 12.0],
        yaw: ((f * 0.37) % 6.0) - 3.0,
        speed: 1.0 + (f % 7.0),
        altitude: 8.0 + (f % 10.0),
        acceptance_radius: 2.0,
        confidence: 0.9,
        step: 1 + (i % 4) as u16,
        action: ActionMode::Goto as u8,
        seq: i as u64 + 1,
        ..Decision::default()
    }
}

fn corrupt(mut d: Decision, i: usize) -> Decision {
    match i % 4 {
        0 => d.speed = f32::NAN,
        1 => d.altitude = 500.0,
        2 => d.action = 0xEE,
        _ => d.target[0] = f32::INFINITY,
    }
    d
}

fn wall_grid() -> OccupancyGrid {
    let mut g = OccupancyGrid {
        cells: [0; aeris_schemas::OCCUPANCY_CELLS],
        ..OccupancyGrid::observed([0.0, 0.0], 2.0)
    };
    // a 30 m tall wall 16 m north of the vehicle, across the whole grid
    let row = OCCUPANCY_SIDE / 2 + 8;
    for c in 0..OCCUPANCY_SIDE {
        g.cells[row * OCCUPANCY_SIDE + c] = 30;
    }
    g
}

/// Time `calls` decisions of each mix through `DecisionGate::admit`.
pub fn run(calls: usize) -> Result<GateReport, BenchError> {
    if calls == 0 {
        return Err(BenchError::Config("--calls must be at least 1".into()));
    }
    let gate = DecisionGate::new(limits()).map_err(|e| BenchError::Config(e.to_string()))?;
    let grid = wall_grid();
    let position = [0.0, 0.0, 12.0];
    let valid: Vec<Decision> = (0..1024).map(decision).collect();
    let invalid: Vec<Decision> = (0..1024).map(|i| corrupt(decision(i), i)).collect();
    let mut samples = vec![0.0f64; calls];

    let mut overhead = vec![0.0f64; 1024];
    for o in overhead.iter_mut() {
        let t0 = monotonic_ns();
        *o = (monotonic_ns() - t0) as f64;
    }
    let clock_overhead_ns = percentile(&overhead, 50.0).unwrap_or(0.0);

    let mut rows = Vec::new();
    for (mix, set, grid) in [
        ("valid", &valid, None),
        ("occupancy", &valid, Some(&grid)),
        ("invalid", &invalid, None),
    ] {
        let mut admitted = 0;
        // warm-up
        for d in set.iter() {
            let _ = std::hint::black_box(gate.admit(d, position, grid));
        }
        for (i, s) in samples.iter_mut().enumerate() {
            let d = &set[i % set.len()];
            let t0 = monotonic_ns();
            let r = std::hint::black_box(gate.admit(std::hint::black_box(d), position, grid));
            *s = (monotonic_ns() - t0) as f64;
            admitted += usize::from(r.is_ok());
        }
        let median = percentile(&samples, 50.0).unwrap_or(0.0);
        rows.push(GateRow {
            mix,
            calls,
            admitted,
            median_us: ns_to_us(median),
            p99_us: ns_to_us(percentile(&samples, 99.0).unwrap_or(0.0)),
            median_ns: median,
        });
    }
    Ok(GateReport {
        rows,
        clock_overhead_ns,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mixes_exercise_admit_clamp_and_reject() {
        let r = run(2048).unwrap();
        let by = |m: &str| r.rows.iter().find(|x| x.mix == m).unwrap().clone();
        assert_eq!(by("valid").admitted, 2048);
        assert_eq!(by("invalid").admitted, 0);
        // the wall blocks or clamps: every admitted setpoint stays short of it
        let gate = DecisionGate::new(limits()).unwrap();
        let grid = wall_grid();
        for i in 0..1024 {
            if let Ok(sp) = gate.admit(&decision(i), [0.0, 0.0, 12.0], Some(&grid)) {
                assert!(sp.position[0] < 16.0, "{:?}", sp.position);
            }
        }
        assert!(run(0).is_err());
    }
}
