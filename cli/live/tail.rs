//! Follows a growing file of lines (the monitor's JSON-lines log) from where it last stopped reading, so
//! that a long run's log is not read again at every look.

use std::io::{Read as _, Seek as _, SeekFrom};
use std::path::{Path, PathBuf};

/// The tail of a file of lines.
#[derive(Debug, Clone)]
pub struct LogTail {
    path: PathBuf,
    offset: u64,
    partial: Vec<u8>,
}

impl LogTail {
    /// Follows `path` from its start (a file that does not exist yet has no lines).
    pub fn new(path: &Path) -> Self {
        Self { path: path.to_path_buf(), offset: 0, partial: Vec::new() }
    }

    /// The complete lines appended since the last call (a line still being written waits for the next).
    pub fn poll(&mut self) -> Vec<String> {
        let Ok(mut f) = std::fs::File::open(&self.path) else { return Vec::new() };
        if f.seek(SeekFrom::Start(self.offset)).is_err() {
            return Vec::new();
        }
        let mut buf = Vec::new();
        let Ok(n) = f.read_to_end(&mut buf) else { return Vec::new() };
        self.offset += n as u64;
        self.partial.extend_from_slice(&buf);
        let Some(end) = self.partial.iter().rposition(|&b| b == b'\n') else { return Vec::new() };
        let complete: Vec<u8> = self.partial.drain(..=end).collect();
        complete[..end].split(|&b| b == b'\n').map(|l| String::from_utf8_lossy(l).into_owned()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_complete_new_lines_come_out() {
        let path = std::env::temp_dir().join(format!("uavloc-tail-{}", std::process::id()));
        let mut t = LogTail::new(&path);
        assert!(t.poll().is_empty(), "no file yet");
        std::fs::write(&path, "a\nb\npart").unwrap();
        assert_eq!(t.poll(), ["a", "b"]);
        let mut f = std::fs::OpenOptions::new().append(true).open(&path).unwrap();
        std::io::Write::write_all(&mut f, b"ial\nc\n").unwrap();
        assert_eq!(t.poll(), ["partial", "c"]);
        assert!(t.poll().is_empty());
        std::fs::remove_file(&path).ok();
    }
}
