//! Simulated time for the processes of one flight, in lockstep.
//!
//! A flight on simulated time has one small shared-memory segment (a file in its run
//! directory, mapped by every process of the flight) that holds the flight's time and one
//! slot per process on that time (a *participant*: each role process). Time moves only
//! when the flight's [`SimClockMaster`] moves it, and the master moves it to the next
//! instant only when every participant has finished what the present instant asked of it
//! and said when it next wants to run. At each instant the participants due run **one at
//! a time, in the order of their ranks** (the supervisor gives the pipeline's order:
//! vehicle, camera, perception, ..., reasoner, hub, controller), so each sees exactly what
//! the ones before it published at this instant and what everyone published before it:
//! a flight's result does not depend on the machine's speed or load, only on its inputs.
//! While a participant works, time stands still (a reasoner thinking does not move the
//! vehicle); how long the work took on the wall clock is measured apart.
//!
//! This is the lockstep PX4's SITL runs with its simulator, over futexes on the shared
//! segment instead of sockets. The protocol (all fields atomics in the segment):
//! - a participant claims a free slot with its pid and rank and says `STARTING` until its
//!   role is built; then, before each cycle, it writes the instant it wants (`wake_ns`),
//!   says `WAITING` and waits until the master says `GRANTED`;
//! - the master grants the due participant of the lowest rank, waits for it to be
//!   `WAITING` again (its cycle done), and so on; when none is due, it sets the time to
//!   the earliest `wake_ns`; it stands still while any participant is `STARTING`;
//! - every change bumps `generation`, the futex word both sides wait on;
//! - a participant that died without leaving (killed) is found by its pid and its slot
//!   freed, so a crashed role does not stop the flight's time.

use core::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::fs::OpenOptions;
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Processes one flight's simulated time can hold.
pub const MAX_PARTICIPANTS: usize = 64;

/// `"AERISCLK"`, then the layout's version in the low byte.
const MAGIC: u64 = 0x4145_5249_5343_4c01;

const FREE: u32 = 0;
const STARTING: u32 = 1;
const WAITING: u32 = 2;
const GRANTED: u32 = 3;

/// One participant's slot.
#[repr(C)]
struct Slot {
    /// Its process id; 0 when the slot is free.
    pid: AtomicU32,
    /// `FREE`, `STARTING`, `WAITING` or `GRANTED`.
    state: AtomicU32,
    /// Its order among the participants due at one instant (lowest first).
    rank: AtomicU32,
    _reserved: AtomicU32,
    /// The instant it next wants to run (flight-clock ns), valid while `WAITING`.
    wake_ns: AtomicU64,
    /// Turns it has been granted.
    turns: AtomicU64,
}

/// The shared segment.
#[repr(C)]
struct Segment {
    magic: AtomicU64,
    /// The flight's time (ns).
    now_ns: AtomicU64,
    /// Bumped on every change; the futex word.
    generation: AtomicU32,
    _reserved: AtomicU32,
    slots: [Slot; MAX_PARTICIPANTS],
}

/// The segment's size in the file: one page.
const SEGMENT_FILE_LEN: usize = 4096;
const _: () = assert!(core::mem::size_of::<Segment>() <= SEGMENT_FILE_LEN);

/// Why simulated time could not be set up or joined.
#[derive(Debug, thiserror::Error)]
pub enum SimClockError {
    /// The segment file could not be created, opened or mapped.
    #[error("cannot map the flight's simulated clock {path}")]
    Map {
        /// The segment file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not a simulated clock of this version.
    #[error("{path} is not a simulated flight clock of this version")]
    NotAClock {
        /// The segment file.
        path: PathBuf,
    },
    /// Every slot is taken.
    #[error("the flight's simulated clock has no free slot (at most {MAX_PARTICIPANTS} processes)")]
    Full,
}

/// The mapped segment; unmapped when the last handle goes.
struct Mapping {
    segment: *const Segment,
}

// SAFETY: the segment holds only atomics, and the mapping lives as long as the `Mapping`.
unsafe impl Send for Mapping {}
// SAFETY: as above: every access is through atomics.
unsafe impl Sync for Mapping {}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: `segment` came from a successful mmap of SEGMENT_FILE_LEN bytes and no
        // reference into it outlives `self`.
        unsafe { libc::munmap(self.segment as *mut libc::c_void, SEGMENT_FILE_LEN) };
    }
}

