//! The adaptive method's image builder on the image thread: the reconstructor, fed
//! with what the controllers passed on, filtered with the bands' newest tilings, timed
//! against its image budget.

use std::{
    collections::VecDeque,
    sync::{atomic::Ordering, Arc},
    time::Instant,
};

use crossbeam_channel::Receiver;

use super::{overlays::TilingOverlays, published::Published, settings::AdaptiveSettings};
use crate::{
    image::Image,
    realtime::{
        config::RealtimeError,
        shared::{lock, take_queued, BuildAt, Built, ImageBuilder, Shared},
    },
    reconstruction::{device::ReconUsed, Reconstructor},
    scene::CameraFrame,
    tiles::TilingSnapshot,
    trace::StreamSample,
};

/// The image builder's reconstructor, on the run's GPU when it has one: refused before
/// any thread starts where the adapter is too small for the display's buffers.
pub(super) fn reconstructor(
    s: &Shared,
    settings: &AdaptiveSettings,
) -> Result<Box<Reconstructor>, RealtimeError> {
    let (w, h) = s.tracer.size();
    // The filters' rate is measured and set at every image ([`Builder::build`]).
    let mut r = Box::new(Reconstructor::new(w, h, 1.0, settings.recon));
    if let Some(gpu) = &settings.gpu {
        r.use_gpu(gpu.clone()).map_err(|e| RealtimeError::Gpu {
            method: super::settings::NAME,
            why: e.to_string(),
        })?;
    }
    // Before the run's clock starts (the threads are not yet spawned).
    r.prepare();
    Ok(r)
}

/// The image thread's side: the reconstructor, fed with what the controllers passed
/// on, filtered with the bands' newest tilings.
pub(super) struct Builder {
    s: Arc<Shared>,
    published: Arc<Published>,
    rx: Receiver<Vec<StreamSample>>,
    recon: Box<Reconstructor>,
    /// Ray counts at recent images, to measure the rate the filters assume.
    rate_window: VecDeque<(f64, u64)>,
    /// Newest samples the reconstructor places ([`next_live_limit`]).
    live_limit: Option<usize>,
    cost: BuildCost,
    figures: ImageFigures,
    /// An image shown before that nothing holds any more, to hand the next image over
    /// in ([`ImageBuilder::recycle`]): a refresh's image then costs no copy.
    spare: Option<Image>,
    /// How long the last parts of recent split refreshes took, seconds
    /// ([`Reconstructor::reconstruct_taking_late`]).
    last_parts: VecDeque<f64>,
}

/// Split refreshes whose last parts say how long the next may take.
const LAST_PARTS: usize = 16;

impl Builder {
    /// Nothing built yet: `recon` fed from `rx`, with the tilings of `published`.
    pub(super) fn new(
        s: Arc<Shared>,
        published: Arc<Published>,
        rx: Receiver<Vec<StreamSample>>,
        recon: Box<Reconstructor>,
    ) -> Self {
        Self {
            s,
            published,
            rx,
            recon,
            rate_window: VecDeque::new(),
            live_limit: None,
            cost: BuildCost::default(),
            figures: ImageFigures::default(),
            spare: None,
            last_parts: VecDeque::new(),
        }
    }
}

/// What the image builder reports ([`ImageBuilder::stats`]).
#[derive(Default)]
pub(super) struct ImageFigures {
    /// The sample rate the filters assume after the newest image, and the ring's
    /// capacity.
    recon_rate: f64,
    ring_capacity: usize,
    /// Images built, those built under a live limit, and the samples they placed.
    images: u64,
    limited_images: u64,
    placed_sum: f64,
    /// Summed over the images, seconds: how long before its refresh each build began
    /// (its lead), and how long before that refresh its newest sample was traced.
    lead_sum: f64,
    lag_sum: f64,
    /// Samples that moving views' refreshes took in while they were built, summed
    /// ([`Reconstructor::reconstruct_taking_late`]).
    late_sum: f64,
    /// Summed over the images, seconds: how far ahead the sampling threads traced the
    /// view after each ([`crate::realtime::RtConfig::view_ahead`]).
    ahead_sum: f64,
}

/// Push the newest samples of `batches` (oldest first) into `r`: as many as its ring
/// holds, and no more than the live limit (the newest samples an image places) when
/// there is one. The image thread takes samples in one at a time, and on many cores
/// more arrive between two images than it can take in and still build an image in
/// its budget; the older ones are not placed, but go to the still-region history,
/// which costs a fraction of placing them (on 16 cores 60-80% of the samples traced
/// were left out of every image, and the history starved).
pub(super) fn push_newest(
    r: &mut Reconstructor,
    batches: &[Vec<StreamSample>],
    limit: Option<usize>,
) {
    let total: usize = batches.iter().map(Vec::len).sum();
    let most = limit.map_or(r.capacity(), |l| l.min(r.capacity()));
    let mut skip = total.saturating_sub(most);
    for batch in batches {
        let from = skip.min(batch.len());
        skip -= from;
        r.push_history_only(&batch[..from]);
        r.push_stream(&batch[from..]);
    }
}

