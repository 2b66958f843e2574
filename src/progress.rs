//! Progress reporting for long stages. Library code calls a [`Progress`] it is handed; the CLI
//! passes a terminal bar ([`TerminalProgress`]), tests and embedders pass [`Silent`].

use std::sync::Mutex;

/// Receiver of progress events. All methods have empty defaults; implementations must be
/// cheap (they may be called from inside solver loops) and thread-safe.
pub trait Progress: Sync {
    /// A stage starts; `total` is the number of work units if known (points, iterations).
    fn begin(&self, _stage: &str, _total: Option<u64>) {}
    /// Work units done so far in the current stage (absolute, not an increment).
    fn set_position(&self, _done: u64) {}
    /// A short status line (e.g. "iter 40, max residual 3.1e-7, 12/33 converged").
    fn message(&self, _msg: &str) {}
    /// The current stage is finished.
    fn finish(&self) {}
    /// Whether the caller asks the work to stop (a Ctrl-C in Python, a GUI's cancel button).
    /// Long stages ask between units of work (between precompute stages, every eigensolver
    /// iteration, every simulation step of a batch run) and then return
    /// [`crate::Error::Cancelled`]; nothing half-done is returned.
    fn cancelled(&self) -> bool {
        false
    }
}

/// Discards every event.
#[derive(Debug, Default, Clone, Copy)]
pub struct Silent;
impl Progress for Silent {}

/// A progress bar on standard error, drawn only when standard error is a terminal.
#[derive(Debug, Default)]
pub struct TerminalProgress {
    bar: Mutex<Option<indicatif::ProgressBar>>,
}

impl TerminalProgress {
    /// A new, idle progress display.
    pub fn new() -> Self {
        Self::default()
    }
}

impl Progress for TerminalProgress {
    fn begin(&self, stage: &str, total: Option<u64>) {
        let bar = match total {
            Some(n) => indicatif::ProgressBar::new(n),
            None => indicatif::ProgressBar::new_spinner(),
        };
        bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        let style = match total {
            Some(_) => indicatif::ProgressStyle::with_template(
                "{prefix:>16} [{bar:30}] {pos}/{len} {elapsed} {msg}",
            ),
            None => {
                indicatif::ProgressStyle::with_template("{prefix:>16} {spinner} {elapsed} {msg}")
            }
        };
        if let Ok(style) = style {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_prefix(stage.to_string());
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        if let Ok(mut slot) = self.bar.lock() {
            if let Some(old) = slot.replace(bar) {
                old.finish_and_clear();
            }
        }
    }
    fn set_position(&self, done: u64) {
        if let Ok(slot) = self.bar.lock() {
            if let Some(bar) = slot.as_ref() {
                bar.set_position(done);
            }
        }
    }
    fn message(&self, msg: &str) {
        if let Ok(slot) = self.bar.lock() {
            if let Some(bar) = slot.as_ref() {
                bar.set_message(msg.to_string());
            }
        }
    }
    fn finish(&self) {
        if let Ok(mut slot) = self.bar.lock() {
            if let Some(bar) = slot.take() {
                bar.finish_and_clear();
            }
        }
    }
}
