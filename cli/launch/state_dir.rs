//! The launcher's files: the per-user state root `$TMPDIR/uavloc-<uid>` (mode 0700), the lock of a
//! domain held for a launch's lifetime and that of a swap in progress (`DomainLock`), and the private
//! directory of one launch
//! (`StateDir`); state directories of launchers that died (SIGKILL) are removed by the next launch.

use std::fs::File;
use std::os::fd::AsRawFd as _;
use std::path::{Path, PathBuf};

use protocol::services::Domain;

use crate::error::CliError;

fn failed(what: &Path, e: std::io::Error) -> CliError {
    CliError::failed_because(format!("the launch's state directory {}", what.display()), e)
}

/// `$TMPDIR/uavloc-<uid>`, created with mode 0700 if missing; refused if it is not this user's 0700
/// directory.
pub(super) fn state_root() -> Result<PathBuf, CliError> {
    use std::os::unix::fs::{DirBuilderExt as _, MetadataExt as _};
    // SAFETY: getuid has no preconditions and cannot fail.
    let uid = unsafe { libc::getuid() };
    let parent = std::env::temp_dir().join(format!("uavloc-{uid}"));
    match std::fs::DirBuilder::new().mode(0o700).create(&parent) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        // An unusable $TMPDIR is bad input: said as such, exit 2.
        Err(e) => {
            return Err(CliError::Input(format!(
                "the temporary directory {} ($TMPDIR) is not usable: cannot create {}: {e}; set TMPDIR to a \
                 writable directory",
                std::env::temp_dir().display(),
                parent.display()
            )));
        }
    }
    let meta = std::fs::symlink_metadata(&parent).map_err(|e| failed(&parent, e))?;
    if !meta.is_dir() || meta.uid() != uid || meta.mode() & 0o077 != 0 {
        return Err(CliError::Failed(format!(
            "the launch's state directory {} is not a directory of this user with mode 0700; remove it",
            parent.display()
        )));
    }
    Ok(parent)
}

/// The exclusive lock of a domain, held while a launch runs in it: `domain-<name>.lock` in the state
/// root, `flock(LOCK_EX | LOCK_NB)`. The kernel releases it when the launcher exits, however it exits
/// (SIGKILL included), so a lock is never stale. Two launches into one domain at the same instant: one
/// gets it, the other is refused (exit 2) before it touches the domain.
///
/// The file is removed when the lock is dropped, while it is still held; a launcher killed before that
/// leaves it, and the next launch removes it ([`remove_unheld_locks`]). Removing a lock file is safe
/// because a taker checks, once it holds the lock, that the file it locked is still the one at the path
/// (else it was removed meanwhile and the taker tries again on the new file).
pub(crate) struct DomainLock {
    /// Holds the lock until dropped.
    _file: File,
    path: PathBuf,
}

