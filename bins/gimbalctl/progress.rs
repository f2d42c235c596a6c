//! How far a long command (`scan`) has come, on stderr: a progress bar
//! (indicatif) when stderr is a terminal, otherwise only the plain lines
//! the command prints at its milestones. stdout keeps only the result.

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// Addresses asked out of those planned so far; the plan grows as the
/// command learns more (a GCU found adds its ports' devices).
#[derive(Debug)]
pub struct Progress {
    bar: Option<ProgressBar>,
}

impl Progress {
    /// A bar of `planned` steps on a terminal's stderr, nothing elsewhere.
    pub fn new(planned: u64, unit: &str) -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let style = ProgressStyle::with_template(&format!(
                "{{spinner}} [{{elapsed_precise}}] {{bar:30}} {{pos}}/{{len}} {unit}  {{msg}}"
            ))
            .unwrap_or_else(|_| ProgressStyle::default_bar());
            let bar = ProgressBar::new(planned).with_style(style);
            bar.enable_steady_tick(Duration::from_millis(200));
            bar
        });
        Self { bar }
    }

    /// A milestone line on stderr (above the bar, which stays).
    pub fn line(&self, text: &str) {
        match &self.bar {
            Some(bar) => bar.suspend(|| sagebrush_host::errln!("{text}")),
            None => sagebrush_host::errln!("{text}"),
        }
    }

    /// `more` steps planned besides those known so far.
    pub fn plan(&self, more: u64) {
        if let Some(bar) = &self.bar {
            bar.inc_length(more);
        }
    }

    /// `done` steps taken; `now` says what is being asked.
    pub fn advance(&self, done: u64, now: String) {
        if let Some(bar) = &self.bar {
            bar.inc(done);
            bar.set_message(now);
        }
    }

    /// The bar goes away (before the result is printed).
    pub fn clear(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.clear();
    }
}
