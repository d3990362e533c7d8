//! What every thread of one pipeline shares, and the interface between the generic
//! pipeline and a real-time method.
//!
//! A method is a static [`MethodInfo`] in its own file. The pipeline gives its `start`
//! a [`Spawner`]; the method starts its sampling threads (and any others it needs)
//! through it, keeping whatever state only it uses in its own types, and returns an
//! [`ImageBuilder`] that the pipeline's image thread calls at the display rate. This
//! file knows no method and no pipeline, so both can depend on it.

use std::{
    sync::{
        atomic::{AtomicBool, AtomicU64, Ordering},
        Arc, Mutex,
    },
    thread::JoinHandle,
    time::{Duration, Instant},
};

use super::{
    clock::PipelineClock,
    config::{RealtimeError, RtConfig},
    pixel_locks::PixelLocks,
};
use crate::{
    image::Image,
    reconstruction::device::{GpuContext, ReconUsed},
    trace::Tracer,
};

/// Longest a sampling thread holds a batch before it sends it, seconds: long enough
/// that channel traffic stays small next to tracing, short next to a refresh.
pub(crate) const BATCH_S: f64 = 1e-3;

/// What a builder's channel holds now, and no more: samples sent while an image is
/// built wait for the next one. Draining until the channel is empty instead never ends
/// while the senders outpace the builder, as a GPU tracer's feeders do (session 26: one
/// image in two seconds at 1920x1080 with 53 M samples/s).
pub(crate) fn take_queued<T>(rx: &crossbeam_channel::Receiver<T>) -> impl Iterator<Item = T> + '_ {
    let queued = rx.len();
    rx.try_iter().take(queued)
}

/// One displayed image.
pub struct Frame {
    /// Increases with every new image.
    pub seq: u64,
    /// Linear RGB.
    pub image: Image,
    /// Scene time it shows.
    pub time: f64,
    /// Mean age of the information in it, seconds.
    pub mean_age: f64,
    /// What draws the method's overlays of it
    /// ([`RtMethod::overlays`](super::registry::RtMethod::overlays)), if it offers any.
    pub overlays: Option<Arc<dyn Overlays>>,
    /// Ages of the information in an evenly spaced subset of its pixels, seconds (NaN:
    /// none yet), for latency percentiles and for telling when a change shows.
    pub ages: Arc<Vec<f32>>,
    /// Scene time of the camera it shows the scene from (NaN: no single camera).
    pub view_time: f64,
    /// Scene time its build began: it knows nothing that happened after. A method
    /// that reprojects shows the scene as it will be at the refresh the image is
    /// meant for (`time`, `view_time`), later than this (`BuildAt`).
    pub began: f64,
    /// Wall-clock seconds since the pipeline started from which it is the newest image
    /// (when it was done, or half a period before the refresh it is meant for if it
    /// was done earlier and shows that refresh's view): a display refresh due before
    /// then still showed the previous one.
    pub published_s: f64,
}

/// The image on screen, and those built for later refreshes, each held until its
/// refresh is near: an image that reprojects to the refresh it is meant for and is
/// done early would otherwise be shown a period early and take the place of the one
/// before it. Every held image is shown in turn, so that an image done before the one
/// ahead of it was shown is not lost (that refresh would show the old image again).
#[derive(Default)]
pub struct Newest {
    shown: Option<Arc<Frame>>,
    /// In the order they were published, which is the order of their refreshes.
    held: std::collections::VecDeque<Arc<Frame>>,
}

impl Newest {
    /// The image to show `now_s` wall seconds into the run.
    pub fn at(&mut self, now_s: f64) -> Option<Arc<Frame>> {
        while self.held.front().is_some_and(|f| f.published_s <= now_s) {
            self.shown = self.held.pop_front();
        }
        self.shown.clone()
    }

