//! The hot path does not allocate: HubCore's state, decision and tick handling (gate and
//! ATT included) run under an allocator that counts.

use aeris_hub::{
    Attention, AttentionPrior, DecisionGate, HubConfig, HubCore, LexicalScorer, TickOutput,
};
use aeris_schemas::{
    ActionMode, Decision, DecisionLimits, OCCUPANCY_CELLS, OccupancyGrid, PerceptionState,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

struct Counting;

thread_local! {
    /// Counting is on for this thread only: the test harness's own threads allocate when
    /// they like (a loaded machine once made the count 1 with nothing on the hot path).
    static ARMED: Cell<bool> = const { Cell::new(false) };
}
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

fn armed() -> bool {
    // `try_with`: during thread teardown the slot may be gone; that thread is not measured
    ARMED.try_with(Cell::get).unwrap_or(false)
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if armed() {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if armed() {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const S: u64 = 1_000_000_000;

#[test]
fn hub_core_hot_path_does_not_allocate() {
    let limits = DecisionLimits {
        v_max: 8.0,
        h_min: 0.0,
        h_max: 60.0,
        r_max: 10.0,
        geofence_min: [-100.0, -100.0, 0.0],
        geofence_max: [100.0, 100.0, 60.0],
        obstacle_clearance_m: 3.0,
        subgoals: 3,
    };
    let texts = ["take off", "fly to the red towers", "land on the blue roof"];
    let attention = Attention::new(
        Box::new(LexicalScorer::new(&texts)),
        3,
        0.5,
        AttentionPrior::default(),
        8,
    )
    .unwrap();
    let mut hub = HubCore::new(
        DecisionGate::new(limits).unwrap(),
        attention,
        HubConfig {
            heartbeat_period_ns: 2 * S,
            decision_deadline_ns: 2 * S,
            no_att: false,
        },
        [0.0; 3],
    )
    .unwrap();
    let mut state = PerceptionState::default();
    state
        .summary
        .set("Red towers ahead, a blue roof further on");
    state.cue_count = 1;
    state.cues[0].text.set("red tower");
    state.cues[0].score = 0.8;
    state.detection_count = 1;
    state.detections[0].label.set("roofs");
    state.detections[0].score = 0.5;
    state.occupancy = OccupancyGrid {
        cells: [0; OCCUPANCY_CELLS],
        ..OccupancyGrid::observed([0.0, 0.0], 1.0)
    };
    for c in 0..64 {
        state.occupancy.cells[50 * 64 + c] = 30;
    }
    let mut good = Decision {
        target: [40.0, 5.0, 10.0],
        yaw: 0.1,
        speed: 5.0,
        altitude: 10.0,
        acceptance_radius: 2.0,
        confidence: 1.0,
        step: 2,
        action: ActionMode::Goto as u8,
        ..Decision::default()
    };
    let mut bad = good;
    bad.speed = f32::NAN;

    ARMED.set(true);
    let mut published = 0;
    for i in 1..=50u64 {
        let now = i * S;
        hub.on_telemetry([i as f32 * 0.1, 0.0, 10.0]);
        hub.on_state(&state, now).ok();
        good.seq = 2 * i;
        good.cycle_start_ns = now - S / 2;
        bad.seq = 2 * i + 1;
        bad.cycle_start_ns = now;
        let _ = hub.on_decision(&good, now);
        let _ = hub.on_decision(&bad, now);
        let TickOutput { setpoint, report } = hub.on_tick(now + 5 * S);
        published += usize::from(setpoint.is_some()) + usize::from(report.is_some());
    }
    ARMED.set(false);
    assert_eq!(ALLOCATIONS.load(Ordering::SeqCst), 0);
    assert!(published >= 50);
    // the work was real: commits, rejects, reuses, ATT updates and a full trace ring
    let c = hub.counters();
    assert_eq!((c.decisions_committed, c.decisions_rejected), (50, 50));
    assert!(c.decisions_reused > 0);
    assert_eq!(hub.attention().updates(), 50);
    assert_eq!(hub.attention().trace().count(), 8);
}
