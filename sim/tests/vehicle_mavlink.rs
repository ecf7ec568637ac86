//! The simulated PX4-like vehicle over a real MAVLink link (UDP and TCP loopback): a client
//! arms it, switches it to offboard, streams setpoints and watches it fly, fail safe, land.

use aeris_mavlink::dialect::{
    COMMAND_LONG_DATA, MavCmd, MavFrame, MavLandedState, MavMessage, MavModeFlag, MavResult,
    PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use aeris_mavlink::px4::{
    PX4_AUTO_SUB_MODE_LOITER, PX4_MAIN_MODE_AUTO, PX4_MAIN_MODE_OFFBOARD, px4_main_mode,
    px4_sub_mode,
};
use aeris_mavlink::{LINK_POLL, MavHeader, MavLink, open_link};
use aeris_sim::mav_vehicle::{FlightMode, SimVehicle, SimVehicleConfig};
use std::time::{Duration, Instant};

const BOUND: Duration = Duration::from_secs(90);

fn free_udp_port() -> u16 {
    let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    s.local_addr().unwrap().port()
}

fn free_tcp_port() -> u16 {
    let s = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    s.local_addr().unwrap().port()
}

/// What the client knows about the vehicle.
#[derive(Debug, Default, Clone, Copy)]
struct Seen {
    heartbeat: Option<(u8, u32)>, // base_mode bits, custom_mode
    heartbeat_type: Option<(u32, u32)>,
    position_ned: Option<[f32; 3]>,
    attitude: bool,
    landed_state: Option<MavLandedState>,
}

impl Seen {
    fn armed(&self) -> bool {
        self.heartbeat
            .is_some_and(|(b, _)| b & MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED.bits() != 0)
    }
    fn main_mode(&self) -> Option<u8> {
        self.heartbeat.map(|(_, c)| px4_main_mode(c))
    }
}

struct Client {
    link: MavLink,
    seen: Seen,
    acks: Vec<(MavCmd, MavResult)>,
    last_setpoint: Option<Instant>,
    confirmation: u8,
}

impl Client {
    fn new(url: &str) -> Self {
        Self {
            link: open_link(url, LINK_POLL).unwrap(),
            seen: Seen::default(),
            acks: Vec::new(),
            last_setpoint: None,
            confirmation: 0,
        }
    }

    fn header() -> MavHeader {
        MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        }
    }

    fn send(&self, msg: &MavMessage) {
        self.link.send(&Self::header(), msg).unwrap();
    }

    fn command(&mut self, command: MavCmd, p1: f32, p2: f32, p3: f32) {
        self.send(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1: p1,
            param2: p2,
            param3: p3,
            param4: 0.0,
            param5: 0.0,
            param6: 0.0,
            param7: 0.0,
            command,
            target_system: 1,
            target_component: 1,
            confirmation: self.confirmation,
        }));
        self.confirmation = self.confirmation.wrapping_add(1);
    }

    fn setpoint(&self, ned: [f32; 3], yaw: f32) {
        let mask = PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VX_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VY_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VZ_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AX_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AY_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AZ_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE;
        self.send(&MavMessage::SET_POSITION_TARGET_LOCAL_NED(
            SET_POSITION_TARGET_LOCAL_NED_DATA {
                time_boot_ms: 0,
                x: ned[0],
                y: ned[1],
                z: ned[2],
                vx: 0.0,
                vy: 0.0,
                vz: 0.0,
                afx: 0.0,
                afy: 0.0,
                afz: 0.0,
                yaw,
                yaw_rate: 0.0,
                type_mask: mask,
                target_system: 1,
                target_component: 1,
                coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            },
        ));
    }

    /// Receive for a while; stream `setpoint` at 20 Hz when given. Returns when `done`
    /// holds or the overall bound passes (then panics with `what`).
    fn pump_until(
        &mut self,
        setpoint: Option<([f32; 3], f32)>,
        what: &str,
        mut each: impl FnMut(&mut Client),
        mut done: impl FnMut(&Client) -> bool,
    ) {
        let start = Instant::now();
        let mut last_each = Instant::now() - Duration::from_secs(1);
        while !done(self) {
            assert!(
                start.elapsed() < BOUND,
                "timed out waiting for {what}: {:?}",
                self.seen
            );
            if let Some((ned, yaw)) = setpoint
                && self
                    .last_setpoint
                    .is_none_or(|t| t.elapsed() >= Duration::from_millis(50))
            {
                self.setpoint(ned, yaw);
                self.last_setpoint = Some(Instant::now());
            }
            if last_each.elapsed() >= Duration::from_millis(500) {
                each(self);
                last_each = Instant::now();
            }
            match self.link.recv() {
                Ok(Some(received)) => {
                    let h = received.header;
                    assert_eq!((h.system_id, h.component_id), (1, 1));
                    match received.message {
                        MavMessage::HEARTBEAT(hb) => {
                            self.seen.heartbeat = Some((hb.base_mode.bits(), hb.custom_mode));
                            self.seen.heartbeat_type =
                                Some((hb.mavtype as u32, hb.autopilot as u32));
                        }
                        MavMessage::LOCAL_POSITION_NED(p) => {
                            assert!(
                                [p.x, p.y, p.z, p.vx, p.vy, p.vz]
                                    .iter()
                                    .all(|v| v.is_finite())
                            );
                            self.seen.position_ned = Some([p.x, p.y, p.z]);
                        }
                        MavMessage::ATTITUDE(a) => {
                            assert!([a.roll, a.pitch, a.yaw].iter().all(|v| v.is_finite()));
                            self.seen.attitude = true;
                        }
                        MavMessage::EXTENDED_SYS_STATE(e) => {
                            self.seen.landed_state = Some(e.landed_state)
                        }
                        MavMessage::COMMAND_ACK(a) => self.acks.push((a.command, a.result)),
                        _ => {}
                    }
                }
                Ok(None) => {}
                Err(e) => panic!("client receive failed: {e}"),
            }
        }
    }

    fn ack_of(&self, cmd: MavCmd) -> Vec<MavResult> {
        self.acks
            .iter()
            .filter(|(c, _)| *c == cmd)
            .map(|(_, r)| *r)
            .collect()
    }
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn offboard_flight_failsafe_and_landing_over_udp() {
    let port = free_udp_port();
    let config = SimVehicleConfig {
        land_speed: 2.0,
        ..SimVehicleConfig::default()
    };
    let vehicle = SimVehicle::spawn(
        &format!("udpin:127.0.0.1:{port}"),
        config,
        Duration::from_millis(10),
    )
    .unwrap();
    let mut client = Client::new(&format!("udpout:127.0.0.1:{port}"));

    // The udpin side only learns our address from our first message.
    client.pump_until(
        None,
        "first heartbeat",
        |c| c.command(MavCmd::MAV_CMD_DO_SET_MODE, 1.0, 6.0, 0.0),
        |c| c.seen.heartbeat.is_some() && !c.ack_of(MavCmd::MAV_CMD_DO_SET_MODE).is_empty(),
    );
    assert_eq!(
        client.seen.heartbeat_type,
        Some((2, 12)),
        "MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_PX4"
    );
    // Offboard without a setpoint stream is refused, like PX4.
    assert!(
        client
            .ack_of(MavCmd::MAV_CMD_DO_SET_MODE)
            .iter()
            .all(|r| *r == MavResult::MAV_RESULT_TEMPORARILY_REJECTED)
    );
    assert!(!client.seen.armed());

    let target_ned = [10.0, -5.0, -8.0];
    client.pump_until(
        Some((target_ned, 0.5)),
        "armed + offboard",
        |c| {
            c.command(MavCmd::MAV_CMD_DO_SET_MODE, 1.0, 6.0, 0.0);
            c.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0, 0.0);
        },
        |c| c.seen.armed() && c.seen.main_mode() == Some(PX4_MAIN_MODE_OFFBOARD),
    );
    assert!(
        client
            .ack_of(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM)
            .contains(&MavResult::MAV_RESULT_ACCEPTED)
    );

    // A non-finite setpoint is rejected and does not disturb the flight.
    client.send(&MavMessage::SET_POSITION_TARGET_LOCAL_NED(
        SET_POSITION_TARGET_LOCAL_NED_DATA {
            x: f32::NAN,
            type_mask: PositionTargetTypemask::empty(),
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        },
    ));
    client.pump_until(
        Some((target_ned, 0.5)),
        "convergence to the setpoint",
        |_| {},
        |c| {
            c.seen
                .position_ned
                .is_some_and(|p| dist(p, target_ned) < 0.3)
        },
    );
    assert!(client.seen.attitude);
    assert_eq!(
        client.seen.landed_state,
        Some(MavLandedState::MAV_LANDED_STATE_IN_AIR)
    );
    let status = vehicle.status().unwrap();
    assert_eq!(status.mode, FlightMode::Offboard);
    assert!(status.stats.setpoints_rejected >= 1, "{:?}", status.stats);
    assert!((status.state.yaw - 0.5).abs() < 0.1, "{:?}", status.state);

    // Disarming in the air without force is denied.
    let before = client.ack_of(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM).len();
    client.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 0.0, 0.0);
    client.pump_until(
        Some((target_ned, 0.5)),
        "disarm ack",
        |_| {},
        |c| c.ack_of(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM).len() > before,
    );
    assert_eq!(
        client.ack_of(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM).last(),
        Some(&MavResult::MAV_RESULT_DENIED)
    );
    assert!(client.seen.armed());

    // Stop streaming: offboard-loss failsafe -> hold, still armed, still there.
    client.pump_until(
        None,
        "offboard-loss failsafe",
        |_| {},
        |c| c.seen.main_mode() == Some(PX4_MAIN_MODE_AUTO),
    );
    let custom = client.seen.heartbeat.unwrap().1;
    assert_eq!(px4_sub_mode(custom), PX4_AUTO_SUB_MODE_LOITER);
    assert!(client.seen.armed());
    let status = vehicle.status().unwrap();
    assert_eq!(status.mode, FlightMode::Hold);
    assert!(status.stats.failsafes >= 1);
    assert!(dist(client.seen.position_ned.unwrap(), target_ned) < 1.0);

    // Land: descends to the ground at the same north/east and disarms by itself.
    client.command(MavCmd::MAV_CMD_NAV_LAND, 0.0, 0.0, 0.0);
    client.pump_until(
        None,
        "landing and auto-disarm",
        |_| {},
        |c| {
            !c.seen.armed()
                && c.seen.landed_state == Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND)
        },
    );
    assert!(
        client
            .ack_of(MavCmd::MAV_CMD_NAV_LAND)
            .contains(&MavResult::MAV_RESULT_ACCEPTED)
    );
    let p = client.seen.position_ned.unwrap();
    assert!(p[2].abs() < 0.05, "on the ground: {p:?}");
    assert!(
        dist([p[0], p[1], 0.0], [target_ned[0], target_ned[1], 0.0]) < 1.0,
        "landed where it was: {p:?}"
    );
    let stats = vehicle.stop();
    assert!(stats.steps > 0 && stats.messages_sent > 0);
}

