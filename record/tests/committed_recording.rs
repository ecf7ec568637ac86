//! A recording made by an earlier build opens, reads back as typed messages, and every
//! message's JSON is what this build's codec makes of its raw bytes: a change to how the
//! recorder encodes a payload cannot pass unnoticed.
//!
//! `data/flight-s8.mcap` is the first 1.5 s of the built-in flight, recorded by the build of
//! cc5bc97 (before the codec was derived from the schema types) with
//! `aeris run --record flight-s8.mcap --record-no-exact-frames --record-frame-every 0
//! --max-duration 1.5`. A new schema version makes it unreadable on purpose (a replay
//! refuses another schema): record it again with that command and rename it.

use aeris_record::codec::PayloadCodec;
use aeris_record::read::Recording;
use aeris_schemas::{SCHEMA_VERSION, VehicleTelemetry, topics};
use std::path::PathBuf;

/// Fields the JSON gained since the recording was made, by topic: the hand-written JSON of
/// `controller/link` had drifted from its type and left out the lease epoch.
const ADDED: &[(&str, &str)] = &[(topics::CONTROLLER_LINK, "lease_epoch")];

fn committed() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(format!("flight-s{SCHEMA_VERSION}.mcap"))
}

#[test]
fn every_recorded_json_message_is_what_the_codec_makes_of_its_raw_bytes() {
    let path = committed();
    let mut rec = Recording::open(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (a new schema version: record it again, see this file's doc)",
            path.display()
        )
    });
    let mut compared_topics = 0;
    for topic in topics::ALL {
        let raw_topic = format!("{topic}/raw");
        if rec.message_count(topic) == 0 || rec.message_count(&raw_topic) == 0 {
            continue;
        }
        let payload = topics::payload_of(topic).expect("a flight topic has a payload");
        let (mut json, mut raw) = (Vec::new(), Vec::new());
        rec.for_each(&[topic, raw_topic.as_str()], None, None, |t, _, data| {
            if t == topic {
                json.push(data.to_vec());
            } else {
                raw.push(data.to_vec());
            }
            true
        })
        .unwrap();
        assert_eq!(
            json.len(),
            raw.len(),
            "{topic}: one JSON message per raw one"
        );
        for (i, (j, r)) in json.iter().zip(&raw).enumerate() {
            let mut now = payload
                .to_json(r)
                .unwrap_or_else(|| panic!("{topic} #{i}: {} bytes are no payload", r.len()));
            for (_, field) in ADDED.iter().filter(|(t, _)| *t == topic) {
                let added = now.as_object_mut().and_then(|o| o.remove(*field));
                assert!(added.is_some(), "{topic} #{i}: no {field}");
            }
            assert_eq!(
                now.to_string(),
                String::from_utf8_lossy(j),
                "{topic} #{i}: the codec encodes this message differently from the recording"
            );
        }
        compared_topics += 1;
    }
    // telemetry, S_t, decisions, setpoints, hub reports, lease, link, heartbeats, frames
    assert!(
        compared_topics >= 8,
        "only {compared_topics} topics compared"
    );
    let telemetry = rec
        .typed::<VehicleTelemetry>(topics::VEHICLE_TELEMETRY)
        .unwrap();
    assert_eq!(
        telemetry.len() as u64,
        rec.message_count(&format!("{}/raw", topics::VEHICLE_TELEMETRY))
    );
    assert!(telemetry.windows(2).all(|w| w[0].stamp_ns <= w[1].stamp_ns));
}
