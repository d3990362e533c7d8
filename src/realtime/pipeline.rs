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
    /// Times per second the sampling threads offered their cores to a waiting thread
    /// (every `SAMPLING_TURN` of work).
    pub sampling_yields_per_s: f64,
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
    /// How far ahead the sampling threads traced a moving view at the end, ms: the
    /// method's smoothed delay from trace to display (0 with `--no-view-ahead`;
    /// [`super::RtConfig::view_ahead`]).
    pub view_ahead_ms: f64,
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
        lock(&self.shared.latest).at(self.shared.clock.elapsed())
    }

    /// Shaded samples delivered to the image thread so far: the run's own progress,
    /// which other processes on the machine slow but do not change the meaning of.
    pub fn samples(&self) -> u64 {
        self.shared.samples.load(Ordering::Relaxed)
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
            sampling_yields_per_s: s.yields.load(Ordering::Relaxed) as f64 / seconds,
            mean_age_s: mean(&img.ages),
            age_p50_s: img.age_hist.quantile(0.5),
            age_p95_s: img.age_hist.quantile(0.95),
            age_p99_s: img.age_hist.quantile(0.99),
            pixel_conflicts: s.locks.conflicts(),
            view_ahead_ms: s.view_ahead.seconds() * 1e3,
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

/// How long before the refresh it is for the image thread starts a build: as short a
/// time as recent builds allow, so that the image is ready when the refresh scans out
/// and shows what was traced until just before it.
///
/// A build that starts `L` seconds before its refresh and takes longer misses it: that
/// refresh shows the previous image again, and the late one is replaced by the next
/// before it is shown. So an image is on screen `L + MISS × period × P(build > L)`
/// after its build started, on average, counting a missed refresh as [`Lead::MISS`]
/// periods (the period it is late and the repeated image). The lead is the `L` that
/// minimises that over the builds of about the last second ([`Lead::window`]; each
/// build's time plus a margin is a candidate, never less than their median): for
/// builds of even cost, just above the slowest; for builds that now and then take much
/// longer, short, letting those miss;
/// up to [`Lead::MOST`] periods, so that builds of uneven cost near a period are
/// started a period early rather than missing often. Builds whose median is longer
/// than a period run back to back instead ([`Schedule::due`]), each for the refresh it
/// is expected to be done by.
struct Lead {
    /// The last [`Lead::window`] builds' wall times, seconds (a ring).
    recent: Vec<f64>,
    next: usize,
    period: f64,
}

impl Lead {
    /// Slack on top of a build's time, seconds: scheduling jitter.
    const MARGIN_S: f64 = super::shared::SCHEDULING_MARGIN.as_secs_f64();
    /// The largest lead where the recent builds' median is shorter, in periods.
    const MOST: f64 = 2.0;
    /// What a missed refresh costs, in periods of delay: more than the period it is
    /// late, for the repeated image is a visible stutter (measured against 2 and 8:
    /// docs/performance.md, session 30).
    const MISS: f64 = 4.0;
    /// The newest builds whose median the lead never starts below
    /// ([`Lead::newest_median`]).
    const NEWEST: usize = 3;
    /// The fewest and most builds it looks back over.
    const FEWEST_BUILDS: usize = 16;
    const MOST_BUILDS: usize = 64;

    fn new(period: f64) -> Self {
        Self {
            recent: vec![0.0; Self::window(period)],
            next: 0,
            period,
        }
    }

    /// Builds it looks back over at refresh period `period`: about a second's. The
    /// share of builds that miss their refresh at a given lead is read off them, and
    /// it is a few percent: over 16 builds (a quarter of a second at 60 Hz) about half
    /// the windows hold none of the slow ones, the lead is then set too short, and the
    /// slow builds that follow miss (measured: docs/performance.md, session 35).
    fn window(period: f64) -> usize {
        let per_second = (1.0 / period).round();
        if per_second.is_nan() {
            return Self::FEWEST_BUILDS;
        }
        per_second.clamp(Self::FEWEST_BUILDS as f64, Self::MOST_BUILDS as f64) as usize
    }

    /// Seconds before the refresh it is for that a build starts.
    fn seconds(&self) -> f64 {
        let n = self.recent.len() as f64;
        let floor = self.median().max(self.newest_median()) + Self::MARGIN_S;
        let most = (Self::MOST * self.period).max(floor);
        let delay = |lead: f64| {
            let late = self
                .recent
                .iter()
                .filter(|&&b| b + Self::MARGIN_S > lead)
                .count();
            lead + Self::MISS * self.period * late as f64 / n
        };
        let candidates = self
            .recent
            .iter()
            .map(|b| (b + Self::MARGIN_S).clamp(floor, most));
        std::iter::once(floor)
            .chain(candidates)
            .min_by(|a, b| delay(*a).total_cmp(&delay(*b)))
            .unwrap_or(floor)
    }

    /// The refresh a build that begins `elapsed` wall seconds into the run is
    /// expected to be done by: after the median of the recent builds. (Not the margin
    /// too: the lead is never less than the median and the margin, so a build the
    /// thread starts a little late, by less than the margin, is still for the refresh
    /// it was due before; with the margin, every fast build woken a few microseconds
    /// late would be for the refresh after, and the one before it would be skipped.)
    /// A build whose refresh is due sooner is shown at this one instead, and should
    /// show the scene as it will be then.
    fn done_by(&self, elapsed: f64) -> u64 {
        ((elapsed + self.median()) / self.period).ceil() as u64
    }

    /// The median of the last [`Lead::NEWEST`] builds' wall times, seconds. Where builds
    /// have just become longer for good (a view that starts to move after holding:
    /// adaptive re-splats its ring instead of carrying its sums), the window's
    /// statistics would take several builds to see it, each of them missing its
    /// refresh and shown a refresh late, a period's motion away from where the view
    /// is (on a fast turn about eight images of FLIP 0.5: docs/performance.md, session
    /// 61); two long builds in a row are enough. A single long build, which the lead
    /// may let miss, does not move it.
    fn newest_median(&self) -> f64 {
        let len = self.recent.len();
        median_of((1..=Self::NEWEST.min(len)).map(|k| self.recent[(self.next + len - k) % len]))
    }

    /// The median of the recent builds' wall times, seconds.
    fn median(&self) -> f64 {
        median_of(self.recent.iter().copied())
    }

    fn record(&mut self, build_s: f64) {
        self.recent[self.next] = build_s;
        self.next = (self.next + 1) % self.recent.len();
    }
}

/// The median of `times` (the upper one of an even count), seconds; never empty here.
fn median_of(times: impl Iterator<Item = f64>) -> f64 {
    let mut sorted: Vec<f64> = times.collect();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

/// When builds start and the refresh each is for: each is due [`Lead`] seconds before
/// the refresh after the last build's, and is for that one or, where it starts late,
/// the one it is expected to be done by. So no two builds are meant for one refresh
/// (the first's work would be lost, and a method that reprojects would see one view
/// twice: a reconstructor that carries its sums while the view holds then restarts
/// them), and a build done early is held until its refresh ([`Newest`]).
///
/// [`Newest`]: super::shared::Newest
struct Schedule {
    /// The refresh the next build is for.
    next: u64,
}

impl Schedule {
    /// Seconds into the run at which the next build is due: [`Lead::seconds`] before
    /// its refresh. Where the recent builds' median is longer than a period, at once
    /// (waiting for a refresh instant would leave the thread idle for most of one),
    /// but not before the refresh of the build before it less a median build: builds
    /// a little shorter than a period, run back to back, would each be done earlier
    /// before its refresh than the last, until images waited more than a period to be
    /// shown.
    fn due(&self, lead: &Lead) -> f64 {
        let median = lead.median();
        if median + Lead::MARGIN_S > lead.period {
            return (self.next as f64 - 1.0) * lead.period - median;
        }
        self.next as f64 * lead.period - lead.seconds()
    }

    /// A build begins `elapsed` seconds into the run: the refresh it is for.
    fn begin(&mut self, lead: &Lead, elapsed: f64) -> u64 {
        let shown = lead.done_by(elapsed).max(self.next);
        self.next = shown + 1;
        shown
    }
}

/// The images the image thread published last, until nothing else holds them: then
/// their buffers go back to the builder ([`ImageBuilder::recycle`]), so that a large
/// image is not allocated and copied anew at every refresh.
#[derive(Default)]
struct Recent(std::collections::VecDeque<Arc<Frame>>);

impl Recent {
    /// Images older than this many are let go, held or not (recorded ones, say).
    const MOST: usize = 4;

    /// Keep `frame`; hand `builder` the oldest image nothing else holds any more.
    fn keep(&mut self, frame: Arc<Frame>, builder: &mut dyn ImageBuilder) {
        self.0.push_back(frame);
        while let Some(oldest) = self.0.pop_front() {
            match Arc::try_unwrap(oldest) {
                Ok(f) => {
                    builder.recycle(f.image);
                    break;
                }
                Err(held) if self.0.len() < Self::MOST => {
                    self.0.push_front(held);
                    break;
                }
                Err(_) => {}
            }
        }
    }
}

/// Build an image for every display refresh with the method's builder, concurrently
/// with sampling, each started [`Lead`] seconds before its refresh. When building an
/// image takes longer than a refresh period the thread starts the next one at once:
/// images then come at a lower rate, while the display keeps refreshing on time with
/// the newest one.
fn image_thread(s: &Shared, mut builder: Box<dyn ImageBuilder>) {
    // It wakes at each build's due time: late by a slice, the build misses its refresh.
    super::shared::prompt_wakeups();
    let period = 1.0 / s.config.refresh_hz;
    let mut lead = Lead::new(period);
    let mut schedule = Schedule { next: 1 };
    let mut seq = 0;
    let mut recent = Recent::default();
    while !s.stopped() {
        let due = s.clock.instant_at(schedule.due(&lead));
        let now = Instant::now();
        if due > now {
            // Sleep in short steps so that a stop request is seen promptly.
            std::thread::sleep((due - now).min(Duration::from_millis(5)));
            continue;
        }
        let t0 = Instant::now();
        let now = s.clock.now();
        // Refresh j is scanned out at scene time `start + j·period`.
        let shown_refresh = schedule.begin(&lead, s.clock.elapsed());
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
        let done_s = s.clock.elapsed();
        let mut published_s = done_s;
        if built.view_time > now {
            // It shows its refresh's view: not before that refresh.
            published_s = published_s.max((shown_refresh as f64 - 0.5) * period);
        }
        let frame = Arc::new(Frame {
            seq,
            image: built.image,
            time,
            mean_age,
            overlays: built.overlays,
            ages: ages.clone(),
            view_time: built.view_time,
            began: now,
            published_s,
        });
        lock(&s.latest).publish(frame.clone(), done_s);
        recent.keep(frame, builder.as_mut());
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
    use super::{Lead, Schedule};

    fn lead_after(period: f64, builds: &[f64]) -> f64 {
        let mut l = Lead::new(period);
        for &b in builds {
            l.record(b);
        }
        l.seconds()
    }

    #[test]
    fn builds_that_became_longer_are_covered_after_two_of_them() {
        let p = 1.0 / 60.0;
        let n = Lead::window(p);
        let mut builds = vec![4e-3; n];
        // One long build: a spike the lead lets miss.
        builds.push(10e-3);
        assert!((lead_after(p, &builds) - (4e-3 + Lead::MARGIN_S)).abs() < 1e-12);
        // A second in a row: builds are longer now (a view that starts to move), and
        // the next starts early enough for one of them, not a second late.
        builds.push(10e-3);
        assert!((lead_after(p, &builds) - (10e-3 + Lead::MARGIN_S)).abs() < 1e-12);
    }

    #[test]
    fn the_lead_covers_builds_unless_few_are_long() {
        let p = 1.0 / 60.0;
        let n = Lead::window(p);
        let covers = |builds: &[f64], b: f64| {
            let lead = lead_after(p, builds);
            assert!(
                (lead - (b + Lead::MARGIN_S)).abs() < 1e-12,
                "{lead} for {b}"
            );
        };
        // Builds of 4–6 ms: start just before the slowest would finish.
        let even: Vec<f64> = (0..n).map(|i| 4e-3 + 2e-3 * (i % 5) as f64 / 4.0).collect();
        covers(&even, 6e-3);
        // Warps of 2 ms and, once in 16 refreshes, a fold of 12 ms: waiting 13.5 ms
        // for every image would cost more than one refresh shown again.
        let rare: Vec<f64> = (0..n)
            .map(|i| if i % 16 == 0 { 12e-3 } else { 2e-3 })
            .collect();
        covers(&rare, 2e-3);
        // A fold every fourth refresh: so many repeated images cost more than the wait.
        let mixed: Vec<f64> = (0..n)
            .map(|i| if i % 4 == 0 { 12e-3 } else { 2e-3 })
            .collect();
        covers(&mixed, 12e-3);
        // Never less than the median.
        let half: Vec<f64> = (0..n)
            .map(|i| if i % 2 == 0 { 9e-3 } else { 2e-3 })
            .collect();
        covers(&half, 9e-3);
        // Builds up to two periods are covered (those over one start before the refresh
        // before theirs), and slower ones get their median and the margin: they run
        // back to back.
        covers(&vec![14e-3; n], 14e-3);
        covers(&vec![25e-3; n], 25e-3);
        covers(&vec![0.1; n], 0.1);
    }

    #[test]
    fn the_lead_looks_back_about_a_second() {
        assert_eq!(Lead::window(1.0 / 60.0), 60);
        assert_eq!(Lead::window(1.0 / 30.0), 30);
        // Bounded both ways, and for any period.
        assert_eq!(Lead::window(1.0 / 240.0), Lead::MOST_BUILDS);
        assert_eq!(Lead::window(1.0 / 5.0), Lead::FEWEST_BUILDS);
        assert_eq!(Lead::window(f64::INFINITY), Lead::FEWEST_BUILDS);
        assert_eq!(Lead::window(0.0), Lead::MOST_BUILDS);
        assert_eq!(Lead::window(f64::NAN), Lead::FEWEST_BUILDS);
        // Nearly a fifth of the builds are slow, all in the first part of the second: the
        // last 16 builds hold none, but the second's share of repeated refreshes
        // still outweighs starting each build earlier, so the lead covers them.
        let p = 1.0 / 60.0;
        let n = Lead::window(p);
        let builds: Vec<f64> = (0..n)
            .map(|i| {
                if i < n - 16 && i % 4 == 0 {
                    12e-3
                } else {
                    2e-3
                }
            })
            .collect();
        let lead = lead_after(p, &builds);
        assert!((lead - (12e-3 + Lead::MARGIN_S)).abs() < 1e-12, "{lead}");
    }

    /// Builds of uneven cost one after another on the image thread's schedule, and
    /// the refreshes that showed a new image (each shows the newest image done by it
    /// that is not meant for a later refresh).
    fn schedule_builds(period: f64, builds: &[f64]) -> (Vec<(u64, f64, f64)>, usize) {
        let mut lead = Lead::new(period);
        let mut schedule = Schedule { next: 1 };
        let mut t = 0.0_f64;
        let mut done = Vec::new();
        for &b in builds {
            t = t.max(schedule.due(&lead));
            let shown = schedule.begin(&lead, t);
            done.push((shown, t, t + b));
            t += b;
            lead.record(b);
        }
        let last = done.last().map_or(0, |d| d.0);
        let mut on_screen = None;
        let mut new_images = 0;
        for j in 1..=last {
            let scan = j as f64 * period;
            let newest = done
                .iter()
                .enumerate()
                .rfind(|(_, (k, _, end))| *end <= scan && *k <= j)
                .map(|(i, _)| i);
            new_images += (newest.is_some() && newest != on_screen) as usize;
            on_screen = newest;
        }
        (done, new_images)
    }

    /// Mostly 8.5–11.5 ms and one in five 13–23 ms, as live builds on two busy cores
    /// (a fixed pseudo-random sequence): the lead moves between covering the builds
    /// and letting them miss the refresh they start before.
    fn uneven_builds(n: usize) -> Vec<f64> {
        let mut x: u64 = 12345;
        (0..n)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (x >> 33) as f64 / (1u64 << 31) as f64;
                if u < 0.8 {
                    8.5e-3 + 3e-3 * u / 0.8
                } else {
                    13e-3 + 10e-3 * (u - 0.8) / 0.2
                }
            })
            .collect()
    }

    #[test]
    fn no_two_builds_are_meant_for_one_refresh() {
        let p = 1.0 / 60.0;
        let builds = uneven_builds(600);
        let slowest = builds.iter().copied().fold(0.0, f64::max);
        let (done, new_images) = schedule_builds(p, &builds);
        for w in done.windows(2) {
            let ((a, _, _), (b, start, _)) = (w[0], w[1]);
            assert!(b > a, "two builds for refresh {b}: {w:?}");
            // Never for a refresh already scanned out when it starts, nor for one so
            // far ahead that its image would wait a period and more.
            assert!(b as f64 * p > start, "{w:?}");
            assert!(
                b as f64 * p - start <= p + slowest + Lead::MARGIN_S,
                "{w:?}"
            );
        }
        // Builds that start early are not lost: at least 91% of refreshes show a new
        // image (a fifth of the builds are long, but most fit a period; letting two
        // builds be for one refresh, 89% do).
        let refreshes = done.last().unwrap().0 as usize;
        assert!(
            new_images * 100 >= refreshes * 91,
            "{new_images} of {refreshes}"
        );
    }

    #[test]
    fn a_thread_woken_a_little_late_skips_no_refresh() {
        let p = 1.0 / 60.0;
        let mut lead = Lead::new(p);
        let mut schedule = Schedule { next: 1 };
        let mut t = 0.0_f64;
        let mut last = 0;
        for i in 0..200 {
            // Builds of 0.2 ms, each begun 0.3 ms after it was due (well within the
            // margin): one for every refresh.
            t = t.max(schedule.due(&lead)) + 0.3e-3;
            let shown = schedule.begin(&lead, t);
            if i > Lead::window(p) {
                assert_eq!(shown, last + 1, "build {i}");
            }
            last = shown;
            t += 0.2e-3;
            lead.record(0.2e-3);
        }
    }

    #[test]
    fn builds_longer_than_a_period_run_back_to_back() {
        let p = 1.0 / 60.0;
        for b in [20e-3, 30e-3, 120e-3] {
            let (done, _) = schedule_builds(p, &[b; 100]);
            // After the lead has seen a window of builds.
            for w in done[Lead::window(p)..].windows(2) {
                // The next starts as the last ends, for a later refresh.
                assert!((w[1].1 - w[0].2).abs() < 1e-12, "{w:?}");
                assert!(w[1].0 > w[0].0);
            }
        }
    }

    #[test]
    fn builds_a_little_shorter_than_a_period_do_not_run_ahead() {
        // 31.3–33.0 ms at 30 Hz: the median and the margin outlast the period, so
        // the builds run back to back, though each is shorter than it.
        let p = 1.0 / 30.0;
        let builds: Vec<f64> = (0..600)
            .map(|i| 31.3e-3 + 1.7e-3 * ((i * 7 % 11) as f64 / 10.0))
            .collect();
        let (done, new_images) = schedule_builds(p, &builds);
        for d in &done[Lead::window(p)..] {
            let (k, _, end) = *d;
            // Done no more than a period (and the spread of the builds) before the
            // refresh it is for, not ever earlier as builds go on.
            assert!(k as f64 * p - end <= 1.1 * p, "{d:?}");
        }
        let refreshes = done.last().unwrap().0 as usize;
        assert!(
            new_images * 100 >= refreshes * 97,
            "{new_images} of {refreshes}"
        );
    }

    #[test]
    fn a_held_image_is_shown_from_its_refresh_on() {
        use crate::realtime::shared::{Frame, Newest};
        use std::sync::Arc;
        let frame = |seq, published_s| {
            Arc::new(Frame {
                seq,
                image: crate::image::Image::new(1, 1),
                time: 0.0,
                mean_age: 0.0,
                overlays: None,
                ages: Arc::new(Vec::new()),
                view_time: 0.0,
                began: 0.0,
                published_s,
            })
        };
        let mut n = Newest::default();
        n.publish(frame(1, 0.010), 0.010);
        // Done at 0.012 for a refresh from 0.025 on: the first stays on screen till then.
        n.publish(frame(2, 0.025), 0.012);
        assert_eq!(n.at(0.020).map(|f| f.seq), Some(1));
        assert_eq!(n.at(0.025).map(|f| f.seq), Some(2));
        assert_eq!(n.at(0.030).map(|f| f.seq), Some(2));
        // Two done before the first of them is shown: each is shown at its refresh.
        n.publish(frame(3, 0.045), 0.031);
        n.publish(frame(4, 0.062), 0.040);
        assert_eq!(n.at(0.044).map(|f| f.seq), Some(2));
        assert_eq!(n.at(0.050).map(|f| f.seq), Some(3));
        assert_eq!(n.at(0.062).map(|f| f.seq), Some(4));
        // One shown at once replaces those still held.
        n.publish(frame(5, 0.080), 0.070);
        n.publish(frame(6, 0.071), 0.071);
        assert_eq!(n.at(0.090).map(|f| f.seq), Some(6));
    }

    #[test]
    fn a_build_is_meant_for_the_refresh_it_is_expected_to_be_done_by() {
        let p = 1.0 / 60.0;
        let mut l = Lead::new(p);
        for _ in 0..Lead::window(p) {
            l.record(6e-3);
        }
        // Begun 10 ms before refresh 5: done by it.
        assert_eq!(l.done_by(5.0 * p - 10e-3), 5);
        // Begun 5 ms before it: done 2.5 ms after it, shown at the next.
        assert_eq!(l.done_by(5.0 * p - 5e-3), 6);
        // Builds longer than a period: shown two refreshes on.
        let mut slow = Lead::new(p);
        for _ in 0..Lead::window(p) {
            slow.record(20e-3);
        }
        assert_eq!(slow.done_by(5.0 * p), 7);
        // The median, not the slowest: a rare long build is the one shown late.
        let mut mixed = Lead::new(p);
        for i in 0..Lead::window(p) {
            mixed.record(if i % 4 == 0 { 14e-3 } else { 2e-3 });
        }
        assert_eq!(mixed.done_by(5.0 * p - 5e-3), 5);
    }
}
