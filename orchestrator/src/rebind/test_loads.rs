//! The loads the re-binding tests share: a hogged executor, and a reasoner over budget
//! wherever it runs.

use super::{ExecutorLoad, RoleLoad};

/// A movable role on executor `executor` with its budget, latency and demand.
pub(super) fn role(
    name: &str,
    executor: usize,
    budget: f64,
    latency: f64,
    demand: f64,
) -> RoleLoad {
    RoleLoad {
        name: name.into(),
        executor,
        budget_ms: Some(budget),
        latency_ms: Some(latency),
        slowdown: 1.0,
        demand,
        waiting: 0.0,
        movable: true,
        crosses_hosts: true,
        reads_frames: false,
        threads: 1,
        kind_variant: (aeris_schemas::RoleKind::Detector, "yolo".into()),
        accelerator_ms: Vec::new(),
        cpu_base_ms: None,
    }
}

/// A one-core executor `busy` cores busy.
pub(super) fn ex(name: &str, busy: f64) -> ExecutorLoad {
    ExecutorLoad::local(name, 1.0, busy)
}

/// Two CPUs; a hog saturates CPU 1 where the reasoner, the camera and perception run.
pub(super) fn hog_case() -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
    let mut reasoning = role("reasoning", 1, 1000.0, 1800.0, 0.3);
    reasoning.slowdown = 3.0;
    reasoning.waiting = 0.6;
    let mut camera = role("camera", 1, 100.0, 60.0, 0.1);
    camera.slowdown = 2.0;
    camera.waiting = 0.1;
    let roles = vec![
        role("hub", 0, 20.0, 0.5, 0.05),
        role("controller", 0, 20.0, 0.4, 0.05),
        camera,
        role("perception", 1, 500.0, 30.0, 0.05),
        reasoning,
    ];
    (roles, vec![ex("control", 0.2), ex("perception", 1.0)])
}

/// The reasoner over budget wherever it runs: relief, never a cure.
pub(super) fn relief_case() -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
    let mut reasoning = role("reasoning", 1, 1000.0, 6000.0, 0.2);
    reasoning.slowdown = 5.0;
    reasoning.waiting = 0.8;
    let roles = vec![
        role("hub", 0, 20.0, 0.5, 0.05),
        role("text", 0, 500.0, 200.0, 0.5),
        role("camera", 1, 100.0, 40.0, 0.05),
        reasoning,
    ];
    (roles, vec![ex("control", 0.55), ex("perception", 1.0)])
}
