//! What the controller heard on its autopilot link, and whom it believes: the receive
//! thread passes every frame through [`LinkLedger::accept`], which binds the controller to
//! the first system that announces itself as an autopilot it can fly (its system and
//! component id and its firmware come from that HEARTBEAT, not from constants), ignores
//! and counts everyone else (a ground station, MAVProxy, a camera), refuses MAVLink 1 when
//! the workflow asked for MAVLink 2 only, and notes every command the autopilot refused.
//! [`link_state`] says from the ledger's clock whether the link is waiting, up, silent or
//! lost. Pure: no I/O, no allocation.

use aeris_mavlink::dialect::{MavMessage, MavResult};
use aeris_mavlink::{Autopilot, MavlinkVersion, Received};
use aeris_schemas::{AutopilotKind, AutopilotLinkStatus, FixedText, LinkState};
use core::fmt::Write;

/// The autopilot the controller flies: the first system that announced itself as one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AutopilotIdentity {
    /// Its MAVLink system id.
    pub system_id: u8,
    /// Its MAVLink component id.
    pub component_id: u8,
    /// Its firmware, from its HEARTBEAT.
    pub autopilot: Autopilot,
}

/// Every frame the controller heard, by what became of it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LinkLedger {
    /// The autopilot bound to, once its HEARTBEAT arrived.
    pub bound: Option<AutopilotIdentity>,
    /// Counters and the last foreign sender, as published on `controller/link`.
    pub status: AutopilotLinkStatus,
}

impl LinkLedger {
    /// Take in `r`; `Some(flavour)` when it comes from the autopilot flown (and is to be
    /// applied to its state), `None` when it is ignored or refused. `v2_only`: MAVLink 1
    /// frames are refused.
    pub fn accept(&mut self, r: &Received, v2_only: bool) -> Option<Autopilot> {
        let s = &mut self.status;
        s.frames += 1;
        if v2_only && r.version == Some(MavlinkVersion::V1) {
            s.v1_refused += 1;
            return None;
        }
        let (sys, comp) = (r.header.system_id, r.header.component_id);
        let from =
            |id: &AutopilotIdentity| u32::from(id.system_id) == sys && id.component_id == comp;
        let autopilot = match (&self.bound, &r.message) {
            (Some(id), _) if from(id) => Some(id.autopilot),
            (None, MavMessage::HEARTBEAT(hb)) => match Autopilot::from_heartbeat(hb) {
                Some(ap) if sys <= u32::from(u8::MAX) => {
                    let id = AutopilotIdentity {
                        system_id: sys as u8,
                        component_id: comp,
                        autopilot: ap,
                    };
                    self.bound = Some(id);
                    s.system_id = id.system_id;
                    s.component_id = id.component_id;
                    s.autopilot = match ap {
                        Autopilot::Px4 => AutopilotKind::Px4,
                        Autopilot::ArduPilotCopter => AutopilotKind::ArduPilot,
                    } as u8;
                    Some(ap)
                }
                _ => None,
            },
            _ => None,
        };
        let Some(ap) = autopilot else {
            s.other_frames += 1;
            s.other_system_id = sys.min(u32::from(u8::MAX)) as u8;
            s.other_component_id = comp;
            if let MavMessage::HEARTBEAT(hb) = &r.message {
                s.foreign_heartbeats += 1;
                if (s.foreign_type, s.foreign_autopilot) != (hb.mavtype as u8, hb.autopilot as u8)
                    || s.foreign.is_empty()
                {
                    s.foreign_type = hb.mavtype as u8;
                    s.foreign_autopilot = hb.autopilot as u8;
                    s.foreign = FixedText::new();
                    let _ = write!(s.foreign, "{:?}, {:?}", hb.mavtype, hb.autopilot);
                }
            }
            return None;
        };
        s.autopilot_frames += 1;
        match &r.message {
            MavMessage::HEARTBEAT(_) => {
                s.heard_version = match r.version {
                    Some(MavlinkVersion::V1) => 1,
                    Some(MavlinkVersion::V2) => 2,
                    None => 0,
                };
            }
            MavMessage::COMMAND_ACK(ack)
                if !matches!(
                    ack.result,
                    MavResult::MAV_RESULT_ACCEPTED | MavResult::MAV_RESULT_IN_PROGRESS
                ) =>
            {
                s.commands_refused += 1;
                s.last_refused_command = ack.command as u16;
                s.last_refused_result = ack.result as u8;
                s.last_refusal = FixedText::new();
                let _ = write!(s.last_refusal, "{:?}: {:?}", ack.command, ack.result);
            }
            _ => {}
        }
        Some(ap)
    }
}

/// Where the link is at `now_ns` for a controller that started at `start_ns` and last
/// heard its autopilot's HEARTBEAT at `last_heartbeat_ns`, with `timeout_ns` the link
/// timeout: silent when nothing came within the timeout of the start, lost when the last
/// heartbeat is older than the timeout.
pub fn link_state(
    now_ns: u64,
    start_ns: u64,
    last_heartbeat_ns: Option<u64>,
    timeout_ns: u64,
) -> LinkState {
    match last_heartbeat_ns {
        None if now_ns.saturating_sub(start_ns) >= timeout_ns => LinkState::Silent,
        None => LinkState::Waiting,
        Some(t) if now_ns.saturating_sub(t) > timeout_ns => LinkState::Lost,
        Some(_) => LinkState::Up,
    }
}

