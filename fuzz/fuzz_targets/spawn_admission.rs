//! The bytes of a `spawn` request as they reach an agent from the network, admitted the way
//! the agent admits them (`aeris_hosts::admission`), and an admitted request's files written
//! as the agent writes them, under a private run directory. Checks
//! (`aeris_hosts::testing::fuzz_check_spawn_on_disk`): every admitted request's spec and log
//! lie under the run directory by plain components and its spec resolves there once
//! written; its kind and variant are on the allow-list; no parameter from the network that
//! names a file, model, pipeline or endpoint survives; a bridge's link is the agent's.

#![no_main]

use aeris_hosts::testing::fuzz_check_spawn_on_disk;
use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::LazyLock;

/// One private run directory per fuzzing process.
static RUN_DIR: LazyLock<PathBuf> = LazyLock::new(|| {
    let dir = std::env::temp_dir().join(format!("aeris-fuzz-spawn-{}", std::process::id()));
    aeris_hosts::private_dir::ensure_private_dir(&dir).expect("a private run directory")
});

fuzz_target!(|data: &[u8]| {
    fuzz_check_spawn_on_disk(data, &RUN_DIR);
});
