//! What the aligned reasoner reads, and the training pairs written from it (issue 37).
//!
//! [`StudentView`] builds the observation an aligned model decides on (S_t's detections
//! placed on the ground with the planner's geometry, its own last decision as memory, never
//! the plan). [`DistillWriter`] appends one training pair per decision to a JSON-lines file:
//! the aligned prompt's system and user messages for that observation
//! ([`PromptStyle::Aligned`], the very function the aligned variant decodes from) and the
//! teacher's decision as the grammar writes it ([`DecisionView::to_json`]).
//!
//! Who writes: the planner (parameter `distill`: it is the teacher and flies, so the pairs
//! are the states it reaches) and a language role with the aligned prompt (the student
//! flies and the planner it carries labels the states the student reaches: a DAgger round).
//! The parameter is a local path only: a workflow's roles on other hosts cannot carry it
//! (`REMOTE_PARAMS`).

use crate::grounding::sight;
use crate::reasoner_io::DecisionDue;
use aeris_geometry::CameraModel;
use aeris_llm::prompt::DETECTIONS_IN_PROMPT;
use aeris_llm::{DecisionView, MissionBrief, Observation, PromptStyle, Sighted};
use aeris_runtime::{ConfigError, RoleError, RoleSpec};
use aeris_schemas::{Decision, PerceptionState};
use std::io::Write;
use std::os::unix::fs::OpenOptionsExt;
use std::path::PathBuf;

pub use aeris_runtime::DISTILL_PARAM;

/// What an aligned reasoner sees besides S_t: the mission, the camera, its last decision.
#[derive(Debug, Clone)]
pub struct StudentView {
    brief: MissionBrief,
    camera: CameraModel,
    previous: Option<DecisionView>,
}

impl StudentView {
    /// The view of the mission and camera in `spec`.
    pub fn new(spec: &RoleSpec) -> Result<Self, RoleError> {
        let c = &spec.camera;
        let camera = CameraModel::new(c.width, c.height, c.hfov_deg.to_radians())
            .map_err(|e| ConfigError::refused("the camera model", e))?;
        Ok(Self {
            brief: crate::reasoner_io::mission_brief(&spec.mission)?,
            camera,
            previous: None,
        })
    }

    /// The mission as the prompt states it.
    pub fn brief(&self) -> &MissionBrief {
        &self.brief
    }

    /// S_t's first detections placed on the ground from its pose at capture.
    pub fn sighted(&self, state: Option<&PerceptionState>) -> Vec<Sighted> {
        let Some(s) = state else {
            return Vec::new();
        };
        s.detections()
            .iter()
            .take(DETECTIONS_IN_PROMPT)
            .map(|d| Sighted {
                label: d.label.as_str_lossy().to_string(),
                point: sight(d, s.position, s.yaw, &self.camera).point,
            })
            .collect()
    }

    /// The observation for a decision due on `state` (no plan).
    pub fn observation<'a>(
        &'a self,
        due: &DecisionDue,
        state: Option<&'a PerceptionState>,
        sighted: &'a [Sighted],
    ) -> Observation<'a> {
        Observation {
            position: due.position,
            yaw: due.yaw,
            landed: due.landed,
            state,
            previous: self.previous.as_ref(),
            plan: None,
            sighted,
        }
    }

    /// Remember the decision the reasoner made (its memory line next heartbeat).
    pub fn decided(&mut self, view: DecisionView) {
        self.previous = Some(view);
    }
}

/// One training pair as a line of the pairs' file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DistillPair {
    /// The system message.
    pub system: String,
    /// The user message (what the model reads this heartbeat).
    pub user: String,
    /// The teacher's decision, as the decision grammar writes it.
    pub target: String,
}

/// Appends training pairs to a file (parameter [`DISTILL_PARAM`]).
#[derive(Debug)]
pub struct DistillWriter {
    file: std::fs::File,
    path: PathBuf,
    written: u64,
}

impl DistillWriter {
    /// The writer `spec` asks for (`None` without the parameter). The file is created
    /// anew (never through a symbolic link, owner-only) or appended to.
    pub fn from_spec(spec: &RoleSpec) -> Result<Option<Self>, RoleError> {
        let Some(value) = spec.params.get(DISTILL_PARAM) else {
            return Ok(None);
        };
        let path = value
            .as_str()
            .filter(|p| !p.is_empty())
            .map(PathBuf::from)
            .ok_or_else(|| RoleError::param(DISTILL_PARAM, "must be a file path"))?;
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .mode(0o600)
            .custom_flags(libc::O_NOFOLLOW)
            .open(&path)
            .map_err(|e| {
                ConfigError::param_refused(
                    DISTILL_PARAM,
                    std::io::Error::new(e.kind(), format!("{}: {e}", path.display())),
                )
            })?;
        Ok(Some(Self {
            file,
            path,
            written: 0,
        }))
    }

    /// Write the pair for `obs` (in the aligned prompt) labelled with `teacher`'s decision.
    pub fn write(
        &mut self,
        brief: &MissionBrief,
        obs: &Observation<'_>,
        teacher: &Decision,
    ) -> Result<(), RoleError> {
        let (system, user) = PromptStyle::Aligned.messages(brief, obs);
        let pair = DistillPair {
            system: system.to_string(),
            user,
            target: DecisionView::from_decision(teacher).to_json(),
        };
        let mut line =
            serde_json::to_vec(&pair).map_err(|e| RoleError::step("writing a training pair", e))?;
        line.push(b'\n');
        // one write per line on an append-only file: a line is whole or absent
        self.file.write_all(&line).map_err(|e| {
            RoleError::step(
                format!("writing a training pair to {}", self.path.display()),
                e,
            )
        })?;
        self.written += 1;
        Ok(())
    }

    /// Pairs written so far.
    pub fn written(&self) -> u64 {
        self.written
    }
}
