//! A finished flight as text: what `aeris run` prints of a [`FlightOutcome`] (its `--json`
//! prints the [`FlightSummary`](crate::FlightSummary) itself).

use crate::monitor::FlightOutcome;
use crate::recording::RecordingSummary;
use std::fmt;

impl fmt::Display for FlightOutcome {
    /// The verdict, why it ended early, then one line per concern (distance, cycle time,
    /// decisions, controller, autopilot, memory, links, video, recording).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.summary;
        let verdict = if s.reached_goal {
            "goal reached"
        } else {
            "goal NOT reached"
        };
        writeln!(f, "flight {}: {verdict}", s.flight)?;
        if let Some(why) = &self.failure {
            writeln!(f, "  reason: {why}")?;
        }
        let time = match s.clock {
            crate::FlightClock::Wall => format!("{:.1} s", s.duration_s),
            crate::FlightClock::Sim => format!(
                "{:.1} s of simulated time ({:.1} s of wall time)",
                s.duration_s, s.wall_s
            ),
        };
        writeln!(
            f,
            "  final distance to goal {:.2} m after {time}; subgoals reached by ATT {}/{}",
            s.final_distance_m, s.max_active_step, s.subgoals_total
        )?;
        let st = &s.stages_mean_s;
        writeln!(
            f,
            "  cycles {} (committed {}), CT mean {:.3} s (std {:.3}, p95 {:.3}); stages: perception {:.3} reasoning {:.3} routing {:.4} binding {:.4} s",
            s.cycles,
            s.cycles_committed,
            s.ct_mean_s,
            s.ct_std_s,
            s.ct_p95_s,
            st.perception,
            st.reasoning,
            st.routing,
            st.binding
        )?;
        let h = &s.hub;
        writeln!(
            f,
            "  EER {:.2}%; decisions received {} rejected {} late {} reused {}; sequence gaps {} reorders {}",
            s.eer * 100.0,
            h.decisions_received,
            h.decisions_rejected,
            h.decisions_late,
            h.decisions_reused,
            h.sequence_gaps,
            h.sequence_reorders
        )?;
        writeln!(
            f,
            "  compute on this machine: CT mean {:.3} s (p95 {:.3}), EER {:.2}% (cycles over the deadline on compute alone){}",
            s.ct_compute_mean_s,
            s.ct_compute_p95_s,
            s.eer_compute * 100.0,
            if s.clock == crate::FlightClock::Sim {
                "; on simulated time CT and EER above are on the flight's clock, where work takes no time"
            } else {
                ""
            }
        )?;
        writeln!(
            f,
            "  controller ticks {} missed {} refused setpoints {}; role restarts {}, stalls {}, live migrations {}",
            s.controller_ticks,
            s.controller_missed_ticks,
            s.controller_refused_setpoints,
            s.role_restarts,
            s.stalls,
            s.migrations
        )?;
        write!(
            f,
            "  autopilot {}; link losses {}, commands refused {}",
            s.autopilot.as_deref().unwrap_or("never heard"),
            s.autopilot_link_losses,
            s.autopilot_commands_refused
        )?;
        let m = &s.memory;
        if m.samples > 0 {
            let roles: Vec<String> = m
                .roles
                .iter()
                .map(|r| format!("{} {:.0}", r.role, r.pss_peak_mib.unwrap_or(r.rss_peak_mib)))
                .collect();
            let (kind, total) = match m.total_pss_peak_mib {
                Some(pss) => (
                    "PSS: shared pages divided among the roles",
                    format!("{pss:.0} (RSS summed {:.0})", m.total_rss_peak_mib),
                ),
                None => (
                    "RSS: shared pages counted per role",
                    format!("{:.0}", m.total_rss_peak_mib),
                ),
            };
            write!(
                f,
                "\n  memory of the roles (peak MiB, {kind}): flight {total}; {}",
                roles.join(", ")
            )?;
        }
        for l in &s.links {
            let rtt = l
                .rtt_ms
                .map_or_else(|| "never measured".into(), |r| format!("{r:.3} ms"));
            let coding = l
                .frame_coding_ms
                .map(|c| format!(", a frame encoded in {c:.2} ms"))
                .unwrap_or_default();
            write!(
                f,
                "\n  link to host `{}`: round trip {rtt}, loss {:.0} % of the last probes ({} of {} answered){coding}",
                l.host,
                l.loss * 100.0,
                l.answered,
                l.probes
            )?;
        }
        if let Some(v) = s.first_decision_on_video_s {
            write!(
                f,
                "\n  first decision on the video {v:.2} s after its first frame"
            )?;
        }
        if let Some(r) = &s.recording {
            write!(f, "\n{r}")?;
        }
        Ok(())
    }
}

impl fmt::Display for RecordingSummary {
    /// One line: the recording's files, messages, drops and size, indented as a line of a
    /// flight's summary.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let files: Vec<String> = self.files.iter().map(|p| p.display().to_string()).collect();
        write!(
            f,
            "  recording {}: {} messages, {} dropped, {} bytes{}",
            files.join(", "),
            self.messages,
            self.dropped,
            self.bytes,
            if self.failed { "; writing FAILED" } else { "" }
        )
    }
}
