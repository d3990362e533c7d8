//! The pipeline: it starts the method's threads, runs the image thread that calls the
//! method's image builder at the display rate, and reports the statistics. It knows no
//! method by name: the registry's [`RtSettings`] starts the method they are the
//! settings of.
//!
//! ```text
//!  method's threads (sampling ×N, adaptive: controller) ──► image thread: the
//!  method's builder at the display rate ──► latest Frame (Arc) ──► display (window /
//!  headless) presents the newest at each refresh, never waiting for one
//! ```

use std::{
    sync::{atomic::Ordering, Arc},
    thread::JoinHandle,
    time::{Duration, Instant},
};

use super::{
    clock::WallClock,
    config::{RealtimeError, RtConfig},
    registry::RtSettings,
    shared::{lock, BuildAt, ImageBuilder, Shared, Spawner},
};
use crate::{reconstruction::device::ReconUsed, trace::Tracer};

pub use super::shared::Frame;

/// Statistics of a pipeline run so far.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PipelineStats {
    /// Method name.
    pub method: &'static str,
    /// Sampling threads.
    pub sampling_threads: usize,
    /// Threads of the reconstructor's pool.
    pub recon_threads: usize,
    /// Other threads of the pipeline (the image thread, and the method's own, such as
    /// the adaptive controller).
    pub other_threads: usize,
    /// Cores the OS reports.
    pub cores: usize,
    /// Wall-clock seconds since the start.
    pub seconds: f64,
    /// Shaded samples delivered (crosshair, initiating, frameless, framed samples).
    pub samples: u64,
    /// `samples / seconds`.
    pub samples_per_s: f64,
    /// Every ray, occlusion rays included (the evaluation's budget unit), per second.
    pub rays_per_s: f64,
    /// Images the image thread produced per second.
    pub images_per_s: f64,
    /// Mean wall time to build one image (drain the input, reconstruct), ms.
    pub reconstruct_ms_mean: f64,
    /// 95th percentile of the same, ms.
    pub reconstruct_ms_p95: f64,
    /// Sampling threads' tracing time per image produced, thread-milliseconds.
    pub sampling_ms_per_image: f64,
    /// Share of the sampling threads' wall time spent tracing.
    pub sampling_busy_share: f64,
    /// Mean over images of their mean information age, seconds.
    pub mean_age_s: f64,
    /// Percentiles of the age of the information on screen, seconds: pixel ages of
    /// every image built, pooled (a subset of pixels per image, read from a histogram
    /// with 6% bins).
    pub age_p50_s: f64,
    /// 95th percentile, as `age_p50_s`.
    pub age_p95_s: f64,
    /// 99th percentile, as `age_p50_s`.
    pub age_p99_s: f64,
    /// Attempts to take a pixel that another thread held.
    pub pixel_conflicts: u64,
    /// Where the method reconstructs its images: `{"device": "cpu", "adapter": null}`,
    /// or the GPU and its adapter.
    pub recon: ReconUsed,
    /// Where the samples were traced: the CPU, or the GPU and its adapter (a method
    /// that cannot trace on the GPU traces on the CPU: `trace_failure` says so).
    pub trace: crate::gpu::DeviceUsed,
    /// Why samples were traced on the CPU although a GPU tracer was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace_failure: Option<String>,
    /// The method's own figures, each named by its method and listed in `stats.json`
    /// beside the figures every method has (the `view` section of `docs/usage.md`
    /// says what each is).
    #[serde(flatten)]
    pub method_stats: std::collections::BTreeMap<&'static str, serde_json::Value>,
}

