//! A file the monitor writes in whole lines, gathered per wake-up: the run log and the stamps CSV.

use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use runtime::ProcessError;

/// A file written in whole lines: the lines of one wake-up are gathered and go out in one `write` at
/// [`flush`](Self::flush) (the monitor flushes at the end of every wake-up, before it reports its
/// progress). So a wake-up's lines cost one system call instead of one each, and the lines of other
/// writers appending to the same file (the launcher's `restart` events in the log) never land inside
/// one. A monitor killed mid-wake-up loses that wake-up's lines only: its successor asks for a replay
/// from the first step its files lack, as it would anyway.
pub(crate) struct LineFile {
    out: File,
    path: PathBuf,
    /// The flag that named the file, and what a write error means for the run (for the error message).
    flag: &'static str,
    consequence: &'static str,
    pending: String,
    /// The first write error, reported when it happened.
    error: Option<String>,
}

impl LineFile {
    /// Writes to `out` (the file `flag` named, at `path`); `consequence` ends a write error's message.
    pub(crate) fn new(out: File, path: &Path, flag: &'static str, consequence: &'static str) -> Self {
        LineFile { out, path: path.to_owned(), flag, consequence, pending: String::new(), error: None }
    }

    /// Adds whole lines (each ending in `\n`) to the next write.
    pub(crate) fn push(&mut self, lines: &str) {
        debug_assert!(lines.ends_with('\n'));
        self.pending.push_str(lines);
    }

    /// Writes the lines gathered since the last flush, in one `write`.
    pub(crate) fn flush(&mut self) {
        if self.pending.is_empty() {
            return;
        }
        if let Err(e) = self.out.write_all(self.pending.as_bytes())
            && self.error.is_none()
        {
            self.error = Some(format!("{} {}: {e}{}", self.flag, self.path.display(), self.consequence));
        }
        self.pending.clear();
    }

    /// The first write error, as the unrecoverable end of the run (a restart would hit it again).
    pub(crate) fn check(&self) -> Result<(), ProcessError> {
        match &self.error {
            Some(e) => Err(ProcessError::Unrecoverable(e.clone())),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_go_out_at_the_flush_and_a_write_error_is_kept() {
        let dir = std::env::temp_dir().join(format!("uavloc-lines-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("log");
        let file = std::fs::OpenOptions::new().create(true).append(true).open(&path).unwrap();
        let mut lines = LineFile::new(file, &path, "--log", "");
        lines.push("a\n");
        lines.push("b\n");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "", "nothing before the flush");
        lines.flush();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a\nb\n");
        lines.flush();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a\nb\n", "a flush writes nothing twice");
        assert!(lines.check().is_ok());
        // A file opened read-only cannot be written: the error names the flag and the file, and stays.
        let read_only = File::open(&path).unwrap();
        let mut bad = LineFile::new(read_only, &path, "--stamps", " (no stamps)");
        bad.push("c\n");
        bad.flush();
        let e = bad.check().unwrap_err().to_string();
        assert!(e.contains("--stamps") && e.contains(&path.display().to_string()) && e.ends_with("(no stamps)"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
