//! The end-to-end tests that each fly one flight of the default mission, in one test binary:
//! the harness flies two of them at a time (a planner flight uses about half a core, so two
//! fit the 2-core CI machine), which keeps the suite inside its time budget. The video
//! flights (decoded H.264, a video file without depth) are here too: they flew two at a
//! time in their own binaries already, and here a planner flight is their usual partner.
//! The recording flights are here for the same reason: in a binary of their own, their
//! longest test flew alone at the end while the other thread idled. Flights on simulated
//! time are not here (`sim_flights`): one computes as fast as it can, so beside a
//! wall-clock flight it would take the CPU that flight's timing needs. Flights whose
//! assertions depend on the machine's load or timing (dynamic scheduling, the fault table's
//! lost decisions, hot swaps of language models) keep binaries of their own and fly alone.

mod accelerator;
mod ardupilot;
mod default;
mod external_autopilot;
mod faults;
mod formation;
mod hosts;
mod ladder;
mod liveness;
mod mavproxy;
mod no_depth;
mod record;
mod standby;
mod video;
