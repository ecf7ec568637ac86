//! The transport over real iceoryx2 services (within one process, two nodes).

use aeris_runtime::bus::{BusError, FlightBus, flight_node_census, list_flight_services};
use aeris_schemas::{Decision, FrameFormat, FrameHeader, ZeroCopySend, topics};

fn flight(tag: &str) -> String {
    format!("t-{tag}-{}", std::process::id())
}

#[test]
fn typed_messages_cross_between_nodes_of_one_flight() {
    let f = flight("typed");
    let a = FlightBus::builder(&f).node_name("a").create().unwrap();
    let b = FlightBus::builder(&f).node_name("b").create().unwrap();
    let publisher = a.publisher::<topics::ReasoningDecision>().unwrap();
    let subscriber = b.subscriber::<topics::ReasoningDecision>().unwrap();
    for seq in 1..=3 {
        publisher
            .publish(&Decision {
                seq,
                ..Decision::default()
            })
            .unwrap();
    }
    let mut got = Vec::new();
    subscriber.drain(|d| got.push(d.seq)).unwrap();
    assert_eq!(got, vec![1, 2, 3]);
    assert!(list_flight_services(&f).contains(&topics::REASONING_DECISION.to_string()));
    assert_eq!(flight_node_census(&f), (2, 0));
}

#[test]
fn flights_do_not_cross_talk() {
    let a = FlightBus::builder(&flight("x1"))
        .node_name("a")
        .create()
        .unwrap();
    let b = FlightBus::builder(&flight("x2"))
        .node_name("b")
        .create()
        .unwrap();
    let publisher = a.publisher::<topics::ReasoningDecision>().unwrap();
    let subscriber = b.subscriber::<topics::ReasoningDecision>().unwrap();
    publisher.publish(&Decision::default()).unwrap();
    assert_eq!(subscriber.next().unwrap(), None);
}

#[test]
fn a_vehicles_roles_talk_in_its_scope_and_the_flights_roles_reach_every_scope() {
    use aeris_schemas::RoleHeartbeat;
    let f = flight("scope");
    let v1 = FlightBus::builder(&f)
        .node_name("c1")
        .vehicle(Some(1))
        .create()
        .unwrap();
    let v2 = FlightBus::builder(&f)
        .node_name("c2")
        .vehicle(Some(2))
        .create()
        .unwrap();
    let ground = FlightBus::builder(&f).node_name("ground").create().unwrap();
    // vehicle 2's role publishes "reasoning/decision" as if it were alone in the flight
    let from_v2 = v2.publisher::<topics::ReasoningDecision>().unwrap();
    let at_v1 = v1.subscriber::<topics::ReasoningDecision>().unwrap();
    let at_ground = ground
        .subscriber_in::<topics::ReasoningDecision>(Some(2))
        .unwrap();
    let unscoped = ground.subscriber::<topics::ReasoningDecision>().unwrap();
    from_v2
        .publish(&Decision {
            seq: 7,
            ..Decision::default()
        })
        .unwrap();
    assert_eq!(at_ground.next().unwrap().map(|d| d.seq), Some(7));
    assert_eq!(at_v1.next().unwrap(), None, "vehicle 1 heard vehicle 2");
    assert_eq!(
        unscoped.next().unwrap(),
        None,
        "the flight's own topic heard vehicle 2"
    );
    assert!(list_flight_services(&f).contains(&"v2/reasoning/decision".to_string()));
    // heartbeats stay flight-wide: the supervisor hears every vehicle's roles
    let beats = ground.subscriber::<topics::Heartbeat>().unwrap();
    let beat = v1.publisher::<topics::Heartbeat>().unwrap();
    beat.publish(&RoleHeartbeat::default()).unwrap();
    assert!(beats.next().unwrap().is_some());
}