    /// A new image, `now_s` wall seconds into the run, shown from its `published_s`.
    pub fn publish(&mut self, frame: Arc<Frame>, now_s: f64) {
        self.at(now_s);
        if frame.published_s <= now_s {
            // Newer than any held: they are replaced.
            self.held.clear();
            self.shown = Some(frame);
        } else {
            self.held.push_back(frame);
        }
    }
}

/// Most pixels whose ages an image reports: enough for percentiles to a fraction of a
/// percent, few enough to copy at every refresh of a large display.
pub(crate) const AGE_SAMPLES: usize = 4096;

/// The ages of an evenly spaced subset of `n` pixels (at most [`AGE_SAMPLES`]).
pub(crate) fn sampled_ages(n: usize, age: impl Fn(usize) -> f32) -> Vec<f32> {
    let stride = n.div_ceil(AGE_SAMPLES).max(1);
    (0..n).step_by(stride).map(age).collect()
}

/// A histogram of information ages on log-spaced bins (0.1 ms to 100 s, 40 bins per
/// decade, so a percentile read from it is within 6% of the exact one): a run of any
/// length keeps every displayed pixel age in fixed memory.
#[derive(Clone, Debug)]
pub(crate) struct AgeHistogram {
    bins: Vec<u64>,
}

impl AgeHistogram {
    const LO: f64 = 1e-4;
    const PER_DECADE: f64 = 40.0;
    const BINS: usize = 240;

    fn bin(age: f64) -> usize {
        let b = ((age.max(Self::LO) / Self::LO).log10() * Self::PER_DECADE) as usize;
        b.min(Self::BINS - 1)
    }

    /// Count the finite ages.
    pub fn add(&mut self, ages: &[f32]) {
        for &a in ages.iter().filter(|a| a.is_finite()) {
            self.bins[Self::bin(a as f64)] += 1;
        }
    }

