//! The private directory of one launch.

use std::path::PathBuf;

use protocol::services::Domain;

use crate::error::CliError;

/// The private directory of one launch (checkpoints, and the monitor's log when `--log` is not given):
/// `$TMPDIR/uavloc-<uid>/launch-<pid>`, mode 0700 (as its parent), removed when dropped.
pub(super) struct StateDir(PathBuf);

impl StateDir {
    pub(super) fn create(domain: &Domain) -> Result<Self, CliError> {
        use std::os::unix::fs::{DirBuilderExt as _, MetadataExt as _};
        // SAFETY: getuid has no preconditions and cannot fail.
        let uid = unsafe { libc::getuid() };
        let parent = std::env::temp_dir().join(format!("uavloc-{uid}"));
        let failed = |what: &PathBuf, e: std::io::Error| {
            CliError::Failed(format!("the launch's state directory {}: {e}", what.display()))
        };
        match std::fs::DirBuilder::new().mode(0o700).create(&parent) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(failed(&parent, e)),
        }
        let meta = std::fs::symlink_metadata(&parent).map_err(|e| failed(&parent, e))?;
        if !meta.is_dir() || meta.uid() != uid || meta.mode() & 0o077 != 0 {
            return Err(CliError::Failed(format!(
                "the launch's state directory {} is not a directory of this user with mode 0700; remove it",
                parent.display()
            )));
        }
        let dir = parent.join(format!("launch-{}-{domain}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir); // a leftover of an earlier launch with the same pid
        std::fs::DirBuilder::new().mode(0o700).create(&dir).map_err(|e| failed(&dir, e))?;
        Ok(StateDir(dir))
    }

    pub(super) fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for StateDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