/// The live limit never cuts an image below one new sample per this many pixels, so
/// that an image still moves on where the build's per-pixel work alone exceeds the
/// budget; low enough that on many cores, where more samples arrive than a build can
/// place in a refresh, the limit and not the floor decides (docs/performance.md, "The
/// live limit on many cores").
const LIVE_LIMIT_FLOOR_DIVISOR: usize = 16;

/// The share of the samples the image before placed that an image restarting the
/// carried sums places: it cuts them as well as placing and splatting them, which about
/// doubles their cost (museum4 live on 2 cores, where its camera stops: 114 ns a sample
/// against 56 for the refreshes before it, whole rings of 131,072 samples; such a build
/// took 19 ms against 11–13 and missed its 60 Hz refresh in every run), so that it
/// takes about as long as the images before it.
const RESTART_SHARE: f64 = 0.5;

/// The live limit of an image that restarts the carried sums, after an image that
/// placed `placed` samples under the live limit `limit`.
pub(super) fn restart_limit(limit: Option<usize>, placed: usize) -> Option<usize> {
    let share = ((placed as f64 * RESTART_SHARE) as usize).max(1);
    Some(limit.map_or(share, |l| l.min(share)))
}

/// Images whose build times [`BuildCost`] fits.
const COST_WINDOW: usize = 32;

/// The build's time as a fixed part (the per-pixel passes) plus a part per sample
/// placed, fitted by least squares over the last [`COST_WINDOW`] images.
///
/// It sets the deepest cut worth making: below `fixed / per_sample` samples the fixed
/// part is most of a build, so cutting further buys at most twice the images while
/// each image places few of the samples: images come more often but noisier. That cut
/// never holds an image above what the budget affords, though: where the fixed part
/// alone outlasts the budget, holding the cut made every build several periods long
/// (16 cores, docs/performance.md, "Session 41"), while the samples an image leaves
/// out still reach the still-region history.
#[derive(Default)]
pub(super) struct BuildCost {
    recent: VecDeque<(f64, f64)>,
}

impl BuildCost {
    /// An image that placed `placed` samples in `ms`.
    pub(super) fn add(&mut self, placed: usize, ms: f64) {
        if self.recent.len() == COST_WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back((placed as f64, ms));
    }

    /// `(fixed ms, ms per sample)`, once the images' sample counts spread enough
    /// (10% of their mean) to tell the two apart and the fit is not degenerate.
    pub(super) fn fit(&self) -> Option<(f64, f64)> {
        let n = self.recent.len() as f64;
        if n < 8.0 {
            return None;
        }
        let (mk, mt) = self
            .recent
            .iter()
            .fold((0.0, 0.0), |(a, b), (k, t)| (a + k / n, b + t / n));
        let (mut vk, mut cov) = (0.0, 0.0);
        for (k, t) in &self.recent {
            vk += (k - mk) * (k - mk) / n;
            cov += (k - mk) * (t - mt) / n;
        }
        if vk.sqrt() < 0.1 * mk || vk <= 0.0 {
            return None;
        }
        let per_sample = cov / vk;
        let fixed = mt - per_sample * mk;
        (per_sample > 0.0 && fixed > 0.0).then_some((fixed, per_sample))
    }

    /// The fewest samples an image should place within `budget_ms`: as many as cost
    /// the build's fixed part, when that is known, but no more than the budget has
    /// room for beside it (none where the fixed part alone outlasts it).
    pub(super) fn deepest_cut(&self, budget_ms: f64) -> Option<usize> {
        self.fit().map(|(fixed, per)| {
            let room = (budget_ms - fixed).max(0.0);
            (fixed.min(room) / per) as usize
        })
    }
}

/// The live limit for the next image, after one that placed `placed` samples under
/// `limit` and took `ms` to build, against a budget of `budget_ms` (0: no limit).
///
/// The build's cost is nearly linear in the samples placed, so the limit moves by the
/// square root of budget / time (half the step in the logarithm, against overshoot
/// from one slow image), at most halving or growing by a quarter per image; it is
/// lifted once it would reach `capacity`, and never goes below `floor`.
pub(super) fn next_live_limit(
    limit: Option<usize>,
    placed: usize,
    ms: f64,
    budget_ms: f64,
    floor: usize,
    capacity: usize,
) -> Option<usize> {
    if budget_ms.is_nan() || budget_ms <= 0.0 {
        return None;
    }
    let step = (budget_ms / ms.max(1e-3)).sqrt().clamp(0.5, 1.25);
    let from = match limit {
        None if ms <= budget_ms => return None,
        None => placed,
        // Over budget with fewer samples than the limit allows: the cut starts from
        // what was placed, or a limit above the arrivals would take images to bind.
        Some(k) if ms > budget_ms => k.min(placed.max(1)),
        Some(k) => k,
    };
    let next = (from as f64 * step) as usize;
    (next < capacity).then_some(next.max(floor))
}