    /// The `q`-quantile (0–1), seconds, at its bin's geometric centre; 0 when empty.
    pub fn quantile(&self, q: f64) -> f64 {
        let total: u64 = self.bins.iter().sum();
        if total == 0 {
            return 0.0;
        }
        let want = (q.clamp(0.0, 1.0) * total as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (b, &c) in self.bins.iter().enumerate() {
            seen += c;
            if seen >= want {
                return Self::LO * 10f64.powf((b as f64 + 0.5) / Self::PER_DECADE);
            }
        }
        Self::LO * 10f64.powf(Self::BINS as f64 / Self::PER_DECADE)
    }
}

impl Default for AgeHistogram {
    fn default() -> Self {
        Self {
            bins: vec![0; Self::BINS],
        }
    }
}

/// The `q`-quantile of the finite values (exact; for one image's few thousand ages).
pub(crate) fn quantile_of(values: &[f32], q: f64) -> f64 {
    let mut v: Vec<f32> = values.iter().copied().filter(|a| a.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    let k = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    let (_, x, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    *x as f64
}

/// A lock that survives a panicking holder: the data are plain values, always valid.
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// State shared by every thread of one pipeline, whatever the method.
pub(crate) struct Shared {
    pub tracer: Arc<Tracer>,
    pub clock: PipelineClock,
    pub config: RtConfig,
    pub stop: AtomicBool,
    pub locks: PixelLocks,
    /// Shaded samples delivered to the image thread's input.
    pub samples: AtomicU64,
    /// Every ray traced (samples plus occlusion rays).
    pub rays: AtomicU64,
    /// Nanoseconds sampling threads spent tracing (summed over threads).
    pub busy_ns: AtomicU64,
    pub latest: Mutex<Newest>,
    pub image_stats: Mutex<ImageThreadStats>,
    /// Times sampling threads gave up their core ([`Turns`]).
    pub yields: AtomicU64,
    /// How far ahead the sampling threads trace a moving view.
    pub view_ahead: ViewAhead,
}

/// How far ahead of now the sampling threads trace a moving view
/// ([`RtConfig::view_ahead`]): the smoothed delay, over about the last eight images,
/// from the trace of what an image shows to its refresh, as the method's image thread
/// measures it. One writer (the image thread), any number of readers.
pub(crate) struct ViewAhead {
    on: bool,
    /// The refresh period, seconds.
    period: f64,
    /// Seconds as `f64` bits; 0 until the first image.
    bits: AtomicU64,
}

/// The weight of an image's delay in [`ViewAhead`]'s smoothed one: about the last
/// eight images, so that one late build does not swing the view traced.
const VIEW_AHEAD_SMOOTHING: f64 = 0.125;

impl ViewAhead {
    pub fn new(on: bool, refresh_hz: f64) -> Self {
        Self {
            on,
            period: 1.0 / refresh_hz,
            bits: AtomicU64::new(0f64.to_bits()),
        }
    }

    /// Seconds ahead to trace the view now (0 when off, and before the first image).
    pub fn seconds(&self) -> f64 {
        f64::from_bits(self.bits.load(Ordering::Relaxed))
    }

    /// An image was shown `delay` seconds after what it shows was traced (a NaN or
    /// negative delay is left out).
    pub fn shown_after(&self, delay: f64) {
        if !self.on || delay.is_nan() || delay < 0.0 {
            return;
        }
        let now = self.seconds();
        let next = if now > 0.0 {
            now + VIEW_AHEAD_SMOOTHING * (delay - now)
        } else {
            delay
        };
        self.bits.store(next.to_bits(), Ordering::Relaxed);
    }

    /// An image built from the samples in hand when its build began, `lead` seconds
    /// before its refresh, was shown: each sample is first shown by the first build
    /// that begins after its trace, and was traced on average half a refresh before it.
    pub fn build_led_by(&self, lead: f64) {
        self.shown_after(lead + 0.5 * self.period);
    }
}

impl Shared {
    /// Count `n` shaded samples (one ray each) that a sampling thread traced in `busy`
    /// and delivered.
    pub fn traced(&self, n: u64, busy: std::time::Duration) {
        self.samples.fetch_add(n, Ordering::Relaxed);
        self.rays.fetch_add(n, Ordering::Relaxed);
        self.busy_ns
            .fetch_add(busy.as_nanos() as u64, Ordering::Relaxed);
    }

    /// Nothing running yet; scene time `config.start` will be when the first thread
    /// starts.
    pub fn new(tracer: Arc<Tracer>, config: RtConfig) -> Self {
        let (w, h) = tracer.size();
        let view_ahead = ViewAhead::new(config.view_ahead, config.refresh_hz);
        Self {
            clock: PipelineClock::new(config.start),
            locks: PixelLocks::new(w, h),
            tracer,
            config,
            stop: AtomicBool::new(false),
            samples: AtomicU64::new(0),
            rays: AtomicU64::new(0),
            busy_ns: AtomicU64::new(0),
            latest: Mutex::new(Newest::default()),
            image_stats: Mutex::new(ImageThreadStats::default()),
            yields: AtomicU64::new(0),
            view_ahead,
        }
    }

    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// What the image thread measured.
#[derive(Clone, Debug, Default)]
pub(crate) struct ImageThreadStats {
    pub images: u64,
    pub build_ms: Vec<f64>,
    pub ages: Vec<f64>,
    /// Pixel ages of every image built, pooled.
    pub age_hist: AgeHistogram,
    /// The method's own figures after its newest image ([`ImageBuilder::stats`]).
    pub method: Vec<(&'static str, serde_json::Value)>,
    /// Where its images are reconstructed ([`ImageBuilder::recon`]; `None`: not yet
    /// known, the CPU).
    pub recon: Option<ReconUsed>,
}

/// An image a method built for the display.
pub(crate) struct Built {
    /// Linear RGB.
    pub image: Image,
    /// Mean age of the information in it, seconds (NaN: nothing in it yet).
    pub mean_age: f64,
    /// What draws the method's overlays of it, if it offers any.
    pub overlays: Option<Arc<dyn Overlays>>,
    /// Ages of a subset of its pixels ([`sampled_ages`]).
    pub ages: Vec<f32>,
    /// Scene time of the camera it shows the scene from (NaN: each pixel from the
    /// camera of its own sample, as traditional frameless shows it). A method that
    /// reprojects to [`BuildAt::shown`] measures its ages from that time too.
    pub view_time: f64,
}

/// When an image is built and when it will be seen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct BuildAt {
    /// Scene time the build begins: the samples it drains were traced before.
    pub now: f64,
    /// Scene time of the refresh the image is expected to be shown at first (not
    /// before `now`). A method that reprojects what it holds (adaptive, the warps)
    /// shows the scene as it will be then, not as it was when the build began: the
    /// scene's animation and a scripted camera are known ahead, and a camera a person
    /// steers is the one last set (nothing of their input is predicted). Built at
    /// `now`, an image would show the view a build time and more out of date.
    pub shown: f64,
}

/// A method's side of the image thread: it drains what the method's threads sent and
/// builds the image for the display ([`BuildAt`]). `None`: nothing to show yet.
pub(crate) trait ImageBuilder: Send {
    fn build(&mut self, at: BuildAt) -> Option<Built>;

    /// One of its images that nothing shows or holds any more: its buffer, for a
    /// later image to be built in instead of a new one (ignored unless the method
    /// can use it).
    fn recycle(&mut self, _image: Image) {}

    /// The method's own figures so far, by the names the pipeline statistics give
    /// them (beside the figures every method has).
    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        Vec::new()
    }

    /// Where it reconstructs its images: the CPU unless the method runs a
    /// reconstructor on the GPU.
    fn recon(&self) -> ReconUsed {
        ReconUsed::cpu()
    }
}

/// An image a method offers besides the displayed one (the adaptive method's tiling,
/// say), which the viewer cycles through.
#[derive(Debug, PartialEq, Eq)]
pub struct Overlay {
    /// Its name (`--vis`, the title bar).
    pub name: &'static str,
    /// The name with its colour key, for the title bar.
    pub key: &'static str,
}

/// Draws a method's overlays of one image.
pub trait Overlays: Send + Sync {
    /// The overlay named `name` of `image` (`None`: not one of the method's).
    fn draw(&self, name: &str, image: &Image) -> Option<Image>;
}

/// A method's own settings: their range checks, and where they take a GPU.
pub trait MethodSettings: Clone + std::fmt::Debug + Default + Send + Sync + 'static {
    /// Check ranges.
    fn validate(&self) -> Result<(), RealtimeError> {
        Ok(())
    }

    /// Take the GPU its reconstruction may run on (`None`: the CPU); a method that
    /// reconstructs nothing ignores it.
    fn use_gpu(&mut self, _gpu: Option<Arc<GpuContext>>) {}
}

/// The settings of a method that has none of its own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoSettings;

impl MethodSettings for NoSettings {}

/// The description of one real-time method, a `const` in the method's own file that
/// the registry maps its [`RtMethod`](super::registry::RtMethod) variant to; `S`, its
/// own settings.
pub(crate) struct MethodInfo<S: 'static = NoSettings> {
    /// Command-line name.
    pub name: &'static str,
    /// One line for help texts.
    pub about: &'static str,
    /// Default sampling threads on a machine with this many cores.
    pub default_sampling_threads: fn(usize) -> usize,
    /// Threads it runs besides its sampling threads and the pipeline's image thread,
    /// given the run's settings (its sampling threads, whether it traces on a GPU).
    pub extra_threads: fn(&RtConfig) -> usize,
    /// The images it offers besides the displayed one ([`Built::overlays`] draws them).
    pub overlays: &'static [Overlay],
    /// Whether its sampling traces on the GPU tracer when the run has one
    /// ([`RtConfig::rays`]); a method that cannot refuses such a run.
    pub traces_on_gpu: bool,
    /// Check that a `width × height` display fits the run budgets with its buffers
    /// under `config` and its settings ([`display_only`] for a method with no buffer
    /// beyond the image).
    pub check_size: fn(&RtConfig, &S, u32, u32) -> Result<(), crate::limits::LimitError>,
    /// Start its threads with its settings; the image thread then calls the builder it
    /// returns.
    pub start: Start<S>,
}

/// How a method with settings `S` starts ([`MethodInfo::start`]).
pub(crate) type Start<S> = fn(&mut Spawner<'_>, &S) -> Result<Box<dyn ImageBuilder>, RealtimeError>;

/// What a framed method shows at a refresh: its newest image as built, or that image
/// warped to the camera of the refresh (the late warps).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Shown {
    /// The newest image as built.
    AsBuilt,
    /// The newest image reprojected to the camera at every refresh.
    Warped,
}

/// [`MethodInfo::check_size`] of a method whose per-pixel state is the display's.
pub(crate) fn display_only<S>(
    _: &RtConfig,
    _: &S,
    width: u32,
    height: u32,
) -> Result<(), crate::limits::LimitError> {
    crate::limits::check_display(width, height)
}

/// What a method starts its threads with: the shared state, and a place for the
/// handles that the pipeline joins when it stops.
pub(crate) struct Spawner<'a> {
    shared: &'a Arc<Shared>,
    handles: &'a mut Vec<(&'static str, JoinHandle<()>)>,
}