impl Mapping {
    fn open(path: &Path, create: bool) -> Result<Self, SimClockError> {
        let map_err = |source| SimClockError::Map {
            path: path.to_path_buf(),
            source,
        };
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(create)
            .mode(0o600)
            .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
            .open(path)
            .map_err(map_err)?;
        if create {
            file.set_len(SEGMENT_FILE_LEN as u64).map_err(map_err)?;
        } else if file.metadata().map_err(map_err)?.len() < SEGMENT_FILE_LEN as u64 {
            return Err(SimClockError::NotAClock {
                path: path.to_path_buf(),
            });
        }
        // SAFETY: a shared read-write mapping of a file we opened read-write and sized;
        // the result is checked before use.
        let ptr = unsafe {
            libc::mmap(
                core::ptr::null_mut(),
                SEGMENT_FILE_LEN,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(map_err(std::io::Error::last_os_error()));
        }
        Ok(Self {
            segment: ptr as *const Segment,
        })
    }

    fn segment(&self) -> &Segment {
        // SAFETY: mapped, page-aligned, at least size_of::<Segment>() bytes, atomics only
        // (any bit pattern is valid), alive as long as `self`.
        unsafe { &*self.segment }
    }
}

impl Segment {
    fn bump(&self) {
        self.generation.fetch_add(1, Ordering::AcqRel);
        futex_wake_all(&self.generation);
    }
}

/// Wait while `word` holds `expected`, at most `timeout`; returns on a change, a wake, a
/// signal or the timeout alike (the caller re-reads).
fn futex_wait(word: &AtomicU32, expected: u32, timeout: Duration) {
    let ts = libc::timespec {
        tv_sec: timeout.as_secs() as libc::time_t,
        tv_nsec: timeout.subsec_nanos() as libc::c_long,
    };
    // SAFETY: `word` is a valid, aligned u32 in a shared mapping (a shared futex: not
    // FUTEX_PRIVATE); `ts` lives for the call.
    unsafe {
        libc::syscall(
            libc::SYS_futex,
            word.as_ptr(),
            libc::FUTEX_WAIT,
            expected,
            &ts as *const libc::timespec,
        );
    }
}

fn futex_wake_all(word: &AtomicU32) {
    // SAFETY: as in `futex_wait`; waking has no memory effects of its own.
    unsafe {
        libc::syscall(libc::SYS_futex, word.as_ptr(), libc::FUTEX_WAKE, i32::MAX);
    }
}

/// `false` when no process `pid` exists any more (a zombie still exists until reaped).
fn process_exists(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks for existence.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

/// A reader of a flight's simulated time that takes no part in it (a process that
/// stamps, or measures ages, on the flight's clock without being stepped by it).
#[derive(Clone)]
pub struct SimClockReader {
    map: Arc<Mapping>,
}

impl core::fmt::Debug for SimClockReader {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SimClockReader")
            .field("now_ns", &self.now_ns())
            .finish()
    }
}

impl SimClockReader {
    /// Map the clock at `path` (made by the flight's [`SimClockMaster`]).
    pub fn open(path: &Path) -> Result<Self, SimClockError> {
        let map = Mapping::open(path, false)?;
        if map.segment().magic.load(Ordering::Acquire) != MAGIC {
            return Err(SimClockError::NotAClock {
                path: path.to_path_buf(),
            });
        }
        Ok(Self { map: Arc::new(map) })
    }

    /// The flight's time (ns).
    #[inline]
    pub fn now_ns(&self) -> u64 {
        self.map.segment().now_ns.load(Ordering::Acquire)
    }

    /// Take part in the flight's time as process `pid` of rank `rank`: the slot says
    /// `STARTING` (time stands still) until [`SimParticipant::wait_for`] first asks for an
    /// instant.
    pub fn join(&self, pid: u32, rank: u32) -> Result<SimParticipant, SimClockError> {
        let segment = self.map.segment();
        for (index, slot) in segment.slots.iter().enumerate() {
            if slot
                .pid
                .compare_exchange(0, pid, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
            {
                slot.rank.store(rank, Ordering::Relaxed);
                slot.turns.store(0, Ordering::Relaxed);
                slot.state.store(STARTING, Ordering::Release);
                segment.bump();
                return Ok(SimParticipant {
                    reader: self.clone(),
                    slot: index,
                });
            }
        }
        Err(SimClockError::Full)
    }
}

/// One process's part in a flight's simulated time; leaving frees its slot.
#[derive(Debug)]
pub struct SimParticipant {
    reader: SimClockReader,
    slot: usize,
}

/// What [`SimParticipant::wait_for`] ended with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Turn {
    /// The flight's time is at the instant asked for and it is this participant's turn:
    /// work, then ask for the next instant.
    Granted,
    /// Not yet, after the wall-clock time given (say it is alive, check for a stop, and
    /// wait again with [`SimParticipant::wait_again`]).
    NotYet,
}

impl SimParticipant {
    fn slot(&self) -> &Slot {
        &self.reader.map.segment().slots[self.slot]
    }