/// The sample rate over about the last second, after `rays` traced by `el` seconds
/// into the run; `window` holds the ray counts of recent images.
fn measured_rate(window: &mut VecDeque<(f64, u64)>, el: f64, rays: u64) -> f64 {
    window.push_back((el, rays));
    while window.len() > 2 && el - window[0].0 > 1.0 {
        window.pop_front();
    }
    let (e0, r0) = window[0];
    if el - e0 > 0.05 {
        (rays - r0) as f64 / (el - e0)
    } else {
        rays as f64 / el.max(1e-3)
    }
    .max(1.0)
}

impl Builder {
    /// The live limit of the image seen by `camera`: a restart of the carried sums
    /// under an image budget places fewer samples ([`restart_limit`]); without a budget
    /// (`--image-budget 0`) every sample is placed.
    fn limit_at(&self, camera: &crate::scene::CameraFrame) -> Option<usize> {
        let budgeted = self.published.settings.image_budget > 0.0;
        if budgeted && self.recon.restarts_at(camera) {
            restart_limit(self.live_limit, self.recon.placed())
        } else {
            self.live_limit
        }
    }
}

impl Builder {
    /// The image at `t` seen by `camera`; with [`AdaptiveSettings::late_samples`], a
    /// moving view's taking in what arrives while its ring is placed and splatted,
    /// where its last part, as long as the longest of late, still ends before the
    /// refresh: a late image costs more than a lag.
    fn reconstruct(&mut self, t: f64, camera: &CameraFrame, tiling: &TilingSnapshot) {
        if !self.published.settings.late_samples {
            self.recon.reconstruct(t, camera, tiling);
            return;
        }
        let (rx, clock) = (&self.rx, &self.s.clock);
        let margin = crate::realtime::shared::SCHEDULING_MARGIN.as_secs_f64();
        let needs = self.last_parts.iter().fold(0.0f64, |m, &p| m.max(p)) + margin;
        let mut called = None;
        let late = self.recon.reconstruct_taking_late(t, camera, tiling, || {
            called = Some(Instant::now());
            if t - clock.now() > needs {
                take_queued(rx).collect()
            } else {
                Vec::new()
            }
        });
        if let Some(c) = called {
            if self.last_parts.len() == LAST_PARTS {
                self.last_parts.pop_front();
            }
            self.last_parts.push_back(c.elapsed().as_secs_f64());
        }
        self.figures.late_sum += late as f64;
    }
}

impl ImageBuilder for Builder {
    fn recycle(&mut self, image: Image) {
        self.spare = Some(image);
    }