impl<'a> Spawner<'a> {
    pub fn new(
        shared: &'a Arc<Shared>,
        handles: &'a mut Vec<(&'static str, JoinHandle<()>)>,
    ) -> Self {
        Self { shared, handles }
    }

    pub fn shared(&self) -> &Arc<Shared> {
        self.shared
    }

    /// Start a thread named `frameless-{what}`. When that fails every thread started
    /// so far is told to stop, so that the pipeline can join them.
    pub fn spawn(
        &mut self,
        what: &'static str,
        f: impl FnOnce() + Send + 'static,
    ) -> Result<(), RealtimeError> {
        // The run's time starts with its first thread: what the method did before
        // (allocating, backing buffers with memory) is not part of it.
        self.shared.clock.begin();
        let h = std::thread::Builder::new()
            .name(format!("frameless-{what}"))
            .spawn(f)
            .map_err(|source| {
                self.shared.stop.store(true, Ordering::Relaxed);
                RealtimeError::Spawn { what, source }
            })?;
        self.handles.push((what, h));
        Ok(())
    }

    /// `config.sampling_threads` sampling threads running `f(thread index, senders)`,
    /// each with a clone of `tx` (dropped here, so that channels close when they all
    /// end).
    pub fn sampling_threads<T: Clone + Send + 'static>(
        &mut self,
        tx: T,
        f: impl Fn(u64, T) + Clone + Send + 'static,
    ) -> Result<(), RealtimeError> {
        for i in 0..self.shared.config.sampling_threads {
            let (f, tx) = (f.clone(), tx.clone());
            self.spawn("sampling", move || {
                lower_priority();
                f(i as u64, tx)
            })?;
        }
        Ok(())
    }
}

