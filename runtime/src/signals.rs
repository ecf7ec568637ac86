//! SIGTERM / SIGINT turned into a flag that role loops poll.

use core::sync::atomic::{AtomicBool, AtomicI32, Ordering};

static TERMINATION_REQUESTED: AtomicBool = AtomicBool::new(false);
static LAST_SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(sig: libc::c_int) {
    // Only async-signal-safe work: two atomic stores.
    LAST_SIGNAL.store(sig, Ordering::SeqCst);
    TERMINATION_REQUESTED.store(true, Ordering::SeqCst);
}

/// Install handlers for SIGTERM and SIGINT (idempotent). Without SA_RESTART, so blocking
/// sleeps return early and loops notice the request at once.
pub fn install_termination_handlers() -> std::io::Result<()> {
    for sig in [libc::SIGTERM, libc::SIGINT] {
        // SAFETY: a zeroed sigaction is a valid starting point; the handler only touches
        // atomics, which is async-signal-safe.
        unsafe {
            let mut sa: libc::sigaction = core::mem::zeroed();
            sa.sa_sigaction = on_signal as *const () as usize;
            sa.sa_flags = 0;
            libc::sigemptyset(&mut sa.sa_mask);
            if libc::sigaction(sig, &sa, core::ptr::null_mut()) != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
    }
    Ok(())
}

/// `true` once SIGTERM or SIGINT arrived (or [`request_termination`] was called).
#[inline]
pub fn termination_requested() -> bool {
    TERMINATION_REQUESTED.load(Ordering::Relaxed)
}

/// Ask the loops of this process to stop, as a signal would.
pub fn request_termination() {
    TERMINATION_REQUESTED.store(true, Ordering::SeqCst);
}

/// The last termination signal received (0 = none).
pub fn last_signal() -> i32 {
    LAST_SIGNAL.load(Ordering::Relaxed)
}
