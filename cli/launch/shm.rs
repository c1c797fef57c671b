//! The shared memory a launch needs: checked before the run, and a child's SIGBUS explained.
//!
//! iceoryx2 keeps every topic's samples in files of `/dev/shm` (a tmpfs). A file is created at its full
//! size but its pages are only taken when written; when the tmpfs is full, a write to a page not yet
//! taken kills the writer with SIGBUS. A restart cannot help with that, so the launch refuses to start
//! without room, and a child's SIGBUS fails the launch at once, saying what it was.

use std::path::Path;

use crate::error::CliError;

/// Where iceoryx2 puts its shared memory on Linux.
pub const SHM_DIR: &str = "/dev/shm";

/// The shared memory of one launch's domain, bytes: the files of a running default launch add up to
/// 3.05 MB (63 files, measured; the messages have a fixed size, so the UAV count does not change it),
/// with room for a swapped-in process's ports.
pub const DOMAIN_SHM_BYTES: u64 = 4 << 20;

/// The free bytes of the file system at `dir` (`None` when it cannot be asked).
pub fn free_bytes(dir: &Path) -> Option<u64> {
    let path = std::ffi::CString::new(dir.as_os_str().as_encoded_bytes()).ok()?;
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: a NUL-terminated path and a statvfs to fill, both valid for the call.
    (unsafe { libc::statvfs(path.as_ptr(), &mut st) } == 0).then(|| st.f_bavail as u64 * st.f_frsize as u64)
}

/// Whether `free` bytes hold a domain (`need` bytes): an error naming both, and what to do.
pub fn check_room(dir: &Path, free: u64, need: u64) -> Result<(), CliError> {
    if free >= need {
        return Ok(());
    }
    Err(CliError::Input(format!(
        "{} has {:.1} MB free; a launch needs {:.1} MB of shared memory (iceoryx2's topics) — its processes \
         would die of SIGBUS. Free some (`uavloc process resources --remove-dead` removes what killed runs \
         left; `df -h {}`)",
        dir.display(),
        free as f64 / 1e6,
        need as f64 / 1e6,
        dir.display()
    )))
}

/// [`check_room`] for `/dev/shm` now (nothing to check where it cannot be asked).
pub fn check() -> Result<(), CliError> {
    let dir = Path::new(SHM_DIR);
    free_bytes(dir).map_or(Ok(()), |free| check_room(dir, free, DOMAIN_SHM_BYTES))
}

/// What a child's SIGBUS means, for the launch's error.
pub fn sigbus_reason() -> String {
    let free = free_bytes(Path::new(SHM_DIR)).map_or_else(|| "unknown".into(), |f| format!("{:.1} MB", f as f64 / 1e6));
    format!(
        "SIGBUS: the shared memory is exhausted ({SHM_DIR} has {free} free; a launch needs {:.1} MB) — a restart \
         cannot help; free some and start again",
        DOMAIN_SHM_BYTES as f64 / 1e6
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn too_little_room_is_refused_naming_both_amounts() {
        let dir = Path::new(SHM_DIR);
        assert!(check_room(dir, DOMAIN_SHM_BYTES, DOMAIN_SHM_BYTES).is_ok());
        let e = check_room(dir, 1_500_000, DOMAIN_SHM_BYTES).unwrap_err().to_string();
        assert!(e.contains("/dev/shm has 1.5 MB free") && e.contains("needs 4.2 MB"), "{e}");
        assert!(matches!(check_room(dir, 0, 1), Err(CliError::Input(_))));
    }

    #[test]
    fn the_free_space_of_a_real_file_system_is_read() {
        let free = free_bytes(&std::env::temp_dir()).expect("statvfs of the temporary directory");
        assert!(free > 0);
        assert_eq!(free_bytes(Path::new("/no/such/dir")), None);
    }
}
