//! Role heartbeat counters by name: the one place that says, for each kind of role read
//! by another, what each slot of [`crate::RoleHeartbeat::counters`] holds. The wire stays
//! eight `u64` slots (a zero-copy message has no variable shape); writers and readers go
//! through these structs, never through a slot number.

/// Declares a role's heartbeat counters: a struct of at most eight `u64` fields, carried in
/// [`crate::RoleHeartbeat::counters`] in the order written (unused slots 0).
macro_rules! heartbeat_counters {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$field_meta:meta])* pub $field:ident, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
        pub struct $name {
            $( $(#[$field_meta])* pub $field: u64, )+
        }

        const _: () = assert!(
            [$(stringify!($field)),+].len() <= 8,
            "a heartbeat carries eight counters"
        );

        impl $name {
            /// As a heartbeat carries them.
            pub fn to_heartbeat(&self) -> [u64; 8] {
                let mut slots = [0u64; 8];
                let fields = [$(self.$field),+];
                slots[..fields.len()].copy_from_slice(&fields);
                slots
            }

            /// Change some of them in place, in a heartbeat's slots.
            pub fn update(slots: &mut [u64; 8], change: impl FnOnce(&mut Self)) {
                let mut counters = Self::from_heartbeat(slots);
                change(&mut counters);
                *slots = counters.to_heartbeat();
            }

            /// From a heartbeat of this kind of role.
            pub fn from_heartbeat(slots: &[u64; 8]) -> Self {
                let mut next = slots.iter().copied();
                Self {
                    $( $field: next.next().unwrap_or(0), )+
                }
            }
        }
    };
}

heartbeat_counters! {
    /// The hub's heartbeat counters (totals since the hub started).
    pub struct HubBeatCounters {
        /// Decisions received.
        pub received,
        /// Decisions rejected (late ones included).
        pub rejected,
        /// Decisions that arrived after the deadline.
        pub late,
        /// Cycles that reused the last valid decision.
        pub reused,
        /// Sequence gaps on incoming decisions.
        pub sequence_gaps,
        /// Out-of-order or duplicate decisions.
        pub reorders,
        /// States received.
        pub states_received,
        /// Decisions of an older reasoning instance ignored.
        pub superseded,
    }
}

heartbeat_counters! {
    /// A language-model reasoner's heartbeat counters (`reasoning` roles of the `smollm2`,
    /// `gemma3`, ... variants): what its last decision cost.
    pub struct LanguageCounters {
        /// Decisions published.
        pub decisions,
        /// Tokens per second of the last decision, times 100.
        pub tokens_per_s_x100,
        /// Generated tokens (last decision).
        pub generated_tokens,
        /// Heartbeats it could not decide (the hub reused the last valid decision).
        pub failures,
        /// Prompt tokens reused from the last decision's cache (last decision).
        pub reused_prompt_tokens,
        /// Prompt tokens (last decision).
        pub prompt_tokens,
        /// Generated tokens verified from the plan's draft (last decision).
        pub drafted_tokens,
        /// 1 when the last decision's step departed from the plan's.
        pub departed_from_plan,
    }
}

heartbeat_counters! {
    /// The planner reasoner's heartbeat counters (`reasoning` roles of the `planner`,
    /// `garbage` and `random` variants).
    pub struct PlannerCounters {
        /// Decisions published.
        pub decisions,
        /// The active subgoal (0-based).
        pub subgoal,
        /// Decisions corrupted on purpose (the `garbage` variant).
        pub corrupted,
        /// Decisions made without occupancy.
        pub blind_decisions,
    }
}

/// Decisions a reasoner of any variant has published: the first counter of
/// [`LanguageCounters`] and [`PlannerCounters`] alike.
pub fn reasoner_decisions(slots: &[u64; 8]) -> u64 {
    PlannerCounters::from_heartbeat(slots).decisions
}

heartbeat_counters! {
    /// The simulated vehicle's heartbeat counters (totals since it started).
    pub struct VehicleCounters {
        /// Setpoints received.
        pub setpoints,
        /// Setpoints outside the geofence that reached it.
        pub outside_fence,
        /// Physics steps.
        pub steps,
        /// Deadlines its cycle missed.
        pub missed_deadlines,
        /// Setpoint ticks missed (no setpoint within the autopilot's period).
        pub setpoint_ticks_missed,
        /// Setpoints rejected.
        pub rejected,
        /// 1 while armed.
        pub armed,
        /// Its flight mode's index.
        pub mode,
    }
}

heartbeat_counters! {
    /// A host bridge's heartbeat counters (totals since it started).
    pub struct BridgeCounters {
        /// Messages sent to the other host.
        pub sent,
        /// Messages received from it.
        pub received,
        /// Bytes sent.
        pub bytes_sent,
        /// Bytes received.
        pub bytes_received,
        /// Messages refused (another schema, or malformed).
        pub refused,
        /// Messages dropped (zenoh or iceoryx2 refused them).
        pub dropped,
        /// 1 while a peer is connected.
        pub connected,
        /// Topics carried.
        pub topics,
    }
}

heartbeat_counters! {
    /// The controller's heartbeat counters (totals of its current term).
    pub struct ControllerCounters {
        /// Control ticks run.
        pub ticks,
        /// Ticks that missed their period.
        pub missed_ticks,
        /// Setpoints the tracker refused.
        pub refused_setpoints,
        /// Ticks spent holding (no valid setpoint).
        pub hold_ticks,
        /// Setpoints sent to the autopilot.
        pub sent,
        /// 1 while it holds the autopilot lease.
        pub lease_held,
        /// Leases it took over from another controller.
        pub takeovers,
        /// The lease's epoch.
        pub lease_epoch,
    }
}

