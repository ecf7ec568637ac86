//! Placement by measurement across the link (`aeris bench hosts`, last scenario): the
//! machine's CPUs split between the two hosts, the YOLO detector on board with a budget, a
//! CPU hog landing on the vehicle's CPUs, and the time until the re-binding policy has moved
//! the detector to the ground host.

use super::{
    Flight, HostsBenchConfig, HostsBenchError, flight_name, ground_workflow, io, start_agent,
};
use aeris_hosts::netns::TwoHosts;
use aeris_runtime::affinity::CpuSet;
use serde::Serialize;
use std::time::Instant;

/// Placement by measurement: a model role (the YOLO detector) on board when a CPU hog
/// lands on the vehicle's CPUs; the re-binding policy moves it to the ground host, whose
/// CPUs are its own (the machine's CPUs are split between the two hosts).
#[derive(Debug, Clone, Serialize)]
pub struct PlacementFigures {
    /// Why the scenario was not flown (one CPU only, the model not provisioned), else `None`.
    pub skipped: Option<String>,
    /// The vehicle's CPUs and the ground's.
    pub vehicle_cpus: String,
    /// The ground host's CPUs.
    pub ground_cpus: String,
    /// Busy processes of the hog, pinned to the vehicle's CPUs.
    pub hog_threads: usize,
    /// The detector's latency budget in this scenario (ms).
    pub budget_ms: f64,
    /// Its latency on board before the hog, as the initial binding measured it (ms).
    pub latency_before_ms: Option<f64>,
    /// The policy moved it before the hog landed: the board was too slow for its budget
    /// already (outside load); the times after the hog are then `None`.
    pub moved_before_hog: bool,
    /// From the hog's landing to the policy's move (ms); `None`: it did not move after it.
    pub moved_after_ms: Option<u64>,
    /// From the hog's landing to the detector's first heartbeat on the ground (ms).
    pub ready_after_ms: Option<u64>,
    /// From the hog's landing to the old process stopped (ms).
    pub done_after_ms: Option<u64>,
    /// The policy's line: the latency, the budget and the prediction there.
    pub why: Option<String>,
    /// The flight's lines about the detector (the initial binding's, probes, moves), up to
    /// [`PLACEMENT_LINES`], for a run where it did not move.
    pub detector_lines: Vec<String>,
    /// The flight reached its goal.
    pub reached_goal: Option<bool>,
    /// Controller ticks whose setpoint never reached the autopilot (the hog shares the
    /// vehicle's CPUs with the controller).
    pub controller_missed_ticks: Option<u64>,
}

/// The detector's budget in the placement scenario (ms): above its cycle on an idle CPU of
/// this kind of machine (about 60 ms), below it under the hog.
const PLACEMENT_BUDGET_MS: f64 = 100.0;
/// The flight's lines about the detector kept in the figures, at most.
const PLACEMENT_LINES: usize = 8;
/// Busy processes of the placement scenario's hog.
const PLACEMENT_HOG_THREADS: usize = 2;

/// The placement scenario's workflow: [`ground_workflow`] with every role on board and the
/// YOLO detector beside the perception role, with its budget.
fn placement_workflow(host_table: &str) -> String {
    ground_workflow(host_table, &[], false).replacen(
        "[[roles]]\nname = \"hub\"",
        &format!(
            "[[roles]]\nname = \"detector\"\nkind = \"detector\"\nvariant = \"yolo\"\nexecutor = \"perception\"\nbudget_ms = {PLACEMENT_BUDGET_MS:.1}\nparams = {{ interval_ms = 500, threads = 1 }}\n\n[[roles]]\nname = \"hub\""
        ),
        1,
    )
}

/// The detector's latency in the initial binding's line (`detector on X (L of B ms)`).
fn latency_in_binding(line: &str) -> Option<f64> {
    let rest = line.split("detector on ").nth(1)?;
    let inside = rest.split('(').nth(1)?;
    inside.split(" of ").next()?.trim().parse().ok()
}

