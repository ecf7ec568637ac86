//! The flight's clock: CLOCK_MONOTONIC of the flight's host, comparable across the
//! processes of a flight. On the flight's host it is CLOCK_MONOTONIC itself. A role on
//! another host reads that host's CLOCK_MONOTONIC shifted by the offset its handle measured
//! between the two hosts ([`set_flight_clock_offset_ns`], from the role's spec): two
//! machines' monotonic clocks start at their own boots, so without the shift a stamp
//! taken there (a decision's cycle start, a heartbeat) would be hours off on the flight's
//! host and every age the hub checks would be wrong.
//!
//! A flight on simulated time ([`sim`]) reads that instead: a process that was handed the
//! flight's simulated clock ([`use_sim_clock`]) reads it in [`monotonic_ns`], so every
//! stamp, period, deadline and timeout of a role follows it. What must stay on the wall
//! clock (how long work took, liveness) reads [`wall_ns`].

use core::sync::atomic::{AtomicI64, Ordering};
use core::time::Duration;
use std::sync::OnceLock;

pub mod sim;

/// The flight's simulated clock, when this process runs on one.
static SIM_CLOCK: OnceLock<sim::SimClockReader> = OnceLock::new();

/// Read the flight's time from `clock` from now on (a process of a flight on simulated
/// time). Set once, when the process starts; `false` when a clock was already set.
pub fn use_sim_clock(clock: sim::SimClockReader) -> bool {
    SIM_CLOCK.set(clock).is_ok()
}

/// `true` when this process reads a simulated flight clock ([`use_sim_clock`]).
pub fn simulated() -> bool {
    SIM_CLOCK.get().is_some()
}

/// What this process adds to its host's CLOCK_MONOTONIC to read the flight's clock.
static FLIGHT_CLOCK_OFFSET_NS: AtomicI64 = AtomicI64::new(0);

/// Read the flight's clock as this host's CLOCK_MONOTONIC plus `offset_ns` from now on (a
/// role on another host: the flight's host's clock minus this one's; 0 on the flight's
/// host). Set once, when the role process starts, before it stamps anything.
pub fn set_flight_clock_offset_ns(offset_ns: i64) {
    FLIGHT_CLOCK_OFFSET_NS.store(offset_ns, Ordering::Relaxed);
}

/// What this process adds to its host's CLOCK_MONOTONIC ([`set_flight_clock_offset_ns`]).
pub fn flight_clock_offset_ns() -> i64 {
    FLIGHT_CLOCK_OFFSET_NS.load(Ordering::Relaxed)
}

/// This host's CLOCK_MONOTONIC (ns), unshifted: for what is compared with this host only
/// (an agent's answer, the kernel's own stamps).
#[inline]
pub fn host_monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Nanoseconds of the flight's clock: its simulated time on a flight on simulated time,
/// else CLOCK_MONOTONIC, shifted on another host (see the module). Never allocates, never
/// fails on Linux.
#[inline]
pub fn monotonic_ns() -> u64 {
    match SIM_CLOCK.get() {
        Some(clock) => clock.now_ns(),
        None => wall_ns(),
    }
}

/// Nanoseconds of the flight host's CLOCK_MONOTONIC (shifted on another host), whatever
/// the flight's clock is: for how long work took on this machine, and for liveness.
#[inline]
pub fn wall_ns() -> u64 {
    to_flight_clock(
        host_monotonic_ns(),
        FLIGHT_CLOCK_OFFSET_NS.load(Ordering::Relaxed),
    )
}

/// CPU time this process has used, all its threads together (ns; CLOCK_PROCESS_CPUTIME_ID).
/// Never allocates; 0 if the clock cannot be read.
pub fn process_cpu_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the timespec we own.
    if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) } != 0 {
        return 0;
    }
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// `host_ns` of this host's clock on the flight's clock, this host's being `offset_ns`
/// behind it.
fn to_flight_clock(host_ns: u64, offset_ns: i64) -> u64 {
    host_ns.saturating_add_signed(offset_ns)
}

/// `flight_ns` of the flight's clock on this host's clock.
fn to_host_clock(flight_ns: u64, offset_ns: i64) -> u64 {
    flight_ns.saturating_add_signed(offset_ns.saturating_neg())
}

/// Sleep until the absolute instant `deadline_ns` of the flight's clock (no drift
/// accumulates). Returns early if a signal interrupts the sleep, so termination requests
/// are seen. On simulated time (a process that is not stepped by it, such as a tool
/// watching the flight) it sleeps what is left until `deadline_ns` on the wall clock.
pub fn sleep_until_ns(deadline_ns: u64) {
    if let Some(clock) = SIM_CLOCK.get() {
        let left = deadline_ns.saturating_sub(clock.now_ns());
        let deadline_ns = wall_ns().saturating_add(left);
        return sleep_until_wall_ns(deadline_ns);
    }
    sleep_until_wall_ns(deadline_ns)
}

/// [`sleep_until_ns`] on the wall clock ([`wall_ns`]).
fn sleep_until_wall_ns(deadline_ns: u64) {
    // back to this host's clock, which the kernel sleeps on
    let deadline_ns = to_host_clock(deadline_ns, FLIGHT_CLOCK_OFFSET_NS.load(Ordering::Relaxed));
    let ts = libc::timespec {
        tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
    };
    // SAFETY: `ts` is valid; a null remainder is allowed with TIMER_ABSTIME.
    unsafe {
        libc::clock_nanosleep(
            libc::CLOCK_MONOTONIC,
            libc::TIMER_ABSTIME,
            &ts,
            core::ptr::null_mut(),
        );
    }
}

/// Duration as whole nanoseconds, saturating.
#[inline]
pub fn duration_ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flight_clock_is_the_host_clock_shifted_both_ways() {
        let hour = 3_600_000_000_000i64;
        assert_eq!(to_flight_clock(5 * hour as u64, -hour), 4 * hour as u64);
        assert_eq!(to_host_clock(4 * hour as u64, -hour), 5 * hour as u64);
        assert_eq!(to_flight_clock(7, 0), 7);
        // saturates instead of wrapping
        assert_eq!(to_flight_clock(5, -hour), 0);
        assert_eq!(to_host_clock(u64::MAX - 1, -hour), u64::MAX);
    }
}
