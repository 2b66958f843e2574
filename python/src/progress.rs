//! Progress for work run from Python: stage lines on `sys.stderr` when asked for, and Ctrl-C.
//!
//! Long work runs with the GIL released; the library asks [`Progress::cancelled`] between
//! units of work, and on the thread that called us this re-takes the GIL to let Python run its
//! signal handlers. A KeyboardInterrupt raised there is kept and re-raised when the work
//! returns [`freeform::Error::Cancelled`].

use freeform::progress::Progress;
use pyo3::prelude::*;
use std::sync::Mutex;
use std::thread::ThreadId;
use std::time::{Duration, Instant};

/// How often the signal handlers run at most: Ctrl-C answers within this, and re-taking the
/// GIL costs about a microsecond, so checks stay invisible in timings.
const SIGNAL_INTERVAL: Duration = Duration::from_millis(50);
/// How often a stage's status line (eigensolver iterations) is printed at most.
const MESSAGE_INTERVAL: Duration = Duration::from_secs(1);

struct State {
    stage: String,
    started: Instant,
    last_signal_check: Instant,
    last_message: Instant,
    interrupt: Option<PyErr>,
}

/// A [`Progress`] for one call from Python.
pub struct PyProgress {
    show: bool,
    caller: ThreadId,
    state: Mutex<State>,
}

impl PyProgress {
    /// Progress for a call on this thread; `show`: print stages to `sys.stderr`.
    pub fn new(show: bool) -> Self {
        let now = Instant::now();
        PyProgress {
            show,
            caller: std::thread::current().id(),
            state: Mutex::new(State {
                stage: String::new(),
                started: now,
                last_signal_check: now - SIGNAL_INTERVAL,
                last_message: now,
                interrupt: None,
            }),
        }
    }

    /// The KeyboardInterrupt (or other exception from a signal handler) that stopped the work.
    pub fn take_interrupt(&self) -> Option<PyErr> {
        self.state.lock().ok()?.interrupt.take()
    }

    fn print(&self, line: &str) {
        if !self.show {
            return;
        }
        // Through Python's sys.stderr, so notebooks show it; a failed write is not worth an
        // error in the middle of a computation.
        Python::attach(|py| {
            let written = py
                .import("sys")
                .and_then(|sys| sys.getattr("stderr"))
                .and_then(|err| err.call_method1("write", (format!("freeform: {line}\n"),)));
            // Python runs pending signal handlers while it runs the write, so a Ctrl-C can
            // surface here: keep it, or `cancelled` would never see it.
            if let Err(e) = written {
                if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
                    if let Ok(mut s) = self.state.lock() {
                        s.interrupt = Some(e);
                    }
                }
            }
        });
    }
}

impl Progress for PyProgress {
    fn begin(&self, stage: &str, _total: Option<u64>) {
        if let Ok(mut s) = self.state.lock() {
            s.stage = stage.to_string();
            s.started = Instant::now();
            s.last_message = s.started;
        }
        self.print(&format!("{stage} ..."));
    }

    fn message(&self, msg: &str) {
        if !self.show {
            return;
        }
        let line = match self.state.lock() {
            Ok(mut s) if s.last_message.elapsed() >= MESSAGE_INTERVAL => {
                s.last_message = Instant::now();
                format!("{}: {msg}", s.stage)
            }
            _ => return,
        };
        self.print(&line);
    }

    fn finish(&self) {
        if !self.show {
            return;
        }
        let line = match self.state.lock() {
            Ok(s) => format!(
                "{} done in {:.2} s",
                s.stage,
                s.started.elapsed().as_secs_f64()
            ),
            Err(_) => return,
        };
        self.print(&line);
    }

    fn cancelled(&self) -> bool {
        let Ok(mut s) = self.state.lock() else {
            return false;
        };
        if s.interrupt.is_some() {
            return true;
        }
        // Signal handlers run on the main thread only; worker threads just see the flag.
        if std::thread::current().id() != self.caller
            || s.last_signal_check.elapsed() < SIGNAL_INTERVAL
        {
            return false;
        }
        s.last_signal_check = Instant::now();
        drop(s);
        let raised = Python::attach(|py| py.check_signals().err());
        match raised {
            Some(e) => {
                if let Ok(mut s) = self.state.lock() {
                    s.interrupt = Some(e);
                }
                true
            }
            None => false,
        }
    }
}
