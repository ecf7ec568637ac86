//! Rendering a frame and perceiving a frame never touch the heap, and the camera /
//! perception cycles allocate nothing beyond what the transport does per loaned sample
//! (counted by a global allocator, per thread).
//!
//! iceoryx2 0.10 allocates one small `Rc` per loaned sample
//! (`ChunkMutSharedState::new` in `Publisher::loan_*`); that is the transport's, not the
//! roles': the camera loans 2 samples per cycle, perception 1.

use aeris_runtime::{CycleOutcome, CycleReport, FlightBus, Role, RoleContext, RoleSpec};
use aeris_schemas::{FrameFormat, FrameHeader, PerceptionState, VehicleTelemetry, topics};
use aeris_sim::render::Renderer;
use aeris_sim::world::World;
use aeris_sim_roles::camera::CameraRole;
use aeris_sim_roles::perception::{InstructionWords, PerceptionRole, Segmenter};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_in(f: impl FnOnce()) -> u64 {
    let before = ALLOCS.with(|c| c.get());
    f();
    ALLOCS.with(|c| c.get()) - before
}

#[test]
fn render_and_perceive_do_not_allocate() {
    let world = World::builtin("village").unwrap();
    let r = Renderer::new(160, 120, 1.5).unwrap();
    let mut rgb = vec![0; r.rgb_len()];
    let mut depth = vec![0; r.depth_len()];
    let mut seg = Segmenter::new();
    let words = InstructionWords::new(["turn right at the red-roofed building"]);
    let mut state = Box::<PerceptionState>::default();
    let header = FrameHeader {
        seq: 1,
        width: 160,
        height: 120,
        camera_position: [40.0, 18.0, 20.0],
        hfov: 1.5,
        format: FrameFormat::Rgb8 as u8,
        ..FrameHeader::default()
    };
    let n = allocations_in(|| {
        r.render(&world, [40.0, 18.0, 20.0], 0.0, &mut rgb, &mut depth)
            .unwrap();
        seg.perceive(&rgb, &depth, &header, &words, &mut state, &mut |_, _| {})
            .unwrap();
    });
    assert_eq!(n, 0, "{n} heap allocations");
    assert!(state.detection_count > 0 && state.cue_count > 0);
}

#[test]
fn camera_and_perception_cycles_allocate_only_inside_the_transport() {
    let flight = format!("t-noalloc-{}", std::process::id());
    let spec = |kind: &str, variant: &str| -> RoleSpec {
        serde_json::from_value(serde_json::json!({
            "flight": flight, "name": kind, "kind": kind, "variant": variant,
            "camera": { "width": 160, "height": 120, "fps": 10.0, "hfov_deg": 90.0 },
            "mission": { "instruction": "x", "subgoals": [
                { "text": "turn right at the red-roofed building", "action": "goto", "waypoint": [62.0, 64.0, 12.0] }
            ] }
        }))
        .unwrap()
    };
    let bus = |kind: &str| {
        FlightBus::builder(&flight)
            .node_name(kind)
            .create()
            .unwrap()
    };
    let mut cam_ctx = RoleContext::new(spec("camera", "sim-render"), bus("camera")).unwrap();
    let mut per_ctx = RoleContext::new(spec("perception", "geometric"), bus("perception")).unwrap();
    let mut camera = CameraRole::new(&mut cam_ctx).unwrap();
    let mut perception = PerceptionRole::new(&mut per_ctx).unwrap();
    let tool = FlightBus::builder(&flight)
        .node_name("tool")
        .create()
        .unwrap();
    let telemetry = tool.publisher::<topics::VehicleTelemetry>().unwrap();
    let states = tool.subscriber::<topics::PerceptionState>().unwrap();
    // warm-up round (first sends may set up connections)
    telemetry
        .publish(&VehicleTelemetry {
            position: [40.0, 18.0, 20.0],
            ..VehicleTelemetry::default()
        })
        .unwrap();
    camera
        .cycle(&mut cam_ctx, &mut CycleReport::default())
        .unwrap();
    perception
        .cycle(&mut per_ctx, &mut CycleReport::default())
        .unwrap();
    let mut outcomes = (CycleOutcome::Idle, CycleOutcome::Idle);
    let mut report = CycleReport::default();
    let camera_allocs = allocations_in(|| {
        outcomes.0 = camera.cycle(&mut cam_ctx, &mut report).unwrap();
    });
    let perception_allocs = allocations_in(|| {
        outcomes.1 = perception.cycle(&mut per_ctx, &mut report).unwrap();
    });
    assert_eq!(outcomes, (CycleOutcome::Worked, CycleOutcome::Worked));
    const TRANSPORT_ALLOCS_PER_LOAN: u64 = 1;
    assert_eq!(camera_allocs, 2 * TRANSPORT_ALLOCS_PER_LOAN, "camera cycle");
    assert_eq!(
        perception_allocs, TRANSPORT_ALLOCS_PER_LOAN,
        "perception cycle"
    );
    // an idle perception cycle (no new frames) allocates nothing at all
    let idle = allocations_in(|| {
        outcomes.1 = perception.cycle(&mut per_ctx, &mut report).unwrap();
    });
    assert_eq!((outcomes.1, idle), (CycleOutcome::Idle, 0));
    assert_eq!(states.latest().unwrap().unwrap().frame_seq, 2);
}
