//! What the supervisor hands each role process at launch.
//!
//! The supervisor validates the workflow file once and writes one [`RoleSpec`] per role as
//! JSON; the role process reads it with [`RoleSpec::load`]. Roles never parse the workflow
//! themselves, so there is one validator.

use aeris_schemas::{ActionMode, DecisionLimits, MAX_SUBGOALS, StepReading, StepReadingError};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Timing of the flight (MISSION §6).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimingSpec {
    /// Semantic heartbeat period (ms), default 2000.
    pub heartbeat_period_ms: u64,
    /// Decision deadline after the cycle start (ms), default = heartbeat period.
    pub decision_deadline_ms: u64,
    /// Controller rate (Hz), default 50.
    pub control_rate_hz: f64,
    /// The controller holds position when no setpoint arrives within this (ms).
    pub setpoint_timeout_ms: u64,
    /// A role that did no work publishes a liveness heartbeat at least this often (ms).
    pub idle_heartbeat_ms: u64,
}

impl Default for TimingSpec {
    fn default() -> Self {
        Self {
            heartbeat_period_ms: 2000,
            decision_deadline_ms: 2000,
            control_rate_hz: 50.0,
            setpoint_timeout_ms: 500,
            idle_heartbeat_ms: 100,
        }
    }
}

/// Camera geometry and rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSpec {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Frames per second.
    pub fps: f64,
    /// Horizontal field of view (degrees).
    pub hfov_deg: f32,
}

impl Default for CameraSpec {
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            fps: 10.0,
            hfov_deg: 90.0,
        }
    }
}

/// One subgoal g_i of the segmented instruction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubgoalSpec {
    /// The instruction text of this step.
    pub text: String,
    /// Action that completes it: takeoff, goto, hover, turn, ascend, descend, land, stop.
    pub action: String,
    /// Waypoint `[N, E, U]` that marks its completion, when the mission gives it; without
    /// one the reasoner must find the step's landmark in S_t (the VLN setting: the
    /// instruction names places, not coordinates).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub waypoint: Option<[f32; 3]>,
    /// What a language model read in `text` (turn, landmark, relation, sign, height), when
    /// one read it; the planner reads what it leaves out from `text` by its phrase rules.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading: Option<StepReading>,
}

impl SubgoalSpec {
    /// The action as an [`ActionMode`]; `None` when the name is unknown.
    pub fn action_mode(&self) -> Option<ActionMode> {
        ActionMode::from_name(&self.action)
    }
}

/// Hard limits of the flight (MISSION §3 ranges): the workflow's `[mission.limits]`, which
/// is the schemas' [`DecisionLimits`] (one type for the file, Valid(D_t) and the gate).
/// Kept under this name for the crates that name it; its `subgoals` is not read from the
/// file: [`MissionSpec::decision_limits`] sets it from the mission.
pub type LimitsSpec = DecisionLimits;

/// The mission G: instruction, its subgoals, and the limits it is flown under.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MissionSpec {
    /// The natural-language instruction.
    pub instruction: String,
    /// The instruction segmented into subgoals g_1..g_H.
    pub subgoals: Vec<SubgoalSpec>,
    /// Built-in world the simulator renders.
    #[serde(default = "default_world")]
    pub world: String,
    /// Start position `[N, E, U]`.
    #[serde(default)]
    pub start: [f32; 3],
    /// Cruise speed (m/s) the planner asks for.
    #[serde(default = "default_cruise")]
    pub cruise_speed: f32,
    /// Distance to the goal under which the goal counts as reached (m).
    #[serde(default = "default_acceptance")]
    pub acceptance_radius_m: f32,
    /// Give up after this long (s).
    #[serde(default = "default_max_duration")]
    pub max_duration_s: f64,
    /// Hard limits.
    #[serde(default)]
    pub limits: DecisionLimits,
}

fn default_world() -> String {
    "village".into()
}
fn default_cruise() -> f32 {
    5.0
}
fn default_acceptance() -> f32 {
    3.0
}
fn default_max_duration() -> f64 {
    240.0
}

