//! The real-time clock: scene time advances with the wall clock.

use std::time::{Duration, Instant};

/// Maps wall-clock instants to scene time (`start` seconds of scene time at `origin`).
#[derive(Clone, Copy, Debug)]
pub struct WallClock {
    origin: Instant,
    start: f64,
}

impl WallClock {
    /// Scene time `start` now.
    pub fn new(start: f64) -> Self {
        Self {
            origin: Instant::now(),
            start,
        }
    }

    /// The scene time now.
    pub fn now(&self) -> f64 {
        self.start + self.origin.elapsed().as_secs_f64()
    }

    /// Wall-clock seconds since the origin.
    pub fn elapsed(&self) -> f64 {
        self.origin.elapsed().as_secs_f64()
    }

    /// The instant `s` wall-clock seconds after the origin.
    pub fn instant_at(&self, s: f64) -> Instant {
        self.origin + Duration::from_secs_f64(s.max(0.0))
    }

    /// Scene time at wall-clock origin.
    pub fn start(&self) -> f64 {
        self.start
    }
}
