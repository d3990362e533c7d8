//! Long work off the interpreter's thread: it runs on a thread of its own while the
//! caller's thread, with the GIL released, waits for it in short slices, checking for
//! Ctrl-C (a pending signal) and handing progress to a Python callback between them.
//!
//! The library's loops report progress through [`Progress`]; a cancelled run is
//! stopped at its next report by unwinding from inside it (the `Cancelled` payload,
//! silenced in the panic hook), so the library needs no cancellation of its own and
//! every thread it uses returns before the call does.
//!
//! At exit, CPython ends a daemon thread that asks for the GIL back by unwinding its
//! stack with a forced unwind (`pthread_exit`). Through our frames that unwind reaches
//! PyO3's `catch_unwind`, which cannot stop it, and the process aborts (`FATAL:
//! exception not rethrown`). So no thread of ours asks for the GIL back once exit has
//! begun: every release of the GIL goes through [`detach`], which parks the thread for
//! good instead, and an `atexit` hook ([`at_exit`]), which runs before the interpreter
//! finalises, waits until every thread inside this module has let go of the GIL.

use std::{
    cell::Cell,
    panic::{self, AssertUnwindSafe},
    sync::{
        atomic::{AtomicBool, AtomicU64, Ordering},
        Condvar, Mutex, Once, PoisonError,
    },
    time::Duration,
};

use crossbeam_channel as mpsc;
use frameless::evaluation::Progress;
use pyo3::{exceptions::PyRuntimeError, prelude::*};

/// How often the waiting thread looks for a signal and reports progress.
const SLICE: Duration = Duration::from_millis(100);

/// The unwinding payload of a cancelled run.
struct Cancelled;

/// Whether the interpreter is exiting, and how many threads are inside this module
/// holding (or waiting for) the GIL.
struct GateState {
    exiting: bool,
    attached: usize,
}

static GATE: Mutex<GateState> = Mutex::new(GateState {
    exiting: false,
    attached: 0,
});
static GATE_CHANGED: Condvar = Condvar::new();

fn gate() -> std::sync::MutexGuard<'static, GateState> {
    GATE.lock().unwrap_or_else(PoisonError::into_inner)
}

fn attached_less_one() {
    gate().attached -= 1;
    GATE_CHANGED.notify_all();
}

thread_local! {
    /// This thread's calls into the module under way (a progress callback may call in
    /// again); the thread counts as attached once, at the first.
    static DEPTH: Cell<u32> = const { Cell::new(0) };
}

/// Marks this thread as inside the module, holding the GIL, while it lives.
pub struct Inside(());

impl Inside {
    pub fn new() -> Inside {
        if DEPTH.get() == 0 {
            gate().attached += 1;
        }
        DEPTH.set(DEPTH.get() + 1);
        Inside(())
    }
}

impl Drop for Inside {
    fn drop(&mut self) {
        DEPTH.set(DEPTH.get() - 1);
        if DEPTH.get() == 0 {
            attached_less_one();
        }
    }
}