#[test]
fn frames_travel_with_their_header() {
    let f = flight("frames");
    let a = FlightBus::builder(&f).node_name("cam").create().unwrap();
    let b = FlightBus::builder(&f).node_name("per").create().unwrap();
    let publisher = a.frame_publisher::<topics::CameraRgb>(4 * 2 * 3).unwrap();
    let subscriber = b.frame_subscriber::<topics::CameraRgb>().unwrap();
    let header = FrameHeader {
        seq: 7,
        width: 4,
        height: 2,
        format: FrameFormat::Rgb8 as u8,
        ..FrameHeader::default()
    };
    publisher
        .publish_with(&header, 24, |bytes| {
            bytes.iter_mut().enumerate().for_each(|(i, b)| *b = i as u8)
        })
        .unwrap();
    let frame = subscriber.latest().unwrap().expect("a frame");
    assert_eq!(frame.user_header().seq, 7);
    assert_eq!(
        frame.user_header().validate(frame.payload().len()),
        Ok(FrameFormat::Rgb8)
    );
    assert_eq!(frame.payload()[23], 23);
}

/// A payload with another layout under the same type name family: what a build with
/// another schema would send.
#[derive(Debug, Clone, Copy, iceoryx2::prelude::ZeroCopySend)]
#[type_name("aeris::Decision@s0")]
#[repr(C)]
struct OldDecision {
    seq: u64,
    speed: f32,
}

/// `reasoning/decision` as a build with [`OldDecision`] declares it.
struct OldDecisionTopic;

impl topics::Topic for OldDecisionTopic {
    const INFO: topics::TopicInfo = <topics::ReasoningDecision as topics::Topic>::INFO;
}

impl topics::MessageTopic for OldDecisionTopic {
    type Message = OldDecision;
}

