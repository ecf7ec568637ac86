//! # aeris-formation
//!
//! Multi-UAV formations (the paper's formation experiment), as pure functions:
//!
//! - [`slots`]: where each vehicle of a formation program's `assume` phase goes (`[N, E, U]`);
//! - [`assign`]: which vehicle takes which slot, so that their straight-line, synchronised
//!   transitions keep them apart.

#![deny(missing_docs)]

pub mod assign;
pub mod slots;

pub use assign::{AssignError, Assignment, assign, min_separation_along};
pub use slots::{formation_offsets, slots};
