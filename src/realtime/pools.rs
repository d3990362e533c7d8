//! The threads an image build runs its parallel loops on: a pool of the builds' own,
//! so that building cannot take every core from sampling and the display, and a wider
//! one for while builds on the first cannot keep up with the refresh.
//!
//! A method's build costs a part per new sample and a part per pixel. The live limit
//! of the adaptive method cuts the first; where the second alone takes longer than a
//! refresh period (1280×720 on two cores), cutting samples cannot bring the images
//! back to the refresh rate, and more threads can. They are taken from the sampling
//! threads, so builds widen only where the wider pool can bring them within a period
//! (not at 1920×1080 on two cores, where fewer samples would buy more images but no
//! refresh rate, and a worse image by every score: docs/performance.md, session 37),
//! and narrow again once they are short.

use std::time::Instant;

use super::{
    config::RtConfig,
    shared::{prompt_wakeups, BuildAt, Built, ImageBuilder},
};
use crate::{image::Image, reconstruction::device::ReconUsed};

/// Builds whose mean time decides a change of pool: enough that one slow build (the
/// adaptive reconstructor's restart when the camera stops) does not widen.
pub(crate) const WIDEN_WINDOW: usize = 8;

/// On the wide pool, builds shorter than this share of the refresh period on average
/// go back to the narrow one. A half: the narrow pool has at least half the wide
/// one's threads, so its builds then still fit a period.
pub(crate) const NARROW_BELOW: f64 = 0.5;

/// The share of the wider pool's threads a live build is counted on to gain: on two
/// cores, next to the sampling threads and the controllers, two threads built an image
/// 1.4–1.6× as fast as one (docs/performance.md, session 37), where a build alone
/// gains 1.8–1.9×.
pub(crate) const WIDE_GAIN: f64 = 0.75;

/// Which pool the next build runs on, from the times of the builds before it.
#[derive(Clone, Debug)]
pub(crate) struct Widening {
    period_ms: f64,
    /// How many times faster a build on the wide pool is counted on to be.
    speedup: f64,
    wide: bool,
    recent: Vec<f64>,
    builds: u64,
    wide_builds: u64,
}

impl Widening {
    /// Builds for a display refreshing at `refresh_hz` on `narrow` threads, or `wide`
    /// (more); narrow at first.
    pub fn new(refresh_hz: f64, narrow: usize, wide: usize) -> Self {
        let gained = (wide.saturating_sub(narrow)) as f64 * WIDE_GAIN;
        Self {
            period_ms: 1e3 / refresh_hz,
            speedup: (narrow as f64 + gained) / narrow.max(1) as f64,
            wide: false,
            recent: Vec::with_capacity(WIDEN_WINDOW),
            builds: 0,
            wide_builds: 0,
        }
    }

    /// Whether the next build runs on the wide pool.
    pub fn wide(&self) -> bool {
        self.wide
    }

    /// A build (on the pool [`Widening::wide`] named) took `ms`: over a window of
    /// builds, a mean beyond the period widens, unless even the wide pool's speed-up
    /// would leave it beyond; on the wide pool, a mean below [`NARROW_BELOW`] of the
    /// period narrows again.
    pub fn after(&mut self, ms: f64) {
        self.builds += 1;
        self.wide_builds += self.wide as u64;
        self.recent.push(ms);
        if self.recent.len() < WIDEN_WINDOW {
            return;
        }
        let mean = self.recent.iter().sum::<f64>() / self.recent.len() as f64;
        self.recent.clear();
        if self.wide {
            self.wide = mean >= NARROW_BELOW * self.period_ms;
        } else {
            self.wide = mean > self.period_ms && mean / self.speedup <= self.period_ms;
        }
    }

    /// Share of the builds so far that ran on the wide pool.
    pub fn wide_share(&self) -> f64 {
        self.wide_builds as f64 / self.builds.max(1) as f64
    }
}

/// A builder whose builds run their parallel loops (rayon) on a pool of their own of
/// `config.recon_threads` threads, or of `config.wide_recon_threads` while builds on
/// that pool cannot keep up with the refresh ([`Widening`]); without a pool (it could
/// not be made) they run on the calling thread.
pub(crate) struct Pooled<B> {
    builder: B,
    narrow: Option<rayon::ThreadPool>,
    /// `None` where the wide pool would have no more threads than the narrow one.
    wide: Option<rayon::ThreadPool>,
    widening: Widening,
}

/// A build pool of `threads` threads named after `kind`.
fn pool(threads: usize, kind: &'static str) -> Option<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |i| format!("frameless-{kind}-{i}"))
        .start_handler(|_| prompt_wakeups())
        .build()
        .ok()
}

impl<B: ImageBuilder> Pooled<B> {
    pub fn new(config: &RtConfig, builder: B) -> Self {
        let wider = config.wide_recon_threads > config.recon_threads;
        Self {
            builder,
            narrow: pool(config.recon_threads, "recon"),
            wide: wider
                .then(|| pool(config.wide_recon_threads, "recon-wide"))
                .flatten(),
            widening: Widening::new(
                config.refresh_hz,
                config.recon_threads,
                config.wide_recon_threads,
            ),
        }
    }
}

impl<B: ImageBuilder> ImageBuilder for Pooled<B> {
    fn build(&mut self, at: BuildAt) -> Option<Built> {
        let wide = self.widening.wide().then_some(self.wide.as_ref()).flatten();
        let t0 = Instant::now();
        let built = match wide.or(self.narrow.as_ref()) {
            Some(p) => p.install(|| self.builder.build(at)),
            None => self.builder.build(at),
        };
        if built.is_some() && self.wide.is_some() {
            self.widening.after(t0.elapsed().as_secs_f64() * 1e3);
        }
        built
    }

