//! The binary's progress display: `indicatif` bars on stderr for the library's long stages
//! ([`radiosity::progress`]), drawn only when stderr is a terminal and `--quiet` is not given,
//! the verbose notes of `-v` and the warnings as they happen (printed above the bar, or
//! plainly when there is none). Without a terminal, `-v` also prints a line on the stages that
//! run long: how far they are and the time left ([`LOG_EVERY`]), so a log shows it too.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radiosity::pipeline::estimate::duration;
use radiosity::progress::{set_observer, Observer};

/// How often a verbose log without a terminal says how far a stage is.
pub const LOG_EVERY: Duration = Duration::from_secs(15);

/// Installs the observer for this run (always: warnings are shown as they happen, also with
/// `--quiet` and when stderr is not a terminal).
pub fn install(quiet: bool, verbose: bool) {
    let bars = !quiet && std::io::stderr().is_terminal();
    set_observer(Box::new(Bars {
        bars,
        verbose,
        current: Mutex::new(None),
    }));
}

struct Bars {
    bars: bool,
    verbose: bool,
    current: Mutex<Option<Current>>,
}

/// The stage running now.
struct Current {
    name: String,
    /// Its bar, when bars are drawn.
    bar: Option<ProgressBar>,
    total: Option<u64>,
    done: u64,
    started: Instant,
    /// When its first units were reported, and the count then: the pace is measured from
    /// there, so the set-up before a stage's first unit (the display refinement's screening
    /// of every edge) is not taken for its pace.
    first: Option<(Instant, u64)>,
    /// When its last log line was printed (logs without a terminal).
    logged: Instant,
    /// Its last status.
    status: String,
}

impl Current {
    /// "gather: 45 % after 1.0 min, about 1.2 min left", or for a stage of unknown length
    /// its time so far and status.
    fn line(&self) -> String {
        let elapsed = self.started.elapsed().as_secs_f64();
        match self.total {
            Some(total) if total > 0 && self.done > 0 => {
                let f = (self.done as f64 / total as f64).min(1.0);
                let head = format!(
                    "{}: {:.0} % after {}",
                    self.name,
                    100.0 * f,
                    duration(elapsed)
                );
                // The pace is the units since the first report over the time since: until a
                // second report there is none to tell the time left by.
                match self.first {
                    Some((at, first)) if self.done > first && at.elapsed().as_secs_f64() > 0.0 => {
                        let rate = (self.done - first) as f64 / at.elapsed().as_secs_f64();
                        let left = total.saturating_sub(self.done) as f64 / rate;
                        format!("{head}, about {} left", duration(left))
                    }
                    _ => head,
                }
            }
            _ if self.status.is_empty() => format!("{}: {} so far", self.name, duration(elapsed)),
            _ => format!(
                "{}: {} ({} so far)",
                self.name,
                self.status,
                duration(elapsed)
            ),
        }
    }

    /// The progress line, if a log line is due.
    fn due(&mut self) -> Option<String> {
        (self.logged.elapsed() >= LOG_EVERY).then(|| {
            self.logged = Instant::now();
            self.line()
        })
    }
}

impl Observer for Bars {
    fn start(&self, name: &str, total: Option<u64>) {
        if !self.bars && !self.verbose {
            return;
        }
        let bar = self.bars.then(|| match total {
            Some(t) => ProgressBar::with_draw_target(Some(t), ProgressDrawTarget::stderr())
                .with_style(
                    ProgressStyle::with_template(
                        "{msg:>14} [{bar:32}] {percent:>3}% {elapsed_precise} (eta {eta})",
                    )
                    .expect("valid template")
                    .progress_chars("=> "),
                ),
            None => {
                let b = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
                    .with_style(
                        ProgressStyle::with_template("{spinner} {msg} {elapsed_precise}")
                            .expect("valid template"),
                    );
                b.enable_steady_tick(Duration::from_millis(120));
                b
            }
        });
        if let Some(b) = &bar {
            b.set_message(name.to_string());
        }
        if let Ok(mut c) = self.current.lock() {
            if let Some(old) = c.take().and_then(|o| o.bar) {
                old.finish_and_clear();
            }
            *c = Some(Current {
                name: name.to_string(),
                bar,
                total,
                done: 0,
                started: Instant::now(),
                first: None,
                logged: Instant::now(),
                status: String::new(),
            });
        }
    }

    fn advance(&self, done: u64) {
        let line = self.current.lock().ok().and_then(|mut c| {
            let c = c.as_mut()?;
            c.done += done;
            c.first.get_or_insert((Instant::now(), c.done));
            match &c.bar {
                Some(bar) => {
                    bar.inc(done);
                    None
                }
                None => c.due(),
            }
        });
        if let Some(line) = line {
            eprintln!("{line}");
        }
    }

    fn status(&self, message: &str) {
        let line = self.current.lock().ok().and_then(|mut c| {
            let c = c.as_mut()?;
            c.status = message.to_string();
            match &c.bar {
                Some(bar) => {
                    bar.set_message(format!("{}: {message}", c.name));
                    None
                }
                None => c.due(),
            }
        });
        if let Some(line) = line {
            eprintln!("{line}");
        }
    }

    fn finish(&self) {
        if let Ok(mut c) = self.current.lock() {
            if let Some(bar) = c.take().and_then(|o| o.bar) {
                bar.finish_and_clear();
            }
        }
    }

    fn note(&self, message: &str) {
        if self.verbose {
            self.line(message);
        }
    }

    fn warning(&self, message: &str) {
        self.line(&format!("warning: {message}"));
    }
}

impl Bars {
    /// A line on stderr, above the bar when one is drawn.
    fn line(&self, message: &str) {
        let bar = self
            .current
            .lock()
            .ok()
            .and_then(|c| c.as_ref().and_then(|c| c.bar.clone()));
        match bar {
            Some(bar) => bar.println(message),
            None => eprintln!("{message}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stage(total: Option<u64>, done: u64, seconds: u64, status: &str) -> Current {
        let started = Instant::now() - Duration::from_secs(seconds);
        Current {
            name: "gather".into(),
            bar: None,
            total,
            done,
            started,
            // Counted from the start (no set-up before the first unit).
            first: Some((started, 0)),
            logged: started,
            status: status.into(),
        }
    }

    #[test]
    fn a_log_line_says_how_far_a_stage_is_and_the_time_left() {
        // A quarter done in 30 s: three quarters left at that rate, 90 s.
        assert_eq!(
            stage(Some(200), 50, 30, "").line(),
            "gather: 25 % after 30 s, about 1.5 min left"
        );
        // A stage whose first units came after a minute of set-up, 45 more in the 30 s
        // since: the 150 left at 1.5 a second, 100 s (not the 270 s its whole time gives).
        let mut s = stage(Some(200), 50, 90, "");
        s.first = Some((Instant::now() - Duration::from_secs(30), 5));
        assert_eq!(s.line(), "gather: 25 % after 1.5 min, about 1.7 min left");
        // Its first report alone gives no pace: how far, not the time left.
        s.first = Some((Instant::now(), 50));
        assert_eq!(s.line(), "gather: 25 % after 1.5 min");
        // A stage of unknown length says its status and its time so far.
        assert_eq!(
            stage(None, 0, 20, "sweep 3: residual 1.00e-3").line(),
            "gather: sweep 3: residual 1.00e-3 (20 s so far)"
        );
        // A line is due every LOG_EVERY, not more often.
        let mut s = stage(Some(10), 1, 20, "");
        assert!(s.due().is_some());
        assert!(s.due().is_none());
    }
}
