//! The `aeris` command line.
fn main() {}