/// Placement by measurement: the hog lands on the vehicle's CPUs, the detector moves.
pub(super) fn placement(config: &HostsBenchConfig) -> Result<PlacementFigures, HostsBenchError> {
    let online = CpuSet::available();
    let cpus = online.cpus();
    let half = cpus.len() / 2;
    let list = |c: &[usize]| {
        c.iter()
            .map(|c| c.to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    let (ground_cpus, vehicle_cpus) = (list(&cpus[..half]), list(&cpus[half..]));
    let mut fig = PlacementFigures {
        skipped: None,
        vehicle_cpus: vehicle_cpus.clone(),
        ground_cpus: ground_cpus.clone(),
        hog_threads: PLACEMENT_HOG_THREADS,
        budget_ms: PLACEMENT_BUDGET_MS,
        latency_before_ms: None,
        moved_before_hog: false,
        moved_after_ms: None,
        ready_after_ms: None,
        done_after_ms: None,
        why: None,
        detector_lines: Vec::new(),
        reached_goal: None,
        controller_missed_ticks: None,
    };
    if half == 0 {
        fig.skipped = Some("one CPU: nothing to split between two hosts".into());
        return Ok(fig);
    }
    let dir = config.work_dir.join("placement");
    std::fs::create_dir_all(&dir).map_err(io(format!("create {}", dir.display())))?;
    let mut hosts = TwoHosts::new()?;
    hosts.split_cpus(&vehicle_cpus, &ground_cpus);
    let link = hosts.make_keys(&dir)?;
    let _agent = start_agent(&hosts, &config.aeris, &link, &dir)?;
    let workflow = dir.join("workflow.toml");
    std::fs::write(
        &workflow,
        placement_workflow(&hosts.ground_host_toml(&link)),
    )
    .map_err(io(format!("write {}", workflow.display())))?;
    let name = flight_name("placement");
    let mut flight = Flight::start(&hosts, &config.aeris, &workflow, &name, &dir.join("run"))?;
    let binding = match flight.wait_line("initial binding") {
        Ok(_) => flight
            .seen
            .iter()
            .rev()
            .find(|(_, l)| l.contains("initial binding"))
            .map(|(_, l)| l.clone()),
        Err(e) => {
            // the model is not provisioned, or the flight could not start
            fig.skipped = Some(e.to_string());
            return Ok(fig);
        }
    };
    fig.latency_before_ms = binding.as_deref().and_then(latency_in_binding);
    flight.wait_line("step 2/4")?;
    let vehicle = CpuSet::parse(&vehicle_cpus).map_err(|e| {
        HostsBenchError::Flight(format!("the vehicle's CPUs `{vehicle_cpus}`: {e}"))
    })?;
    let hog_at = Instant::now();
    let hog = crate::flights::BusyProcesses::start(Some(&vehicle), PLACEMENT_HOG_THREADS)?;
    let ms = |t: Instant| t.saturating_duration_since(hog_at).as_millis() as u64;
    if let Ok(t) = flight.wait_line("moves `detector` to ground:") {
        fig.why = flight
            .seen
            .iter()
            .find(|(_, l)| l.contains("moves `detector` to ground:"))
            .map(|(_, l)| l.trim_start_matches("aeris: ").to_string());
        // before the hog: the board was too slow for it already (outside load)
        fig.moved_before_hog = t < hog_at;
        if !fig.moved_before_hog {
            fig.moved_after_ms = Some(ms(t));
            fig.ready_after_ms = flight.wait_line("`yolo` (pid").ok().map(ms);
            fig.done_after_ms = flight
                .wait_line("move of `yolo` to host `ground`")
                .ok()
                .map(ms);
        }
    }
    let (summary, _, lines) = flight.finish_with_lines()?;
    drop(hog);
    fig.detector_lines = lines
        .into_iter()
        .filter(|l| l.contains("detector"))
        .map(|l| l.trim_start_matches("aeris: ").to_string())
        .take(PLACEMENT_LINES)
        .collect();
    fig.reached_goal = summary["reached_goal"].as_bool();
    fig.controller_missed_ticks = summary["controller_missed_ticks"].as_u64();
    Ok(fig)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_placement_workflow_adds_the_detector_on_board_with_its_budget() {
        let text = placement_workflow(
            "[hosts.ground]\nendpoint = \"tls/10.1.2.2:7447\"\nkeys = \"keys/vehicle\"\n",
        );
        let w = aeris_orchestrator::workflow::Workflow::from_toml_str(&text).unwrap();
        let d = w.role("detector").expect("the detector");
        assert_eq!(w.role_host(d), None);
        assert_eq!(d.budget_ms, Some(PLACEMENT_BUDGET_MS));
        assert_eq!(
            latency_in_binding(
                "aeris: initial binding kept: camera on perception (6.7 of 100 ms); detector on perception (60.6 of 100 ms); reasoning on perception (0.1 of 1000 ms)"
            ),
            Some(60.6)
        );
    }
}