    fn recycle(&mut self, image: Image) {
        self.builder.recycle(image);
    }

    /// The builder's figures, and `wide_build_share`: the share of its builds that
    /// ran on the wide pool (0 without one).
    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        let mut figures = self.builder.stats();
        figures.push(("wide_build_share", self.widening.wide_share().into()));
        figures
    }

    fn recon(&self) -> ReconUsed {
        self.builder.recon()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Builds of `ms`, one after another, returning whether each next build was to be
    /// wide.
    fn run(w: &mut Widening, ms: &[f64]) -> Vec<bool> {
        ms.iter()
            .map(|&m| {
                w.after(m);
                w.wide()
            })
            .collect()
    }

    #[test]
    fn builds_longer_than_a_period_widen_after_a_window_and_short_ones_narrow() {
        // One thread or two at 30 Hz: two count as 1.75 times as fast.
        let mut w = Widening::new(30.0, 1, 2);
        assert!(!w.wide());
        // 40 ms builds against a 33.3 ms period: wide once a window's mean is known.
        let first = run(&mut w, &[40.0; WIDEN_WINDOW]);
        assert_eq!(first[..WIDEN_WINDOW - 1], [false; WIDEN_WINDOW - 1]);
        assert!(first[WIDEN_WINDOW - 1]);
        // 20 ms on the wide pool: more than half a period, so it stays wide.
        assert!(run(&mut w, &[20.0; WIDEN_WINDOW]).iter().all(|&x| x));
        // 10 ms: less than half, narrow again.
        assert!(!run(&mut w, &[10.0; WIDEN_WINDOW])[WIDEN_WINDOW - 1]);
        assert!(
            (w.wide_share() - 2.0 / 3.0).abs() < 1e-9,
            "{}",
            w.wide_share()
        );
    }

    #[test]
    fn one_slow_build_among_short_ones_does_not_widen() {
        let mut w = Widening::new(60.0, 1, 2);
        let mut ms = [10.0; WIDEN_WINDOW];
        ms[3] = 24.0;
        assert!(run(&mut w, &ms).iter().all(|&x| !x));
        // Builds just within a period stay narrow too.
        assert!(run(&mut w, &[16.0; WIDEN_WINDOW]).iter().all(|&x| !x));
        assert_eq!(w.wide_share(), 0.0);
    }

    #[test]
    fn builds_the_wide_pool_could_not_bring_within_a_period_stay_narrow() {
        // 1.75 times faster: 58 ms builds would still take 33.1 ms, 59 ms ones 33.7.
        let mut w = Widening::new(30.0, 1, 2);
        assert!(run(&mut w, &[59.0; WIDEN_WINDOW]).iter().all(|&x| !x));
        assert!(run(&mut w, &[58.0; WIDEN_WINDOW])[WIDEN_WINDOW - 1]);
        // Four threads against two (half the cores of 8, and all of them): 1.75 too.
        let mut w = Widening::new(30.0, 4, 8);
        assert!(run(&mut w, &[100.0; WIDEN_WINDOW]).iter().all(|&x| !x));
        assert!(run(&mut w, &[50.0; WIDEN_WINDOW])[WIDEN_WINDOW - 1]);
    }

    /// A builder whose builds take `ms` and record the threads they could use.
    struct Slow {
        ms: u64,
        threads: Vec<usize>,
    }

    impl ImageBuilder for Slow {
        fn build(&mut self, _: BuildAt) -> Option<Built> {
            std::thread::sleep(std::time::Duration::from_millis(self.ms));
            self.threads.push(rayon::current_num_threads());
            Some(Built {
                image: Image::new(1, 1),
                mean_age: 0.0,
                overlays: None,
                ages: Vec::new(),
                view_time: 0.0,
            })
        }
    }

    fn slow_builds(fixed: Option<usize>) -> (Vec<usize>, serde_json::Value) {
        let mut config = RtConfig::for_cores(crate::realtime::registry::RtMethod::Adaptive, 4);
        config.refresh_hz = 50.0;
        if let Some(n) = fixed {
            config.fix_recon_threads(n);
        }
        // 25 ms builds against a 20 ms period: the wide pool, twice the threads,
        // counted 1.75 times as fast, brings them within it (with 10 ms to spare for
        // a busy machine's late wake-ups).
        let mut pooled = Pooled::new(
            &config,
            Slow {
                ms: 25,
                threads: Vec::new(),
            },
        );
        let at = BuildAt {
            now: 0.0,
            shown: 0.0,
        };
        for _ in 0..2 * WIDEN_WINDOW {
            pooled.build(at).unwrap();
        }
        let share = pooled
            .stats()
            .into_iter()
            .find(|(k, _)| *k == "wide_build_share");
        (pooled.builder.threads, share.unwrap().1)
    }

    #[test]
    fn slow_builds_move_to_the_wide_pool_unless_the_threads_were_fixed() {
        let (threads, share) = slow_builds(None);
        assert_eq!(threads[..WIDEN_WINDOW], [2; WIDEN_WINDOW]);
        assert_eq!(threads[WIDEN_WINDOW..], [4; WIDEN_WINDOW]);
        assert_eq!(share, 0.5);
        let (threads, share) = slow_builds(Some(2));
        assert!(threads.iter().all(|&n| n == 2), "{threads:?}");
        assert_eq!(share, 0.0);
    }
}
