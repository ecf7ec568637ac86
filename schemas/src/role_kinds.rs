//! The role kinds: what a workflow's `kind = "..."` names, and what each kind is: the
//! variants this build can run, the topics it reads and writes, whether it can be
//! hot-swapped (each declared once, by its type in [`crate::kinds`], which gives
//! [`RoleKind::info`]). The supervisor validates workflows against it, hosts' agents admit
//! roles by it, and `aeris role` dispatches on it (the runners are the binary's, one per
//! variant).

/// A role kind, as written in workflow files and role specs (`text-reader`, `hub`, ...).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
pub enum RoleKind {
    /// `vehicle`.
    Vehicle,
    /// `camera`.
    Camera,
    /// `perception`.
    Perception,
    /// `text-reader`.
    TextReader,
    /// `detector`.
    Detector,
    /// `cues`.
    Cues,
    /// `occupancy`.
    Occupancy,
    /// `image-to-text`.
    ImageToText,
    /// `reasoning`.
    Reasoning,
    /// `hub`.
    Hub,
    /// `controller`.
    Controller,
    /// `recorder`.
    Recorder,
    /// `bridge`.
    Bridge,
    /// `replay`.
    Replay,
    /// `formation`.
    Formation,
}

/// What a role kind is: its variants, its ports, its swap policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RoleKindInfo {
    /// Variants this build can run.
    pub variants: &'static [&'static str],
    /// Topics the kind subscribes to.
    pub subscribes: &'static [&'static str],
    /// Topics the kind publishes (besides `heartbeat`, which every role publishes).
    pub publishes: &'static [&'static str],
    /// Topics the kind reads the latest sample of now and then, never waiting for one (a
    /// reasoner reads the hub's last setpoint when it starts, to resume at the hub's active
    /// step). Such a read orders nothing, so it closes no cycle in the flight's graph; it
    /// still crosses hosts like a subscription.
    pub reads_latest: &'static [&'static str],
    /// Topics it exchanges with tools outside the flight (`aeris formation say`), not with
    /// other roles: the flight's graph leaves them out.
    pub with_tools: &'static [&'static str],
    /// What it does, for `--help` and errors.
    pub summary: &'static str,
    /// `None`: a running role of this kind can be hot-swapped make-before-break (old and new
    /// process overlap, publishing the same topics for a moment). `Some(why)`: it cannot.
    pub swap_refusal: Option<&'static str>,
}

impl RoleKind {
    /// Every role kind this build knows, in the order `aeris roles` lists them.
    pub const ALL: [RoleKind; 15] = [
        RoleKind::Vehicle,
        RoleKind::Camera,
        RoleKind::Perception,
        RoleKind::TextReader,
        RoleKind::Detector,
        RoleKind::Cues,
        RoleKind::Occupancy,
        RoleKind::ImageToText,
        RoleKind::Reasoning,
        RoleKind::Hub,
        RoleKind::Controller,
        RoleKind::Recorder,
        RoleKind::Bridge,
        RoleKind::Replay,
        RoleKind::Formation,
    ];

    /// Its name in workflow files and specs.
    pub const fn name(self) -> &'static str {
        match self {
            RoleKind::Vehicle => "vehicle",
            RoleKind::Camera => "camera",
            RoleKind::Perception => "perception",
            RoleKind::TextReader => "text-reader",
            RoleKind::Detector => "detector",
            RoleKind::Cues => "cues",
            RoleKind::Occupancy => "occupancy",
            RoleKind::ImageToText => "image-to-text",
            RoleKind::Reasoning => "reasoning",
            RoleKind::Hub => "hub",
            RoleKind::Controller => "controller",
            RoleKind::Recorder => "recorder",
            RoleKind::Bridge => "bridge",
            RoleKind::Replay => "replay",
            RoleKind::Formation => "formation",
        }
    }

    /// The kind named `name`, if there is one.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Every kind's name, comma-separated (for an error that lists them).
    pub fn known_names() -> String {
        Self::ALL.map(RoleKind::name).join(", ")
    }
}

impl core::fmt::Display for RoleKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // `pad`, not `write_str`: `{:<10}` in a table aligns a kind as it did a string
        f.pad(self.name())
    }
}

/// A role kind that does not exist.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown role kind `{0}` (known: {known})", known = RoleKind::known_names())]
pub struct UnknownRoleKind(pub String);

impl core::str::FromStr for RoleKind {
    type Err = UnknownRoleKind;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s).ok_or_else(|| UnknownRoleKind(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kind_is_read_back_from_its_name() {
        for k in RoleKind::ALL {
            assert_eq!(k.name().parse::<RoleKind>(), Ok(k));
            assert_eq!(k.to_string(), k.name());
        }
        assert_eq!(format!("[{:<6}]", RoleKind::Hub), "[hub   ]");
        let err = "gpt".parse::<RoleKind>().expect_err("no such kind");
        assert!(
            err.to_string()
                .starts_with("unknown role kind `gpt` (known: vehicle, camera")
        );
    }
}