impl Drop for DomainLock {
    fn drop(&mut self) {
        // Still held: a taker that opened the old file finds it gone from the path and takes the new one.
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Whether `file` is the file at `path` now (same device and inode).
fn still_at(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt as _;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// `flock(LOCK_EX | LOCK_NB)` on `file`: `Ok(false)` when another holds it.
fn try_flock(file: &File) -> std::io::Result<bool> {
    // SAFETY: flock on a file descriptor we own, valid for the call.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.raw_os_error() == Some(libc::EWOULDBLOCK) { Ok(false) } else { Err(e) }
}

/// Removes the lock files in `root` (`domain-*.lock`, `swap-*.lock`) that nobody holds — left by
/// launchers and swaps that were killed; returns how many.
pub(super) fn remove_unheld_locks(root: &Path) -> usize {
    let locks = std::fs::read_dir(root).into_iter().flatten().flatten().map(|e| e.path()).filter(|p| {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        name.ends_with(".lock") && (name.starts_with("domain-") || name.starts_with("swap-"))
    });
    let mut removed = 0;
    for path in locks {
        let Ok(file) = File::open(&path) else { continue };
        // Held under the lock, and only if it is still the file at the path: the same rule as a taker's.
        if try_flock(&file).unwrap_or(false) && still_at(&file, &path) && std::fs::remove_file(&path).is_ok() {
            removed += 1;
        }
    }
    removed
}

impl DomainLock {
    pub(super) fn acquire(domain: &Domain) -> Result<Self, CliError> {
        Self::take(&format!("domain-{domain}.lock"), |path| {
            format!("domain {domain} is in use (another launch holds {}); choose another --domain", path.display())
        })
    }

    /// The lock of a swap of `role` in `domain` (`swap-<domain>-<role>.lock`), held while `uavloc swap`
    /// runs: of two swaps at once, both new processes would take over from the same step and the second
    /// at once from the first, while both swaps reported success. The second is refused (exit 2).
    pub(crate) fn acquire_swap(domain: &Domain, role: &str) -> Result<Self, CliError> {
        Self::take(&format!("swap-{domain}-{role}.lock"), |path| {
            format!(
                "a swap of the {role} in domain {domain} is in progress (another `uavloc swap` holds {}); run this \
                 one once it has finished",
                path.display()
            )
        })
    }

    /// `flock(LOCK_EX | LOCK_NB)` on `name` in the state root; `busy` words the refusal.
    fn take(name: &str, busy: impl FnOnce(&Path) -> String) -> Result<Self, CliError> {
        Self::take_in(&state_root()?, name, busy)
    }

    fn take_in(root: &Path, name: &str, busy: impl FnOnce(&Path) -> String) -> Result<Self, CliError> {
        let path = root.join(name);
        // A file removed between our open and our lock (its holder let go): try again on the new one. Each
        // round needs another holder to have taken and released the lock meanwhile, so few rounds do.
        for _ in 0..100 {
            let file = std::fs::OpenOptions::new()
                .create(true)
                .truncate(false)
                .write(true)
                .open(&path)
                .map_err(|e| failed(&path, e))?;
            // Held: by a launch (refused), or for an instant by the sweep of a stale file (gone then).
            let deadline = std::time::Instant::now() + std::time::Duration::from_millis(100);
            let locked = loop {
                if try_flock(&file).map_err(|e| failed(&path, e))? {
                    break true;
                }
                if !still_at(&file, &path) {
                    break false;
                }
                if std::time::Instant::now() > deadline {
                    return Err(CliError::Input(busy(&path)));
                }
                std::thread::sleep(std::time::Duration::from_millis(5));
            };
            if locked && still_at(&file, &path) {
                return Ok(Self { _file: file, path });
            }
        }
        Err(CliError::Failed(format!("the lock file {} kept being replaced; try again", path.display())))
    }
}

/// Whether process `pid` exists (a zombie counts as gone).
pub(crate) fn pid_alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| s.rsplit_once(") ").map(|(_, rest)| !rest.starts_with('Z')))
        .unwrap_or(false)
}

/// The launches' state directories `launch-<pid>-<domain>` in `root`: (launcher pid, domain, path).
fn launch_dirs(root: &Path) -> impl Iterator<Item = (u32, String, PathBuf)> {
    std::fs::read_dir(root).into_iter().flatten().flatten().filter_map(|entry| {
        let name = entry.file_name().to_str()?.strip_prefix("launch-")?.to_string();
        let (pid, domain) = name.split_once('-')?;
        Some((pid.parse().ok()?, domain.to_string(), entry.path()))
    })
}

/// Removes the state directories in `root` whose launcher is gone (it was killed and could not clean
/// up); returns how many.
pub(super) fn remove_stale_state_dirs(root: &Path) -> usize {
    let stale = launch_dirs(root).filter(|(pid, ..)| *pid != std::process::id() && !pid_alive(*pid));
    stale.filter(|(.., path)| std::fs::remove_dir_all(path).is_ok()).count()
}

/// What a running launch tells a `uavloc swap` about its run (`run.json` in its state directory), so a
/// swapped-in process runs the same scenario.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunSettings {
    /// The scenario file (absolute), if not the default.
    pub scenario: Option<PathBuf>,
    /// The launch's own copy of that file (in its state directory), which its processes — and a process
    /// swapped in — read: an edit of the original during the run changes no restart.
    #[serde(default)]
    pub scenario_copy: Option<PathBuf>,
    /// Planning steps.
    pub steps: usize,
    /// Run seed.
    pub seed: u64,
    /// The flags the launch gave its planner and its estimator (`--name=value`, as
    /// [`runtime::flags::to_flags`] writes them): a process swapped in takes every flag its `uavloc swap`
    /// does not give from there, so a swap meant to restart a role changes nothing else.
    #[serde(default)]
    pub planner: Vec<String>,
    #[serde(default)]
    pub estimator: Vec<String>,
}

/// The settings of the launch running in `domain` (its launcher alive), with the file they came from.
pub fn find_run_settings(domain: &Domain) -> Option<(RunSettings, PathBuf, u32)> {
    launch_dirs(&state_root().ok()?).filter(|(pid, d, _)| d == domain.as_str() && pid_alive(*pid)).find_map(
        |(pid, _, dir)| {
            let path = dir.join("run.json");
            let settings = serde_json::from_str(&std::fs::read_to_string(&path).ok()?).ok()?;
            Some((settings, path, pid))
        },
    )
}

/// The private directory of one launch (emitter-sim's snapshot file, and the monitor's log when `--log` is
/// not given): `$TMPDIR/uavloc-<uid>/launch-<pid>-<domain>`, mode 0700 (as its parent), removed when
/// dropped.
pub(super) struct StateDir(PathBuf);

