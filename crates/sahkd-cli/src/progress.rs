//! Progress display on stderr, for steps that may take more than a second.
//!
//! Shown only when stderr is a terminal and the user asked for neither `--quiet` nor
//! `--json`; otherwise every bar is hidden and costs nothing.

use indicatif::{ProgressBar, ProgressStyle};
use std::borrow::Cow;
use std::io::IsTerminal;
use std::time::Duration;

const TICK: Duration = Duration::from_millis(100);

#[derive(Clone, Copy, Debug)]
pub struct Progress {
    enabled: bool,
}

impl Progress {
    pub fn new(quiet: bool, json: bool) -> Progress {
        Progress {
            enabled: !quiet && !json && std::io::stderr().is_terminal(),
        }
    }

    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// A spinner for a step of unknown length; call `finish_and_clear` when it is done.
    pub fn spinner(&self, message: impl Into<Cow<'static, str>>) -> ProgressBar {
        if !self.enabled {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new_spinner().with_message(message);
        if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} {elapsed}") {
            bar.set_style(style);
        }
        bar.enable_steady_tick(TICK);
        bar
    }

    /// A bar over `len` items.
    pub fn bar(&self, len: u64, message: impl Into<Cow<'static, str>>) -> ProgressBar {
        if !self.enabled {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new(len).with_message(message);
        if let Ok(style) =
            ProgressStyle::with_template("{msg} [{bar:40}] {human_pos}/{human_len} {elapsed}")
        {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.enable_steady_tick(TICK);
        bar
    }
}
