//! Recording what a display shows: the pipeline runs on the wall clock, and at every
//! refresh of a window the image on screen is kept as the display shows it (8-bit) with
//! its scan-out time, so that it can be scored against the ideal image of that instant
//! afterwards ([`crate::evaluation::live`]).
//!
//! A refresh shows the newest image published before its due instant, as a display
//! with vertical sync does. The loop wakes at each due instant and looks at the newest
//! image; when it woke late and that image was published after the instant, the
//! refresh shows the one seen before it instead. A refresh the loop slept through
//! entirely is recorded all the same, with what was on screen then.

use std::sync::Arc;

use super::{
    config::{RealtimeError, RtConfig},
    machine::{load_average, others_load, CpuMark, CpuShares},
    pacing::Pacer,
    pipeline::{Frame, Pipeline, PipelineStats},
    registry::RtSettings,
};
use crate::trace::Tracer;

/// Which refreshes to record: the pipeline starts at scene time `config.start`, runs
/// `warmup` refreshes unrecorded, then records `refreshes`. Refresh `k` of the pipeline
/// (1, 2, …) is scanned out at scene time `config.start + k / refresh_hz`.
#[derive(Clone, Copy, Debug)]
pub struct Window {
    /// Refreshes before the first recorded one (at least 1: the first refresh of the
    /// pipeline is one period after its start).
    pub warmup: u64,
    /// Refreshes recorded.
    pub refreshes: usize,
}

/// One image a refresh of the window showed, as displayed.
#[derive(Clone, Debug)]
pub struct ShownImage {
    /// 8-bit RGB, clamped and quantized as a display does.
    pub rgb: Arc<Vec<u8>>,
    /// Scene time it shows.
    pub time: f64,
    /// Mean age of its information when it was built, seconds (NaN: none).
    pub mean_age: f64,
}

/// The live figures of the recorded window (the warm-up is not counted).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct LiveFigures {
    /// Shaded samples delivered per wall second.
    pub samples_per_s: f64,
    /// Distinct images the refreshes showed, per wall second.
    pub images_per_s: f64,
    /// Refreshes that came more than half a period late.
    pub late_refreshes: u64,
    /// Share of the machine's cores this process used (all its threads).
    pub machine_share: Option<f64>,
    /// Share of the machine's cores every other process used meanwhile.
    pub others_share: Option<f64>,
    /// The 1-minute load average just before the pipeline started. It carries the last
    /// minute's work of this process too, such as a run before this one.
    pub load_average_before: Option<f64>,
    /// Tasks of other processes running or waiting for a core just before the pipeline
    /// started (averaged over [`BEFORE_SAMPLES`] readings).
    pub others_load_before: Option<f64>,
}

/// Readings of other processes' load before a run, [`BEFORE_GAP`] apart.
pub const BEFORE_SAMPLES: usize = 25;
/// The gap between those readings.
pub const BEFORE_GAP: std::time::Duration = std::time::Duration::from_millis(10);

/// What one recorded run showed and cost.
pub struct Recording {
    /// The distinct images the window showed, in the order first shown.
    pub images: Vec<ShownImage>,
    /// Per refresh of the window: the index in `images` of what it showed (`None`:
    /// nothing yet, a black screen).
    pub shown: Vec<Option<u32>>,
    /// The window's live figures.
    pub figures: LiveFigures,
    /// The pipeline's own figures over the whole run, warm-up included.
    pub pipeline: PipelineStats,
}

/// What the loop keeps of an image it saw: the frame, and its index in the recording
/// once a recorded refresh showed it.
struct Seen {
    frame: Arc<Frame>,
    rgb: Arc<Vec<u8>>,
    index: Option<u32>,
}

/// The window's start: counters to subtract at its end.
struct Mark {
    cpu: CpuMark,
    samples: u64,
    seconds: f64,
    late: u64,
}