    /// The flight's time (ns).
    pub fn now_ns(&self) -> u64 {
        self.reader.now_ns()
    }

    /// This participant's work for the present instant is done; run it next at
    /// `wake_ns` (at once if that is not ahead of the flight's time, after the others due
    /// now). Waits at most `wall` for the turn.
    pub fn wait_for(&self, wake_ns: u64, wall: Duration) -> Turn {
        let slot = self.slot();
        slot.wake_ns.store(wake_ns, Ordering::Relaxed);
        slot.state.store(WAITING, Ordering::Release);
        self.reader.map.segment().bump();
        self.wait_again(wall)
    }

    /// Wait on for the turn asked for with [`SimParticipant::wait_for`], at most `wall`.
    pub fn wait_again(&self, wall: Duration) -> Turn {
        let segment = self.reader.map.segment();
        let slot = self.slot();
        let until = Instant::now() + wall;
        loop {
            let generation = segment.generation.load(Ordering::Acquire);
            if slot.state.load(Ordering::Acquire) == GRANTED {
                return Turn::Granted;
            }
            let now = Instant::now();
            if now >= until {
                return Turn::NotYet;
            }
            futex_wait(&segment.generation, generation, until - now);
        }
    }

    /// Turns granted so far.
    pub fn turns(&self) -> u64 {
        self.slot().turns.load(Ordering::Relaxed)
    }
}

impl Drop for SimParticipant {
    fn drop(&mut self) {
        let slot = self.slot();
        slot.state.store(FREE, Ordering::Release);
        slot.pid.store(0, Ordering::Release);
        self.reader.map.segment().bump();
    }
}

/// What [`SimClockMaster::advance`] ended with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Advance {
    /// The flight's time reached the instant asked for, every participant done with it.
    Reached,
    /// The wall-clock budget ran out first: a participant is working, or starting.
    Working {
        /// The participant's process, when one holds the turn.
        pid: Option<u32>,
    },
}

/// The flight's simulated time: it makes the segment, and moves time (see the module).
pub struct SimClockMaster {
    reader: SimClockReader,
    path: PathBuf,
    /// Participants that must have joined before time first moves.
    expected: usize,
    /// Time has moved (every expected participant had joined and was built).
    started: bool,
}

impl core::fmt::Debug for SimClockMaster {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SimClockMaster")
            .field("path", &self.path)
            .field("now_ns", &self.now_ns())
            .field("started", &self.started)
            .finish()
    }
}

impl SimClockMaster {
    /// Make the clock at `path` (a new file, owner-only) starting at `start_ns`; time moves
    /// only once `expected` participants have joined and none is starting.
    pub fn create(path: &Path, start_ns: u64, expected: usize) -> Result<Self, SimClockError> {
        let map = Mapping::open(path, true)?;
        let segment = map.segment();
        segment.now_ns.store(start_ns, Ordering::Relaxed);
        segment.magic.store(MAGIC, Ordering::Release);
        Ok(Self {
            reader: SimClockReader { map: Arc::new(map) },
            path: path.to_path_buf(),
            expected,
            started: false,
        })
    }

    /// Time first moves once `participants` have joined (and none is starting).
    pub fn expect(&mut self, participants: usize) {
        self.expected = participants;
    }

    /// The segment's file, which participants open.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A reader of this clock.
    pub fn reader(&self) -> SimClockReader {
        self.reader.clone()
    }

    /// The flight's time (ns).
    pub fn now_ns(&self) -> u64 {
        self.reader.now_ns()
    }

