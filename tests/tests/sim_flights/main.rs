//! The end-to-end flights on simulated time (`--clock sim`), in a test binary of their own:
//! a flight on simulated time computes as fast as the machine lets it, so it never flies
//! beside a wall-clock flight, whose timing it would starve (cargo runs test binaries one
//! after another). Two fly at a time here; their results do not depend on it.

mod distill;
mod garbage;
mod replay_max;
mod sim_time;
mod vln_eval;
