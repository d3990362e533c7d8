//! Progress of long work: a bar when stderr is a terminal; otherwise (a log file, CI, a
//! pipe) a line every few seconds, so that a long run is never silent there.
//!
//! The remaining time is the elapsed time scaled by the work left over the work done.
//! That is fair because callers count work in units of about even cost (an evaluation
//! counts rays); a rate averaged over the last few seconds, indicatif's own estimate,
//! swings with every change between cheap and costly phases.

use std::{
    io::IsTerminal,
    sync::Mutex,
    time::{Duration, Instant},
};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};

/// How often a line is printed when stderr is not a terminal.
const LINE_EVERY: Duration = Duration::from_secs(5);

/// Progress of one piece of work, counted in `unit`s.
pub struct Meter {
    what: String,
    unit: &'static str,
    /// The bar, when stderr is a terminal; hidden until the total is known, so that it
    /// never shows an empty `0/0` as full.
    bar: Option<ProgressBar>,
    lines: Mutex<Lines>,
}

struct Lines {
    total: u64,
    done: u64,
    started: Instant,
    last: Instant,
    msg: String,
}

impl Meter {
    /// A meter of `what` (printed first), counting `unit`s; shows nothing until
    /// [`Meter::set_total`].
    pub fn new(what: &str, unit: &'static str) -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
            bar.set_style(
                ProgressStyle::with_template(
                    "{prefix} {msg:22} [{bar:32}] {percent:>3}%  {elapsed} elapsed, {left} left",
                )
                .expect("static template")
                .with_key("left", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                    let left = remaining(s.elapsed(), s.pos(), s.len().unwrap_or(0));
                    let _ = w.write_str(&left.map_or("?".into(), clock));
                })
                .progress_chars("=> "),
            );
            bar.set_prefix(what.to_string());
            bar
        });
        let now = Instant::now();
        Self {
            what: what.to_string(),
            unit,
            bar,
            lines: Mutex::new(Lines {
                total: 0,
                done: 0,
                started: now,
                last: now,
                msg: String::new(),
            }),
        }
    }

    /// A spinner for work of unknown length (on a terminal; a line elsewhere).
    pub fn spinner(what: &str) -> Spinner {
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new_spinner().with_message(what.to_string());
            bar.enable_steady_tick(Duration::from_millis(120));
            Spinner(Some(bar))
        } else {
            eprintln!("{what}");
            Spinner(None)
        }
    }

    /// The total amount of work, in units; the bar appears (or the first line is
    /// printed) now.
    pub fn set_total(&self, total: u64) {
        let mut l = self.lines.lock().unwrap_or_else(|e| e.into_inner());
        l.total = total;
        l.started = Instant::now();
        l.last = l.started;
        if let Some(bar) = &self.bar {
            bar.set_length(total);
            bar.reset_elapsed();
            bar.set_draw_target(ProgressDrawTarget::stderr());
        } else {
            eprintln!("{}: {} {}", self.what, human(total), self.unit);
        }
    }

    /// `n` more units done, working on `msg`.
    pub fn advance(&self, msg: &str, n: u64) {
        let mut l = self.lines.lock().unwrap_or_else(|e| e.into_inner());
        l.done += n;
        if l.msg != msg {
            l.msg = msg.to_string();
            if let Some(bar) = &self.bar {
                bar.set_message(msg.to_string());
            }
        }
        if let Some(bar) = &self.bar {
            bar.set_position(l.done);
        } else {
            self.line(&mut l);
        }
    }

    /// One more unit done.
    pub fn inc(&self, n: u64) {
        let msg = self.lines.lock().map(|l| l.msg.clone()).unwrap_or_default();
        self.advance(&msg, n);
    }

    /// Units done so far, `done` in all.
    pub fn set_position(&self, done: u64) {
        let mut l = self.lines.lock().unwrap_or_else(|e| e.into_inner());
        l.done = done;
        if let Some(bar) = &self.bar {
            bar.set_position(done);
        } else {
            self.line(&mut l);
        }
    }

    /// Remove the bar; elsewhere print how long it took.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        } else {
            let l = self.lines.lock().unwrap_or_else(|e| e.into_inner());
            eprintln!("{}: done in {}", self.what, clock(l.started.elapsed()));
        }
    }

    /// Print a line if the last was long enough ago.
    fn line(&self, l: &mut Lines) {
        let now = Instant::now();
        if now.duration_since(l.last) < LINE_EVERY {
            return;
        }
        l.last = now;
        let elapsed = now.duration_since(l.started);
        let pct = if l.total > 0 {
            100.0 * l.done as f64 / l.total as f64
        } else {
            0.0
        };
        let left = remaining(elapsed, l.done, l.total)
            .map_or(String::new(), |d| format!(", about {} left", clock(d)));
        eprintln!(
            "{}: {pct:.0}% ({} of {} {}), {} elapsed{left}{}",
            self.what,
            human(l.done),
            human(l.total),
            self.unit,
            clock(elapsed),
            if l.msg.is_empty() {
                String::new()
            } else {
                format!("; {}", l.msg)
            }
        );
    }
}

impl frameless::evaluation::Progress for Meter {
    fn total(&self, n: u64) {
        self.set_total(n);
    }
    fn advance(&self, msg: &str, n: u64) {
        Meter::advance(self, msg, n);
    }
    fn warn(&self, msg: &str) {
        match &self.bar {
            Some(bar) => bar.suspend(|| eprintln!("warning: {msg}")),
            None => eprintln!("warning: {msg}"),
        }
    }
}

/// A spinner that [`Spinner::finish`] removes.
pub struct Spinner(Option<ProgressBar>);

impl Spinner {
    /// Remove it.
    pub fn finish(self) {
        if let Some(bar) = self.0 {
            bar.finish_and_clear();
        }
    }
}

/// Time left if the rest goes at the average pace so far; unknown before any work.
fn remaining(elapsed: Duration, done: u64, total: u64) -> Option<Duration> {
    if done == 0 || total == 0 {
        return None;
    }
    let left = total.saturating_sub(done) as f64 / done as f64;
    Some(elapsed.mul_f64(left.min(1e6)))
}

/// `42s`, `3m 05s`, `1h 02m`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    match s {
        0..60 => format!("{s}s"),
        60..3600 => format!("{}m {:02}s", s / 60, s % 60),
        _ => format!("{}h {:02}m", s / 3600, (s % 3600) / 60),
    }
}

/// `950`, `12.3K`, `27M`, `1.2G`.
fn human(n: u64) -> String {
    let v = n as f64;
    match n {
        0..1_000 => n.to_string(),
        1_000..1_000_000 => format!("{:.1}K", v / 1e3),
        1_000_000..1_000_000_000 => format!("{:.1}M", v / 1e6),
        _ => format!("{:.1}G", v / 1e9),
    }
    .replace(".0", "")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remaining_scales_elapsed_by_work_left() {
        let d = remaining(Duration::from_secs(10), 25, 100).unwrap();
        assert_eq!(d, Duration::from_secs(30));
        assert_eq!(remaining(Duration::from_secs(10), 0, 100), None);
        assert_eq!(
            remaining(Duration::from_secs(10), 100, 100),
            Some(Duration::ZERO)
        );
    }

    #[test]
    fn readable_numbers_and_times() {
        assert_eq!(clock(Duration::from_secs(42)), "42s");
        assert_eq!(clock(Duration::from_secs(185)), "3m 05s");
        assert_eq!(clock(Duration::from_secs(3720)), "1h 02m");
        assert_eq!(human(950), "950");
        assert_eq!(human(12_345), "12.3K");
        assert_eq!(human(27_000_000), "27M");
    }
}
