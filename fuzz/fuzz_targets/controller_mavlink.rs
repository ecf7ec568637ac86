//! The controller's MAVLink input path: bytes from the autopilot link, decoded by the
//! mavlink crate as the link does, applied by the receive thread's state update, then control
//! ticks. Input: one scene byte (the hub's setpoint, MAVLink 1 or not), then the byte stream.
//! Checks: `aeris_roles::controller::testing::fuzz_check_mavlink`.
//!
//! The mutator repairs the CRC of the frames in most mutated inputs (not all: broken
//! checksums must be fuzzed too), so mutations reach the payload decoders.

#![no_main]

use aeris_roles::controller::TrackerConfig;
use aeris_roles::controller::testing::fuzz_check_mavlink;
use libfuzzer_sys::{fuzz_mutator, fuzz_target, fuzzer_mutate};
use std::sync::LazyLock;

static TRACKER: LazyLock<TrackerConfig> = LazyLock::new(aeris_fuzz::default_tracker);

fuzz_target!(|data: &[u8]| {
    fuzz_check_mavlink(*TRACKER, data);
});

fuzz_mutator!(|data: &mut [u8], size: usize, max_size: usize, seed: u32| {
    let size = fuzzer_mutate(data, size, max_size);
    if seed % 8 != 0 && size > 1 {
        aeris_fuzz::fix_mavlink_crcs(&mut data[1..size]);
    }
    size
});
