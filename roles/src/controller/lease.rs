//! The autopilot lease (hot standby): which of the flight's controllers may write to the
//! autopilot. Pure: no I/O, no allocation; the role feeds it the leases heard on
//! `controller/lease` and publishes the one it holds.
//!
//! The holder publishes a [`ControllerLease`] at every poll. A standby claims the lease when
//! none was heard for [`LEASE_SILENCE_PERIODS`] control periods, with an epoch above every epoch it heard and at
//! least the system's monotonic clock in milliseconds (so a controller that never heard the
//! holder, which was stopped before it came up, still outranks every earlier claim when
//! that holder resumes). A holder that hears a higher claim steps down. A controller
//! listens [`LEASE_LISTEN_PERIODS`] control periods after it starts before it claims (a
//! standby twice as long); two claims of one epoch go to the primary.

use aeris_schemas::ControllerLease;

/// Control periods without a lease heard after which a standby claims it: long enough that
/// a holder delayed by a busy machine for a few ticks keeps it (a takeover moves the
/// autopilot link to another process), short enough that at the default 50 Hz (100 ms) the
/// autopilot, which gives up on offboard setpoints after PX4's `COM_OF_LOSS_T` (1 s by
/// default), does not notice a dead holder. (At a control rate under 5 Hz it would.)
pub const LEASE_SILENCE_PERIODS: u64 = 5;

/// Control periods a primary controller listens for a lease holder after it starts before
/// it claims the lease itself (a standby listens twice as long).
pub const LEASE_LISTEN_PERIODS: u64 = 10;

/// What [`LeaseArbiter::decide`] did this poll.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeaseChange {
    /// Nothing changed.
    Kept,
    /// This controller claimed the lease: it is the holder from now on.
    TookOver,
    /// A higher claim was heard: this controller is a standby from now on.
    SteppedDown,
}

/// The autopilot lease as one controller sees it (pure: no I/O, no allocation).
#[derive(Debug, Clone, Copy)]
pub struct LeaseArbiter {
    pid: u32,
    rank: u8,
    silence_ns: u64,
    listen_until_ns: u64,
    epoch: u64,
    active: bool,
    /// The newest sample of the highest claim heard from another controller (its tracking
    /// state is what a takeover adopts).
    highest_seen: Option<ControllerLease>,
    last_heard_ns: Option<u64>,
    takeovers: u64,
}

impl LeaseArbiter {
    /// A standby controller `pid` started at `now_ns`: it claims the lease after
    /// `listen_ns` of silence from start, and later when no other holder was heard for
    /// `silence_ns`. `primary` wins a tie of epochs.
    pub fn new(pid: u32, primary: bool, now_ns: u64, silence_ns: u64, listen_ns: u64) -> Self {
        Self {
            pid,
            rank: u8::from(primary),
            silence_ns,
            listen_until_ns: now_ns.saturating_add(listen_ns),
            epoch: 0,
            active: false,
            highest_seen: None,
            last_heard_ns: None,
            takeovers: 0,
        }
    }

    /// Take in a lease another controller published; samples of this process are ignored.
    /// `now_ns` bounds the sample's stamp (a stamp from the future counts as now).
    pub fn observe(&mut self, lease: &ControllerLease, now_ns: u64) {
        if lease.holder_pid == self.pid {
            return;
        }
        if self
            .highest_seen
            .is_none_or(|h| (lease.key(), lease.stamp_ns) >= (h.key(), h.stamp_ns))
        {
            self.highest_seen = Some(*lease);
        }
        let stamp = lease.stamp_ns.min(now_ns);
        if self.last_heard_ns.is_none_or(|t| stamp > t) {
            self.last_heard_ns = Some(stamp);
        }
    }

    /// Claim or give up the lease at `now_ns` on what was observed.
    pub fn decide(&mut self, now_ns: u64) -> LeaseChange {
        let heard_recently = self
            .last_heard_ns
            .is_some_and(|t| now_ns.saturating_sub(t) <= self.silence_ns);
        if self.active {
            let outranked = self.highest_seen.is_some_and(|h| h.key() > self.key());
            if outranked && heard_recently {
                self.active = false;
                self.epoch = 0;
                return LeaseChange::SteppedDown;
            }
            return LeaseChange::Kept;
        }
        if heard_recently || now_ns < self.listen_until_ns {
            return LeaseChange::Kept;
        }
        // above every claim heard, and above every claim made before now by anyone (the
        // clock is CLOCK_MONOTONIC, one for every process of the host; a term lasts longer
        // than a millisecond)
        self.epoch = (self.highest_seen.map_or(0, |h| h.epoch) + 1).max(now_ns / 1_000_000);
        self.active = true;
        self.takeovers += 1;
        LeaseChange::TookOver
    }

    /// This controller holds the lease.
    pub fn is_active(&self) -> bool {
        self.active
    }

    /// The epoch held (0 when standby).
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// The newest sample of the highest claim another controller made (what a takeover
    /// goes on from).
    pub fn highest_seen(&self) -> Option<&ControllerLease> {
        self.highest_seen.as_ref()
    }

    /// Leases claimed so far.
    pub fn takeovers(&self) -> u64 {
        self.takeovers
    }

    fn key(&self) -> (u64, u8, u32) {
        (self.epoch, self.rank, self.pid)
    }