/// A builder whose builds run their parallel loops (rayon) on a pool of their own of
/// `config.recon_threads` threads, so that building cannot take every core from
/// sampling and the display; without a pool (it could not be made) they run on the
/// calling thread.
pub(crate) struct Pooled<B> {
    builder: B,
    pool: Option<rayon::ThreadPool>,
}

impl<B: ImageBuilder> Pooled<B> {
    pub fn new(config: &RtConfig, builder: B) -> Self {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(config.recon_threads)
            .thread_name(|i| format!("frameless-recon-{i}"))
            .start_handler(|_| prompt_wakeups())
            .build()
            .ok();
        Self { builder, pool }
    }
}

impl<B: ImageBuilder> ImageBuilder for Pooled<B> {
    fn build(&mut self, at: BuildAt) -> Option<Built> {
        match &self.pool {
            Some(p) => p.install(|| self.builder.build(at)),
            None => self.builder.build(at),
        }
    }

    fn recycle(&mut self, image: Image) {
        self.builder.recycle(image);
    }

    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        self.builder.stats()
    }

    fn recon(&self) -> ReconUsed {
        self.builder.recon()
    }
}

/// Frames assembled on the image thread from rows that several sampling threads traced:
/// a frame is complete once all its rows arrived, and then every older unfinished
/// frame is given up (it could never be shown) and counted in `abandoned`. Used by the
/// framed methods and taa, whose frames differ only in what a row carries.
pub(crate) struct Assembly<F> {
    /// Frames being assembled: id, buffer, rows received.
    building: Vec<(u64, F, u32)>,
    /// Unfinished frames given up since the last [`Assembly::take_abandoned`].
    abandoned: u64,
}