    /// Move time up to `until_ns`, granting every participant due on the way its turns,
    /// for at most `wall` of wall-clock time. Returns [`Advance::Reached`] when the time is
    /// `until_ns` and every participant due at or before it has had its turn.
    pub fn advance(&mut self, until_ns: u64, wall: Duration) -> Advance {
        let segment = self.reader.map.segment();
        let deadline = Instant::now() + wall;
        loop {
            let generation = segment.generation.load(Ordering::Acquire);
            let now = segment.now_ns.load(Ordering::Acquire);
            let mut joined = 0usize;
            let mut busy: Option<usize> = None;
            let mut due: Option<(u32, usize)> = None;
            let mut next_wake = u64::MAX;
            for (index, slot) in segment.slots.iter().enumerate() {
                match slot.state.load(Ordering::Acquire) {
                    FREE => continue,
                    STARTING | GRANTED => busy = Some(index),
                    _ => {
                        let wake = slot.wake_ns.load(Ordering::Relaxed);
                        if wake <= now {
                            let rank = slot.rank.load(Ordering::Relaxed);
                            if due.is_none_or(|(r, i)| (rank, index) < (r, i)) {
                                due = Some((rank, index));
                            }
                        } else {
                            next_wake = next_wake.min(wake);
                        }
                    }
                }
                joined += 1;
            }
            let waiting_for_joins = !self.started && joined < self.expected;
            if busy.is_some() || waiting_for_joins {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    return Advance::Working {
                        pid: busy.map(|i| segment.slots[i].pid.load(Ordering::Relaxed)),
                    };
                }
                futex_wait(
                    &segment.generation,
                    generation,
                    left.min(Duration::from_millis(50)),
                );
                if busy.is_some() {
                    self.free_gone();
                }
                continue;
            }
            self.started = true;
            if let Some((_, index)) = due {
                let slot = &segment.slots[index];
                // only a slot still waiting is granted: one that left (or was taken by a
                // new process) since the scan is looked at again
                if slot
                    .state
                    .compare_exchange(WAITING, GRANTED, Ordering::AcqRel, Ordering::Acquire)
                    .is_ok()
                {
                    slot.turns.fetch_add(1, Ordering::Relaxed);
                    segment.bump();
                }
                continue;
            }
            if now >= until_ns {
                return Advance::Reached;
            }
            segment
                .now_ns
                .store(next_wake.min(until_ns), Ordering::Release);
        }
    }

    /// Free the slots of processes that are gone (killed without leaving).
    fn free_gone(&self) {
        let segment = self.reader.map.segment();
        for slot in &segment.slots {
            let pid = slot.pid.load(Ordering::Acquire);
            if pid != 0 && !process_exists(pid) {
                slot.state.store(FREE, Ordering::Release);
                let _ = slot
                    .pid
                    .compare_exchange(pid, 0, Ordering::AcqRel, Ordering::Relaxed);
                segment.bump();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    fn clock(name: &str, expected: usize) -> (tempdir::Dir, SimClockMaster) {
        let dir = tempdir::Dir::new(name);
        let master = SimClockMaster::create(&dir.path.join("clock"), 1_000, expected)
            .expect("creating the clock");
        (dir, master)
    }

    /// A directory of the test's own, removed after.
    mod tempdir {
        pub struct Dir {
            pub path: std::path::PathBuf,
        }
        impl Dir {
            pub fn new(name: &str) -> Self {
                let path = std::env::temp_dir()
                    .join(format!("aeris-sim-clock-{name}-{}", std::process::id()));
                let _ = std::fs::remove_dir_all(&path);
                std::fs::create_dir_all(&path).expect("test dir");
                Self { path }
            }
        }
        impl Drop for Dir {
            fn drop(&mut self) {
                let _ = std::fs::remove_dir_all(&self.path);
            }
        }
    }

    /// A participant on a thread of its own: every `period_ns` it notes `(time, name)`.
    fn periodic(
        reader: SimClockReader,
        rank: u32,
        name: &'static str,
        period_ns: u64,
        until_ns: u64,
        log: Arc<Mutex<Vec<(u64, &'static str)>>>,
    ) -> std::thread::JoinHandle<u64> {
        std::thread::spawn(move || {
            let me = reader.join(1, rank).expect("joining");
            let mut next = me.now_ns();
            loop {
                let mut turn = me.wait_for(next, Duration::from_secs(5));
                while turn == Turn::NotYet {
                    turn = me.wait_again(Duration::from_secs(5));
                }
                let now = me.now_ns();
                if now > until_ns {
                    return me.turns();
                }
                log.lock().expect("log").push((now, name));
                next += period_ns;
            }
        })
    }

    #[test]
    fn participants_run_at_their_instants_one_at_a_time_in_rank_order() {
        let (_dir, mut master) = clock("order", 2);
        let log = Arc::new(Mutex::new(Vec::new()));
        // joined in the opposite order of their ranks
        let slow = periodic(master.reader(), 1, "b", 20, 1_050, log.clone());
        let fast = periodic(master.reader(), 0, "a", 10, 1_050, log.clone());
        assert_eq!(
            master.advance(1_060, Duration::from_secs(30)),
            Advance::Reached
        );
        assert_eq!(master.now_ns(), 1_060);
        let seen = log.lock().expect("log").clone();
        let expected: Vec<(u64, &str)> = vec![
            (1_000, "a"),
            (1_000, "b"),
            (1_010, "a"),
            (1_020, "a"),
            (1_020, "b"),
            (1_030, "a"),
            (1_040, "a"),
            (1_040, "b"),
            (1_050, "a"),
        ];
        assert_eq!(seen, expected);
        // past their end both leave; time still moves without them
        assert_eq!(
            master.advance(2_000, Duration::from_secs(30)),
            Advance::Reached
        );
        assert_eq!(fast.join().expect("a"), 7);
        assert_eq!(slow.join().expect("b"), 4);
        assert_eq!(
            master.advance(3_000, Duration::from_secs(30)),
            Advance::Reached
        );
        assert_eq!(master.now_ns(), 3_000);
    }

    #[test]
    fn time_stands_still_while_a_participant_starts_or_works() {
        let (_dir, mut master) = clock("still", 1);
        // nobody has joined: the flight's time waits for its participant
        assert_eq!(
            master.advance(5_000, Duration::from_millis(20)),
            Advance::Working { pid: None }
        );
        assert_eq!(master.now_ns(), 1_000);
        let pid = std::process::id();
        let me = master.reader().join(pid, 0).expect("joining");
        assert_eq!(
            master.advance(5_000, Duration::from_millis(20)),
            Advance::Working { pid: Some(pid) }
        );
        assert_eq!(master.now_ns(), 1_000);
        // built: its first turn is now; it works (holds the turn) and time does not move
        assert_eq!(me.wait_for(1_000, Duration::ZERO), Turn::NotYet);
        assert_eq!(
            master.advance(5_000, Duration::from_millis(20)),
            Advance::Working { pid: Some(pid) }
        );
        assert_eq!(me.wait_again(Duration::ZERO), Turn::Granted);
        assert_eq!(master.now_ns(), 1_000);
        // done, next at 3000: time moves there and the turn is granted again
        assert_eq!(me.wait_for(3_000, Duration::ZERO), Turn::NotYet);
        assert_eq!(
            master.advance(5_000, Duration::from_millis(20)),
            Advance::Working { pid: Some(pid) }
        );
        assert_eq!(master.now_ns(), 3_000);
        assert_eq!(me.wait_again(Duration::ZERO), Turn::Granted);
        assert_eq!(me.turns(), 2);
    }

    #[test]
    fn a_participant_killed_without_leaving_does_not_stop_time() {
        // time moves without waiting for anyone to join; the ghost below blocks it until
        // it is found gone
        let (_dir, mut master) = clock("gone", 0);
        let reader = master.reader();
        // a process that has exited and been reaped: its pid exists no more
        let mut child = std::process::Command::new("true")
            .spawn()
            .expect("spawning true");
        let pid = child.id();
        child.wait().expect("reaping");
        let ghost = reader.join(pid, 0).expect("joining");
        // it "dies" while starting: nothing runs its Drop
        core::mem::forget(ghost);
        assert_eq!(
            master.advance(9_000, Duration::from_secs(5)),
            Advance::Reached
        );
        assert_eq!(master.now_ns(), 9_000);
    }

    #[test]
    fn a_file_that_is_not_a_clock_is_refused_by_name() {
        let dir = tempdir::Dir::new("refused");
        let path = dir.path.join("clock");
        std::fs::write(&path, vec![0u8; SEGMENT_FILE_LEN]).expect("writing");
        let e = SimClockReader::open(&path).expect_err("zeros are no clock");
        assert!(e.to_string().contains(&path.display().to_string()), "{e}");
        assert!(
            SimClockMaster::create(&path, 0, 1).is_err(),
            "never overwrites"
        );
    }
}
