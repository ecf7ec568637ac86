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
    // this host's clock an hour ahead of the flight's
    let hour = 3_600_000_000_000u64;
    set_flight_clock_offset_ns(-(hour as i64));
    let flight = monotonic_ns();
    let host = host_monotonic_ns();
    assert!(host - flight >= hour, "{host} {flight}");
    // a deadline 1 ms ahead on the flight's clock is 1 ms ahead on this host's, not an
    // hour in the past (no sleep) or the future (a hang)
    let t = host_monotonic_ns();
    sleep_until_ns(monotonic_ns() + 1_000_000);
    assert!(host_monotonic_ns() - t >= 1_000_000);
    set_flight_clock_offset_ns(0);
}
