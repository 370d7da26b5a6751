//! Long calls run on a worker thread with the GIL released, while the calling (main) thread
//! watches them: it runs Python's signal handlers every few milliseconds, so that Ctrl-C
//! raises `KeyboardInterrupt` (Python runs handlers only on the main thread), and it calls
//! the progress callback whenever the work reports progress.

use ebiv::process::FieldDone;
use ebiv::settings::{RunObserver, RunPlan};
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::time::Duration;

/// How often the calling thread looks at signals and progress.
const POLL: Duration = Duration::from_millis(20);

/// Shared between the work and the thread watching it.
#[derive(Default)]
pub struct Watch {
    stop: Arc<AtomicBool>,
    done: AtomicU64,
    total: AtomicU64,
}

impl Watch {
    /// The flag that is set when the caller is interrupted, for work that polls it.
    pub fn stop_flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// Report progress: `done` of `total` steps.
    pub fn progress(&self, done: u64, total: u64) {
        self.total.store(total, Ordering::Relaxed);
        self.done.store(done, Ordering::Relaxed);
    }

    /// An error once the caller was interrupted, to end the work at its next step.
    pub fn check(&self) -> ebiv::Result<()> {
        if self.stop.load(Ordering::Relaxed) {
            return Err(ebiv::Error::io(
                "",
                std::io::Error::new(std::io::ErrorKind::Interrupted, "interrupted"),
            ));
        }
        Ok(())
    }
}

/// Run `work` on a worker thread with the GIL released, calling `progress(done, total)`
/// as it advances. A signal handler's exception (`KeyboardInterrupt`) or the callback's
/// own exception stops the work at its next step and is raised.
pub fn watched<T: Send>(
    py: Python<'_>,
    progress: Option<&Py<PyAny>>,
    work: impl FnOnce(&Watch) -> ebiv::Result<T> + Send,
) -> PyResult<T> {
    let watch = Watch::default();
    let mut raised: Option<PyErr> = None;
    let mut shown = (u64::MAX, u64::MAX);
    let mut look = |raised: &mut Option<PyErr>| {
        Python::attach(|py| {
            let state = (
                watch.done.load(Ordering::Relaxed),
                watch.total.load(Ordering::Relaxed),
            );
            let mut result = py.check_signals();
            if let (Ok(()), Some(callback)) = (&result, progress) {
                if state != shown && state.1 > 0 {
                    shown = state;
                    result = callback.call1(py, state).map(drop);
                }
            }
            if let Err(e) = result {
                watch.stop.store(true, Ordering::Relaxed);
                raised.get_or_insert(e);
            }
        })
    };
    let outcome = py.detach(|| {
        std::thread::scope(|scope| {
            let (done, finished) = std::sync::mpsc::channel::<()>();
            let watch = &watch;
            let worker = scope.spawn(move || {
                let result = work(watch);
                let _ = done.send(());
                result
            });
            // Returns as soon as the work ends; looks at signals and progress meanwhile.
            while let Err(RecvTimeoutError::Timeout) = finished.recv_timeout(POLL) {
                look(&mut raised);
            }
            look(&mut raised);
            worker.join()
        })
    });
    if let Some(e) = raised {
        return Err(e);
    }
    match outcome {
        Ok(result) => result.map_err(crate::errors::to_py),
        Err(_) => Err(crate::errors::EbivError::new_err(
            "internal error: the computation panicked; please report it with the call that caused it",
        )),
    }
}

/// A run's observer that reports its fields to a [`Watch`] and stops when it says so.
pub struct FieldWatch<'a>(pub &'a Watch);

impl RunObserver for FieldWatch<'_> {
    fn planned(&mut self, plan: &RunPlan) -> ebiv::Result<()> {
        self.0.progress(0, plan.times.len() as u64);
        self.0.check()
    }

    fn field(&mut self, done: &FieldDone) -> ebiv::Result<()> {
        self.0.progress(done.done as u64, done.total as u64);
        self.0.check()
    }
}
