//! Lines on stderr written whole: the processes of a pipeline share one stderr (the launcher's), and
//! `eprintln!` writes a formatted line piece by piece (one `write` per literal and per argument), so two
//! processes logging at the same moment interleave mid-line. [`write_line`] formats the line first and
//! hands it to the kernel in one `write`, which a pipe keeps whole up to `PIPE_BUF` (4096 bytes) and a
//! terminal in practice.

use std::fmt;
use std::io::Write;

/// Writes `args` and a newline to stderr in one `write` (an error writing stderr is ignored, as
/// `eprintln!` would panic on it: a log line is not worth a crash).
pub fn write_line(args: fmt::Arguments<'_>) {
    let mut line = fmt::format(args);
    line.push('\n');
    let _ = std::io::stderr().lock().write_all(line.as_bytes());
}

/// `eprintln!` with the line written whole ([`write_line`]).
#[macro_export]
macro_rules! log_line {
    ($($arg:tt)*) => {
        $crate::stderr::write_line(format_args!($($arg)*))
    };
}

#[cfg(test)]
mod tests {
    use std::io::Read;
    use std::process::{Command, Stdio};

    /// Set in the children of the test below: which writer they are.
    const CHILD: &str = "UAVLOC_STDERR_TEST_CHILD";
    const LINES: usize = 3000;

    /// The line child `c` writes `k`-th: several arguments, so that `eprintln!` would write it in pieces.
    fn expected(c: &str, k: usize) -> String {
        format!("child {c}: line {k} of {LINES}, {} {} {}", k * 3, "x".repeat(k % 40), k % 7)
    }

    #[test]
    fn the_lines_of_two_processes_sharing_stderr_do_not_interleave() {
        if let Ok(c) = std::env::var(CHILD) {
            for k in 0..LINES {
                crate::log_line!("{}", expected(&c, k));
            }
            return;
        }
        // Two children of this test binary (running only this test) write to one pipe at once.
        let (mut reader, writer) = std::io::pipe().unwrap();
        let children: Vec<_> = ["a", "b"]
            .iter()
            .map(|c| {
                Command::new(std::env::current_exe().unwrap())
                    .args(["--exact", "stderr::tests::the_lines_of_two_processes_sharing_stderr_do_not_interleave"])
                    .args(["--nocapture", "--test-threads", "1"])
                    .env(CHILD, c)
                    .stdout(Stdio::null())
                    .stderr(writer.try_clone().unwrap())
                    .spawn()
                    .unwrap()
            })
            .collect();
        drop(writer);
        let mut text = String::new();
        reader.read_to_string(&mut text).unwrap();
        for mut child in children {
            assert!(child.wait().unwrap().success());
        }
        let mut next = [0usize; 2];
        for line in text.lines().filter(|l| l.starts_with("child ")) {
            let c = usize::from(line.as_bytes()[6] == b'b');
            let name = if c == 0 { "a" } else { "b" };
            assert_eq!(line, expected(name, next[c]), "a line broken by the other process's");
            next[c] += 1;
        }
        assert_eq!(next, [LINES, LINES], "every line of both children, whole and in order");
    }
}
