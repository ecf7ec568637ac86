//! The memory the flight's roles hold (issue 21's memory budget): each role's resident and
//! proportional set sizes, sampled once a second from `/proc`, kept at their peaks, and the
//! flight's total (the sum over the roles at one sample, its peak over the flight). Roles on
//! another host are not counted: their memory is that host's.

use aeris_orchestrator::executors::process_memory;
use aeris_orchestrator::supervisor::Supervisor;
use serde::Serialize;
use std::time::{Duration, Instant};

/// How often the roles' memory is sampled.
pub const MEMORY_SAMPLE_PERIOD: Duration = Duration::from_secs(1);

const MIB: f64 = 1024.0 * 1024.0;

/// One role's peak memory over the flight.
#[derive(Debug, Clone, Serialize)]
pub struct RoleMemory {
    /// The role.
    pub role: String,
    /// Its peak resident set size (MiB), shared pages counted whole.
    pub rss_peak_mib: f64,
    /// Its peak proportional set size (MiB), shared pages divided among the processes
    /// mapping them (`None` where the kernel has no `smaps_rollup`).
    pub pss_peak_mib: Option<f64>,
}

/// The flight's memory at the end of a flight.
#[derive(Debug, Clone, Default, Serialize)]
pub struct MemorySummary {
    /// Each role on the flight's host, in start order.
    pub roles: Vec<RoleMemory>,
    /// The peak over the flight of the roles' summed PSS (MiB): what the roles held
    /// together, each shared page once (`None` where the kernel has no `smaps_rollup`).
    pub total_pss_peak_mib: Option<f64>,
    /// The peak of the roles' summed RSS (MiB): pages two roles share counted twice.
    pub total_rss_peak_mib: f64,
    /// Samples taken.
    pub samples: u64,
}

/// Samples the roles' memory during a flight.
#[derive(Debug)]
pub struct MemoryWatch {
    next: Instant,
    summary: MemorySummary,
}

impl Default for MemoryWatch {
    fn default() -> Self {
        MemoryWatch {
            next: Instant::now(),
            summary: MemorySummary::default(),
        }
    }
}

impl MemoryWatch {
    /// Sample every running role on the flight's host, if a sample is due.
    pub fn sample(&mut self, sup: &Supervisor) {
        let now = Instant::now();
        if now < self.next {
            return;
        }
        self.next = now + MEMORY_SAMPLE_PERIOD;
        let (mut rss, mut pss, mut pss_known) = (0.0, 0.0, true);
        for role in sup.roles().iter().filter(|r| r.host().is_none()) {
            let Some(m) = role.pid().and_then(process_memory) else {
                continue;
            };
            let (r, p) = (
                m.rss_bytes as f64 / MIB,
                m.pss_bytes.map(|b| b as f64 / MIB),
            );
            rss += r;
            match p {
                Some(p) => pss += p,
                None => pss_known = false,
            }
            let i = match self
                .summary
                .roles
                .iter()
                .position(|e| e.role == role.name())
            {
                Some(i) => i,
                None => {
                    self.summary.roles.push(RoleMemory {
                        role: role.name().to_string(),
                        rss_peak_mib: 0.0,
                        pss_peak_mib: None,
                    });
                    self.summary.roles.len() - 1
                }
            };
            let entry = &mut self.summary.roles[i];
            entry.rss_peak_mib = entry.rss_peak_mib.max(r);
            // a sample without PSS (a process exiting between two reads) keeps the peak
            if let Some(p) = p {
                entry.pss_peak_mib = Some(entry.pss_peak_mib.map_or(p, |a| a.max(p)));
            }
        }
        self.summary.samples += 1;
        self.summary.total_rss_peak_mib = self.summary.total_rss_peak_mib.max(rss);
        // the flight's PSS only from samples where every role's was read
        if pss_known {
            self.summary.total_pss_peak_mib =
                Some(self.summary.total_pss_peak_mib.map_or(pss, |a| a.max(pss)));
        }
    }

    /// What was measured.
    pub fn summary(&self) -> MemorySummary {
        self.summary.clone()
    }
}