/// Why a mission is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MissionError {
    /// No subgoals, or more than [`MAX_SUBGOALS`].
    #[error("the mission has {0} subgoals; it needs 1..={MAX_SUBGOALS}")]
    SubgoalCount(usize),
    /// A subgoal names an unknown action.
    #[error(
        "subgoal {index} (`{text}`): unknown action `{action}` (expected one of takeoff, goto, hover, turn, ascend, descend, land, stop)"
    )]
    UnknownAction {
        /// 1-based subgoal index.
        index: usize,
        /// Its text.
        text: String,
        /// The bad action.
        action: String,
    },
    /// A waypoint is outside the geofence / altitude band or not finite.
    #[error(
        "subgoal {index} (`{text}`): waypoint {waypoint:?} is outside the geofence or altitude limits"
    )]
    WaypointOutside {
        /// 1-based subgoal index.
        index: usize,
        /// Its text.
        text: String,
        /// The waypoint.
        waypoint: [f32; 3],
    },
    /// A step's reading is unusable.
    #[error("subgoal {index} (`{text}`): its reading is unusable")]
    BadReading {
        /// 1-based subgoal index.
        index: usize,
        /// Its text.
        text: String,
        /// What is wrong with the reading.
        source: StepReadingError,
    },
    /// The limits are incoherent (e.g. h_min > h_max, NaN).
    #[error(
        "mission limits are incoherent (check v_max > 0, h_min <= h_max, geofence_min <= geofence_max, the altitude band [h_min, h_max] meets the geofence's [min U, max U], all finite)"
    )]
    BadLimits,
    /// Cruise speed, acceptance radius or duration out of range.
    #[error("mission field `{0}` is out of range")]
    BadField(&'static str),
}

impl MissionSpec {
    /// The limits Valid(D_t) and the gate use: the mission's limits with its subgoal count.
    pub fn decision_limits(&self) -> DecisionLimits {
        DecisionLimits {
            subgoals: self.subgoals.len().min(MAX_SUBGOALS) as u16,
            ..self.limits
        }
    }

    /// The goal: the last subgoal's waypoint, when the mission gives it (the start for a
    /// mission without subgoals).
    pub fn goal(&self) -> Option<[f32; 3]> {
        match self.subgoals.last() {
            Some(s) => s.waypoint,
            None => Some(self.start),
        }
    }

    /// Check the mission is flyable on its own terms.
    pub fn validate(&self) -> Result<(), MissionError> {
        if self.subgoals.is_empty() || self.subgoals.len() > MAX_SUBGOALS {
            return Err(MissionError::SubgoalCount(self.subgoals.len()));
        }
        let limits = self.decision_limits();
        // the gate and the tracker fly only altitudes both the band and the fence allow
        let band_meets_fence =
            limits.h_min.max(limits.geofence_min[2]) <= limits.h_max.min(limits.geofence_max[2]);
        if !limits.is_coherent() || !band_meets_fence {
            return Err(MissionError::BadLimits);
        }
        if !(self.cruise_speed > 0.0 && self.cruise_speed <= self.limits.v_max) {
            return Err(MissionError::BadField("cruise_speed"));
        }
        if !(self.acceptance_radius_m > 0.0 && self.acceptance_radius_m <= self.limits.r_max) {
            return Err(MissionError::BadField("acceptance_radius_m"));
        }
        if !(self.max_duration_s > 0.0 && self.max_duration_s.is_finite()) {
            return Err(MissionError::BadField("max_duration_s"));
        }
        if !limits.inside_geofence(self.start) {
            return Err(MissionError::BadField("start"));
        }
        for (i, s) in self.subgoals.iter().enumerate() {
            if s.action_mode().is_none() {
                return Err(MissionError::UnknownAction {
                    index: i + 1,
                    text: s.text.clone(),
                    action: s.action.clone(),
                });
            }
            if let Some(Err(source)) = s.reading.as_ref().map(StepReading::validate) {
                return Err(MissionError::BadReading {
                    index: i + 1,
                    text: s.text.clone(),
                    source,
                });
            }
            let Some(w) = s.waypoint else {
                continue;
            };
            if !aeris_schemas::all_finite(&w) || !limits.inside_geofence(w) || w[2] > limits.h_max {
                return Err(MissionError::WaypointOutside {
                    index: i + 1,
                    text: s.text.clone(),
                    waypoint: w,
                });
            }
        }
        Ok(())
    }
}