    /// `tiles` now; `reprojected_share` of visits whose reprojection step ran (the
    /// controllers skip it while behind their input); `history_maps` the controllers
    /// received ([`crate::methods::adaptive::SamplerParams::discount_converged`]); the
    /// `recon_rate` the filters assume (measured, /s); the `ring_capacity`;
    /// `placed_mean` samples placed per image (the ring within the temporal cutoff, at
    /// most the live limit); `limited_share` of images built under a live limit
    /// ([`AdaptiveSettings::image_budget`]); `build_fixed_ms` and
    /// `build_ns_per_sample`, the build's time fitted over the last images as a fixed
    /// part and a part per sample placed ([`BuildCost`]), where the fit holds;
    /// `gpu_failure`, why the GPU reconstructor
    /// was given up, if it was (the images after it were built on the CPU);
    /// `gpu_carried_sums`, how the GPU's carrying refreshes got their sums
    /// ([`crate::reconstruction::Reconstructor::gpu_carried_sums`]).
    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        let p = &*self.published;
        let (rv, sv) = (
            p.reprojected_visits.load(Ordering::Relaxed),
            p.skipped_reprojections.load(Ordering::Relaxed),
        );
        let f = &self.figures;
        let per_image = |x: f64| x / f.images.max(1) as f64;
        let mut figures = vec![
            ("tiles", p.tiles().into()),
            (
                "reprojected_share",
                (rv as f64 / (rv + sv).max(1) as f64).into(),
            ),
            (
                "history_maps",
                p.history_maps.load(Ordering::Relaxed).into(),
            ),
            ("recon_rate", f.recon_rate.into()),
            ("ring_capacity", f.ring_capacity.into()),
            ("placed_mean", per_image(f.placed_sum).into()),
            ("lead_ms_mean", (per_image(f.lead_sum) * 1e3).into()),
            ("sample_lag_ms_mean", (per_image(f.lag_sum) * 1e3).into()),
            ("view_ahead_ms_mean", (per_image(f.ahead_sum) * 1e3).into()),
            ("late_samples_mean", per_image(f.late_sum).into()),
            ("limited_share", per_image(f.limited_images as f64).into()),
            ("pass_ms", pass_ms(self.recon.pass_times())),
        ];
        if let Some((fixed, per_sample)) = self.cost.fit() {
            figures.push(("build_fixed_ms", fixed.into()));
            figures.push(("build_ns_per_sample", (per_sample * 1e6).into()));
        }
        if let Some(why) = self.recon.gpu_failure() {
            figures.push(("gpu_failure", why.into()));
        }
        if let Some((uploaded, replayed)) = self.recon.gpu_carried_sums() {
            let by = serde_json::json!({ "uploaded": uploaded, "replayed": replayed });
            figures.push(("gpu_carried_sums", by));
        }
        figures
    }

    fn recon(&self) -> ReconUsed {
        self.recon.used()
    }

    fn build(&mut self, at: BuildAt) -> Option<Built> {
        let t0 = Instant::now();
        // Samples are reprojected to the scene of the refresh the image is meant for.
        let t = at.shown;
        let s = self.s.clone();
        let began = s.clock.now();
        let (w, h) = s.tracer.size();
        let tiling = Arc::new(self.published.whole_tiling()?);
        let batches: Vec<Vec<StreamSample>> = take_queued(&self.rx).collect();
        // The filters need the sample rate R, measured over the last second; a new
        // rate takes effect at the next refresh, keeping the ring, the splat scale and
        // the still-region history.
        let rays = s.rays.load(Ordering::Relaxed);
        let rate = measured_rate(&mut self.rate_window, s.clock.elapsed(), rays);
        let state = s.tracer.state_at(t);
        let camera = state.camera;
        let limit = self.limit_at(&camera);
        let r = &mut self.recon;
        r.set_rate(rate);
        push_newest(r, &batches, self.live_limit);
        r.set_motion(Some(state));
        r.set_live_limit(limit);
        self.reconstruct(t, &camera, &tiling);
        let r = &mut self.recon;
        let image = r.take_image(self.spare.take());
        let settings = &self.published.settings;
        if settings.sampler.discount_converged {
            if let Some(counts) = r.history_counts() {
                // Each controller reads the newest; an older map none has read is
                // replaced (its buffer reused).
                let mut maps = lock(&self.published.history_counts);
                maps.0 += 1;
                maps.1.clear();
                maps.1.extend_from_slice(counts);
            }
        }
        let ages = r.pixel_ages();
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let budget_ms = settings.image_budget * 1e3 / s.config.refresh_hz;
        self.cost.add(r.placed(), ms);
        let pixel_floor = ((w as usize * h as usize) / LIVE_LIMIT_FLOOR_DIVISOR).max(1);
        let floor = pixel_floor.max(self.cost.deepest_cut(budget_ms).unwrap_or(0));
        let limited = self.live_limit.is_some();
        self.live_limit = next_live_limit(
            self.live_limit,
            r.placed(),
            ms,
            budget_ms,
            floor,
            r.capacity(),
        );
        let fig = &mut self.figures;
        fig.recon_rate = rate;
        fig.ring_capacity = r.capacity();
        fig.images += 1;
        fig.limited_images += limited as u64;
        fig.placed_sum += r.placed() as f64;
        fig.lead_sum += t - began;
        fig.lag_sum += r.sample_lag(t);
        s.view_ahead.build_led_by(t - began);
        fig.ahead_sum += s.view_ahead.seconds();
        Some(Built {
            image,
            mean_age: r.mean_age(),
            overlays: Some(Arc::new(TilingOverlays(tiling))),
            ages: crate::realtime::shared::sampled_ages(ages.len(), |i| ages[i]),
            view_time: t,
        })
    }
}

/// Mean milliseconds per CPU refresh of each step of the reconstructor, as a JSON
/// object in the steps' order (what names the image's first bottleneck).
fn pass_ms(p: &crate::reconstruction::PassTimes) -> serde_json::Value {
    let m: serde_json::Map<String, serde_json::Value> = p
        .mean_ms()
        .into_iter()
        .map(|(name, ms)| (name.to_string(), ms.into()))
        .collect();
    m.into()
}
