//! Ordered delivery: publisher sequence numbers, gaps, reorders and duplicates.

/// What one observed sequence number means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeqVerdict {
    /// The first sequence number seen (whatever its value: the hub may start late).
    First,
    /// Exactly one more than the last one.
    InOrder,
    /// Newer than expected: `missing` sequence numbers were skipped.
    Gap {
        /// How many numbers are missing.
        missing: u64,
    },
    /// `1` after a higher number, stamped later than anything seen: the publisher restarted
    /// (sequences start at 1); the tracker resynchronises.
    Restart,
    /// Equal to the last one.
    Duplicate,
    /// Older than the last one.
    Reordered,
    /// 0, which publishers never send.
    Zero,
}

impl SeqVerdict {
    /// `true` when the message may be used (first, in order, after a gap, restart).
    pub fn accepted(self) -> bool {
        matches!(
            self,
            SeqVerdict::First | SeqVerdict::InOrder | SeqVerdict::Gap { .. } | SeqVerdict::Restart
        )
    }
}

/// Observes the sequence numbers of one topic and counts gaps, reorders and duplicates.
///
/// Publishers number messages from 1. A `1` after a higher number whose stamp is newer than
/// every stamp accepted so far is taken as a publisher restart (a restarted role starts over
/// at 1 with fresh timestamps) rather than as a reorder, so a restarted reasoner is not
/// locked out until it catches up with its predecessor's numbers; a replayed old message
/// (old stamp) is still a reorder.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SequenceTracker {
    last: u64,
    newest_stamp: u64,
    seen: bool,
    gaps: u64,
    missing: u64,
    reorders: u64,
    duplicates: u64,
    restarts: u64,
}

impl SequenceTracker {
    /// A tracker that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Observe `seq` of a message stamped `stamp_ns` (e.g. its cycle start) and classify
    /// it. Older-or-equal numbers do not move the tracker.
    pub fn observe(&mut self, seq: u64, stamp_ns: u64) -> SeqVerdict {
        if seq == 0 {
            self.reorders += 1;
            return SeqVerdict::Zero;
        }
        if !self.seen {
            self.seen = true;
            self.last = seq;
            self.newest_stamp = stamp_ns;
            return SeqVerdict::First;
        }
        let last = self.last;
        if seq == 1 && last > 1 && stamp_ns > self.newest_stamp {
            self.restarts += 1;
            self.last = 1;
            self.newest_stamp = stamp_ns;
            return SeqVerdict::Restart;
        }
        if seq == last {
            self.duplicates += 1;
            self.reorders += 1;
            return SeqVerdict::Duplicate;
        }
        if seq < last {
            self.reorders += 1;
            return SeqVerdict::Reordered;
        }
        self.last = seq;
        self.newest_stamp = self.newest_stamp.max(stamp_ns);
        let missing = seq - last - 1;
        if missing == 0 {
            SeqVerdict::InOrder
        } else {
            self.gaps += 1;
            self.missing = self.missing.saturating_add(missing);
            SeqVerdict::Gap { missing }
        }
    }

    /// The highest accepted sequence number (0 before the first).
    pub fn last(&self) -> u64 {
        self.last
    }

    /// Gaps detected (events, each may miss several numbers).
    pub fn gaps(&self) -> u64 {
        self.gaps
    }

    /// Sequence numbers missing over all gaps.
    pub fn missing(&self) -> u64 {
        self.missing
    }

    /// Out-of-order messages: reordered, duplicate and zero sequence numbers.
    pub fn reorders(&self) -> u64 {
        self.reorders
    }

    /// Duplicates (a subset of [`SequenceTracker::reorders`]).
    pub fn duplicates(&self) -> u64 {
        self.duplicates
    }

    /// Publisher restarts detected.
    pub fn restarts(&self) -> u64 {
        self.restarts
    }

    /// Forget the last sequence number (keep the counters): the next message is the first
    /// of a new publisher, whatever its number.
    pub fn resync(&mut self) {
        self.seen = false;
    }
}

/// What one decision's publisher instance means to the hub.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceVerdict {
    /// The first decision the hub sees: its publisher becomes the active one.
    First,
    /// From the active publisher.
    Active,
    /// From another instance that now becomes the active one: a newer instance (hot swap,
    /// restart), or an older one after the active one fell silent for a whole slot.
    Switched {
        /// The instance that was active.
        from: u32,
    },
    /// From an older instance while a newer one is live: ignored.
    Superseded {
        /// The instance that stays active.
        active: u32,
    },
}

/// Chooses which reasoning instance the hub takes decisions from.
///
/// The supervisor numbers every process it starts, so a higher instance number is a newer
/// process (a restart, or the new side of a make-before-break swap). The hub follows the
/// newest instance and ignores older ones, unless the newest has been silent for longer
/// than `stale_after_ns` (it died, or its swap was rolled back): then the next instance that
/// speaks may take over again. Taking over is the caller's choice ([`SourceSelector::adopt`],
/// for a decision it commits), so a candidate whose first decision is late or invalid does
/// not displace a working reasoner. Pure and allocation-free.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SourceSelector {
    active: Option<u32>,
    last_ns: u64,
    stale_after_ns: u64,
    switches: u64,
    superseded: u64,
}

impl SourceSelector {
    /// A selector that drops an active instance silent for more than `stale_after_ns`.
    pub fn new(stale_after_ns: u64) -> Self {
        Self {
            active: None,
            last_ns: 0,
            stale_after_ns,
            switches: 0,
            superseded: 0,
        }
    }

