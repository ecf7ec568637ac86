//! The decision gate fed raw bytes as a `Decision` in shared memory (a misbehaving or
//! compromised reasoning process can write any bytes), then a vehicle position and an
//! occupancy grid from the bytes after it. Checks: `aeris_hub::testing::fuzz_check_bytes`.

#![no_main]

use aeris_hub::DecisionGate;
use aeris_hub::testing::fuzz_check_bytes;
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static GATE: LazyLock<DecisionGate> = LazyLock::new(aeris_fuzz::default_gate);

fuzz_target!(|data: &[u8]| {
    fuzz_check_bytes(&GATE, data);
});
