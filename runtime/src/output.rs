//! Output flags checked before a run, so that a run is never computed for nothing: what `launch`,
//! `simulate`, `bench` and the monitor process check of their `--out` and `--record` before they start.
//! Errors name the flag (bad input: exit code 2).

use std::path::{Path, PathBuf};

/// Checks an output directory flag: `dir` must be a directory or not exist yet; it is created (with its
/// parents) and a probe file is written and removed in it.
pub fn check_out_dir(flag: &str, dir: &Path) -> Result<(), String> {
    let bad = |what: String| format!("{flag} {}: {what}", dir.display());
    if dir.exists() && !dir.is_dir() {
        return Err(bad("exists and is not a directory".into()));
    }
    std::fs::create_dir_all(dir).map_err(|e| bad(e.to_string()))?;
    let probe = dir.join(format!(".uavloc-write-probe-{}", std::process::id()));
    std::fs::write(&probe, b"probe").map_err(|e| bad(format!("cannot write there: {e}")))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Checks an output file flag: `file` must not be a directory, and its directory must exist (or be
/// creatable) and be writable. Returns the absolute path (what a child process is given).
pub fn check_out_file(flag: &str, file: &Path) -> Result<PathBuf, String> {
    let bad = |what: String| format!("{flag} {}: {what}", file.display());
    if file.is_dir() {
        return Err(bad("is a directory".into()));
    }
    let abs = std::path::absolute(file).map_err(|e| bad(e.to_string()))?;
    if let Some(dir) = abs.parent() {
        check_out_dir(&format!("{flag} {}: its directory", file.display()), dir)?;
    }
    Ok(abs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_checked_before_a_run() {
        let root = std::env::temp_dir().join(format!("uavloc-output-check-{}", std::process::id()));
        let nested = root.join("a/b");
        check_out_dir("--out", &nested).unwrap();
        assert!(nested.is_dir(), "created with its parents");
        assert!(std::fs::read_dir(&nested).unwrap().next().is_none(), "the probe is removed");
        let file = root.join("f.json");
        std::fs::write(&file, "x").unwrap();
        assert!(check_out_dir("--out", &file).unwrap_err().contains("not a directory"));
        assert!(check_out_file("--record", &nested).unwrap_err().starts_with("--record"));
        assert!(check_out_file("--record", &file.join("under-a-file.json")).is_err());
        assert!(check_out_file("--record", Path::new("rel.json")).unwrap().is_absolute());
        std::fs::remove_dir_all(&root).ok();
    }
}
