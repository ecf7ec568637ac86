//! What every command of `aeris` is: its arguments (a clap struct in the command's own
//! file) and one [`Execute::execute`] that calls the libraries and prints what they return.
//! `main.rs` parses the command line and dispatches; it does no command's work.

use std::process::ExitCode;

/// One command of `aeris`.
pub trait Execute {
    /// Do what the command asks; its exit status.
    fn execute(self) -> anyhow::Result<ExitCode>;
}