/// A running pipeline. Dropping it stops and joins its threads.
pub struct Pipeline {
    shared: Arc<Shared>,
    settings: RtSettings,
    handles: Vec<(&'static str, JoinHandle<()>)>,
}

impl Pipeline {
    /// Start the threads of the method `settings` are for; scene time `config.start`
    /// is when the first of them starts (what the method prepares before is not part
    /// of the run).
    pub fn start(
        tracer: Arc<Tracer>,
        config: RtConfig,
        settings: RtSettings,
    ) -> Result<Self, RealtimeError> {
        config.validate()?;
        settings.validate()?;
        let (w, h) = tracer.size();
        settings.check_size(&config, w, h)?;
        let shared = Arc::new(Shared::new(tracer, config));
        let mut handles = Vec::new();
        let mut spawner = Spawner::new(&shared, &mut handles);
        // On an error here the handles go with `p`, whose drop stops and joins them.
        let started = settings.start(&mut spawner);
        let mut p = Pipeline {
            shared,
            settings,
            handles,
        };
        let builder = started?;
        lock(&p.shared.image_stats).recon = Some(builder.recon());
        let s = p.shared.clone();
        Spawner::new(&p.shared, &mut p.handles)
            .spawn("image", move || image_thread(&s, builder))?;
        Ok(p)
    }

    /// The newest image, if any yet.
    pub fn latest(&self) -> Option<Arc<Frame>> {
        lock(&self.shared.latest).clone()
    }

    /// The pipeline's clock.
    pub fn clock(&self) -> WallClock {
        self.shared.clock.wall()
    }

    /// The tracer (set its live camera to move the view).
    pub fn tracer(&self) -> &Arc<Tracer> {
        &self.shared.tracer
    }

    /// The settings every method shares.
    pub fn config(&self) -> &RtConfig {
        &self.shared.config
    }

    /// The method's own settings.
    pub fn settings(&self) -> &RtSettings {
        &self.settings
    }