    /// What a decision of instance `source` received at `now_ns` is, without taking it.
    pub fn classify(&self, source: u32, now_ns: u64) -> SourceVerdict {
        match self.active {
            None => SourceVerdict::First,
            Some(a) if a == source => SourceVerdict::Active,
            Some(a) if source > a || now_ns.saturating_sub(self.last_ns) > self.stale_after_ns => {
                SourceVerdict::Switched { from: a }
            }
            Some(a) => SourceVerdict::Superseded { active: a },
        }
    }

    /// Take instance `source` (from now on, or still) as the active one: it spoke at
    /// `now_ns`. Counts a switch when it was another.
    pub fn adopt(&mut self, source: u32, now_ns: u64) {
        if self.active.is_some_and(|a| a != source) {
            self.switches += 1;
        }
        self.active = Some(source);
        self.last_ns = self.last_ns.max(now_ns);
    }

    /// Count a decision ignored as superseded.
    pub fn supersede(&mut self) {
        self.superseded += 1;
    }

    /// The active instance (`None` before the first decision).
    pub fn active(&self) -> Option<u32> {
        self.active
    }

    /// Switches between instances so far.
    pub fn switches(&self) -> u64 {
        self.switches
    }

    /// Decisions ignored because a newer instance was live.
    pub fn superseded(&self) -> u64 {
        self.superseded
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classifies_and_counts() {
        let mut t = SequenceTracker::new();
        assert_eq!(t.observe(5, 50), SeqVerdict::First);
        assert_eq!(t.observe(6, 60), SeqVerdict::InOrder);
        assert_eq!(t.observe(9, 90), SeqVerdict::Gap { missing: 2 });
        assert_eq!(t.observe(9, 90), SeqVerdict::Duplicate);
        assert_eq!(t.observe(7, 70), SeqVerdict::Reordered);
        assert_eq!(t.observe(0, 99), SeqVerdict::Zero);
        assert_eq!(t.observe(10, 100), SeqVerdict::InOrder);
        assert_eq!(t.observe(13, 130), SeqVerdict::Gap { missing: 2 });
        assert_eq!(
            (
                t.last(),
                t.gaps(),
                t.missing(),
                t.reorders(),
                t.duplicates()
            ),
            (13, 2, 4, 3, 1)
        );
        assert!(!SeqVerdict::Reordered.accepted() && !SeqVerdict::Duplicate.accepted());
        assert!(SeqVerdict::Gap { missing: 1 }.accepted());
    }

    #[test]
    fn the_newest_live_instance_wins_and_a_silent_one_is_dropped() {
        let mut s = SourceSelector::new(100);
        let take = |s: &mut SourceSelector, source, now| {
            let v = s.classify(source, now);
            match v {
                SourceVerdict::Superseded { .. } => s.supersede(),
                _ => s.adopt(source, now),
            }
            v
        };
        assert_eq!(take(&mut s, 3, 0), SourceVerdict::First);
        assert_eq!(take(&mut s, 3, 10), SourceVerdict::Active);
        // a newer instance (swap) takes over at once
        assert_eq!(take(&mut s, 5, 20), SourceVerdict::Switched { from: 3 });
        // the old one, still running, is ignored while the new one is live
        assert_eq!(take(&mut s, 3, 30), SourceVerdict::Superseded { active: 5 });
        assert_eq!(take(&mut s, 5, 110), SourceVerdict::Active);
        assert_eq!(
            take(&mut s, 3, 200),
            SourceVerdict::Superseded { active: 5 }
        );
        // the new one fell silent for more than a slot: the old one speaks and is taken
        assert_eq!(take(&mut s, 3, 211), SourceVerdict::Switched { from: 5 });
        assert_eq!(s.active(), Some(3));
        assert_eq!((s.switches(), s.superseded()), (2, 2));
        // a late message stamped before the last one never moves time back
        assert_eq!(take(&mut s, 3, 150), SourceVerdict::Active);
        // classifying alone changes nothing: a candidate the caller does not adopt
        assert_eq!(s.classify(4, 215), SourceVerdict::Switched { from: 3 });
        assert_eq!((s.active(), s.switches()), (Some(3), 2));
    }

    #[test]
    fn resync_takes_any_number_as_the_first() {
        let mut t = SequenceTracker::new();
        t.observe(40, 400);
        t.observe(42, 420);
        t.resync();
        assert_eq!(t.observe(1, 430), SeqVerdict::First);
        assert_eq!(t.observe(2, 440), SeqVerdict::InOrder);
        assert_eq!(t.gaps(), 1, "counters survive a resync");
    }

    #[test]
    fn a_restarted_publisher_is_resynchronised_but_a_replay_is_not() {
        let mut t = SequenceTracker::new();
        for s in 1..=40 {
            assert!(t.observe(s, s * 10).accepted());
        }
        // seq 1 again with its old stamp: a replay
        assert_eq!(t.observe(1, 10), SeqVerdict::Reordered);
        // seq 1 with a newer stamp than anything seen: a restarted publisher
        assert_eq!(t.observe(1, 1_000), SeqVerdict::Restart);
        assert_eq!(t.observe(2, 1_010), SeqVerdict::InOrder);
        assert_eq!(t.observe(2, 1_010), SeqVerdict::Duplicate);
        assert_eq!((t.restarts(), t.reorders(), t.gaps()), (1, 2, 0));
        // a duplicate of 1 right after 1 is a duplicate, not a restart
        let mut t = SequenceTracker::new();
        t.observe(1, 5);
        assert_eq!(t.observe(1, 6), SeqVerdict::Duplicate);
    }
}
