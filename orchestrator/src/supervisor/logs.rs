//! Role logs: opening one with the supervisor's header line, and quoting its last lines in
//! errors and swap replies.

use std::fs::OpenOptions;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

/// Lines of a role's log quoted in errors.
pub const LOG_TAIL_LINES: usize = 8;

/// Open (append) a role's log and write `header` to it.
pub(super) fn open_log(log: &Path, header: &str) -> std::io::Result<std::fs::File> {
    let mut file = OpenOptions::new().create(true).append(true).open(log)?;
    writeln!(file, "{header}")?;
    Ok(file)
}

/// The last `lines` lines of a file (reads at most its last 16 KiB); empty when unreadable.
pub fn log_tail(path: &Path, lines: usize) -> Vec<String> {
    let Ok(mut f) = std::fs::File::open(path) else {
        return Vec::new();
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let start = len.saturating_sub(16 * 1024);
    if f.seek(SeekFrom::Start(start)).is_err() {
        return Vec::new();
    }
    let mut buf = Vec::new();
    if f.read_to_end(&mut buf).is_err() {
        return Vec::new();
    }
    let text = String::from_utf8_lossy(&buf);
    let all: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    // the first line may be cut when we did not read from the start
    let skip_first = usize::from(start > 0 && all.len() > lines);
    let from = all.len().saturating_sub(lines).max(skip_first);
    all[from..].iter().map(|l| l.to_string()).collect()
}

/// Append `tail` to `out`, one indented `| line` each ("(log is empty)" for none).
pub(super) fn quote_tail(out: &mut String, tail: &[String]) {
    if tail.is_empty() {
        out.push_str("\n    (log is empty)");
    }
    for line in tail {
        out.push_str("\n    | ");
        out.push_str(line);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_tail_keeps_the_last_lines() {
        let dir = std::env::temp_dir().join(format!("aeris-orch-tail-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.log");
        let text: String = (0..20).map(|i| format!("line {i}\n")).collect();
        std::fs::write(&p, text).unwrap();
        assert_eq!(log_tail(&p, 2), vec!["line 18", "line 19"]);
        assert!(log_tail(&dir.join("missing.log"), 3).is_empty());
        // a long log: only whole lines from the end
        let long: String = (0..5000).map(|i| format!("entry {i:05}\n")).collect();
        std::fs::write(&p, long).unwrap();
        assert_eq!(log_tail(&p, 1), vec!["entry 04999"]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