heartbeat_counters! {
    /// A camera's heartbeat counters (the GStreamer camera's; the simulator's camera
    /// counts only `rgb_frames`).
    pub struct CameraCounters {
        /// RGB frames published.
        pub rgb_frames,
        /// Depth frames published.
        pub depth_frames,
        /// Pipeline restarts.
        pub restarts,
        /// Pipeline errors.
        pub errors,
        /// Ends of stream.
        pub ends_of_stream,
        /// Stalls (no frame for too long).
        pub stalls,
        /// Frames stamped on arrival (they carried no PTS).
        pub stamped_on_arrival,
        /// Frames posed outside the telemetry ring (held, or before any telemetry).
        pub held_pose,
    }
}

heartbeat_counters! {
    /// A perception role's heartbeat counters: the detector, text reader, occupancy and
    /// cue scorer, each publishing a block of the state per frame it reads.
    pub struct BlockCounters {
        /// Blocks published.
        pub blocks,
        /// What the last block held: detections, regions read, observed cells, or phrases
        /// scored.
        pub items,
        /// Frames rejected (malformed, or of another format).
        pub frames_rejected,
    }
}

heartbeat_counters! {
    /// The composer's heartbeat counters (the typed state S_t assembled from the blocks).
    pub struct ComposeCounters {
        /// States published.
        pub states,
        /// Blocks in the last state (bit count).
        pub blocks,
    }
}

heartbeat_counters! {
    /// The simulator's geometric perception's heartbeat counters.
    pub struct GeometricPerceptionCounters {
        /// States published.
        pub states,
        /// Frames rejected.
        pub frames_rejected,
    }
}

heartbeat_counters! {
    /// The formation role's heartbeat counters.
    pub struct FormationCounters {
        /// The phase flown (1-based; a replan or a new instruction starts a new program).
        pub phase,
        /// The executor's state: 0 waiting for the vehicles, 1 flying, 2 settling, 3 done,
        /// 4 stuck.
        pub state,
        /// Vehicles that left the formation (each one replanned around).
        pub vehicles_left,
        /// Setpoints published.
        pub setpoints,
        /// The longest wait at a phase's end (ms).
        pub longest_settle_ms,
        /// Vehicles in the formation.
        pub vehicles,
        /// The time the first program took to write, check and repair (ms).
        pub program_ms,
        /// Slots the gate refused to bind.
        pub refused_slots,
    }
}

heartbeat_counters! {
    /// The flight recorder's heartbeat counters.
    pub struct RecorderCounters {
        /// MCAP messages written.
        pub messages,
        /// Samples dropped (queue full, or recording stopped).
        pub dropped,
        /// Bytes of message data written.
        pub bytes,
        /// 1 once writing failed.
        pub failed,
        /// Samples received from the bus.
        pub received,
        /// Which file: 0 = `path`, n = `path.n`.
        pub file_index,
    }
}

heartbeat_counters! {
    /// The replay source's heartbeat counters.
    pub struct ReplayCounters {
        /// Frames published (RGB and depth).
        pub frames,
        /// Telemetry messages published.
        pub telemetry,
        /// 1 once the whole range is published (the flight may end).
        pub done,
        /// Most a message was published after its scheduled time (µs).
        pub late_max_us,
        /// 1 while waiting for the other roles' first heartbeats.
        pub waiting,
        /// The recording's clock minus this machine's at the start (ns, as `u64` bits of an
        /// `i64`): what turns a replayed stamp back into a recorded one.
        pub offset,
        /// The recording time the replay starts at (ns, recording clock).
        pub start,
        /// 1 once the start is fixed (`offset` and `start` hold).
        pub started,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_keep_their_slots_and_unused_slots_are_zero() {
        let c = PlannerCounters {
            decisions: 7,
            subgoal: 2,
            corrupted: 0,
            blind_decisions: 1,
        };
        assert_eq!(c.to_heartbeat(), [7, 2, 0, 1, 0, 0, 0, 0]);
        assert_eq!(PlannerCounters::from_heartbeat(&c.to_heartbeat()), c);
        let slots = [1, 2, 3, 4, 5, 6, 7, 8];
        assert_eq!(
            HubBeatCounters::from_heartbeat(&slots).to_heartbeat(),
            slots
        );
        assert_eq!(
            LanguageCounters::from_heartbeat(&slots).departed_from_plan,
            8
        );
        assert_eq!(BridgeCounters::from_heartbeat(&slots).connected, 7);
        assert_eq!(ControllerCounters::from_heartbeat(&slots).lease_held, 6);
        assert_eq!(VehicleCounters::from_heartbeat(&slots).rejected, 6);
        assert_eq!(reasoner_decisions(&slots), 1);
        // a change in place keeps the other slots
        let mut slots = [9, 8, 0, 0, 0, 0, 0, 0];
        BlockCounters::update(&mut slots, |c| c.frames_rejected = 3);
        assert_eq!(slots, [9, 8, 3, 0, 0, 0, 0, 0]);
        assert_eq!(
            reasoner_decisions(
                &LanguageCounters {
                    decisions: 3,
                    ..Default::default()
                }
                .to_heartbeat()
            ),
            3
        );
    }
}
