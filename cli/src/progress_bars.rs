//! The binary's progress display: `indicatif` bars on stderr for the library's long stages
//! ([`radiosity::progress`]), drawn only when stderr is a terminal and `--quiet` is not given,
//! the verbose notes of `-v` and the warnings as they happen (printed above the bar, or
//! plainly when there is none).

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radiosity::progress::{set_observer, Observer};

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
    current: Mutex<Option<(String, ProgressBar)>>,
}

impl Observer for Bars {
    fn start(&self, name: &str, total: Option<u64>) {
        if !self.bars {
            return;
        }
        let bar = match total {
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
        };
        bar.set_message(name.to_string());
        if let Ok(mut c) = self.current.lock() {
            if let Some((_, old)) = c.take() {
                old.finish_and_clear();
            }
            *c = Some((name.to_string(), bar));
        }
    }

    fn advance(&self, done: u64) {
        if let Ok(c) = self.current.lock() {
            if let Some((_, bar)) = c.as_ref() {
                bar.inc(done);
            }
        }
    }

    fn status(&self, message: &str) {
        if let Ok(c) = self.current.lock() {
            if let Some((name, bar)) = c.as_ref() {
                bar.set_message(format!("{name}: {message}"));
            }
        }
    }

    fn finish(&self) {
        if let Ok(mut c) = self.current.lock() {
            if let Some((_, bar)) = c.take() {
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
        match self.current.lock().ok().as_deref() {
            Some(Some((_, bar))) => bar.println(message),
            _ => eprintln!("{message}"),
        }
    }
}
