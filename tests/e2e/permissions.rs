//! The resources a running pipeline creates are its user's: every iceoryx2 file that belongs to the domain
//! (found by name or content under `<temp>/iceoryx2` and `/dev/shm`), and the launch's private state
//! directory (emitter-sim's snapshot file), allow no access to group or others. (The socket transport's directories are
//! checked in `protocol/tests/transports/uds.rs`.)

use crate::common;

use std::os::unix::fs::{MetadataExt as _, PermissionsExt as _};
use std::path::Path;
use std::time::Duration;

use common::{Launch, assert_nothing_left, domain, files_mentioning, scratch};

#[test]
fn the_resources_of_a_running_pipeline_are_private_to_its_user() {
    let _scenario = common::scenario(module_path!());
    let d = domain("perm", "launch");
    let dir = scratch("perm-launch");
    let mut launch = Launch::start(&d, &dir, &["--steps", "400", "--step-delay-ms", "5"]);
    launch.wait_for_step(20, Duration::from_secs(30));

    let mut files = Vec::new();
    files_mentioning(&std::env::temp_dir().join("iceoryx2"), &d, &mut files);
    files_mentioning(Path::new("/dev/shm"), &d, &mut files);
    assert!(files.len() >= 4, "the domain's iceoryx2 files were not found: {files:?}");
    // SAFETY: getuid has no preconditions.
    let uid = unsafe { libc::getuid() };
    for f in &files {
        let meta = std::fs::metadata(f).unwrap();
        assert_eq!(meta.uid(), uid, "{f}");
        assert_eq!(
            meta.permissions().mode() & 0o077,
            0,
            "{f} is accessible to others: {:o}",
            meta.permissions().mode()
        );
    }

    // The launch's state directory: $TMPDIR/uavloc-<uid>/launch-<pid>-<domain>, 0700, with emitter-sim's snapshot file.
    let parent = std::env::temp_dir().join(format!("uavloc-{uid}"));
    let state = std::fs::read_dir(&parent)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.to_string_lossy().ends_with(&format!("-{d}")))
        .expect("the launch's state directory");
    for p in [&parent, &state] {
        assert_eq!(std::fs::metadata(p).unwrap().permissions().mode() & 0o777, 0o700, "{}", p.display());
    }
    let run = launch.finish_json();
    assert_eq!(run["steps"].as_array().unwrap().len(), 401);
    assert!(!state.exists(), "the state directory is removed at the end");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}
