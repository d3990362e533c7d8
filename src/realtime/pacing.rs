//! Display pacing: refresh on a fixed grid of wall-clock instants whatever the image
//! thread is doing, and measure how well that held.

use std::time::Instant;

use super::clock::WallClock;

/// The display's refresh schedule and what it showed.
pub struct Pacer {
    clock: WallClock,
    period: f64,
    k: u64,
    presents: u64,
    distinct: u64,
    last_seq: u64,
    late: u64,
    late_sum_ms: f64,
    max_late_ms: f64,
}

/// How the display kept time.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct DisplayStats {
    /// Target refresh rate, Hz.
    pub refresh_hz: f64,
    /// Refreshes per second achieved.
    pub present_hz: f64,
    /// New images shown per second (a refresh that shows the same image again does not
    /// count): the frame rate a viewer sees.
    pub display_fps: f64,
    /// Refreshes more than half a period late.
    pub late_refreshes: u64,
    /// Mean lateness of refreshes, ms.
    pub mean_late_ms: f64,
    /// Worst lateness, ms.
    pub max_late_ms: f64,
}

impl Pacer {
    /// Refresh at `hz` on `clock`'s grid.
    pub fn new(clock: WallClock, hz: f64) -> Self {
        Self {
            clock,
            period: 1.0 / hz,
            k: 1,
            presents: 0,
            distinct: 0,
            last_seq: 0,
            late: 0,
            late_sum_ms: 0.0,
            max_late_ms: 0.0,
        }
    }

    /// When the next refresh is due.
    pub fn next_due(&self) -> Instant {
        self.clock.instant_at(self.k as f64 * self.period)
    }

    /// Whether the next refresh is due now.
    pub fn due(&self) -> bool {
        Instant::now() >= self.next_due()
    }

    /// Sleep until the next refresh is due.
    pub fn wait(&self) {
        let due = self.next_due();
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
    }

    /// Count a refresh happening now that shows image `seq` (0: nothing yet). A
    /// refresh missed entirely is skipped, not made up.
    pub fn present(&mut self, seq: u64) {
        let late = (Instant::now() - self.next_due().min(Instant::now())).as_secs_f64();
        let late_ms = late * 1e3;
        self.late_sum_ms += late_ms;
        self.max_late_ms = self.max_late_ms.max(late_ms);
        if late > 0.5 * self.period {
            self.late += 1;
        }
        self.presents += 1;
        if seq != self.last_seq && seq != 0 {
            self.distinct += 1;
            self.last_seq = seq;
        }
        self.k = (self.clock.elapsed() / self.period).floor() as u64 + 1;
    }

    /// New images shown so far.
    pub fn images_shown(&self) -> u64 {
        self.distinct
    }

    /// Statistics over `seconds` of display.
    pub fn stats(&self, seconds: f64) -> DisplayStats {
        let s = seconds.max(1e-9);
        DisplayStats {
            refresh_hz: 1.0 / self.period,
            present_hz: self.presents as f64 / s,
            display_fps: self.distinct as f64 / s,
            late_refreshes: self.late,
            mean_late_ms: if self.presents > 0 {
                self.late_sum_ms / self.presents as f64
            } else {
                0.0
            },
            max_late_ms: self.max_late_ms,
        }
    }
}
