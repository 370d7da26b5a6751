//! Ctrl-C (SIGINT) and SIGTERM while a command writes a long output: the first signal asks the
//! command to stop at its next check, so that it ends with an error and its unfinished files
//! (written under temporary names) are removed, and the process then ends by that signal, as
//! if it had not been caught (shells and scripts see the interrupt); a second signal ends the
//! process at once. A signal the parent set to be ignored stays ignored.

use std::sync::atomic::{AtomicI32, Ordering};

/// The first SIGINT or SIGTERM received while a [`Catch`] is alive, or 0.
static RECEIVED: AtomicI32 = AtomicI32::new(0);

#[cfg(unix)]
const SIGNALS: [libc::c_int; 2] = [libc::SIGINT, libc::SIGTERM];

/// While alive, SIGINT and SIGTERM are recorded ([`check`]) instead of ending the process
/// (a second one still ends it); dropping it restores the handling it replaced.
pub struct Catch {
    #[cfg(unix)]
    previous: Vec<(libc::c_int, libc::sigaction)>,
}

/// Catch SIGINT and SIGTERM until the returned guard is dropped; a signal whose disposition is
/// "ignore" (a background job of a shell without job control) is left alone.
pub fn catch() -> Catch {
    RECEIVED.store(0, Ordering::SeqCst);
    #[cfg(unix)]
    {
        let mut previous = Vec::new();
        for signal in SIGNALS {
            // SAFETY: `sigaction` with a null new action only reads the current one into
            // `old`, which is a valid, zeroed `sigaction`.
            let mut old: libc::sigaction = unsafe { std::mem::zeroed() };
            if unsafe { libc::sigaction(signal, std::ptr::null(), &mut old) } != 0
                || old.sa_sigaction == libc::SIG_IGN
            {
                continue;
            }
            // SAFETY: a zeroed `sigaction` with an empty mask, no flags but SA_RESTART, and a
            // handler that only touches an atomic and calls `_exit` (async-signal-safe).
            unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as usize;
                action.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut action.sa_mask);
                if libc::sigaction(signal, &action, std::ptr::null_mut()) == 0 {
                    previous.push((signal, old));
                }
            }
        }
        Catch { previous }
    }
    #[cfg(not(unix))]
    Catch {}
}

/// An error if a SIGINT or SIGTERM arrived since [`catch`]: the command writing `path` is to
/// stop (its unfinished files are removed as it returns the error).
pub fn check(path: &std::path::Path) -> Result<(), ebiv::Error> {
    if RECEIVED.load(Ordering::SeqCst) == 0 {
        return Ok(());
    }
    Err(ebiv::Error::io(
        path,
        std::io::Error::new(
            std::io::ErrorKind::Interrupted,
            "interrupted; no unfinished file is left",
        ),
    ))
}

/// Whether a SIGINT or SIGTERM arrived since [`catch`].
pub fn received() -> bool {
    RECEIVED.load(Ordering::SeqCst) != 0
}

/// If a caught signal arrived, end the process by it now, with its default action (after the
/// command has cleaned up and reported): the exit status then says the signal, as shells
/// expect. Returns otherwise.
pub fn resend_caught_signal() {
    let signal = RECEIVED.load(Ordering::SeqCst);
    #[cfg(unix)]
    if signal != 0 {
        // SAFETY: SIG_DFL is a valid disposition; raising a signal the process received.
        unsafe {
            libc::signal(signal, libc::SIG_DFL);
            libc::raise(signal);
        }
    }
    #[cfg(not(unix))]
    let _ = signal;
}

#[cfg(unix)]
extern "C" fn on_signal(signal: libc::c_int) {
    if RECEIVED.swap(signal, Ordering::SeqCst) != 0 {
        // SAFETY: `_exit` is async-signal-safe; 128 + signal is the shell's code for it.
        unsafe { libc::_exit(128 + signal) };
    }
}

impl Drop for Catch {
    fn drop(&mut self) {
        #[cfg(unix)]
        for (signal, old) in &self.previous {
            // SAFETY: restores the disposition `sigaction` reported for this signal.
            unsafe { libc::sigaction(*signal, old, std::ptr::null_mut()) };
        }
    }
}