impl<F> Default for Assembly<F> {
    fn default() -> Self {
        Self {
            building: Vec::new(),
            abandoned: 0,
        }
    }
}

impl<F> Assembly<F> {
    /// One row of frame `id`, which has `rows` rows: `new` makes the frame's buffer
    /// when its first row arrives, `put` writes the row into it. Returns the frame when
    /// this row completes it.
    pub fn add(
        &mut self,
        id: u64,
        rows: u32,
        new: impl FnOnce() -> F,
        put: impl FnOnce(&mut F),
    ) -> Option<F> {
        let i = match self.building.iter().position(|f| f.0 == id) {
            Some(i) => i,
            None => {
                self.building.push((id, new(), 0));
                self.building.len() - 1
            }
        };
        let f = &mut self.building[i];
        put(&mut f.1);
        f.2 += 1;
        if f.2 < rows {
            return None;
        }
        let (_, done, _) = self.building.swap_remove(i);
        let before = self.building.len();
        self.building.retain(|f| f.0 > id);
        self.abandoned += (before - self.building.len()) as u64;
        Some(done)
    }

    /// Unfinished frames given up since the last call.
    pub fn take_abandoned(&mut self) -> u64 {
        std::mem::take(&mut self.abandoned)
    }
}

/// Niceness of the sampling threads on Linux: the lowest, below the controller and
/// image threads, so that where they all share too few cores, the latter get a core
/// when they need one (an image late by a time slice is a missed refresh) and sampling
/// takes the rest. At niceness 10 a build still waited 1–4 ms a refresh behind them on
/// 2 cores (measured: docs/performance.md, tuning records).
const SAMPLING_NICE: i32 = 19;

/// Give the calling thread [`SAMPLING_NICE`] (Linux; elsewhere nothing changes).
fn lower_priority() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: `gettid` and `setpriority` take and return plain integers and touch
        // no memory of ours; raising one's own niceness needs no privilege, and a
        // refusal only leaves the thread at its priority. Exercised by
        // `tests::sampling_threads_run_below_the_others`.
        unsafe {
            let tid = libc::gettid();
            libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, SAMPLING_NICE);
        }
    }
}

/// The slack the image thread's lead leaves a build for scheduling jitter: a build
/// started up to this late still makes its refresh.
pub(crate) const SCHEDULING_MARGIN: Duration = Duration::from_micros(1500);

/// Longest a sampling thread keeps its core before it offers it to a waiting thread
/// ([`Turns`]): half the [`SCHEDULING_MARGIN`], so that a build woken behind a
/// sampling thread still starts within it.
pub(crate) const SAMPLING_TURN: Duration =
    Duration::from_nanos(SCHEDULING_MARGIN.as_nanos() as u64 / 2);

/// A sampling thread's turns on its core. Linux (6.18, measured) gives a woken image or
/// reconstruction thread the core at once only where the scheduler finds it due;
/// otherwise it waits for the scheduler's next tick (4 ms at 250 Hz), even behind a
/// sampling thread at the lowest priority, and a build that starts 4 ms late misses a
/// 60 Hz refresh. A sampling thread that yields every [`SAMPLING_TURN`] bounds that
/// wait (docs/performance.md, session 36). A yield with nothing waiting returns at
/// once.
pub(crate) struct Turns {
    since: Instant,
}

