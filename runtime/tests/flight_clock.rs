//! The process-wide flight clock offset (a test binary of its own: the offset is global).

use aeris_runtime::clock::{
    flight_clock_offset_ns, host_monotonic_ns, monotonic_ns, set_flight_clock_offset_ns,
    sleep_until_ns,
};

#[test]
fn a_role_on_another_host_reads_and_sleeps_on_the_flights_clock() {
    assert_eq!(flight_clock_offset_ns(), 0);
    let before = host_monotonic_ns();
    assert!(monotonic_ns() >= before);
    // this host's clock ahead of the flight's (the flight's host booted later) by half its
    // own uptime, and behind it by an hour (booted earlier): a fixed hour ahead cannot be
    // tested on a machine booted less than an hour ago, whose clock reads less than that
    let ahead = (before / 2) as i64;
    let hour = 3_600_000_000_000i64;
    for offset in [-ahead, hour] {
        set_flight_clock_offset_ns(offset);
        // the flight's clock is this host's shifted by the offset, read between two
        // readings of this host's
        let (lo, flight, hi) = (
            host_monotonic_ns() as i64,
            monotonic_ns() as i64,
            host_monotonic_ns() as i64,
        );
        assert!(
            lo + offset <= flight && flight <= hi + offset,
            "offset {offset}: host {lo}..{hi}, flight {flight}"
        );
        // a deadline 1 ms ahead on the flight's clock is 1 ms ahead on this host's, not
        // far in the past (no sleep) or the future (a hang)
        let t = host_monotonic_ns();
        sleep_until_ns(monotonic_ns() + 1_000_000);
        assert!(host_monotonic_ns() - t >= 1_000_000, "offset {offset}");
    }
    set_flight_clock_offset_ns(0);
}