/// `py.detach(f)`, except that once the interpreter is exiting the thread never takes
/// the GIL back: it parks for good, and the process's exit ends it.
pub fn detach<T, F>(py: Python<'_>, f: F) -> T
where
    F: Send + FnOnce() -> T,
    T: Send,
{
    let _inside = Inside::new();
    attached_less_one();
    py.detach(move || {
        let _back = Reattach;
        f()
    })
}

/// Counts the thread as attached again as it leaves a [`detach`] (also when unwinding
/// from it), or parks it for good once the interpreter is exiting.
struct Reattach;

impl Drop for Reattach {
    fn drop(&mut self) {
        let mut g = gate();
        if g.exiting {
            drop(g);
            loop {
                std::thread::park();
            }
        }
        g.attached += 1;
    }
}

/// The `atexit` hook: from now on no thread takes the GIL back through [`detach`];
/// wait, with the GIL released, until no thread is inside the module holding or
/// waiting for it (a thread in a progress callback returns to its next wait).
#[pyfunction]
pub fn at_exit(py: Python<'_>) {
    gate().exiting = true;
    py.detach(|| {
        let mut g = gate();
        while g.attached > 0 {
            g = GATE_CHANGED.wait(g).unwrap_or_else(PoisonError::into_inner);
        }
    });
}

/// Progress shared between the working thread and the waiting one.
#[derive(Default)]
pub struct Work {
    cancel: AtomicBool,
    done: AtomicU64,
    total: AtomicU64,
    msg: Mutex<String>,
}

impl Work {
    /// Stop here if the caller asked for it (unwinds to [`run`]).
    pub fn checkpoint(&self) {
        if self.cancel.load(Ordering::Relaxed) {
            panic::panic_any(Cancelled);
        }
    }

    fn snapshot(&self) -> (u64, u64, String) {
        let msg = self.msg.lock().map(|m| m.clone()).unwrap_or_default();
        (
            self.done.load(Ordering::Relaxed),
            self.total.load(Ordering::Relaxed),
            msg,
        )
    }
}

impl Progress for Work {
    fn total(&self, n: u64) {
        self.checkpoint();
        self.total.store(n, Ordering::Relaxed);
    }

    fn advance(&self, msg: &str, n: u64) {
        self.checkpoint();
        self.done.fetch_add(n, Ordering::Relaxed);
        if let Ok(mut m) = self.msg.lock() {
            if *m != msg {
                msg.clone_into(&mut m);
            }
        }
    }
}

/// A panic hook that says nothing for a cancelled run and defers to the one before it
/// for every other panic.
fn quiet_cancellation() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if !info.payload().is::<Cancelled>() {
                previous(info);
            }
        }));
    });
}

type Outcome<T> = std::thread::Result<PyResult<T>>;

/// Run `job` on a thread of its own; see the module's notes. `progress` is called as
/// `progress(done, total, message)` about ten times a second and once at the end.
pub fn run<T: Send + 'static>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    job: impl FnOnce(&Work) -> PyResult<T> + Send + 'static,
) -> PyResult<T> {
    quiet_cancellation();
    // Counted for the whole call: the progress callback runs Python code between waits.
    let _inside = Inside::new();
    let work = std::sync::Arc::new(Work::default());
    let (tx, rx) = mpsc::unbounded::<Outcome<T>>();
    let shared = work.clone();
    std::thread::Builder::new()
        .name("frameless-py".into())
        .spawn(move || {
            let outcome = panic::catch_unwind(AssertUnwindSafe(|| job(&shared)));
            // The receiver is gone only if the caller's thread died first.
            let _ = tx.send(outcome);
        })
        .map_err(|e| PyRuntimeError::new_err(format!("starting a worker thread: {e}")))?;
    let report = |w: &Work| -> PyResult<()> {
        match progress {
            Some(cb) => cb.call1(w.snapshot()).map(drop),
            None => Ok(()),
        }
    };
    loop {
        match detach(py, || rx.recv_timeout(SLICE)) {
            Ok(outcome) => {
                let value = finish(outcome)?;
                report(&work)?;
                return Ok(value);
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err("the worker thread vanished"));
            }
        }
        if let Err(e) = py.check_signals().and_then(|()| report(&work)) {
            // Ctrl-C, or the callback failed: stop the run, wait for its threads.
            work.cancel.store(true, Ordering::Relaxed);
            let _ = detach(py, || rx.recv());
            return Err(e);
        }
    }
}

/// The job's result, with a panic (other than a cancellation) as a RuntimeError.
fn finish<T>(outcome: Outcome<T>) -> PyResult<T> {
    outcome.unwrap_or_else(|payload| {
        let why = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "cancelled".into());
        Err(PyRuntimeError::new_err(format!("internal error: {why}")))
    })
}
