//! Printing an error with its causes.
//!
//! Our error messages say what failed and name the offender once; the cause is the error's
//! [`source`](std::error::Error::source), never repeated in its own message. Whoever turns an
//! error into text (a log line, a reply to `aeris swap`) prints the whole chain with
//! [`chain`], the way the binary's `{:#}` of an `anyhow::Error` does.

use std::error::Error;
use std::fmt;

/// Displays an error and every source below it, joined by `": "`.
#[derive(Debug, Clone, Copy)]
pub struct ErrorChain<'a>(&'a (dyn Error + 'static));

/// `error: its source: the source's source ...`, for log lines and replies.
pub fn chain<'a>(error: &'a (dyn Error + 'static)) -> ErrorChain<'a> {
    ErrorChain(error)
}

impl fmt::Display for ErrorChain<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)?;
        let mut next = self.0.source();
        while let Some(cause) = next {
            write!(f, ": {cause}")?;
            next = cause.source();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("cannot read role spec {path}")]
    struct Outer {
        path: &'static str,
        source: std::io::Error,
    }

    #[test]
    fn every_cause_is_printed_once_in_order() {
        let e = Outer {
            path: "/x/spec.json",
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        };
        assert_eq!(
            chain(&e).to_string(),
            "cannot read role spec /x/spec.json: no such file"
        );
        let io = std::io::Error::other("disk full");
        assert_eq!(chain(&io).to_string(), "disk full");
    }
}