#[test]
fn a_service_of_another_schema_is_refused_with_a_clear_error() {
    let f = flight("skew");
    let new = FlightBus::builder(&f).node_name("new").create().unwrap();
    let _p = new.publisher::<topics::ReasoningDecision>().unwrap();
    let old = FlightBus::builder(&f).node_name("old").create().unwrap();
    let err = old.subscriber::<OldDecisionTopic>().err().expect("refused");
    assert!(
        matches!(err, BusError::IncompatibleSchema { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("another schema version"), "{err}");
    // SAFETY: type_name has no preconditions.
    let _ = unsafe { <OldDecision as ZeroCopySend>::type_name() };
}

/// Set in the child process of [`joining_a_flight_logs_nothing_of_iceoryx2s_own`].
const QUIET_CHILD: &str = "AERIS_BUS_QUIET_CHILD";

/// A process that joins a flight, opens a topic, lists the flight's services and reaches
/// iceoryx2's global configuration writes nothing to stderr: iceoryx2's configuration is set
/// up quietly, so its "No config file was loaded" warning (in every role and test log
/// before) is not printed. Checked in a child process (this
/// test binary run again on this test alone), whose stderr holds only what it printed.
#[test]
fn joining_a_flight_logs_nothing_of_iceoryx2s_own() {
    if std::env::var_os(QUIET_CHILD).is_some() {
        let f = flight("quiet");
        let bus = FlightBus::builder(&f).node_name("quiet").create().unwrap();
        let _publisher = bus.publisher::<topics::ReasoningDecision>().unwrap();
        assert!(list_flight_services(&f).contains(&topics::REASONING_DECISION.to_string()));
        // iceoryx2's own paths that take its global configuration (the clean-up of a dead
        // node whose details are gone) find it set up, and say nothing either
        let _ = iceoryx2::prelude::Config::global_config();
        return;
    }
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "joining_a_flight_logs_nothing_of_iceoryx2s_own",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(QUIET_CHILD, "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "child failed: {stdout}{stderr}");
    assert!(
        stdout.contains("1 passed"),
        "the child ran no test: {stdout}"
    );
    assert!(stderr.trim().is_empty(), "the child logged: {stderr}");
}

/// Every node of ours waits [`SERVICE_CREATION_TIMEOUT`] (not iceoryx2's 1 s) for a service
/// another process is still creating: on two busy cores the hub once took longer than 1 s to
/// create `hub/report`, and `aeris run` failed the flight.
#[test]
fn opening_a_service_waits_for_a_slow_creator() {
    use aeris_runtime::bus::{SERVICE_CREATION_TIMEOUT, iceoryx_config};
    assert!(SERVICE_CREATION_TIMEOUT >= core::time::Duration::from_secs(10));
    assert!(iceoryx_config().global.creation_timeout >= SERVICE_CREATION_TIMEOUT);
}

#[test]
fn a_refused_port_keeps_iceoryx2s_error_as_its_source() {
    let f = flight("full");
    let bus = FlightBus::builder(&f).node_name("many").create().unwrap();
    let most = <topics::HubReport as topics::Topic>::INFO
        .qos
        .max_subscribers;
    let _room: Vec<_> = (0..most)
        .map(|_| bus.subscriber::<topics::HubReport>().unwrap())
        .collect();
    let err = bus
        .subscriber::<topics::HubReport>()
        .err()
        .expect("one subscriber more than the topic's QoS allows is refused");
    assert!(matches!(err, BusError::Port { .. }), "{err:?}");
    let cause = std::error::Error::source(&err).expect("iceoryx2's error is the source");
    assert!(
        cause
            .downcast_ref::<iceoryx2::port::subscriber::SubscriberCreateError>()
            .is_some(),
        "{cause:?}"
    );
    let text = aeris_runtime::error_chain::chain(&err).to_string();
    assert!(text.starts_with("cannot create a port on `"), "{text}");
    assert_eq!(text.matches("hub/report").count(), 1, "{text}");
    assert!(text.contains("ExceedsMaxSupportedSubscribers"), "{text}");
}

/// A role process's bus opens typed ports only on the topics its kind declares, so the
/// flight's graph the supervisor derives from the declarations is what the role does; the
/// supervisor's and tools' buses open any.
#[test]
fn a_role_bus_opens_the_ports_its_kind_declares_and_a_context_refuses_another_kind() {
    // (an undeclared port does not compile: the `compile_fail` examples on `RoleBus`)
    use aeris_runtime::{RoleBus, RoleContext, RoleSpec};
    use aeris_schemas::kinds;
    let f = flight("declared");
    let node = |name: &str| FlightBus::builder(&f).node_name(name).create().unwrap();
    let hub = RoleBus::<kinds::Hub>::new(node("hub"));
    hub.subscriber::<topics::ReasoningDecision>().unwrap();
    hub.publisher::<topics::HubSetpoint>().unwrap();
    // a reasoner reads the hub's setpoint without waiting (reads_latest); the formation
    // role answers `aeris formation say` (a tool's topic)
    let reasoner = RoleBus::<kinds::Reasoning>::new(node("reasoning"));
    reasoner.subscriber::<topics::HubSetpoint>().unwrap();
    let formation = RoleBus::<kinds::Formation>::new(node("formation"));
    formation.subscriber::<topics::FormationSay>().unwrap();
    formation.publisher::<topics::FormationReply>().unwrap();
    // a runner handed a spec of another kind is refused, naming both
    let spec: RoleSpec = serde_json::from_value(serde_json::json!({
        "flight": f, "name": "det", "kind": "detector", "variant": "yolo",
        "mission": { "instruction": "x", "subgoals": [] }
    }))
    .unwrap();
    match RoleContext::<kinds::Hub>::new(spec, node("det")) {
        Err(e) => assert_eq!(
            format!(
                "{}: {}",
                e,
                std::error::Error::source(&e).map_or(String::new(), |s| s.to_string())
            ),
            "invalid configuration: `kind` is detector, but this role is a hub"
        ),
        Ok(_) => panic!("a hub context was made from a detector's spec"),
    }
}
