//! The launcher's termination signals: SIGINT/SIGTERM/SIGHUP (and the live view's `q`) are recorded, not
//! fatal, so that the launcher stops its children in order and writes the steps done before it exits
//! (SIGHUP: the terminal of an ssh session that closed; a launch with its output in files keeps it).

use std::sync::atomic::{AtomicI32, Ordering};

/// The last SIGINT/SIGTERM/SIGHUP the launcher received (0: none).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(signal: libc::c_int) {
    SIGNAL.store(signal, Ordering::SeqCst);
}

/// Routes SIGINT, SIGTERM and SIGHUP to [`SIGNAL`] (instead of killing the launcher before it stops its
/// children).
pub(super) fn catch_termination() {
    for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: `on_signal` only performs an atomic store, which is async-signal-safe; the sigaction struct
        // is fully initialised (zeroed, then handler and an empty mask set) before the call.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

/// The termination signal the launcher received, if any (its name).
pub(super) fn received() -> Option<&'static str> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(signal_name(s)),
    }
}

/// The value of [`SIGNAL`] when the user pressed `q` in the live view.
const QUIT_KEY: i32 = -1;

/// Stops the launch as a signal would (the live view's `q`): every child stopped, the steps done kept.
pub(super) fn stop_requested_by_user() {
    SIGNAL.store(QUIT_KEY, Ordering::SeqCst);
}

fn signal_name(signal: i32) -> &'static str {
    match signal {
        QUIT_KEY => "the q key",
        libc::SIGINT => "SIGINT",
        libc::SIGHUP => "SIGHUP",
        _ => "SIGTERM",
    }
}