impl Turns {
    pub fn new() -> Self {
        Self {
            since: Instant::now(),
        }
    }

    /// Between two pieces of a sampling thread's work: yield the core if its turn is
    /// over, counting the yield in `s`.
    pub fn between(&mut self, s: &Shared) {
        let now = Instant::now();
        if self.over(now) {
            std::thread::yield_now();
            s.yields.fetch_add(1, Ordering::Relaxed);
            self.since = now;
        }
    }

    /// Whether the turn that began at `self.since` is over at `now`.
    fn over(&self, now: Instant) -> bool {
        now.saturating_duration_since(self.since) >= SAMPLING_TURN
    }
}

/// The scheduling slice the image and reconstruction threads ask for, nanoseconds: the
/// shortest Linux grants. With a slice shorter than the running thread's (1.4 ms by
/// default on the development machine), a woken thread takes the core at once instead
/// of waiting out that slice (Linux 6.12 and later; earlier kernels keep their own).
const PROMPT_SLICE_NS: u64 = 100_000;

/// Ask that the calling thread, when woken, preempt the threads of its priority and
/// below at once ([`PROMPT_SLICE_NS`]): a build that starts a few milliseconds late
/// misses its refresh (measured: docs/performance.md, session 33). It keeps its
/// niceness, under the normal policy (which the pipeline's threads have). Linux only;
/// a refusal leaves the thread as it was.
pub(crate) fn prompt_wakeups() {
    #[cfg(target_os = "linux")]
    let _ = request_slice(PROMPT_SLICE_NS);
}

/// `sched_setattr(2)`'s argument, the layout of its first version (48 bytes).
#[cfg(target_os = "linux")]
#[repr(C)]
struct SchedAttr {
    size: u32,
    policy: u32,
    flags: u64,
    nice: i32,
    priority: u32,
    runtime: u64,
    deadline: u64,
    period: u64,
}

#[cfg(target_os = "linux")]
const _: () = assert!(
    std::mem::size_of::<SchedAttr>() == 48,
    "the kernel's first `struct sched_attr` is 48 bytes"
);