    /// Statistics so far.
    pub fn stats(&self) -> PipelineStats {
        let s = &self.shared;
        let seconds = s.clock.elapsed().max(1e-9);
        let img = lock(&s.image_stats).clone();
        let samples = s.samples.load(Ordering::Relaxed);
        let busy = s.busy_ns.load(Ordering::Relaxed) as f64 * 1e-9;
        let mean = |v: &[f64]| {
            if v.is_empty() {
                0.0
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let mut sorted = img.build_ms.clone();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let p95 = sorted
            .get(((sorted.len() as f64 - 1.0) * 0.95).max(0.0) as usize)
            .copied()
            .unwrap_or(0.0);
        let cfg = &s.config;
        let method = self.settings.method();
        PipelineStats {
            method: method.name(),
            sampling_threads: cfg.sampling_threads,
            recon_threads: cfg.recon_threads,
            // The image thread and the method's own.
            other_threads: 1 + method.extra_threads(cfg),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            seconds,
            samples,
            samples_per_s: samples as f64 / seconds,
            rays_per_s: s.rays.load(Ordering::Relaxed) as f64 / seconds,
            images_per_s: img.images as f64 / seconds,
            reconstruct_ms_mean: mean(&img.build_ms),
            reconstruct_ms_p95: p95,
            sampling_ms_per_image: if img.images > 0 {
                busy * 1e3 / img.images as f64
            } else {
                0.0
            },
            sampling_busy_share: busy / (seconds * cfg.sampling_threads as f64),
            mean_age_s: mean(&img.ages),
            age_p50_s: img.age_hist.quantile(0.5),
            age_p95_s: img.age_hist.quantile(0.95),
            age_p99_s: img.age_hist.quantile(0.99),
            pixel_conflicts: s.locks.conflicts(),
            recon: img.recon.unwrap_or_else(ReconUsed::cpu),
            trace: crate::trace::batch::used(cfg.rays.as_ref()),
            trace_failure: cfg.rays.as_ref().and_then(|r| r.failure()),
            method_stats: img.method.iter().cloned().collect(),
        }
    }

    /// Stop every thread and wait for them; the final statistics.
    pub fn stop(mut self) -> Result<PipelineStats, RealtimeError> {
        let stats = self.stats();
        self.shared.stop.store(true, Ordering::Relaxed);
        let mut result = Ok(stats);
        for (what, h) in self.handles.drain(..) {
            if h.join().is_err() && result.is_ok() {
                result = Err(RealtimeError::Panicked(what));
            }
        }
        result
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        for (_, h) in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

/// When the image thread starts a build: as late before a refresh as recent builds
/// allow, so that the image is ready when the refresh scans out and shows what was
/// traced until just before it. Starting at the refresh instant itself would put every
/// image on screen a whole period after it was built.
///
/// A build that starts `L` seconds before its refresh and takes longer is shown one
/// refresh later, so an image is on screen `L + period × P(build > L)` after its build
/// started, on average. The lead is the `L` that minimises that over the last few
/// builds (each build's time plus a margin is a candidate, and no lead): for builds of
/// even cost, just above the slowest; for a method whose builds are mostly short and
/// now and then long (`taa` folding a frame), short, letting the long ones miss their
/// refresh; none when builds take longer than the largest lead.
struct Lead {
    /// The last few builds' wall times, seconds.
    recent: [f64; 16],
    next: usize,
    period: f64,
}

impl Lead {
    /// Slack on top of a build's time, seconds: scheduling jitter.
    const MARGIN_S: f64 = 1.5e-3;
    /// The largest lead, as a share of the period: a build slower than that starts at
    /// once after the previous one anyway.
    const MOST: f64 = 0.75;

    fn new(period: f64) -> Self {
        Self {
            recent: [0.0; 16],
            next: 0,
            period,
        }
    }

    /// Seconds before a refresh that a build starts.
    fn seconds(&self) -> f64 {
        let n = self.recent.len() as f64;
        let delay = |lead: f64| {
            let late = self
                .recent
                .iter()
                .filter(|&&b| b + Self::MARGIN_S > lead)
                .count();
            lead + self.period * late as f64 / n
        };
        // No lead at all is a candidate too: when every build is longer than the
        // largest lead, starting early only adds the lead to a refresh that is missed
        // anyway.
        let capped = self
            .recent
            .iter()
            .map(|b| (b + Self::MARGIN_S).min(Self::MOST * self.period));
        std::iter::once(0.0)
            .chain(capped)
            .min_by(|a, b| delay(*a).total_cmp(&delay(*b)))
            .unwrap_or(0.0)
    }

    /// The refresh a build that begins `elapsed` wall seconds into the run is
    /// expected to be done by: after the median of the recent builds and the margin.
    /// A build whose refresh is due sooner is shown at this one instead, and should
    /// show the scene as it will be then.
    fn done_by(&self, elapsed: f64) -> u64 {
        let mut recent = self.recent;
        recent.sort_by(f64::total_cmp);
        let median = recent[recent.len() / 2];
        ((elapsed + median + Self::MARGIN_S) / self.period).ceil() as u64
    }

    fn record(&mut self, build_s: f64) {
        self.recent[self.next] = build_s;
        self.next = (self.next + 1) % self.recent.len();
    }
}

/// Build an image for every display refresh with the method's builder, concurrently
/// with sampling, each started [`Lead`] seconds before its refresh. When building an
/// image takes longer than a refresh period the thread starts the next one at once:
/// images then come at a lower rate, while the display keeps refreshing on time with
/// the newest one.
fn image_thread(s: &Shared, mut builder: Box<dyn ImageBuilder>) {
    let period = 1.0 / s.config.refresh_hz;
    let mut lead = Lead::new(period);
    let mut k: u64 = 1;
    let mut seq = 0;
    while !s.stopped() {
        let ahead = lead.seconds();
        let due = s.clock.instant_at(k as f64 * period - ahead);
        let now = Instant::now();
        if due > now {
            // Sleep in short steps so that a stop request is seen promptly.
            std::thread::sleep((due - now).min(Duration::from_millis(5)));
            continue;
        }
        // This build is for refresh k, or for a later one when the thread woke over half
        // a period late; the next build is for the refresh after.
        k = ((s.clock.elapsed() + ahead) / period).round().max(k as f64) as u64 + 1;
        let t0 = Instant::now();
        let now = s.clock.now();
        // Refresh j is scanned out at scene time `start + j·period`.
        let shown_refresh = lead.done_by(s.clock.elapsed()).max(k - 1);
        let at = BuildAt {
            now,
            shown: now.max(s.clock.start() + shown_refresh as f64 * period),
        };
        let Some(built) = builder.build(at) else {
            continue;
        };
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        lead.record(ms * 1e-3);
        seq += 1;
        let mean_age = built.mean_age;
        let ages = Arc::new(built.ages);
        // The build drains what the threads traced until it runs, so an image can show
        // a view from after `now` (a small frame started and finished meanwhile), and
        // a method that reprojects shows the view of the refresh it is meant for: its
        // time is then that view's, never earlier than what it shows.
        // (`f64::max` keeps `now` where the view time is NaN: no single view.)
        let time = now.max(built.view_time);
        *lock(&s.latest) = Some(Arc::new(Frame {
            seq,
            image: built.image,
            time,
            mean_age,
            overlays: built.overlays,
            ages: ages.clone(),
            view_time: built.view_time,
            began: now,
            published_s: s.clock.elapsed(),
        }));
        let mut st = lock(&s.image_stats);
        st.method = builder.stats();
        st.recon = Some(builder.recon());
        st.images += 1;
        st.build_ms.push(ms);
        st.age_hist.add(&ages);
        if mean_age.is_finite() {
            st.ages.push(mean_age);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Lead;

    fn lead_after(period: f64, builds: &[f64]) -> f64 {
        let mut l = Lead::new(period);
        for &b in builds {
            l.record(b);
        }
        l.seconds()
    }

    #[test]
    fn the_lead_covers_even_builds_and_lets_rare_long_ones_miss() {
        let p = 1.0 / 60.0;
        // Builds of 4–6 ms: start just before the slowest would finish.
        let even: Vec<f64> = (0..16)
            .map(|i| 4e-3 + 2e-3 * (i % 5) as f64 / 4.0)
            .collect();
        assert!((lead_after(p, &even) - (6e-3 + Lead::MARGIN_S)).abs() < 1e-12);
        // Warps of 2 ms and, every fourth refresh, a fold of 12 ms: waiting 13.5 ms
        // for every image would cost more than showing a fold one refresh late.
        let mixed: Vec<f64> = (0..16)
            .map(|i| if i % 4 == 0 { 12e-3 } else { 2e-3 })
            .collect();
        assert!((lead_after(p, &mixed) - (2e-3 + Lead::MARGIN_S)).abs() < 1e-12);
        // Half of them long: covering them is worth it.
        let half: Vec<f64> = (0..16)
            .map(|i| if i % 2 == 0 { 9e-3 } else { 2e-3 })
            .collect();
        assert!((lead_after(p, &half) - (9e-3 + Lead::MARGIN_S)).abs() < 1e-12);
        // Builds up to three quarters of a period are covered; longer ones get no lead:
        // their image would miss its refresh all the same.
        assert!((lead_after(p, &[10e-3; 16]) - (10e-3 + Lead::MARGIN_S)).abs() < 1e-12);
        assert_eq!(lead_after(p, &[14e-3; 16]), 0.0);
        assert_eq!(lead_after(p, &[0.1; 16]), 0.0);
    }

    #[test]
    fn a_build_is_meant_for_the_refresh_it_is_expected_to_be_done_by() {
        let p = 1.0 / 60.0;
        let mut l = Lead::new(p);
        for _ in 0..16 {
            l.record(6e-3);
        }
        // Begun 10 ms before refresh 5: done by it.
        assert_eq!(l.done_by(5.0 * p - 10e-3), 5);
        // Begun 5 ms before it: done 2.5 ms after it, shown at the next.
        assert_eq!(l.done_by(5.0 * p - 5e-3), 6);
        // Builds longer than a period: shown two refreshes on.
        let mut slow = Lead::new(p);
        for _ in 0..16 {
            slow.record(20e-3);
        }
        assert_eq!(slow.done_by(5.0 * p), 7);
        // The median, not the slowest: a rare long build is the one shown late.
        let mut mixed = Lead::new(p);
        for i in 0..16 {
            mixed.record(if i % 4 == 0 { 14e-3 } else { 2e-3 });
        }
        assert_eq!(mixed.done_by(5.0 * p - 5e-3), 5);
    }
}
