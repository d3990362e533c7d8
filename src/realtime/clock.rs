//! The real-time clock: scene time advances with the wall clock.

use std::{
    sync::OnceLock,
    time::{Duration, Instant},
};

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

/// A pipeline's clock: a [`WallClock`] whose origin is fixed when the pipeline's first
/// thread starts ([`PipelineClock::begin`]), or at its first reading if that comes
/// first. What a method prepares before starting its threads (a reconstructor backing
/// its buffers with memory) then takes none of the run's time.
#[derive(Debug)]
pub(crate) struct PipelineClock {
    origin: OnceLock<Instant>,
    start: f64,
}

impl PipelineClock {
    /// Scene time `start` at the origin, not yet fixed.
    pub(crate) fn new(start: f64) -> Self {
        Self {
            origin: OnceLock::new(),
            start,
        }
    }

    /// Fix the origin now, unless it is fixed already.
    pub(crate) fn begin(&self) {
        self.origin();
    }

    fn origin(&self) -> Instant {
        *self.origin.get_or_init(Instant::now)
    }

    /// The clock as a [`WallClock`] (fixing its origin if not yet).
    pub(crate) fn wall(&self) -> WallClock {
        WallClock {
            origin: self.origin(),
            start: self.start,
        }
    }

    /// [`WallClock::now`].
    pub(crate) fn now(&self) -> f64 {
        self.wall().now()
    }

    /// [`WallClock::elapsed`].
    pub(crate) fn elapsed(&self) -> f64 {
        self.wall().elapsed()
    }

    /// Scene time at the origin.
    pub(crate) fn start(&self) -> f64 {
        self.start
    }

    /// [`WallClock::instant_at`].
    pub(crate) fn instant_at(&self, s: f64) -> Instant {
        self.wall().instant_at(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pipeline_clock_starts_when_begun_not_when_made() {
        let c = PipelineClock::new(2.0);
        std::thread::sleep(Duration::from_millis(30));
        c.begin();
        let t = c.now();
        assert!((2.0..2.02).contains(&t), "{t}");
        // Begun once: a later call leaves the origin.
        std::thread::sleep(Duration::from_millis(10));
        c.begin();
        assert!(c.elapsed() >= 0.01);
    }
}
