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
    CliError::Failed(format!("the launch's state directory {}: {e}", what.display()))
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
pub(crate) struct DomainLock {
    _file: File,
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
        let path = state_root()?.join(name);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| failed(&path, e))?;
        // SAFETY: flock on a file descriptor we own, valid for the call.
        let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
        if rc != 0 {
            let e = std::io::Error::last_os_error();
            if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
                return Err(CliError::Input(busy(&path)));
            }
            return Err(failed(&path, e));
        }
        Ok(Self { _file: file })
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
            .map_err(|e| CliError::Input(format!("--scenario {}: cannot copy it: {e}", file.display())))?;
        let again = model::load_scenario(Some(&copy), Some(loaded.steps), Some(loaded.seed))
            .map_err(|e| CliError::Input(format!("--scenario {}: {e}", file.display())))?;
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
}
