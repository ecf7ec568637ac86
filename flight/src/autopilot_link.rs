//! The autopilot link as the flight reports it: the controller's `controller/link` status
//! turned into events (bound, lost, back, a refused command) and, for a link that never
//! heard an autopilot, the diagnosis that ends the flight.

use aeris_schemas::{AutopilotKind, AutopilotLinkStatus, LinkState};

/// Something that happened on the autopilot link.
#[derive(Debug, Clone, PartialEq)]
pub enum AutopilotEvent {
    /// The controller bound to the autopilot its HEARTBEAT announced.
    Bound {
        /// The firmware (`PX4`, `ArduPilot`).
        autopilot: String,
        /// Its MAVLink system id.
        system_id: u8,
        /// Its MAVLink component id.
        component_id: u8,
        /// The MAVLink version of its heartbeat (0: not reported by the link).
        heard_version: u8,
    },
    /// No autopilot HEARTBEAT for the link timeout, after it had been heard.
    Lost {
        /// The autopilot's URL.
        url: String,
        /// The link timeout (ms).
        timeout_ms: u32,
    },
    /// The autopilot is heard again after a loss.
    Restored,
    /// The autopilot refused a command.
    CommandRefused {
        /// The command and its MAV_RESULT, by name.
        refusal: String,
    },
}

impl core::fmt::Display for AutopilotEvent {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            AutopilotEvent::Bound {
                autopilot,
                system_id,
                component_id,
                heard_version,
            } => {
                write!(
                    f,
                    "flying {autopilot} at system {system_id} component {component_id}"
                )?;
                if *heard_version > 0 {
                    write!(f, " (MAVLink {heard_version})")?;
                }
                Ok(())
            }
            AutopilotEvent::Lost { url, timeout_ms } => write!(
                f,
                "autopilot link lost: no HEARTBEAT on {url} for {:.1} s",
                f64::from(*timeout_ms) / 1e3
            ),
            AutopilotEvent::Restored => f.write_str("autopilot link back"),
            AutopilotEvent::CommandRefused { refusal } => {
                write!(f, "the autopilot refused a command: {refusal}")
            }
        }
    }
}

/// Follows the controller's link status and says what changed.
///
/// The status comes from whichever controller holds the autopilot lease. A standby that
/// takes the lease while the autopilot is silent starts its own term "up" and judges the
/// link lost again a timeout later: that is still the one outage, so the flight keeps its
/// own state (lost or not) and counts a loss once; the link is back only when the same
/// controller hears the autopilot again. Holders are told apart by their lease epoch, so a
/// former holder's status read late changes nothing.
#[derive(Debug, Default)]
pub(crate) struct LinkFollower {
    last: Option<AutopilotLinkStatus>,
    bound: bool,
    refused_seen: u64,
    refused_total: u64,
    /// The link is lost, as the flight sees it.
    lost: bool,
    losses: u64,
}

impl LinkFollower {
    /// Take in `s`, pushing what changed onto `out`.
    pub(crate) fn update(&mut self, s: &AutopilotLinkStatus, out: &mut Vec<AutopilotEvent>) {
        // statuses of two holders may be read out of order (a hand-over, a migration): a
        // former holder's, read after the holder's, is old news
        if self
            .last
            .is_some_and(|last| s.lease_epoch < last.lease_epoch)
        {
            return;
        }
        // another epoch, or a sequence that goes back, is another controller process (a
        // restart, the standby that took the lease): its counters start from zero
        let same = self
            .last
            .filter(|last| last.lease_epoch == s.lease_epoch && s.seq > last.seq);
        if same.is_none() {
            self.refused_seen = 0;
        }
        let state = s.link_state();
        if !self.bound && s.autopilot != AutopilotKind::Unknown as u8 {
            self.bound = true;
            out.push(AutopilotEvent::Bound {
                autopilot: AutopilotKind::from_u8(s.autopilot)
                    .map_or("unknown", AutopilotKind::name)
                    .to_string(),
                system_id: s.system_id,
                component_id: s.component_id,
                heard_version: s.heard_version,
            });
        }
        // a loss and its end both between two statuses read: the controller's count says so
        let missed = same.is_some_and(|last| s.losses > last.losses);
        if !self.lost && (state == Some(LinkState::Lost) || missed) {
            self.lost = true;
            self.losses += 1;
            out.push(AutopilotEvent::Lost {
                url: s.url.as_str_lossy().to_string(),
                timeout_ms: s.timeout_ms,
            });
        }
        let heard_again = same.is_some_and(|last| s.autopilot_frames > last.autopilot_frames);
        if self.lost && state == Some(LinkState::Up) && heard_again {
            self.lost = false;
            out.push(AutopilotEvent::Restored);
        }
        if s.commands_refused > self.refused_seen {
            self.refused_total += s.commands_refused - self.refused_seen;
            self.refused_seen = s.commands_refused;
            out.push(AutopilotEvent::CommandRefused {
                refusal: s.last_refusal.as_str_lossy().to_string(),
            });
        }
        self.last = Some(*s);
    }