/// Give the calling thread a scheduling slice of `ns` under the normal policy, keeping
/// its niceness.
#[cfg(target_os = "linux")]
fn request_slice(ns: u64) -> std::io::Result<()> {
    // SAFETY: `gettid` and `getpriority` take and return plain integers and touch no
    // memory of ours.
    let nice = unsafe {
        let tid = libc::gettid();
        libc::getpriority(libc::PRIO_PROCESS, tid as libc::id_t)
    };
    let attr = SchedAttr {
        size: std::mem::size_of::<SchedAttr>() as u32,
        policy: libc::SCHED_OTHER as u32,
        flags: 0,
        nice,
        priority: 0,
        runtime: ns,
        deadline: 0,
        period: 0,
    };
    // SAFETY: the kernel reads `attr.size` bytes from the pointer, and `size` is the
    // size of the live, `repr(C)` struct it points to, laid out as the kernel's
    // `struct sched_attr` of that size; pid 0 is the calling thread, flags 0. It
    // writes nothing of ours. Exercised by
    // `tests::a_prompt_thread_keeps_its_niceness_and_gets_its_slice`.
    let r = unsafe { libc::syscall(libc::SYS_sched_setattr, 0, &attr as *const SchedAttr, 0u32) };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_view_ahead_follows_the_delays_smoothed_and_stays_0_when_off() {
        let v = super::ViewAhead::new(true, 60.0);
        assert_eq!(v.seconds(), 0.0, "nothing shown yet");
        v.shown_after(0.020);
        assert_eq!(v.seconds(), 0.020, "the first delay as it is");
        v.shown_after(f64::NAN);
        v.shown_after(-1.0);
        assert_eq!(v.seconds(), 0.020, "no delay from a NaN or a negative one");
        v.shown_after(0.100);
        let once = v.seconds();
        assert!(
            once > 0.020 && once < 0.040,
            "one late image moves it a little: {once}"
        );
        for _ in 0..100 {
            v.shown_after(0.100);
        }
        assert!((v.seconds() - 0.100).abs() < 1e-4, "{}", v.seconds());
        let off = super::ViewAhead::new(false, 60.0);
        off.shown_after(0.020);
        assert_eq!(off.seconds(), 0.0);
    }

    /// The calling thread's niceness, from `/proc` (field 19 of its `stat`).
    #[cfg(target_os = "linux")]
    fn nice() -> i32 {
        let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
        let rest = &stat[stat.rfind(')').unwrap() + 2..];
        rest.split_whitespace().nth(16).unwrap().parse().unwrap()
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn sampling_threads_run_below_the_others() {
        let base = nice();
        let lowered = std::thread::spawn(|| {
            super::lower_priority();
            nice()
        })
        .join()
        .unwrap();
        // Another thread's change leaves this one as it was.
        assert_eq!(nice(), base);
        assert_eq!(lowered, super::SAMPLING_NICE.max(base));
    }

    /// The calling thread's scheduling slice in nanoseconds, where the kernel shows it.
    #[cfg(target_os = "linux")]
    fn slice() -> Option<u64> {
        let sched = std::fs::read_to_string("/proc/thread-self/sched").ok()?;
        let line = sched.lines().find(|l| l.starts_with("se.slice"))?;
        line.split(':').nth(1)?.trim().parse().ok()
    }

    /// Whether the running kernel is at least `major.minor`.
    #[cfg(target_os = "linux")]
    fn kernel_at_least(major: u32, minor: u32) -> bool {
        let release = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap();
        let mut v = release
            .trim()
            .split(|c: char| !c.is_ascii_digit())
            .map(|p| p.parse::<u32>().unwrap_or(0));
        (v.next().unwrap_or(0), v.next().unwrap_or(0)) >= (major, minor)
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_prompt_thread_keeps_its_niceness_and_gets_its_slice() {
        let (before, after, result, got) = std::thread::spawn(|| {
            // A thread below the default priority, as a process run under `nice` is.
            super::lower_priority();
            let before = nice();
            let result = super::request_slice(super::PROMPT_SLICE_NS);
            (before, nice(), result, slice())
        })
        .join()
        .unwrap();
        result.expect("sched_setattr under the normal policy at the same niceness");
        assert_eq!(after, before, "the niceness is kept");
        // Custom slices for the normal policy came with Linux 6.12.
        if kernel_at_least(6, 12) {
            assert_eq!(got, Some(super::PROMPT_SLICE_NS));
        }
    }

    /// A sampling thread's turn lasts [`super::SAMPLING_TURN`] from its last yield,
    /// within the lead's margin for scheduling.
    #[test]
    fn a_sampling_turn_ends_after_its_length() {
        use std::time::Duration;
        let turns = super::Turns::new();
        let t0 = turns.since;
        let turn = super::SAMPLING_TURN;
        assert!(!turns.over(t0));
        assert!(!turns.over(t0 + turn - Duration::from_nanos(1)));
        assert!(turns.over(t0 + turn));
        // A clock read before the turn began (another core's) is not past it.
        assert!(!turns.over(t0.checked_sub(turn).unwrap_or(t0)));
        assert!(turn > Duration::ZERO && 2 * turn <= super::SCHEDULING_MARGIN);
    }

    /// A build takes what was queued when it began: a sender that keeps up with it
    /// (here, one more item for every item taken) cannot hold it forever.
    #[test]
    fn a_build_takes_only_what_was_queued() {
        let (tx, rx) = crossbeam_channel::bounded(16);
        for i in 0..3 {
            tx.send(i).unwrap();
        }
        let mut got = Vec::new();
        for x in super::take_queued(&rx) {
            got.push(x);
            tx.send(100 + x).unwrap();
        }
        assert_eq!(got, [0, 1, 2]);
        assert_eq!(super::take_queued(&rx).collect::<Vec<_>>(), [100, 101, 102]);
    }
}