impl StateDir {
    pub(super) fn create(domain: &Domain) -> Result<Self, CliError> {
        use std::os::unix::fs::DirBuilderExt as _;
        let parent = state_root()?;
        remove_stale_state_dirs(&parent);
        remove_unheld_locks(&parent);
        let dir = parent.join(format!("launch-{}-{domain}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir); // a leftover of an earlier launch with the same pid
        std::fs::DirBuilder::new().mode(0o700).create(&dir).map_err(|e| failed(&dir, e))?;
        Ok(StateDir(dir))
    }

    pub(super) fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Copies the scenario `file` into this directory (`scenario.toml`) and checks that the copy is the
    /// scenario `loaded` (the file did not change between the load and the copy); the copy's path.
    pub(super) fn copy_scenario(&self, file: &Path, loaded: &model::Scenario) -> Result<PathBuf, CliError> {
        let copy = self.path("scenario.toml");
        std::fs::copy(file, &copy)
            .map_err(|e| CliError::input_because(format!("--scenario {}: cannot copy it", file.display()), e))?;
        let again = model::load_scenario(Some(&copy), Some(loaded.steps), Some(loaded.seed))
            .map_err(|e| CliError::input_because(format!("--scenario {}", file.display()), e))?;
        if again.fingerprint() != loaded.fingerprint() {
            return Err(CliError::Input(format!(
                "--scenario {}: the file changed while the launch started; start it again",
                file.display()
            )));
        }
        Ok(copy)
    }

    /// Writes the run's settings for `uavloc swap` ([`find_run_settings`]).
    pub(super) fn write_run_settings(&self, settings: &RunSettings) -> Result<(), CliError> {
        let path = self.path("run.json");
        let text = serde_json::to_string_pretty(settings).unwrap_or_default();
        std::fs::write(&path, text).map_err(|e| failed(&path, e))
    }
}

impl Drop for StateDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn launch_dirs_are_named_by_pid_and_domain_and_nothing_else_is_one() {
        let root = std::env::temp_dir().join(format!("uavloc-dirs-test-{}", std::process::id()));
        for name in ["launch-12-lab-1", "launch-x-lab", "launch-13", "other-14-lab"] {
            std::fs::create_dir_all(root.join(name)).unwrap();
        }
        let found: Vec<(u32, String)> = launch_dirs(&root).map(|(pid, domain, _)| (pid, domain)).collect();
        assert_eq!(found, [(12, "lab-1".to_string())]);
        // Pid 12 is not a launcher of this test (and if it runs, it is not removed): removed as stale only
        // when it is gone.
        let removed = remove_stale_state_dirs(&root);
        assert_eq!(removed == 1, !root.join("launch-12-lab-1").exists());
        assert_eq!(removed == 1, !pid_alive(12));
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_lock_file_goes_with_its_lock_and_an_unheld_one_is_swept() {
        let root = std::env::temp_dir().join(format!("uavloc-locks-test-{}", std::process::id()));
        std::fs::create_dir_all(&root).unwrap();
        let busy = |p: &Path| format!("busy {}", p.display());
        let held = DomainLock::take_in(&root, "domain-a.lock", busy).unwrap();
        assert!(root.join("domain-a.lock").exists());
        // A second taker is refused while it is held.
        assert!(matches!(DomainLock::take_in(&root, "domain-a.lock", busy), Err(CliError::Input(_))));
        // A file left by a killed launcher (nobody holds it) is swept, a held one and other files are not.
        std::fs::write(root.join("domain-b.lock"), "").unwrap();
        std::fs::write(root.join("swap-b-planner.lock"), "").unwrap();
        std::fs::write(root.join("notes.lock"), "").unwrap();
        assert_eq!(remove_unheld_locks(&root), 2);
        assert!(root.join("domain-a.lock").exists() && root.join("notes.lock").exists());
        assert!(!root.join("domain-b.lock").exists() && !root.join("swap-b-planner.lock").exists());
        drop(held);
        assert!(!root.join("domain-a.lock").exists(), "the lock file outlived its lock");
        // A taker that opened the file before its holder removed it does not hold a lock on a file that is
        // gone from the path: it takes the new file, which a third taker then finds held.
        let first = DomainLock::take_in(&root, "domain-c.lock", busy).unwrap();
        let early = File::open(root.join("domain-c.lock")).unwrap();
        drop(first);
        assert!(try_flock(&early).unwrap(), "the old file is free once dropped");
        assert!(!still_at(&early, &root.join("domain-c.lock")));
        let second = DomainLock::take_in(&root, "domain-c.lock", busy).unwrap();
        assert!(matches!(DomainLock::take_in(&root, "domain-c.lock", busy), Err(CliError::Input(_))));
        drop(second);
        std::fs::remove_dir_all(&root).unwrap();
    }
}