    /// The lease sample to publish at `now_ns` (`sent`: setpoints sent in this term).
    /// (The tracking state is left empty: [`super::Tracker::write_handover`] fills it in.)
    pub fn lease(&self, now_ns: u64, sent: u64) -> ControllerLease {
        ControllerLease {
            epoch: self.epoch,
            stamp_ns: now_ns,
            sent,
            holder_pid: self.pid,
            rank: self.rank,
            ..ControllerLease::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;
    const PERIOD: u64 = 20 * MS;
    const LISTEN: u64 = 200 * MS;

    fn lease_of(a: &LeaseArbiter, now: u64) -> ControllerLease {
        a.lease(now, 0)
    }

    #[test]
    fn a_lone_controller_claims_the_lease_after_listening() {
        let mut a = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        assert_eq!(a.decide(LISTEN - 1), LeaseChange::Kept);
        assert!(!a.is_active());
        assert_eq!(a.decide(LISTEN), LeaseChange::TookOver);
        assert!(a.is_active());
        assert_eq!(
            (a.epoch(), a.takeovers()),
            (200, 1),
            "the claim's time in ms"
        );
        // its own samples are no competition
        let own = lease_of(&a, LISTEN);
        a.observe(&own, LISTEN + PERIOD);
        assert_eq!(a.decide(LISTEN + PERIOD), LeaseChange::Kept);
        assert!(a.is_active());
    }

    #[test]
    fn a_standby_waits_while_the_holder_is_heard_and_takes_over_after_its_silence_window() {
        let mut holder = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        assert_eq!(holder.decide(LISTEN), LeaseChange::TookOver);
        // the standby starts later (a restarted controller) and hears the holder every poll
        let start = LISTEN + 5 * PERIOD;
        let mut standby = LeaseArbiter::new(11, false, start, PERIOD, LISTEN);
        let mut t = start;
        while t < start + 3 * LISTEN {
            standby.observe(&lease_of(&holder, t), t);
            assert_eq!(standby.decide(t), LeaseChange::Kept, "at {t}");
            t += 5 * MS;
        }
        assert!(!standby.is_active());
        // the holder goes silent after its sample at `last`
        let last = t - 5 * MS;
        assert_eq!(standby.decide(last + PERIOD), LeaseChange::Kept);
        assert_eq!(standby.decide(last + PERIOD + 1), LeaseChange::TookOver);
        assert!(
            standby.epoch() > holder.epoch(),
            "above the silent holder's"
        );
        // the old holder wakes up (SIGCONT), hears the new term and steps down
        let now = last + PERIOD + 5 * MS;
        holder.observe(&lease_of(&standby, now), now);
        assert_eq!(holder.decide(now), LeaseChange::SteppedDown);
        assert!(!holder.is_active());
        assert_eq!(holder.epoch(), 0);
        // and the new holder is not moved by the old term's late samples
        standby.observe(
            &ControllerLease {
                epoch: 200,
                rank: 1,
                holder_pid: 10,
                stamp_ns: now,
                ..Default::default()
            },
            now,
        );
        assert_eq!(standby.decide(now), LeaseChange::Kept);
        assert!(standby.is_active());
    }

    #[test]
    fn a_claimant_that_never_heard_the_stopped_holder_still_outranks_it_when_it_resumes() {
        // the holder claims, then is stopped before the restarted standby comes up: the
        // standby hears nothing at all and claims on its own
        let mut holder = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        assert_eq!(holder.decide(LISTEN), LeaseChange::TookOver);
        let start = LISTEN + 3 * PERIOD;
        let mut standby = LeaseArbiter::new(11, false, start, PERIOD, 2 * LISTEN);
        assert_eq!(standby.decide(start + 2 * LISTEN), LeaseChange::TookOver);
        assert!(standby.epoch() > holder.epoch());
        // SIGCONT: each hears the other; the stale holder steps down, the new one stays
        let now = start + 2 * LISTEN + 5 * MS;
        holder.observe(&lease_of(&standby, now), now);
        standby.observe(&lease_of(&holder, now - MS), now);
        assert_eq!(holder.decide(now), LeaseChange::SteppedDown);
        assert_eq!(standby.decide(now), LeaseChange::Kept);
    }

    #[test]
    fn at_the_start_the_primary_wins_a_tie_and_the_standby_steps_down() {
        let mut primary = LeaseArbiter::new(20, true, 0, PERIOD, LISTEN);
        let mut standby = LeaseArbiter::new(30, false, 0, PERIOD, LISTEN);
        assert_eq!(primary.decide(LISTEN), LeaseChange::TookOver);
        assert_eq!(standby.decide(LISTEN), LeaseChange::TookOver);
        assert_eq!((primary.epoch(), standby.epoch()), (200, 200));
        let t = LISTEN + 5 * MS;
        let (p, s) = (lease_of(&primary, t), lease_of(&standby, t));
        primary.observe(&s, t);
        standby.observe(&p, t);
        // the standby's higher pid does not beat the primary's rank
        assert_eq!(primary.decide(t), LeaseChange::Kept);
        assert_eq!(standby.decide(t), LeaseChange::SteppedDown);
        assert!(primary.is_active() && !standby.is_active());
    }

    #[test]
    fn a_higher_claim_heard_long_ago_does_not_unseat_the_holder() {
        let mut a = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        let ghost = ControllerLease {
            epoch: 7000,
            stamp_ns: 5 * MS,
            holder_pid: 99,
            ..Default::default()
        };
        a.observe(&ghost, 5 * MS);
        assert_eq!(a.decide(LISTEN), LeaseChange::TookOver);
        assert_eq!(a.epoch(), 7001, "above every epoch heard");
        // a stamp from the future counts as now, not as forever
        let future = ControllerLease {
            epoch: 1,
            stamp_ns: u64::MAX,
            holder_pid: 98,
            ..Default::default()
        };
        let mut b = LeaseArbiter::new(11, false, 0, PERIOD, LISTEN);
        b.observe(&future, MS);
        assert_eq!(b.decide(LISTEN), LeaseChange::TookOver);
    }
}
