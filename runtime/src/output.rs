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

/// Checks a run's outputs before it starts: the directory flag `dir` (`(flag, dir, the files it will
/// hold)`, [`check_out_dir`]), each file flag given ([`check_out_file`]), and that no two are one file
/// ([`check_distinct`]). `None`: the flag is not given.
pub fn check_outputs(files: &[(&str, Option<&Path>)], dir: (&str, Option<&Path>, &[&str])) -> Result<(), String> {
    if let (flag, Some(d), _) = dir {
        check_out_dir(flag, d)?;
    }
    for (flag, file) in files {
        if let Some(f) = file {
            check_out_file(flag, f)?;
        }
    }
    check_distinct(files, &[dir])
}

/// Checks that no two outputs of a run are one file: each `(flag, file)` given, and each file an `--out`
/// directory given will hold (`(flag, dir, its file names)`); `None`: the flag is not given. Paths are
/// compared as the system resolves them (relative or absolute, through symbolic links of their
/// directories or of the files themselves).
/// Before, `--log` and `--stamps` on one file left a CSV where the log had been, with exit code 0.
pub fn check_distinct(files: &[(&str, Option<&Path>)], dirs: &[(&str, Option<&Path>, &[&str])]) -> Result<(), String> {
    let mut seen: Vec<(String, PathBuf)> = Vec::new();
    let listed = files.iter().filter_map(|&(flag, f)| Some((flag.to_string(), f?.to_path_buf())));
    let inside =
        dirs.iter().filter_map(|&(flag, dir, names)| Some((flag, dir?, names))).flat_map(|(flag, dir, names)| {
            names.iter().map(move |n| (format!("{flag} {} (its {n})", dir.display()), dir.join(n)))
        });
    for (what, file) in listed.chain(inside) {
        let key = resolved(&file);
        if let Some((other, _)) = seen.iter().find(|(_, k)| *k == key) {
            return Err(format!(
                "{other} and {what} are one file, {}: give each output a file of its own",
                key.display()
            ));
        }
        seen.push((what, key));
    }
    Ok(())
}

/// `file` as the system resolves it: the file itself if it exists, else its directory (if it exists) and
/// its name; else the absolute path.
fn resolved(file: &Path) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(file) {
        return p;
    }
    let abs = std::path::absolute(file).unwrap_or_else(|_| file.to_path_buf());
    match (abs.parent().and_then(|d| std::fs::canonicalize(d).ok()), abs.file_name()) {
        (Some(dir), Some(name)) => dir.join(name),
        _ => abs,
    }
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

    #[test]
    fn two_outputs_on_one_file_are_refused_however_the_file_is_named() {
        let root = std::env::temp_dir().join(format!("uavloc-output-distinct-{}", std::process::id()));
        std::fs::create_dir_all(root.join("d")).unwrap();
        let (a, b) = (root.join("a.jsonl"), root.join("b.csv"));
        assert_eq!(check_distinct(&[("--log", Some(&a)), ("--stamps", Some(&b)), ("--record", None)], &[]), Ok(()));
        // The same file by another name: through `..`, and through a symbolic link to its directory.
        let dotted = root.join("d/../a.jsonl");
        let e = check_distinct(&[("--log", Some(&a)), ("--stamps", Some(&dotted))], &[]).unwrap_err();
        assert!(e.starts_with("--log and --stamps are one file"), "{e}");
        std::os::unix::fs::symlink(&root, root.join("d/link")).unwrap();
        assert!(check_distinct(&[("--log", Some(&a)), ("--record", Some(&root.join("d/link/a.jsonl")))], &[]).is_err());
        // A file that an --out directory will hold.
        let (d, run_json, log) = (root.join("d"), root.join("d/run.json"), root.join("d/log"));
        let e = check_distinct(&[("--log", Some(&run_json))], &[("--out", Some(&d), &["run.json"])]).unwrap_err();
        assert!(e.contains("--out") && e.contains("(its run.json)"), "{e}");
        assert_eq!(
            check_distinct(&[("--log", Some(&log))], &[("--out", Some(&d), &["run.json"]), ("--out", None, &["log"])]),
            Ok(())
        );
        std::fs::remove_dir_all(&root).ok();
    }
}
