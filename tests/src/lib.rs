//! Helpers for the end-to-end tests: find the `aeris` binary, name flights uniquely, and
//! keep spawned processes from outliving a test.

use std::path::PathBuf;
use std::process::{Child, Command};

/// Path of the `aeris` binary built next to the test executable (`target/<profile>/aeris`).
///
/// `cargo test --workspace` builds it; the README's test command builds it first.
pub fn aeris_bin() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test> -> target/<profile>/aeris
    let dir = exe.parent().and_then(|d| d.parent()).expect("target dir");
    let bin = dir.join("aeris");
    assert!(
        bin.exists(),
        "{} is missing: run `cargo build --bin aeris` first (scripts/test.sh does)",
        bin.display()
    );
    bin
}

/// A flight name unique to this test process and tag, so parallel tests never share services.
pub fn unique_flight(tag: &str) -> String {
    format!("{tag}-{}", std::process::id())
}

/// A child process that is killed (SIGKILL) and reaped when dropped.
pub struct ChildGuard(pub Child);

impl ChildGuard {
    /// Spawn `cmd`.
    pub fn spawn(cmd: &mut Command) -> std::io::Result<Self> {
        cmd.spawn().map(ChildGuard)
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.0.id()
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A scratch directory under the system temp dir, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// Create `$TMPDIR/aeris-test-<tag>-<pid>`.
    pub fn new(tag: &str) -> Self {
        let p = std::env::temp_dir().join(format!("aeris-test-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("create temp dir");
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Python interpreter for the independent decoders (`AERIS_PYTHON`, else `python3`).
pub fn python() -> String {
    std::env::var("AERIS_PYTHON").unwrap_or_else(|_| "python3".to_string())
}
