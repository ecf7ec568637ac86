//! Fuzz-check helpers, not part of the controller's API: the checks the `controller_mavlink`
//! target in `fuzz/` runs on every input, shared with the corpus replay test
//! (`roles/tests/fuzz_corpus.rs`) so that stable Rust replays the corpus with the same
//! checks. They panic on a broken promise, as a fuzz target must.

use super::autopilot_state::AutopilotState;
use super::messages::{
    COMPANION_COMPONENT_ID, COMPANION_SYSTEM_ID, Target, position_target_message,
};
use super::tracker::{TrackCommand, Tracker, TrackerConfig, VehicleView, norm};
use aeris_mavlink::dialect::MavMessage;
use aeris_mavlink::{Autopilot, MavHeader};
use aeris_schemas::{ActionMode, BoundSetpoint};

/// Replay `data` as bytes from the autopilot link and check what the controller would send.
///
/// `data[0]` sets the scene: bits 0-3 the hub's setpoint (0 or > 8: none, the controller
/// holds; 1..=8: one valid setpoint of that [`ActionMode`] wire value), bit 4 keeps it fresh
/// (offered again every tick instead of once), bit 5 also accepts MAVLink 1 frames (the link
/// itself reads MAVLink 2 only), bits 6-7 the control ticks after each read (1, 2, 5 or 25:
/// 25 ticks outlast the default setpoint timeout). The rest is the byte stream, decoded by
/// the mavlink crate's reader exactly like the receive thread's link; every message from the
/// autopilot goes through the receive thread's state update, and after each read (message or
/// decode error) come the control ticks. Panics when a tick's output breaks the controller's
/// promises: finite, inside the geofence and under h_max, feed-forward no faster than v_max,
/// and the SET_POSITION_TARGET_LOCAL_NED the same numbers in NED, surviving its own encoding.
pub fn fuzz_check_mavlink(cfg: TrackerConfig, data: &[u8]) {
    use mavlink::error::MessageReadError;
    use mavlink::{MavlinkReader, MavlinkVersion};
    let Some((&scene, stream)) = data.split_first() else {
        return;
    };
    let l = cfg.limits;
    let t0: u64 = 1_000_000_000;
    let period_ns = ((cfg.period_s as f64 * 1e9) as u64).max(1);
    let setpoint = ActionMode::from_u8(scene & 0x0f).map(|mode| {
        let lo = l.h_min.max(l.geofence_min[2]);
        let hi = l.h_max.min(l.geofence_max[2]);
        let u = match mode {
            ActionMode::Land => l.geofence_min[2],
            _ => (lo + hi) / 2.0,
        };
        BoundSetpoint {
            seq: 1,
            decision_seq: 1,
            publish_ns: t0,
            position: [
                (l.geofence_min[0] + l.geofence_max[0]) / 2.0,
                (l.geofence_min[1] + l.geofence_max[1]) / 2.0,
                u,
            ],
            yaw: 0.5,
            speed: l.v_max * 0.6,
            acceptance_radius: 0.0,
            active_step: 1,
            mode: mode as u8,
            ..BoundSetpoint::default()
        }
    });
    let keep_fresh = scene & 0x10 != 0;
    let any_version = scene & 0x20 != 0;
    let ticks = [1, 2, 5, 25][usize::from(scene >> 6)];
    let mut tracker = Tracker::new(cfg);
    let mut ap = AutopilotState::default();
    let mut reader = MavlinkReader::new(stream);
    let mut now = t0;
    // every read consumes at least one byte or ends the stream
    for i in 0..=stream.len() {
        if let Some(sp) = &setpoint
            && (i == 0 || keep_fresh)
        {
            let mut sp = *sp;
            sp.publish_ns = now;
            assert!(
                tracker.offer(&sp, now).is_ok(),
                "valid setpoint refused: {sp:?}"
            );
        }
        let read = if any_version {
            reader.read_any_message::<MavMessage>()
        } else {
            reader.read_message::<MavMessage>(MavlinkVersion::V2)
        };
        match read {
            Ok((h, msg)) if (h.system_id, h.component_id) == (1, 1) => {
                ap.apply(&msg, now, Autopilot::Px4)
            }
            Ok(_) | Err(MessageReadError::Parse(_)) => {}
            Err(MessageReadError::Io(_)) => break,
        }
        let view = ap.vehicle_view(cfg.floor());
        for _ in 0..ticks {
            let cmd = tracker.tick(now, &view);
            fuzz_check_command(&cfg, &cmd, &view);
            now += period_ns;
        }
    }
}

fn fuzz_check_command(cfg: &TrackerConfig, cmd: &TrackCommand, view: &VehicleView) {
    let l = &cfg.limits;
    let p = cmd.position;
    let mut all = p
        .iter()
        .chain(&cmd.velocity)
        .chain(core::iter::once(&cmd.yaw));
    assert!(all.all(|v| v.is_finite()), "{cmd:?} for {view:?}");
    assert!(
        l.inside_geofence(p) && p[2] <= l.h_max,
        "outside the fence: {cmd:?} for {view:?}"
    );
    let speed = norm(cmd.velocity);
    assert!(
        speed <= l.v_max * (1.0 + 1e-5),
        "{speed} m/s > v_max: {cmd:?}"
    );
    let msg = position_target_message(
        cmd,
        1234,
        Target {
            system_id: 1,
            component_id: 1,
        },
    );
    let MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) = &msg else {
        panic!("not a position target: {msg:?}");
    };
    assert_eq!([m.x, m.y, -m.z], p);
    assert_eq!([m.vx, m.vy, -m.vz], cmd.velocity);
    assert_eq!(m.yaw, cmd.yaw);
    // the frame the autopilot receives decodes back to the same message
    let mut frame = [0u8; 300];
    let header = MavHeader {
        system_id: u32::from(COMPANION_SYSTEM_ID),
        component_id: COMPANION_COMPONENT_ID,
        sequence: 7,
    };
    let n = mavlink::write_v2_msg(&mut &mut frame[..], header, &msg).expect("encodes");
    let mut back = mavlink::MavlinkReader::new(&frame[..n]);
    let (h, decoded) = back
        .read_message::<MavMessage>(mavlink::MavlinkVersion::V2)
        .expect("decodes");
    assert_eq!((h.system_id, decoded), (header.system_id, msg));
}