/// The autopilot heartbeat a lease holder's link is judged by in its term, which began at
/// `term_start_ns`: its own link's last one (counted from the term's start), or, when its link
/// has heard none but the flight's autopilot was heard before the term (`heard_before_term`,
/// from the lease it took over), the term's start, so that a vehicle gone quiet reads as a
/// lost link rather than one never heard.
pub fn term_heartbeat(
    own_last_ns: Option<u64>,
    term_start_ns: u64,
    heard_before_term: bool,
) -> Option<u64> {
    own_last_ns
        .map(|t| t.max(term_start_ns))
        .or(heard_before_term.then_some(term_start_ns))
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_mavlink::MavHeader;
    use aeris_mavlink::dialect::{
        COMMAND_ACK_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavModeFlag, MavState, MavType,
    };

    fn frame(sys: u32, comp: u8, message: MavMessage, v: MavlinkVersion) -> Received {
        Received {
            header: MavHeader {
                system_id: sys,
                component_id: comp,
                sequence: 0,
            },
            message,
            version: Some(v),
        }
    }

    fn heartbeat(mavtype: MavType, autopilot: MavAutopilot) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype,
            autopilot,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_STANDBY,
            mavlink_version: 3,
        })
    }

    const V2: MavlinkVersion = MavlinkVersion::V2;

    #[test]
    fn the_first_autopilot_heartbeat_binds_and_every_other_sender_is_ignored() {
        let mut l = LinkLedger::default();
        let gcs = heartbeat(MavType::MAV_TYPE_GCS, MavAutopilot::MAV_AUTOPILOT_INVALID);
        assert_eq!(l.accept(&frame(255, 190, gcs.clone(), V2), false), None);
        let copter = heartbeat(
            MavType::MAV_TYPE_QUADROTOR,
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        );
        // a vehicle at system 7 is flown, with its firmware
        assert_eq!(
            l.accept(&frame(7, 1, copter.clone(), V2), false),
            Some(Autopilot::ArduPilotCopter)
        );
        assert_eq!(
            l.bound,
            Some(AutopilotIdentity {
                system_id: 7,
                component_id: 1,
                autopilot: Autopilot::ArduPilotCopter
            })
        );
        // a second autopilot on the link does not take over
        let px4 = heartbeat(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        assert_eq!(l.accept(&frame(8, 1, px4, V2), false), None);
        assert_eq!(l.accept(&frame(255, 190, gcs, V2), false), None);
        let s = l.status;
        assert_eq!((s.frames, s.autopilot_frames, s.other_frames), (4, 1, 3));
        assert_eq!((s.system_id, s.component_id), (7, 1));
        assert_eq!(s.autopilot, AutopilotKind::ArduPilot as u8);
        assert_eq!((s.other_system_id, s.other_component_id), (255, 190));
        assert_eq!(s.foreign_type, MavType::MAV_TYPE_GCS as u8);
        assert_eq!(
            s.foreign.as_str(),
            Some("MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID")
        );
    }

    #[test]
    fn mavlink_1_is_refused_only_when_the_workflow_asks_for_2_only() {
        let px4 = heartbeat(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        let v1 = frame(1, 1, px4, MavlinkVersion::V1);
        let mut l = LinkLedger::default();
        assert_eq!(l.accept(&v1, true), None);
        assert_eq!((l.status.v1_refused, l.bound), (1, None));
        assert_eq!(l.accept(&v1, false), Some(Autopilot::Px4));
        assert_eq!(l.status.heard_version, 1);
    }

    #[test]
    fn a_refused_command_is_noted_with_its_result() {
        let mut l = LinkLedger::default();
        let px4 = heartbeat(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        l.accept(&frame(1, 1, px4, V2), false);
        let ack = |result| {
            MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                result,
            })
        };
        l.accept(&frame(1, 1, ack(MavResult::MAV_RESULT_ACCEPTED), V2), false);
        assert_eq!(l.status.commands_refused, 0);
        l.accept(&frame(1, 1, ack(MavResult::MAV_RESULT_DENIED), V2), false);
        assert_eq!(l.status.commands_refused, 1);
        assert_eq!(
            l.status.last_refused_command,
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16
        );
        assert_eq!(
            l.status.last_refused_result,
            MavResult::MAV_RESULT_DENIED as u8
        );
        assert_eq!(
            l.status.last_refusal.as_str(),
            Some("MAV_CMD_COMPONENT_ARM_DISARM: MAV_RESULT_DENIED")
        );
    }

    #[test]
    fn silent_waiting_up_and_lost() {
        let s = 1_000;
        let timeout = 5_000;
        assert_eq!(link_state(s + 4_999, s, None, timeout), LinkState::Waiting);
        assert_eq!(link_state(s + 5_000, s, None, timeout), LinkState::Silent);
        assert_eq!(
            link_state(s + 9_000, s, Some(s + 4_500), timeout),
            LinkState::Up
        );
        assert_eq!(
            link_state(s + 9_501, s, Some(s + 4_500), timeout),
            LinkState::Lost
        );
    }

    #[test]
    fn a_holder_that_took_over_from_one_that_heard_the_autopilot_reports_its_silence_as_lost() {
        let (term, timeout) = (1_000, 5_000);
        // its own link never heard the vehicle (over udpout the vehicle answers one peer),
        // the holder before it did: the vehicle's silence is a lost link
        let judged =
            |now, own, before| link_state(now, term, term_heartbeat(own, term, before), timeout);
        assert_eq!(judged(term + 5_000, None, true), LinkState::Up);
        assert_eq!(judged(term + 5_001, None, true), LinkState::Lost);
        // nobody ever heard it: silent, as for a controller that starts alone
        assert_eq!(judged(term + 5_001, None, false), LinkState::Silent);
        // its own heartbeats count, from the term's start
        assert_eq!(
            judged(term + 8_000, Some(term + 4_000), true),
            LinkState::Up
        );
        assert_eq!(judged(term + 5_001, Some(10), false), LinkState::Lost);
    }
}
