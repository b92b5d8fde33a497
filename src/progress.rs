//! Progress of the long stages (form factors, solve, gather, display refinement, render) and
//! verbose notes, for people watching a terminal, and how a duration reads to them
//! ([`duration`]). The library only reports: [`stage`] opens a counter and [`note`] says
//! a sentence; where they go is decided once by the program through [`set_observer`] (the
//! `radiosity` binary draws `indicatif` bars on stderr when it is a terminal, and prints notes
//! with `-v`). Without an observer — the library's default, and in tests — every call is a
//! no-op costing one atomic load, and nothing reported here changes any result.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

/// Receives progress. Implementations must be cheap and thread-safe: `advance` is called
/// from worker threads.
pub trait Observer: Send + Sync {
    /// A stage begins; `total` units of work (`None`: unknown, e.g. sweeps until converged).
    fn start(&self, name: &str, total: Option<u64>);
    /// `done` more units of the current stage are finished.
    fn advance(&self, done: u64);
    /// A short status of the current stage (e.g. the residual of the last sweep).
    fn status(&self, message: &str);
    /// The current stage has ended.
    fn finish(&self);
    /// A line of verbose detail (shown with `-v`).
    fn note(&self, message: &str);
    /// A warning, shown as it happens (also with `--quiet`).
    fn warning(&self, message: &str);
}

static OBSERVER: OnceLock<Box<dyn Observer>> = OnceLock::new();

/// Installs the observer for the rest of the process (later calls are ignored).
pub fn set_observer(observer: Box<dyn Observer>) {
    let _ = OBSERVER.set(observer);
}

fn observer() -> Option<&'static dyn Observer> {
    OBSERVER.get().map(|b| b.as_ref())
}

/// A running stage; ends (and its bar disappears) when dropped. Counts are batched so that
/// worker threads touch the observer rarely.
pub struct Stage {
    pending: AtomicU64,
    batch: u64,
}

/// Begins a stage of `total` units (`None` if unknown).
pub fn stage(name: &str, total: Option<u64>) -> Stage {
    if let Some(o) = observer() {
        o.start(name, total);
    }
    Stage {
        pending: AtomicU64::new(0),
        batch: total.map_or(1, |t| (t / 1000).max(1)),
    }
}

impl Stage {
    /// `done` more units are finished.
    #[inline]
    pub fn advance(&self, done: u64) {
        let Some(o) = observer() else { return };
        let now = self.pending.fetch_add(done, Ordering::Relaxed) + done;
        if now >= self.batch {
            let taken = self.pending.swap(0, Ordering::Relaxed);
            if taken > 0 {
                o.advance(taken);
            }
        }
    }

    /// A short status line for the stage.
    pub fn status(&self, message: impl FnOnce() -> String) {
        if let Some(o) = observer() {
            o.status(&message());
        }
    }
}

impl Drop for Stage {
    fn drop(&mut self) {
        if let Some(o) = observer() {
            let rest = self.pending.swap(0, Ordering::Relaxed);
            if rest > 0 {
                o.advance(rest);
            }
            o.finish();
        }
    }
}

/// A status line for whatever stage is running (for code that does not hold its [`Stage`]).
pub fn note_status(message: impl FnOnce() -> String) {
    if let Some(o) = observer() {
        o.status(&message());
    }
}

/// A warning shown as it happens; false when nobody listens (the caller keeps it to show
/// later).
pub fn warning(message: &str) -> bool {
    observer().map(|o| o.warning(message)).is_some()
}

/// A line of verbose detail; the message is only built when someone listens.
pub fn note(message: impl FnOnce() -> String) {
    if let Some(o) = observer() {
        o.note(&message());
    }
}

/// Seconds as "4 s", "2.5 min", "1.2 h".
pub fn duration(s: f64) -> String {
    if s < 90.0 {
        format!("{:.0} s", s.max(1.0))
    } else if s < 5400.0 {
        format!("{:.1} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}