/// Everything a role process needs, written by the supervisor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RoleSpec {
    /// Flight name: the namespace prefix of every service.
    pub flight: String,
    /// Role instance name (unique in the flight).
    pub name: String,
    /// Role kind.
    pub kind: aeris_schemas::RoleKind,
    /// Variant of the kind.
    pub variant: String,
    /// Executor CPU list the supervisor bound the process to ("" = unbound).
    #[serde(default)]
    pub cpus: String,
    /// Flight timing.
    #[serde(default)]
    pub timing: TimingSpec,
    /// Camera geometry.
    #[serde(default)]
    pub camera: CameraSpec,
    /// The mission.
    pub mission: MissionSpec,
    /// Role-specific parameters (e.g. `autopilot` URL for the controller).
    #[serde(default)]
    pub params: serde_json::Map<String, serde_json::Value>,
    /// Instance number of this process in the flight: the supervisor numbers every process
    /// it starts (start, restart, hot swap) from 1 up and passes it with
    /// `aeris role --instance N`; 0 when run by hand. Decisions carry it, so the hub can
    /// tell a newer reasoner from an older one.
    #[serde(default)]
    pub instance: u32,
    /// Set when the role's executor is on another host: the process the supervisor starts
    /// for it is then its handle, which has that host's agent run the role.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub remote: Option<RemoteSpec>,
    /// The pid the role's heartbeats name when it is not its own: a role a host agent
    /// started names its handle on the flight's host, the process the supervisor knows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heartbeat_pid: Option<u32>,
    /// What the role adds to its host's CLOCK_MONOTONIC to read the flight's clock (ns): 0
    /// on the flight's host; for a role on another host, the offset its handle measured
    /// between the two hosts ([`crate::clock`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub flight_clock_offset_ns: i64,
    /// The accelerator its executor names (`cuda:0`, [`crate::accelerator::Accelerator`]):
    /// a model role runs its sessions there; `None` runs them on its CPUs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accelerator: Option<String>,
    /// The vehicle (1-based) whose scope the role's topics are in, in a flight of several
    /// vehicles ([`crate::bus::FlightBusBuilder::vehicle`]); `None` in a one-vehicle flight
    /// and for a role of the whole flight (the formation role).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vehicle: Option<u8>,
    /// The clock the role runs on: the wall clock, or the flight's simulated time.
    #[serde(default, skip_serializing_if = "ClockSpec::is_wall")]
    pub clock: ClockSpec,
}

fn is_zero(v: &i64) -> bool {
    *v == 0
}

/// The clock a role's cycles, stamps and timeouts follow.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "source", rename_all = "snake_case", deny_unknown_fields)]
pub enum ClockSpec {
    /// CLOCK_MONOTONIC of the flight's host ([`crate::clock`]).
    #[default]
    Wall,
    /// The flight's simulated time ([`crate::clock::sim`]), stepped in lockstep.
    Sim {
        /// The clock's shared segment (in the flight's run directory).
        segment: std::path::PathBuf,
        /// The role's order among those due at one instant (lowest first).
        rank: u32,
    },
}

impl ClockSpec {
    /// `true` for the wall clock.
    pub fn is_wall(&self) -> bool {
        matches!(self, ClockSpec::Wall)
    }
}

/// Where a role runs when its executor is on another host.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RemoteSpec {
    /// The host's name (its `[hosts.NAME]` in the workflow).
    pub host: String,
    /// Its agent's zenoh endpoint (`tls/10.0.0.2:7447`).
    pub endpoint: String,
    /// The flight host's identity directory for the mutual-TLS link (`None`: a plain
    /// `tcp/` link the workflow declared insecure).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keys: Option<String>,
    /// The executor's CPU list on that host ("" = wherever the agent runs roles).
    #[serde(default)]
    pub cpus: String,
    /// The link counts as lost after this long without the agent (ms).
    pub link_timeout_ms: u64,
}

/// Why a spec could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    /// The file could not be read.
    #[error("cannot read role spec {path}")]
    Read {
        /// Path.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// The file is not a valid spec.
    #[error("role spec {path} is invalid")]
    Parse {
        /// Path.
        path: String,
        /// Cause.
        source: serde_json::Error,
    },
    /// The mission inside is invalid.
    #[error("role spec {path} has an unusable mission")]
    Mission {
        /// Path.
        path: String,
        /// Cause.
        source: MissionError,
    },
    /// The flight name is not `[a-z0-9_-]{{1,48}}`.
    #[error("flight name `{0}` is invalid: use 1-48 characters of a-z, 0-9, `_`, `-`")]
    FlightName(String),
}

