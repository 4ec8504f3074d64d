//! What every verb prints through.

use std::io::Write;

/// Prints a line to stdout; a reader that went away early (`marvin ... | head`) is no error.
pub fn emit(line: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{line}").and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => Ok(other?),
    }
}
