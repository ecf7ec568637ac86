//! Logging. Libraries log through `tracing` (levels; a span per role process and per
//! flight); a binary calls [`init_stderr`] once, which prints each message to stderr as it
//! is, one line per event, so a role's log file reads as plain lines. `RUST_LOG` filters
//! (`RUST_LOG=warn`: only what went wrong; default `info`: everything).

use core::fmt;
use tracing::{Event, Subscriber};
use tracing_subscriber::EnvFilter;
use tracing_subscriber::fmt::format::Writer;
use tracing_subscriber::fmt::{FmtContext, FormatEvent, FormatFields};
use tracing_subscriber::registry::LookupSpan;

/// Prints an event's message (and any other fields) and nothing else: no time, level,
/// target or span, which the message itself names where a reader needs it.
struct MessageOnly;

impl<S, N> FormatEvent<S, N> for MessageOnly
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(
        &self,
        ctx: &FmtContext<'_, S, N>,
        mut writer: Writer<'_>,
        event: &Event<'_>,
    ) -> fmt::Result {
        ctx.field_format().format_fields(writer.by_ref(), event)?;
        writeln!(writer)
    }
}

/// Send this process's log events to stderr, filtered by `RUST_LOG` (default `info`).
/// Calling it again does nothing.
pub fn init_stderr() {
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(false)
        .event_format(MessageOnly)
        .try_init();
}