/// Run the method `settings` are for with `config` on `tracer` and record the
/// refreshes of `window`. The caller bounds the memory: at most `window.refreshes`
/// images of `width × height × 3` bytes.
pub fn record(
    tracer: Arc<Tracer>,
    config: RtConfig,
    settings: RtSettings,
    window: Window,
) -> Result<Recording, RealtimeError> {
    if window.warmup == 0 || window.refreshes == 0 {
        return Err(RealtimeError::Config(
            "a recorded window needs a refresh of warm-up and one to record".into(),
        ));
    }
    let before = Before {
        load_average: load_average(),
        others_load: others_load(BEFORE_SAMPLES, BEFORE_GAP),
    };
    let (w, h) = tracer.size();
    // Every refresh of the window may show an image of its own; the two seen last
    // may be waiting for theirs.
    let mut buffers = Buffers::new(window.refreshes + 2, 3 * w as usize * h as usize);
    let pipeline = Pipeline::start(tracer, config.clone(), settings)?;
    let clock = pipeline.clock();
    let period = 1.0 / config.refresh_hz;
    let mut pacer = Pacer::new(clock, config.refresh_hz);
    let (first, last) = (window.warmup, window.warmup + window.refreshes as u64 - 1);
    let mut images = Vec::new();
    let mut shown = Vec::with_capacity(window.refreshes);
    // The newest image seen and the one before it.
    let mut seen: [Option<Seen>; 2] = [None, None];
    let mut next = 1u64;
    let mut mark: Option<Mark> = None;
    while next <= last {
        pacer.wait();
        observe(&pipeline, &mut seen, &mut buffers);
        let due_now = ((clock.elapsed() / period).floor() as u64).min(last);
        if mark.is_none() && due_now >= first {
            mark = Some(mark_now(&pipeline, &pacer, &clock));
        }
        for k in next..=due_now {
            let on = on_screen(&mut seen, k as f64 * period);
            if k >= first {
                shown.push(on.map(|s| keep(s, &mut images)));
            }
        }
        next = next.max(due_now + 1);
        pacer.present(seen[0].as_ref().map_or(0, |s| s.frame.seq));
    }
    let start = mark.expect("the loop ran past the first recorded refresh");
    let end = mark_now(&pipeline, &pacer, &clock);
    let window_images = (window.refreshes as f64 * period, images.len());
    Ok(Recording {
        figures: figures(&start, &end, window_images, &before),
        images,
        shown,
        pipeline: pipeline.stop()?,
    })
}

/// The machine just before a run.
struct Before {
    load_average: Option<f64>,
    others_load: Option<f64>,
}

/// Note the pipeline's newest image, quantized as a display does on arrival (on this
/// thread, into one of `buffers`); the image it replaces as the one seen before gives
/// its buffer back if no refresh showed it.
fn observe(pipeline: &Pipeline, seen: &mut [Option<Seen>; 2], buffers: &mut Buffers) {
    let Some(frame) = pipeline.latest() else {
        return;
    };
    if seen[0].as_ref().is_some_and(|s| s.frame.seq == frame.seq) {
        return;
    }
    let mut rgb = buffers.take();
    frame.image.quantize_into(&mut rgb);
    seen.swap(0, 1);
    let gone = seen[0].replace(Seen {
        frame,
        rgb: Arc::new(rgb),
        index: None,
    });
    if let Some(g) = gone.filter(|g| g.index.is_none()) {
        buffers.give_back(g.rgb);
    }
}

/// Buffers for the displayed images, allocated and backed with memory before the
/// pipeline starts: quantizing an image at a refresh then takes no page faults. The
/// recording is the evaluation's work, not the method's, and should take as little of
/// the machine from the method it measures as it can.
struct Buffers {
    free: Vec<Vec<u8>>,
}

impl Buffers {
    /// `count` buffers of `len` bytes.
    fn new(count: usize, len: usize) -> Self {
        let free = (0..count)
            .map(|_| {
                let mut v = vec![0u8; len];
                crate::reconstruction::touch(&mut v);
                v
            })
            .collect();
        Self { free }
    }

    /// A buffer (an empty one if none is left: quantizing sizes it).
    fn take(&mut self) -> Vec<u8> {
        self.free.pop().unwrap_or_default()
    }

    /// `rgb` back, if nothing else holds it.
    fn give_back(&mut self, rgb: Arc<Vec<u8>>) {
        if let Ok(v) = Arc::try_unwrap(rgb) {
            self.free.push(v);
        }
    }
}

/// The image on screen at wall second `due` of the pipeline: the newest one seen
/// published by then.
fn on_screen(seen: &mut [Option<Seen>; 2], due: f64) -> Option<&mut Seen> {
    seen.iter_mut()
        .flatten()
        .find(|s| s.frame.published_s <= due)
}

/// `s`'s index in `images`, adding it when first shown.
fn keep(s: &mut Seen, images: &mut Vec<ShownImage>) -> u32 {
    *s.index.get_or_insert_with(|| {
        images.push(ShownImage {
            rgb: s.rgb.clone(),
            time: s.frame.time,
            mean_age: s.frame.mean_age,
        });
        (images.len() - 1) as u32
    })
}

fn mark_now(pipeline: &Pipeline, pacer: &Pacer, clock: &super::clock::WallClock) -> Mark {
    let stats = pipeline.stats();
    Mark {
        cpu: CpuMark::now(),
        samples: stats.samples,
        seconds: clock.elapsed(),
        late: pacer.stats(clock.elapsed()).late_refreshes,
    }
}

/// The window's figures from its start and end marks, with `(window seconds, distinct
/// images shown)`.
fn figures(
    start: &Mark,
    end: &Mark,
    (window_s, images): (f64, usize),
    before: &Before,
) -> LiveFigures {
    let seconds = (end.seconds - start.seconds).max(1e-9);
    let CpuShares { process, others } = start.cpu.shares_until(&end.cpu);
    LiveFigures {
        samples_per_s: end.samples.saturating_sub(start.samples) as f64 / seconds,
        images_per_s: images as f64 / window_s,
        late_refreshes: end.late.saturating_sub(start.late),
        machine_share: process,
        others_share: others,
        load_average_before: before.load_average,
        others_load_before: before.others_load,
    }
}
