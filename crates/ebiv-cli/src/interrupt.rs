//! Ctrl-C (SIGINT) and SIGTERM while a command writes a long output: the first signal asks the
//! command to stop at its next check, so that it ends with an error and its unfinished file
//! (written as `NAME.partial`) is removed; a second signal ends the process at once.

use std::sync::atomic::{AtomicBool, Ordering};

/// Set by the first SIGINT or SIGTERM while a [`Catch`] is alive.
static REQUESTED: AtomicBool = AtomicBool::new(false);

/// While alive, SIGINT and SIGTERM set [`requested`] instead of ending the process (a second
/// one still ends it); dropping it restores the default handling.
pub struct Catch(());

/// Catch SIGINT and SIGTERM until the returned guard is dropped.
pub fn catch() -> Catch {
    REQUESTED.store(false, Ordering::SeqCst);
    #[cfg(unix)]
    // SAFETY: `on_signal` only touches an atomic and calls `_exit`, both async-signal-safe;
    // the dispositions are valid for these signals.
    unsafe {
        let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        libc::signal(libc::SIGINT, handler);
        libc::signal(libc::SIGTERM, handler);
    }
    Catch(())
}

/// Whether a SIGINT or SIGTERM arrived since [`catch`].
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

/// An error for a command stopped by a signal while writing `path`.
pub fn error(path: &std::path::Path) -> ebiv::Error {
    ebiv::Error::io(
        path,
        std::io::Error::new(
            std::io::ErrorKind::Interrupted,
            "interrupted; the unfinished file was removed",
        ),
    )
}

#[cfg(unix)]
extern "C" fn on_signal(_: libc::c_int) {
    if REQUESTED.swap(true, Ordering::SeqCst) {
        // SAFETY: `_exit` is async-signal-safe; 130 is the shell's code for an interrupt.
        unsafe { libc::_exit(130) };
    }
}

impl Drop for Catch {
    fn drop(&mut self) {
        #[cfg(unix)]
        // SAFETY: SIG_DFL is a valid disposition for these signals.
        unsafe {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            libc::signal(libc::SIGTERM, libc::SIG_DFL);
        }
    }
}