#[test]
fn serves_a_tcp_client_and_rejects_unknown_commands() {
    let port = free_tcp_port();
    let vehicle = SimVehicle::spawn(
        &format!("tcpin:127.0.0.1:{port}"),
        SimVehicleConfig::default(),
        Duration::from_millis(10),
    )
    .unwrap();
    let mut client = Client::new(&format!("tcpout:127.0.0.1:{port}"));
    client.pump_until(
        None,
        "heartbeat and ack over tcp",
        |c| c.command(MavCmd::MAV_CMD_DO_MOTOR_TEST, 0.0, 0.0, 0.0),
        |c| {
            c.seen.heartbeat.is_some()
                && c.seen.position_ned.is_some()
                && !c.ack_of(MavCmd::MAV_CMD_DO_MOTOR_TEST).is_empty()
        },
    );
    assert!(
        client
            .ack_of(MavCmd::MAV_CMD_DO_MOTOR_TEST)
            .iter()
            .all(|r| *r == MavResult::MAV_RESULT_UNSUPPORTED)
    );
    assert_eq!(client.seen.position_ned, Some([0.0, 0.0, 0.0]));
    assert_eq!(client.seen.main_mode(), Some(3), "position mode after boot");
    drop(client);
    // Stopping joins the physics and receive threads even after the peer went away.
    let stats = vehicle.stop();
    assert!(stats.commands >= 1);
}

#[test]
fn starting_in_the_air_means_armed_and_holding() {
    let port = free_udp_port();
    let mut v = SimVehicle::start(
        &format!("udpin:127.0.0.1:{port}"),
        SimVehicleConfig {
            start: [5.0, 5.0, 20.0],
            ..SimVehicleConfig::default()
        },
    )
    .unwrap();
    for _ in 0..300 {
        v.step(0.01);
    }
    assert!(v.state().armed);
    assert_eq!(v.mode(), FlightMode::Hold);
    assert!(dist(v.state().position, [5.0, 5.0, 20.0]) < 1e-3);
    // Nobody talked to the udpin endpoint yet, so there is nobody to send to.
    assert_eq!(v.status().stats.messages_sent, 0);
    assert_eq!(v.status().stats.steps, 300);
    v.shutdown();
}