impl RoleSpec {
    /// Read and validate a spec written by the supervisor.
    pub fn load(path: &Path) -> Result<Self, SpecError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SpecError::Read {
            path: p.clone(),
            source,
        })?;
        let spec: RoleSpec = serde_json::from_str(&text).map_err(|source| SpecError::Parse {
            path: p.clone(),
            source,
        })?;
        if !aeris_schemas::topics::is_valid_flight_name(&spec.flight) {
            return Err(SpecError::FlightName(spec.flight));
        }
        spec.mission
            .validate()
            .map_err(|source| SpecError::Mission { path: p, source })?;
        Ok(spec)
    }

    /// A string parameter.
    pub fn param_str(&self, key: &str) -> Option<&str> {
        self.params.get(key).and_then(|v| v.as_str())
    }

    /// A numeric parameter.
    pub fn param_f64(&self, key: &str) -> Option<f64> {
        self.params.get(key).and_then(|v| v.as_f64())
    }

    /// A boolean parameter, `default` when absent; a value of another type is a
    /// configuration error naming the role kind and the parameter.
    pub fn param_bool(&self, key: &str, default: bool) -> Result<bool, crate::RoleError> {
        match self.params.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_bool()
                .ok_or_else(|| crate::RoleError::param(key, format!("must be a bool, got {v}"))),
        }
    }
}

/// The reasoning role's parameter naming the file its training pairs are appended to
/// (`aeris_roles::distill`; set by `aeris distill`, never by a remote host).
pub const DISTILL_PARAM: &str = "distill";

#[cfg(test)]
mod tests {
    use super::*;

    fn mission(limits: &str) -> Result<MissionSpec, serde_json::Error> {
        serde_json::from_str(&format!(
            r#"{{"instruction": "take off, then land",
                "subgoals": [{{"text": "take off", "action": "takeoff"}},
                             {{"text": "land", "action": "land"}}],
                "limits": {limits}}}"#
        ))
    }

    /// A step's reading is read from the mission as the reader writes it, and checked with
    /// the mission.
    #[test]
    fn a_steps_reading_is_read_and_checked_with_the_mission() {
        let read = |reading: &str| -> MissionSpec {
            serde_json::from_str(&format!(
                r#"{{"instruction": "up, then down by the CAFE board",
                    "subgoals": [{{"text": "up", "action": "takeoff"}},
                                 {{"text": "down by the CAFE board", "action": "land",
                                   "reading": {reading}}}],
                    "limits": {{}}}}"#
            ))
            .unwrap()
        };
        let m = read(
            r#"{"turn": "left", "relation": "beside", "landmark": "yellow sign",
                "sign": "CAFE", "height_m": null}"#,
        );
        assert_eq!(m.validate(), Ok(()));
        let r = m.subgoals[1].reading.as_ref().unwrap();
        assert_eq!(
            (r.turn, r.relation),
            (
                aeris_schemas::Turn::Left,
                Some(aeris_schemas::Relation::NextTo)
            )
        );
        let m = read(
            r#"{"turn": "none", "relation": null, "landmark": "", "sign": null, "height_m": null}"#,
        );
        let err = m.validate().unwrap_err();
        assert!(
            matches!(err, MissionError::BadReading { index: 2, .. }),
            "{err}"
        );
    }

    /// The workflow's limits are the gate's: fields left out take the defaults, the
    /// subgoal count comes from the mission, and a file cannot set it.
    #[test]
    fn mission_limits_read_as_decision_limits_with_the_missions_subgoal_count() {
        let m = mission(r#"{"v_max": 6.0, "obstacle_clearance_m": 4.5}"#).unwrap();
        let l = m.decision_limits();
        assert_eq!((l.v_max, l.obstacle_clearance_m, l.subgoals), (6.0, 4.5, 2));
        assert_eq!(
            DecisionLimits {
                v_max: 6.0,
                obstacle_clearance_m: 4.5,
                subgoals: 2,
                ..DecisionLimits::default()
            },
            l
        );
        assert!(mission(r#"{"subgoals": 9}"#).is_err());
        // what a role reads back is what the supervisor wrote
        let again: MissionSpec = serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
        assert_eq!(again.decision_limits(), l);
    }
}
