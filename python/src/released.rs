//! Work that runs with the GIL released, on a worker thread, while the calling thread wakes up
//! every 100 ms to report progress to Python and to check for signals: Ctrl-C sets the
//! cancellation flag the simulator checks before every block (`run::run_cancellable`), waits for
//! the worker to stop and raises `KeyboardInterrupt`. Panics of the worker become
//! `SimulationError`s; nothing unwinds across the FFI.

use std::sync::atomic::AtomicBool;
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::time::Duration;

use indicatif::ProgressBar;
use pyo3::prelude::*;

use crate::errors::SimulationError;

/// What the worker shares with the calling thread: a hidden progress bar (its position and
/// length, in the worker's units) and the cancellation flag.
pub struct Progress {
    pub bar: ProgressBar,
    pub cancel: AtomicBool,
}

/// A rayon pool of `threads` threads, or `None` for the global pool (all cores, or
/// `RAYON_NUM_THREADS`).
fn pool(threads: Option<usize>) -> PyResult<Option<rayon::ThreadPool>> {
    match threads {
        None => Ok(None),
        Some(0) => Err(pyo3::exceptions::PyValueError::new_err(
            "threads must be at least 1 (None: all cores)",
        )),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(Some)
            .map_err(|e| SimulationError::new_err(format!("cannot start {n} threads: {e}"))),
    }
}

/// Turn off HDF5's printing of its error stack on this thread. netCDF turns it off when it
/// initialises, but only for the thread that initialised it (HDF5's error stacks are per thread),
/// and its probes for optional attributes print pages of `HDF5-DIAG` lines otherwise.
fn silence_hdf5() {
    // Safety: plain FFI call; a null handler and client data disable automatic printing.
    unsafe {
        hdf5_sys::h5e::H5Eset_auto2(hdf5_sys::h5e::H5E_DEFAULT, None, std::ptr::null_mut());
    }
}

fn panic_message(p: Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Run `work` on a worker thread (in a pool of `threads`), the GIL released. `progress`: a
/// Python callable `(done, total)`, called from the calling thread when the position moved.
/// `Ok(None)`: the worker saw the cancellation flag (never returned to Python: a signal's
/// exception is raised instead).
pub fn run<T: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    threads: Option<usize>,
    total: u64,
    work: impl FnOnce(&Progress) -> T + Send,
) -> PyResult<T> {
    let pool = pool(threads)?;
    let shared = Progress {
        bar: ProgressBar::hidden(),
        cancel: AtomicBool::new(false),
    };
    shared.bar.set_length(total);
    let shared = &shared;
    std::thread::scope(|s| {
        let (tx, mut rx) = mpsc::channel::<()>();
        let h = s.spawn(move || {
            silence_hdf5();
            let r = match &pool {
                Some(p) => p.install(|| {
                    p.broadcast(|_| silence_hdf5());
                    work(shared)
                }),
                None => {
                    rayon::broadcast(|_| silence_hdf5());
                    work(shared)
                }
            };
            let _ = tx.send(());
            r
        });
        let mut shown = u64::MAX;
        let stop = |py: Python<'_>, h: std::thread::ScopedJoinHandle<'_, T>| {
            shared.cancel.store(true, Ordering::Relaxed);
            let _ = py.allow_threads(move || h.join());
        };
        loop {
            let (r, done) = py.allow_threads(move || {
                let done = !matches!(
                    rx.recv_timeout(Duration::from_millis(100)),
                    Err(mpsc::RecvTimeoutError::Timeout)
                );
                (rx, done)
            });
            rx = r;
            let pos = shared.bar.position().min(total);
            if let Some(cb) = progress {
                let pos = if done { total } else { pos };
                if pos != shown {
                    shown = pos;
                    if let Err(e) = cb.call1((pos, total)) {
                        stop(py, h);
                        return Err(e);
                    }
                }
            }
            if let Err(e) = py.check_signals() {
                stop(py, h);
                return Err(e);
            }
            if done {
                break;
            }
        }
        match py.allow_threads(move || h.join()) {
            Ok(v) => Ok(v),
            Err(p) => Err(SimulationError::new_err(format!(
                "internal error (please report it): {}",
                panic_message(p)
            ))),
        }
    })
}