    /// The diagnosis of a link that heard no autopilot within its timeout, if it is one.
    pub(crate) fn silent(&self) -> Option<String> {
        let s = self.last?;
        (s.link_state() == Some(LinkState::Silent)).then(|| silent_diagnosis(&s))
    }

    /// Losses of the link so far, as the flight saw them (over every controller process).
    pub(crate) fn losses(&self) -> u64 {
        self.losses
    }

    /// Commands the autopilot refused so far.
    pub(crate) fn commands_refused(&self) -> u64 {
        self.refused_total
    }

    /// The autopilot flown, as one line, once bound.
    pub(crate) fn autopilot(&self) -> Option<String> {
        let s = self.last?;
        let kind = AutopilotKind::from_u8(s.autopilot)?;
        (kind != AutopilotKind::Unknown).then(|| {
            format!(
                "{} (system {}, component {}, MAVLink {} sent)",
                kind.name(),
                s.system_id,
                s.component_id,
                s.send_version
            )
        })
    }
}

/// What a silent link heard, as one message naming the URL: nothing, or which frames came
/// and why none counted as the autopilot.
pub fn silent_diagnosis(s: &AutopilotLinkStatus) -> String {
    let mut heard = Vec::new();
    if s.v1_refused > 0 {
        heard.push(format!(
            "{} MAVLink 1 frames, refused because the controller is set to MAVLink 2 only \
             (params.mavlink = 2; use \"auto\" or 1)",
            s.v1_refused
        ));
    }
    if s.unsigned_refused > 0 {
        heard.push(format!(
            "{} unsigned frames, refused because signing is on",
            s.unsigned_refused
        ));
    }
    if s.bad_signature_refused > 0 {
        heard.push(format!(
            "{} signed frames whose signature did not check (another key?)",
            s.bad_signature_refused
        ));
    }
    if s.crc_failures > 0 {
        heard.push(format!(
            "{} frames that failed their CRC (a wrong baud rate, a dialect with other CRC \
             seeds, or a damaged line)",
            s.crc_failures
        ));
    }
    if s.other_frames > 0 {
        let mut line = format!(
            "{} frames from system {} component {}",
            s.other_frames, s.other_system_id, s.other_component_id
        );
        if s.foreign_heartbeats > 0 {
            line.push_str(&format!(
                ", whose HEARTBEAT ({}) is not a PX4 or ArduPilot vehicle",
                s.foreign.as_str_lossy()
            ));
        }
        heard.push(line);
    }
    let heard = if heard.is_empty() {
        "nothing".to_string()
    } else {
        heard.join("; ")
    };
    format!(
        "no autopilot HEARTBEAT on {} within {:.1} s; heard: {heard}",
        s.url.as_str_lossy(),
        f64::from(s.timeout_ms) / 1e3
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_schemas::FixedText;

    fn status(state: LinkState) -> AutopilotLinkStatus {
        AutopilotLinkStatus {
            seq: 1,
            state: state as u8,
            timeout_ms: 5000,
            url: FixedText::from_str_truncated("udpout:127.0.0.1:14600"),
            ..Default::default()
        }
    }

    #[test]
    fn a_silent_link_names_the_url_and_what_was_heard() {
        let s = status(LinkState::Silent);
        assert_eq!(
            silent_diagnosis(&s),
            "no autopilot HEARTBEAT on udpout:127.0.0.1:14600 within 5.0 s; heard: nothing"
        );
        let gcs = AutopilotLinkStatus {
            other_frames: 12,
            other_system_id: 255,
            other_component_id: 190,
            foreign_heartbeats: 3,
            foreign: FixedText::from_str_truncated("MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID"),
            v1_refused: 40,
            crc_failures: 7,
            ..s
        };
        let d = silent_diagnosis(&gcs);
        assert!(d.contains("40 MAVLink 1 frames"), "{d}");
        assert!(d.contains("7 frames that failed their CRC"), "{d}");
        assert!(d.contains("12 frames from system 255 component 190"), "{d}");
        assert!(d.contains("MAV_TYPE_GCS"), "{d}");
    }

    #[test]
    fn events_bound_lost_back_and_refused_once_each() {
        let mut f = LinkFollower::default();
        let mut out = Vec::new();
        f.update(&status(LinkState::Waiting), &mut out);
        assert!(out.is_empty() && f.silent().is_none());
        let up = AutopilotLinkStatus {
            seq: 2,
            autopilot: AutopilotKind::ArduPilot as u8,
            system_id: 7,
            component_id: 1,
            ..status(LinkState::Up)
        };
        f.update(&up, &mut out);
        f.update(&AutopilotLinkStatus { seq: 3, ..up }, &mut out);
        let lost = AutopilotLinkStatus {
            seq: 4,
            losses: 1,
            ..AutopilotLinkStatus {
                state: LinkState::Lost as u8,
                ..up
            }
        };
        f.update(&lost, &mut out);
        f.update(&AutopilotLinkStatus { seq: 5, ..lost }, &mut out);
        let refused = AutopilotLinkStatus {
            seq: 6,
            losses: 1,
            autopilot_frames: 1,
            commands_refused: 1,
            last_refusal: FixedText::from_str_truncated(
                "MAV_CMD_COMPONENT_ARM_DISARM: MAV_RESULT_DENIED",
            ),
            ..up
        };
        f.update(&refused, &mut out);
        assert_eq!(out.len(), 4, "{out:?}");
        assert!(matches!(
            &out[0],
            AutopilotEvent::Bound { system_id: 7, .. }
        ));
        assert!(matches!(&out[1], AutopilotEvent::Lost { .. }));
        assert_eq!(out[2], AutopilotEvent::Restored);
        assert!(out[3].to_string().contains("MAV_RESULT_DENIED"));
        assert_eq!((f.losses(), f.commands_refused()), (1, 1));
        // a restarted controller counts from zero again: nothing is lost or doubled
        f.update(&AutopilotLinkStatus { seq: 1, ..up }, &mut out);
        assert_eq!((f.losses(), f.commands_refused(), out.len()), (1, 1, 4));
    }

    #[test]
    fn a_lease_handed_over_during_an_outage_is_still_one_loss() {
        let mut f = LinkFollower::default();
        let mut out = Vec::new();
        let first = |seq, state: LinkState, losses, frames| AutopilotLinkStatus {
            seq,
            lease_epoch: 1000,
            losses,
            autopilot_frames: frames,
            autopilot: AutopilotKind::Px4 as u8,
            ..status(state)
        };
        let holder = |seq, state, losses, frames| AutopilotLinkStatus {
            lease_epoch: 2000,
            ..first(seq, state, losses, frames)
        };
        f.update(&first(100, LinkState::Up, 0, 500), &mut out);
        f.update(&first(101, LinkState::Lost, 1, 500), &mut out);
        // the standby takes the lease: its own term starts up, then it judges the link lost
        f.update(&holder(1, LinkState::Up, 0, 0), &mut out);
        f.update(&holder(2, LinkState::Up, 0, 0), &mut out);
        f.update(&holder(300, LinkState::Lost, 1, 0), &mut out);
        assert_eq!(f.losses(), 1, "{out:?}");
        assert!(!out.contains(&AutopilotEvent::Restored), "{out:?}");
        // the autopilot is heard again by the holder of the lease
        f.update(&holder(301, LinkState::Up, 1, 3), &mut out);
        assert_eq!(out.last(), Some(&AutopilotEvent::Restored));
        // the former holder's last statuses, read late (its losses above the holder's):
        // neither a loss nor anything else
        let events = out.len();
        f.update(&first(102, LinkState::Lost, 1, 500), &mut out);
        f.update(&first(103, LinkState::Up, 1, 501), &mut out);
        assert_eq!((f.losses(), out.len()), (1, events), "{out:?}");
        // a loss and its end between two reads still count, once
        f.update(&holder(302, LinkState::Up, 2, 9), &mut out);
        assert_eq!(f.losses(), 2, "{out:?}");
        let lost = out
            .iter()
            .filter(|e| matches!(e, AutopilotEvent::Lost { .. }));
        assert_eq!(lost.count(), 2);
        assert_eq!(out.last(), Some(&AutopilotEvent::Restored));
    }

    #[test]
    fn silent_only_when_the_controller_says_so() {
        let mut f = LinkFollower::default();
        f.update(&status(LinkState::Silent), &mut Vec::new());
        assert!(f.silent().unwrap().contains("heard: nothing"));
    }
}
