//! Convergence where the view is still: a per-pixel running mean of every sample that
//! landed on a pixel while nothing there changed, blended over the space-time
//! reconstruction.
//!
//! The ring holds about a second of samples and the temporal filter lets a still pixel
//! see only a few of them, so without this the image stops improving after a second.
//! Here every still sample also goes into its pixel's history (box filter: the sample's
//! sub-pixel position decides the pixel, so the mean converges to the same pixel
//! integral the ideal image estimates), which keeps a sample count and has no horizon.
//!
//! When the camera moves the history follows the surfaces (`reproject`, on by
//! default): each pixel's history moves to where its newest sample's hit point is seen
//! now (nearest pixel, nearest depth wins) with its count capped, and new samples go
//! where their hit point is seen now. Without it, a new view drops all of it, and
//! samples pushed between two refreshes count only if the view was the same at both.
//!
//! History is dropped where it can no longer be trusted:
//! - **something moving took part in a sample there** (its hit moves, or a moving
//!   object cast a shadow on it or was seen in its reflection or refraction:
//!   [`crate::trace::Sample::dynamic`]): that pixel, at once;
//! - **the reconstruction disagrees**: at every refresh the history mean is clamped to
//!   the box of the reconstructed colours of the 3×3 pixels around it, widened by
//!   `box_scale` and `tolerance` (the reconstruction follows change within a few
//!   refreshes, because the sampler's temporal gradients shorten its filter there);
//!   where the clamp moves it, the count falls to `clamped_count` so that new samples
//!   take over. This catches what a velocity cannot: moving shadows and reflections on
//!   still surfaces, and surfaces uncovered by an object that started to move.
//!
//! The display is `(recon · recon_weight + Σ history) / (recon_weight + n)`: the
//! reconstruction counts as `recon_weight` samples, so a pixel with no history shows
//! the reconstruction unchanged and one with many shows the converged mean.

mod blend;
pub(super) mod refs;

use blend::BLEND_ROWS;
pub(crate) use blend::CLAMP_ROUNDING;
use glam::Vec3;
use rayon::prelude::*;
use refs::{BandRefs, Refs};

use super::lanes::{prefetch, Lanes, LANES, PREFETCH_AHEAD};
use crate::{image::Image, scene::CameraFrame, trace::luminance};

/// Parameters of the still-region history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HistoryParams {
    /// How many samples' worth the space-time reconstruction counts for in the blend.
    /// Where the view is still it is a blurred average of the few samples of its
    /// temporal window, worth about one sharp sample (docs/performance.md, "Tuning
    /// records", has the measurements behind this and the choices below).
    pub recon_weight: f32,
    /// Largest count: beyond it older samples are down-weighted (a running mean over
    /// the last ~`max_count` samples), which bounds f32 rounding and lets very slow
    /// drifts (a light dimming) through. 1024 samples' worth: far below the noise of
    /// any ideal image we compare with.
    pub max_count: f32,
    /// Widening of the 3×3 reconstruction box the history must stay in. The
    /// reconstruction is smoother than a converged pixel (its spatial filter spans more
    /// than one pixel), so an unwidened box would clip sharp, correct history at edges.
    pub box_scale: f32,
    /// Added to each side of the box, 0–1 colour units: the reconstruction's own noise
    /// in a still region (about 5/255 RMS at 400K on 256×256) must not drop history.
    pub tolerance: f32,
    /// Count kept where the clamp moved the history: what survives a detected change.
    pub clamped_count: f32,
    /// Samples a pixel's history needs before new samples are tested against the
    /// range of its luminances; two in a row outside it cut the history.
    pub min_count_to_test: f32,
    /// Slack on each side of that range, luminance 0–1: 0.1 (≈ 25/255) lets the
    /// shading of a still surface vary a little (textures filtered at a changing
    /// footprint, a sample's exact position) without a cut.
    pub range_tolerance: f32,
    /// The same slack at a refresh whose view is the previous refresh's (at the first
    /// refresh: every sample in hand was traced from its view). Then a sample outside
    /// the range means a change on the surface, which the moving-sample cuts and the
    /// clamp to the reconstruction also catch; while the view moves it may also mean a
    /// history reprojected onto the wrong surface, so only a still view gets the
    /// wider slack.
    pub still_range_tolerance: f32,
    /// How long a sample of a moving surface keeps cutting the history where it has
    /// moved to, seconds: until newer samples of the surface have landed ahead of it.
    pub moving_memory: f64,
    /// Keep the history through camera motion: move each pixel's history to where its
    /// surface point is seen now (nearest pixel, nearest depth wins) with its count
    /// capped at `reprojected_count`, and place new samples where their hit point is
    /// now, instead of cutting everything when the view changes.
    pub reproject: bool,
    /// Count a pixel's history keeps when it is reprojected: nearest-pixel moves
    /// resample it, so it should soon give way to new samples. 8, as `taa`'s moving
    /// cap.
    pub reprojected_count: f32,
}

impl Default for HistoryParams {
    fn default() -> Self {
        Self {
            recon_weight: 1.0,
            max_count: 1024.0,
            box_scale: 2.0,
            tolerance: 0.04,
            clamped_count: 1.0,
            min_count_to_test: 4.0,
            range_tolerance: 0.1,
            still_range_tolerance: 0.2,
            moving_memory: 0.1,
            reproject: true,
            reprojected_count: 8.0,
        }
    }
}

impl HistoryParams {
    /// `Err(name, valid range)` for the first parameter out of range.
    pub fn check(&self) -> Result<(), (&'static str, &'static str)> {
        let ok = |v: f32, lo: f32| v.is_finite() && v >= lo;
        if !ok(self.recon_weight, 1e-3) {
            return Err(("history.recon_weight", "must be finite and > 0"));
        }
        if !ok(self.max_count, 1.0) {
            return Err(("history.max_count", "must be finite and ≥ 1"));
        }
        if !ok(self.box_scale, 1.0) {
            return Err(("history.box_scale", "must be finite and ≥ 1"));
        }
        if !ok(self.tolerance, 0.0) {
            return Err(("history.tolerance", "must be finite and ≥ 0"));
        }
        if !(ok(self.clamped_count, 0.0) && self.clamped_count <= self.max_count) {
            return Err(("history.clamped_count", "must be in [0, max_count]"));
        }
        if !ok(self.min_count_to_test, 0.0)
            || !ok(self.range_tolerance, 0.0)
            || !ok(self.still_range_tolerance, 0.0)
        {
            return Err((
                "history.min_count_to_test/range_tolerance/still_range_tolerance",
                "must be finite and ≥ 0",
            ));
        }
        if !(self.moving_memory.is_finite() && (0.0..=10.0).contains(&self.moving_memory)) {
            return Err(("history.moving_memory", "must be in [0, 10] seconds"));
        }
        Ok(())
    }
}

const EMPTY_RANGE: (f32, f32) = (f32::INFINITY, f32::NEG_INFINITY);

/// One pixel's luminance range and newest hit point: what only taking samples in and
/// moving the history read.
#[derive(Clone, Copy, Debug)]
struct Cell {
    /// Range of the luminances in the pixel's history (empty: `lo > hi`).
    range: (f32, f32),
    /// The hit point of the pixel's newest sample (for reprojection).
    point: Vec3,
}

impl Cell {
    const EMPTY: Cell = Cell {
        range: EMPTY_RANGE,
        point: Vec3::ZERO,
    };
}

/// Each pixel's accumulated history: its count (what most passes test first, and what
/// the sampler reads), what the blend reads in planes (the mean colour: red, green,
/// blue; the sum of the samples' times, for the age of what is shown), so that it
/// loads 8 pixels at a time, and the rest in one [`Cell`].
///
/// The colour is a running mean, not a sum: moved by `(c − mean) / n`, a mean stays
/// exactly `c` while every sample is `c`, where a sum divided by its count is off by
/// a rounding or two (see [`Refs`] for why a rounding matters).
#[derive(Clone)]
struct Accum {
    count: Vec<f32>,
    mean: [Vec<f32>; 3],
    time_sum: Vec<f64>,
    cell: Vec<Cell>,
}

impl Accum {
    fn new(n: usize) -> Self {
        Self {
            count: vec![0.0; n],
            mean: std::array::from_fn(|_| vec![0.0; n]),
            time_sum: vec![0.0; n],
            cell: vec![Cell::EMPTY; n],
        }
    }

    /// Every pixel empty.
    fn reset(&mut self) {
        self.count.fill(0.0);
        self.mean.iter_mut().for_each(|s| s.fill(0.0));
        self.time_sum.fill(0.0);
        self.cell.fill(Cell::EMPTY);
    }

    /// Pixel `q` empty (its point stays: it is read only where the count is not 0).
    fn clear(&mut self, q: usize) {
        self.all().clear(q);
    }

    /// Pixel `d` takes pixel `q` of `from`, keeping at most `cap` samples' worth.
    fn take(&mut self, d: usize, from: &Accum, q: usize, cap: f32) {
        let k = from.count[q].min(cap) / from.count[q];
        for (s, f) in self.mean.iter_mut().zip(&from.mean) {
            s[d] = f[q];
        }
        self.time_sum[d] = from.time_sum[q] * k as f64;
        self.cell[d] = from.cell[q];
        self.count[d] = from.count[q] * k;
    }

    /// Pixel `d` empty, its point too.
    fn empty(&mut self, d: usize) {
        self.clear(d);
        self.cell[d] = Cell::EMPTY;
    }

    /// All pixels, borrowed.
    fn all(&mut self) -> AccumMut<'_> {
        let [r, g, b] = &mut self.mean;
        AccumMut {
            count: &mut self.count,
            mean: [r, g, b],
            time_sum: &mut self.time_sum,
            cell: &mut self.cell,
        }
    }

    /// The pixels in runs of `len` (the last may be shorter), borrowed.
    fn runs_mut(&mut self, len: usize) -> Vec<AccumMut<'_>> {
        let [r, g, b] = &mut self.mean;
        self.count
            .chunks_mut(len)
            .zip(r.chunks_mut(len))
            .zip(g.chunks_mut(len))
            .zip(b.chunks_mut(len))
            .zip(self.time_sum.chunks_mut(len))
            .zip(self.cell.chunks_mut(len))
            .map(|(((((count, r), g), b), time_sum), cell)| AccumMut {
                count,
                mean: [r, g, b],
                time_sum,
                cell,
            })
            .collect()
    }
}

/// A run of consecutive pixels of an [`Accum`], borrowed.
struct AccumMut<'a> {
    count: &'a mut [f32],
    mean: [&'a mut [f32]; 3],
    time_sum: &'a mut [f64],
    cell: &'a mut [Cell],
}

impl AccumMut<'_> {
    /// Pixels `r` of the run.
    fn sub(&mut self, r: std::ops::Range<usize>) -> AccumMut<'_> {
        let [red, green, blue] = &mut self.mean;
        AccumMut {
            count: &mut self.count[r.clone()],
            mean: [
                &mut red[r.clone()],
                &mut green[r.clone()],
                &mut blue[r.clone()],
            ],
            time_sum: &mut self.time_sum[r.clone()],
            cell: &mut self.cell[r],
        }
    }

    fn mean(&self, q: usize) -> Vec3 {
        Vec3::new(self.mean[0][q], self.mean[1][q], self.mean[2][q])
    }

    fn set_mean(&mut self, q: usize, s: Vec3) {
        (self.mean[0][q], self.mean[1][q], self.mean[2][q]) = (s.x, s.y, s.z);
    }

    /// Empty pixel `q` (its point stays: it is read only where the count is not 0).
    fn clear(&mut self, q: usize) {
        self.set_mean(q, Vec3::ZERO);
        self.time_sum[q] = 0.0;
        self.cell[q].range = EMPTY_RANGE;
        self.count[q] = 0.0;
    }
}

/// A sample waiting to enter the history at the next refresh: what taking it in
/// reads, and its pixel once planned. Where it was traced and how its hit moves
/// ([`Traced`]) are read once, to place it, so they stay behind when it is sorted
/// (40 bytes moved, not 56).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Fresh {
    pub(super) t: f64,
    pub(super) color: Vec3,
    pub(super) hit_point: Vec3,
    /// The pixel it enters (set by [`History::plan`]).
    pub(super) pixel: u32,
    pub(super) still: bool,
}

/// Where a fresh sample was traced, and the velocity of its hit.
#[derive(Clone, Copy, Debug)]
struct Traced {
    x: f32,
    y: f32,
    velocity: Vec3,
}

/// What a refresh does to the view the history was gathered in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ViewChange {
    /// The same view: the history stays where it is.
    Same,
    /// A new view: each pixel's history moves to where its surface point is seen now.
    Reproject,
    /// A new view: everything gathered is dropped.
    Reset,
}

/// One refresh of the per-pixel history, decided from the views and the samples
/// pushed since the last refresh. The CPU's arrays ([`Pixels`]) or the GPU's carry
/// it out, in this order: the view change, the fresh samples, the cuts, the blend.
pub(super) struct Step {
    pub(super) t: f64,
    pub(super) camera: CameraFrame,
    pub(super) view: ViewChange,
    /// Slack of the range test at this refresh.
    pub(super) slack: f32,
    /// The samples that enter, in pixel order (stably, so each pixel sees its
    /// samples in the order they came), and their `(pixel, index)`: `index` counts
    /// up from 0 (the order the GPU's upload reads). Unless `in_pixel_order` is
    /// false: then `order` lists them in the order they came, `index` into `fresh`
    /// (every sample pushed, each with its pixel), for a GPU that orders them itself.
    pub(super) fresh: Vec<Fresh>,
    pub(super) order: Vec<(u32, u32)>,
    pub(super) in_pixel_order: bool,
    /// Pixels where recent samples of moving surfaces are now, oldest first.
    pub(super) cuts: Vec<u32>,
}

/// Per-pixel history of still samples.
pub(super) struct History {
    params: HistoryParams,
    width: u32,
    height: u32,
    /// The per-pixel arrays on the CPU; made at the first refresh done here (none
    /// while the GPU holds them).
    pixels: Option<Box<Pixels>>,
    /// Each pixel's count as the GPU last read it back.
    gpu_counts: Vec<f32>,
    /// Recent samples of moving surfaces `(hit point, velocity, time)`: at each refresh
    /// they cut the history where they are now, ahead of the samples that will land
    /// there.
    moving: std::collections::VecDeque<(Vec3, Vec3, f64)>,
    /// The view the history was gathered in.
    camera: Option<CameraFrame>,
    /// The view at the previous refresh.
    last_camera: Option<CameraFrame>,
    /// Time since which the caller knows the view to have been the current one.
    view_since: Option<f64>,
    /// The samples pushed since the last refresh, in arrival order.
    fresh: Vec<Fresh>,
    traced: Vec<Traced>,
    /// A step's vectors between refreshes, and the samples binned by band (reused).
    sorted: Vec<Fresh>,
    order: Vec<(u32, u32)>,
    cut_pixels: Vec<u32>,
    binned: Vec<Fresh>,
    /// Pixels whose history a moving sample or the clamp cut, in all.
    pub(super) cuts: u64,
}

impl History {
    pub(super) fn new(width: u32, height: u32, params: HistoryParams) -> Self {
        Self {
            params,
            width,
            height,
            pixels: None,
            gpu_counts: Vec::new(),
            moving: Default::default(),
            camera: None,
            last_camera: None,
            view_since: None,
            fresh: Vec::new(),
            traced: Vec::new(),
            sorted: Vec::new(),
            order: Vec::new(),
            cut_pixels: Vec::new(),
            binned: Vec::new(),
            cuts: 0,
        }
    }

    #[cfg(feature = "gpu")]
    pub(super) fn params(&self) -> &HistoryParams {
        &self.params
    }

    /// Note a sample pushed to the ring (it enters at the next refresh); `moving`: its
    /// hit moves or something moving took part in it.
    pub(super) fn push(&mut self, s: &super::RingSample, moving: bool) {
        let (x, y) = (s.x, s.y);
        if !(x >= 0.0 && y >= 0.0 && x < self.width as f32 && y < self.height as f32) {
            return;
        }
        self.fresh.push(Fresh {
            t: s.t,
            color: s.color,
            hit_point: s.hit_point,
            pixel: 0,
            still: !moving,
        });
        self.traced.push(Traced {
            x,
            y,
            velocity: s.velocity,
        });
    }

    /// The view has been the one of the next refresh since time `t0`: samples traced
    /// from then on may enter the history. Without it, samples enter only if the view
    /// was the same at the previous refresh.
    pub(super) fn set_view_since(&mut self, t0: f64) {
        self.view_since = Some(t0);
    }

    /// The range test's slack at a refresh seen by `camera`: the still view's when the
    /// view is the one the history was gathered in (at the first refresh: when every
    /// sample in hand was traced since `since`, from this view).
    fn range_slack(&self, camera: &CameraFrame, since: f64) -> f32 {
        let still_view = match self.camera {
            Some(c) => c.same_view(camera),
            None => self.fresh.iter().all(|f| f.t >= since),
        };
        if still_view {
            self.params.still_range_tolerance
        } else {
            self.params.range_tolerance
        }
    }

    /// The pixel where world point `p` is seen from `camera`, if on screen.
    fn pixel_at(&self, camera: &CameraFrame, p: Vec3) -> Option<(usize, f32)> {
        pixel_at(camera, p, self.width, self.height)
    }

    /// Allocate the per-pixel history now, backed with memory
    /// ([`super::Reconstructor::prepare`]); for the CPU only (the GPU keeps its own).
    pub(super) fn prepare(&mut self) {
        let px = self.cpu_pixels();
        for a in [&mut px.acc, &mut px.scratch] {
            super::lanes::touch(&mut a.count);
            a.mean.iter_mut().for_each(|s| super::lanes::touch(s));
            super::lanes::touch(&mut a.time_sum);
        }
    }

    /// The per-pixel arrays of the CPU's history, allocated at the first call.
    fn cpu_pixels(&mut self) -> &mut Pixels {
        let (w, h) = (self.width as usize, self.height as usize);
        self.pixels
            .get_or_insert_with(|| Box::new(Pixels::new(w, h)))
    }

    /// Samples in each pixel's history.
    pub(super) fn counts(&self) -> &[f32] {
        match &self.pixels {
            Some(px) => &px.acc.count,
            None => &self.gpu_counts,
        }
    }

    /// [`History::apply_finishing`] over an image that is final as it is.
    #[cfg(test)]
    pub(super) fn apply(
        &mut self,
        step: Step,
        image: &mut Image,
        age: &mut [f32],
        front: Option<(&[f32], f32)>,
    ) -> f64 {
        let finished = |_: &mut (), _, _: &mut [Vec3], _: &mut [f32]| {};
        self.apply_finishing(step, (image, age), front, &finished)
    }

    /// Carry out `step` (from [`History::plan`]): take in its samples and blend the
    /// history over `image` (the reconstruction at the step's time and view, whose
    /// per-pixel age is `age`, replaced by the age of what is shown); returns the sum
    /// over pixels of the shown age. `front`: the reconstruction's front depths and
    /// `1 / (1 + tolerance)`. The image's rows are made final as the blend first reads
    /// them: `finish(scratch, y, pixels, ages)` on row `y`, once per row, each task
    /// with a scratch of its own, so that a pass that completes the image (the fill's
    /// last push) is done while the blend has the row in the cache.
    pub(super) fn apply_finishing<S: Default + Send>(
        &mut self,
        mut step: Step,
        (image, age): (&mut Image, &mut [f32]),
        front: Option<(&[f32], f32)>,
        finish: &(impl Fn(&mut S, usize, &mut [Vec3], &mut [f32]) + Sync),
    ) -> f64 {
        if !step.in_pixel_order {
            // Planned for a GPU that failed: a stable sort keeps each pixel's samples
            // in the order they came.
            step.order.sort_by_key(|&(q, _)| q);
            step.in_pixel_order = true;
        }
        let (cuts, age_sum) = {
            let params = self.params;
            let pixels = self.cpu_pixels();
            pixels.apply(&step, &params, front, (image, age), finish)
        };
        self.cuts += cuts;
        self.recycle(step);
        age_sum
    }

    /// The counts the GPU last gave back, as a vector to read the next ones into
    /// (left empty: the next refresh's come back or the CPU takes over).
    #[cfg(feature = "gpu")]
    pub(super) fn take_gpu_counts(&mut self) -> Vec<f32> {
        std::mem::take(&mut self.gpu_counts)
    }

    /// After the GPU carried out `step`: its counts and the pixels it cut.
    #[cfg(feature = "gpu")]
    pub(super) fn done_on_gpu(&mut self, step: Step, counts: Vec<f32>, cuts: u64) {
        self.gpu_counts = counts;
        self.cuts += cuts;
        self.recycle(step);
    }

    /// Decide the refresh at `t` seen by `camera`: the view change, the samples that
    /// enter and where, and the pixels moving surfaces cut. `in_pixel_order`: the
    /// entering samples sorted by pixel (for the CPU's arrays), or left in the order
    /// they came (for a GPU, which sorts them there).
    pub(super) fn plan(&mut self, t: f64, camera: &CameraFrame, in_pixel_order: bool) -> Step {
        let since = self.view_since.take().unwrap_or(
            if self.last_camera.is_some_and(|c| c.same_view(camera)) {
                f64::NEG_INFINITY
            } else {
                f64::INFINITY
            },
        );
        self.last_camera = Some(*camera);
        let slack = self.range_slack(camera, since);
        let view = if self.camera.is_some_and(|c| c.same_view(camera)) {
            ViewChange::Same
        } else if self.params.reproject {
            ViewChange::Reproject
        } else {
            // What was gathered belongs elsewhere on screen, and so do the moving
            // surfaces seen so far.
            self.moving.clear();
            ViewChange::Reset
        };
        self.camera = Some(*camera);
        let place = Placing {
            t,
            camera: *camera,
            since,
            width: self.width,
            height: self.height,
            reproject: self.params.reproject,
        };
        let (fresh, order) = if in_pixel_order {
            self.order_fresh(&place)
        } else {
            self.place_fresh(&place)
        };
        let cuts = self.moving_cuts(t, camera);
        Step {
            t,
            camera: *camera,
            view,
            slack,
            fresh,
            order,
            in_pixel_order,
            cuts,
        }
    }

    /// The samples that enter and their pixels, in pixel order: what a sample does
    /// touches only its own pixel, so the outcome is the same as in arrival order, and
    /// the history's arrays and the samples are read in address order instead of at
    /// random. The pushed samples are used up.
    fn order_fresh(&mut self, place: &Placing) -> (Vec<Fresh>, Vec<(u32, u32)>) {
        let mut sorted = std::mem::take(&mut self.sorted);
        let mut order = std::mem::take(&mut self.order);
        let sort = SortFresh {
            pixels: (self.width * self.height) as usize,
            band: BLEND_ROWS * self.width as usize,
            chunk: SORT_CHUNK,
        };
        let moving = sort.run(
            (&self.fresh, &self.traced),
            &|f: &[Fresh], tr: &[Traced], out: &mut [u32]| place.pixels(f, tr, out),
            &mut self.binned,
            (&mut sorted, &mut order),
        );
        // In arrival order: `moving` is kept oldest first.
        self.moving.extend(moving);
        self.fresh.clear();
        self.traced.clear();
        (sorted, order)
    }

    /// The pushed samples (used up) in the order they came, each with its pixel, and
    /// the `(pixel, index)` of those that enter: what a GPU sorts by pixel itself, so
    /// that the CPU does not move the samples.
    fn place_fresh(&mut self, place: &Placing) -> (Vec<Fresh>, Vec<(u32, u32)>) {
        let mut fresh = std::mem::take(&mut self.fresh);
        fresh
            .par_chunks_mut(SORT_CHUNK)
            .zip(self.traced.par_chunks(SORT_CHUNK))
            .for_each(|(f, tr)| {
                for (f, tr) in f.chunks_mut(LANES).zip(tr.chunks(LANES)) {
                    let q = place.lanes(f, tr);
                    for (f, q) in f.iter_mut().zip(q) {
                        f.pixel = q;
                    }
                }
            });
        let mut order = std::mem::take(&mut self.order);
        order.clear();
        for (i, (f, tr)) in fresh.iter().zip(&self.traced).enumerate() {
            if f.pixel == u32::MAX {
                continue;
            }
            order.push((f.pixel, i as u32));
            if !f.still && tr.velocity != Vec3::ZERO {
                self.moving.push_back((f.hit_point, tr.velocity, f.t));
            }
        }
        // The spare vector takes the samples pushed from now on.
        self.fresh = std::mem::take(&mut self.sorted);
        self.fresh.clear();
        self.traced.clear();
        (fresh, order)
    }

    /// Forget moving samples older than the memory; the pixels where the others are now.
    fn moving_cuts(&mut self, t: f64, camera: &CameraFrame) -> Vec<u32> {
        let memory = self.params.moving_memory;
        while self.moving.front().is_some_and(|m| t - m.2 > memory) {
            self.moving.pop_front();
        }
        let mut cuts = std::mem::take(&mut self.cut_pixels);
        cuts.clear();
        for &(hit, v, ts) in &self.moving {
            if let Some((q, _)) = self.pixel_at(camera, hit + v * (t - ts) as f32) {
                cuts.push(q as u32);
            }
        }
        cuts
    }

    /// Keep a step's vectors for the next (samples pushed while the step was out
    /// are in `self.fresh`).
    fn recycle(&mut self, step: Step) {
        self.sorted = step.fresh;
        self.order = step.order;
        self.cut_pixels = step.cuts;
    }
}

/// Where a fresh sample enters the history at a refresh at `t` seen by `camera`:
/// where its surface point is seen now, or where it was traced if it was traced from
/// this view (since `since`).
struct Placing {
    t: f64,
    camera: CameraFrame,
    since: f64,
    width: u32,
    height: u32,
    reproject: bool,
}

impl Placing {
    /// [`Placing::pixel`] of each sample of `fresh` (traced at `traced`) into `out`.
    fn pixels(&self, fresh: &[Fresh], traced: &[Traced], out: &mut [u32]) {
        for ((f, tr), out) in fresh
            .chunks(LANES)
            .zip(traced.chunks(LANES))
            .zip(out.chunks_mut(LANES))
        {
            out.copy_from_slice(&self.lanes(f, tr)[..out.len()]);
        }
    }

    /// [`Placing::pixel`] of up to [`LANES`] samples `fresh` (traced at `traced`), in
    /// the first lanes. Reprojected, they go through the camera a lane at a time: the
    /// divisions were most of a history's plan when each sample went alone.
    fn lanes(&self, fresh: &[Fresh], traced: &[Traced]) -> [u32; LANES] {
        let mut out = [u32::MAX; LANES];
        if !self.reproject {
            for ((f, tr), o) in fresh.iter().zip(traced).zip(&mut out) {
                *o = self.pixel(f, tr);
            }
            return out;
        }
        // Lanes past the samples start at the eye, which no pixel sees.
        let mut d = [[0.0; LANES]; 3];
        for (l, (f, tr)) in fresh.iter().zip(traced).enumerate() {
            let p = f.hit_point + tr.velocity * (self.t - f.t) as f32;
            let e = p - self.camera.eye;
            (d[0][l], d[1][l], d[2][l]) = (e.x, e.y, e.z);
        }
        pixels_of(&self.camera, d, self.width, self.height)
    }

    /// The pixel sample `f` (traced at `tr`) enters, `u32::MAX` for none.
    fn pixel(&self, f: &Fresh, tr: &Traced) -> u32 {
        let (w, h) = (self.width, self.height);
        if self.reproject {
            let p = f.hit_point + tr.velocity * (self.t - f.t) as f32;
            pixel_at(&self.camera, p, w, h).map_or(u32::MAX, |(q, _)| q as u32)
        } else if f.t < self.since {
            u32::MAX
        } else {
            (tr.y as usize * w as usize + tr.x as usize) as u32
        }
    }
}

/// [`pixel_at`]'s pixel (`u32::MAX`: none) of each lane's point, given as its offset
/// `d` from the eye: the same pixels, in vector code.
fn pixels_of(camera: &CameraFrame, d: [Lanes; 3], width: u32, height: u32) -> [u32; LANES] {
    let [x, y, z] = project_lanes(camera, d);
    let (w, h) = (width as f32, height as f32);
    let mut out = [0; LANES];
    for l in 0..LANES {
        let (x, y) = (x[l], y[l]);
        let on = z[l] > 1e-6 && x >= 0.0 && y >= 0.0 && x < w && y < h;
        out[l] = if on {
            y as u32 * width + x as u32
        } else {
            u32::MAX
        };
    }
    out
}

/// [`CameraFrame::project`] of each lane's point, given as its offset `d` from the eye,
/// by the same operations in the same order (so to the bit where that gives a
/// projection), the depth whatever it is.
fn project_lanes(camera: &CameraFrame, d: [Lanes; 3]) -> [Lanes; 3] {
    let (f, c, du, dv) = (camera.forward, camera.corner, camera.du, camera.dv);
    let (su, sv) = (du.length_squared(), dv.length_squared());
    let mut out = [[0.0; LANES]; 3];
    for l in 0..LANES {
        let (dx, dy, dz) = (d[0][l], d[1][l], d[2][l]);
        let z = dx * f.x + dy * f.y + dz * f.z;
        let (qx, qy, qz) = (dx / z - c.x, dy / z - c.y, dz / z - c.z);
        out[0][l] = (qx * du.x + qy * du.y + qz * du.z) / su;
        out[1][l] = (qx * dv.x + qy * dv.y + qz * dv.z) / sv;
        out[2][l] = z;
    }
    out
}

/// The pixel of a `width × height` view `camera` where world point `p` is seen, and
/// its depth, if on screen.
pub(super) fn pixel_at(
    camera: &CameraFrame,
    p: Vec3,
    width: u32,
    height: u32,
) -> Option<(usize, f32)> {
    let (x, y, z) = camera.project(p)?;
    (x >= 0.0 && y >= 0.0 && x < width as f32 && y < height as f32)
        .then(|| (y as usize * width as usize + x as usize, z))
}

/// The history's per-pixel arrays on the CPU.
struct Pixels {
    acc: Accum,
    /// The next `acc` while the history is reprojected (reused), and the depth of
    /// what landed on each pixel.
    scratch: Accum,
    depth: Vec<f32>,
    /// A still sample outside its pixel's range, held back until the next one says
    /// whether it was a rare part of the pixel (kept) or the start of a change.
    held: Vec<Option<(Vec3, f64, Vec3)>>,
    /// The pixels that may hold a sample back (`None`: too many to list, every
    /// pixel may), so that dropping them all costs what was held, not the image.
    held_at: Option<Vec<u32>>,
    /// The lowest and highest colour of the reconstruction before blending over each
    /// pixel and its two neighbours in the row: of the first and last row of every
    /// band, and three rows a band as it goes (reused).
    edges: Vec<f32>,
    rolling: Vec<f32>,
    /// Where each pixel's history lands when the view moves: from, to, depth (reused).
    lands: Vec<(u32, u32, f32)>,
    /// Pixels cut during the step under way.
    cuts: u64,
    /// The reference colours the blend shows flat surfaces at.
    refs: Refs,
}

impl Pixels {
    fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            refs: Refs::new(width, height),
            acc: Accum::new(n),
            scratch: Accum::new(n),
            depth: vec![f32::INFINITY; n],
            held: vec![None; n],
            held_at: Some(Vec::new()),
            edges: Vec::new(),
            rolling: Vec::new(),
            lands: Vec::new(),
            cuts: 0,
        }
    }

    /// Carry out `step` over `image` and `age`; returns the pixels cut and the sum of
    /// the shown ages.
    fn apply<S: Default + Send>(
        &mut self,
        step: &Step,
        p: &HistoryParams,
        front: Option<(&[f32], f32)>,
        (image, age): (&mut Image, &mut [f32]),
        finish: &(impl Fn(&mut S, usize, &mut [Vec3], &mut [f32]) + Sync),
    ) -> (u64, f64) {
        self.cuts = 0;
        match step.view {
            ViewChange::Same => {}
            ViewChange::Reproject => {
                self.reproject_to(&step.camera, front, p.reprojected_count, image.width)
            }
            ViewChange::Reset => {
                self.acc.reset();
                self.drop_held();
            }
        }
        self.take_in_all(step, p, image.width as usize);
        for &q in &step.cuts {
            self.cut(q as usize);
        }
        let (cuts, age_sum) = self.blend(step.t, p, (image, age), finish);
        (self.cuts + cuts, age_sum)
    }

    /// Move every pixel's history to where its surface point is seen from `camera`,
    /// keeping at most `cap` samples' worth; with `front`, a history that lands behind
    /// a nearer surface is dropped: it was seen past a silhouette that now covers it.
    fn reproject_to(
        &mut self,
        camera: &CameraFrame,
        front: Option<(&[f32], f32)>,
        cap: f32,
        width: u32,
    ) {
        let height = (self.acc.count.len() / width.max(1) as usize) as u32;
        self.depth.fill(f32::INFINITY);
        // Where each pixel's history lands, in parallel; then landed one after
        // another in pixel order, the nearest winning as before.
        let (count, cell) = (&self.acc.count, &self.acc.cell);
        let mut lands = std::mem::take(&mut self.lands);
        lands.clear();
        lands.par_extend(
            count
                .par_iter()
                .zip(cell.par_iter())
                .enumerate()
                .filter_map(|(q, (&n, c))| {
                    if n <= 0.0 {
                        return None;
                    }
                    let (d, z) = pixel_at(camera, c.point, width, height)?;
                    (!hidden(front, d, z)).then_some((q as u32, d as u32, z))
                }),
        );
        for &(q, d, z) in &lands {
            let (q, d) = (q as usize, d as usize);
            if z < self.depth[d] {
                self.depth[d] = z;
                self.scratch.take(d, &self.acc, q, cap);
            }
        }
        self.lands = lands;
        // What nothing landed on is empty (cheaper than emptying everything first:
        // most pixels are landed on).
        for (d, _) in self
            .depth
            .iter()
            .enumerate()
            .filter(|(_, z)| **z == f32::INFINITY)
        {
            self.scratch.empty(d);
        }
        std::mem::swap(&mut self.acc, &mut self.scratch);
        self.drop_held();
    }

    /// Every fresh sample of `step` in its pixel ([`Band::take_in`]), bands of
    /// [`BLEND_ROWS`] rows of `width` pixels in parallel: a sample touches only its own
    /// pixel and each pixel sees its samples in their order, so the outcome is the
    /// same on any number of threads.
    fn take_in_all(&mut self, step: &Step, p: &HistoryParams, width: usize) {
        let band = BLEND_ROWS * width.max(1);
        let order = &step.order;
        let per_band: Vec<(u64, Vec<u32>)> = self
            .acc
            .runs_mut(band)
            .into_par_iter()
            .zip(self.held.par_chunks_mut(band))
            .zip(self.refs.bands_mut(BLEND_ROWS))
            .enumerate()
            .map(|(b, ((acc, held), refs))| {
                let base = b * band;
                let lo = order.partition_point(|&(q, _)| (q as usize) < base);
                let hi = order.partition_point(|&(q, _)| (q as usize) < base + held.len());
                let mut band = Band {
                    base,
                    acc,
                    held,
                    refs,
                    cuts: 0,
                    held_at: Vec::new(),
                };
                band.take_in_run(&order[lo..hi], &step.fresh, step.slack, p);
                (band.cuts, band.held_at)
            })
            .collect();
        let limit = self.held.len() / 8;
        for (cuts, held) in per_band {
            self.cuts += cuts;
            if let Some(at) = &mut self.held_at {
                // Listed while there are few; past that every pixel may hold one.
                if at.len() + held.len() <= limit {
                    at.extend(held);
                } else {
                    self.held_at = None;
                }
            }
        }
    }

    /// No pixel holds a sample back.
    fn drop_held(&mut self) {
        match &mut self.held_at {
            Some(at) => {
                for &q in at.iter() {
                    self.held[q as usize] = None;
                }
                at.clear();
            }
            None => {
                self.held.fill(None);
                self.held_at = Some(Vec::new());
            }
        }
    }

    fn cut(&mut self, q: usize) {
        self.cuts += (self.acc.count[q] > 0.0) as u64;
        self.acc.clear(q);
        self.held[q] = None;
    }

    /// Clamp each pixel's history to the box of the reconstruction around it, then
    /// blend it over `image` at time `t`, each row made final by `finish` first;
    /// returns the pixels the clamp cut and the sum of the shown ages.
    fn blend<S: Default + Send>(
        &mut self,
        t: f64,
        p: &HistoryParams,
        (image, age): (&mut Image, &mut [f32]),
        finish: &(impl Fn(&mut S, usize, &mut [Vec3], &mut [f32]) + Sync),
    ) -> (u64, f64) {
        let (edges, rolling) = (&mut self.edges, &mut self.rolling);
        blend::blend_image(
            (&mut self.acc, &self.refs),
            (edges, rolling),
            (t, p),
            (image, age),
            finish,
        )
    }
}

/// A band of consecutive pixels of the history (from pixel `base`) taking in its
/// fresh samples; what it cut and the pixels it held a sample back in are merged after.
struct Band<'a> {
    base: usize,
    acc: AccumMut<'a>,
    held: &'a mut [Option<(Vec3, f64, Vec3)>],
    /// The band's blocks' reference colours: the last sample each took, in pixel
    /// order, still or not.
    refs: BandRefs<'a>,
    cuts: u64,
    held_at: Vec<u32>,
}

impl Band<'_> {
    /// The `(pixel, index)` run `order` of `fresh`, in order.
    fn take_in_run(
        &mut self,
        order: &[(u32, u32)],
        fresh: &[Fresh],
        slack: f32,
        p: &HistoryParams,
    ) {
        for (k, &(q, i)) in order.iter().enumerate() {
            if let Some(&(qa, _)) = order.get(k + PREFETCH_AHEAD) {
                // Pixels are visited in order, but sparsely.
                let qa = qa as usize - self.base;
                prefetch(self.acc.cell, qa);
                prefetch(self.acc.time_sum, qa);
                prefetch(self.held, qa);
            }
            self.take_in(q as usize - self.base, &fresh[i as usize], slack, p);
        }
    }

    /// A still sample joins pixel `q` (of the band) if it agrees with what the pixel
    /// showed; two in a row that do not start the pixel over; a moving one cuts it.
    fn take_in(&mut self, q: usize, f: &Fresh, slack: f32, p: &HistoryParams) {
        self.refs.set(q, f.color);
        if !f.still {
            // Something moving covers (part of) the pixel now.
            self.cut(q);
            return;
        }
        let l = luminance(f.color);
        let (lo, hi) = self.acc.cell[q].range;
        let outside =
            self.acc.count[q] >= p.min_count_to_test && (l < lo - slack || l > hi + slack);
        match (outside, self.held[q].take()) {
            (false, held) => {
                // In range: a held sample was a rare part of the pixel after all.
                if let Some((c, t, hit)) = held {
                    self.add(q, c, t, hit, p.max_count);
                }
                self.add(q, f.color, f.t, f.hit_point, p.max_count);
            }
            (true, None) => {
                self.held[q] = Some((f.color, f.t, f.hit_point));
                self.held_at.push((self.base + q) as u32);
            }
            (true, Some((c, t, hit))) => {
                // Two in a row outside what the pixel showed: it changed (a surface
                // uncovered, a shadow gone); start over from them.
                self.cut(q);
                self.add(q, c, t, hit, p.max_count);
                self.add(q, f.color, f.t, f.hit_point, p.max_count);
            }
        }
    }

    fn cut(&mut self, q: usize) {
        self.cuts += (self.acc.count[q] > 0.0) as u64;
        self.acc.clear(q);
        self.held[q] = None;
    }

    fn add(&mut self, q: usize, c: Vec3, t: f64, hit: Vec3, max: f32) {
        let a = &mut self.acc;
        let mut time_sum = a.time_sum[q] + t;
        let mut count = a.count[q] + 1.0;
        // Past `max` samples, the mean of about the last `max` of them.
        let mean = if a.count[q] > 0.0 {
            let m = a.mean(q);
            m + (c - m) * (1.0 / count)
        } else {
            c
        };
        let l = luminance(c);
        let cell = &mut a.cell[q];
        cell.point = hit;
        cell.range = (cell.range.0.min(l), cell.range.1.max(l));
        if count > max {
            time_sum *= (max / count) as f64;
            count = max;
        }
        a.set_mean(q, mean);
        a.time_sum[q] = time_sum;
        a.count[q] = count;
    }
}

/// Whether a point at depth `z` seen in pixel `q` lies behind the front depth there
/// (beyond the visibility pass's tolerance).
fn hidden(front: Option<(&[f32], f32)>, q: usize, z: f32) -> bool {
    front.is_some_and(|(f, keep)| super::splat::behind_front(f[q], z, keep))
}

/// Samples a chunk of [`SortFresh::run`]'s first pass places and bins: a chunk
/// (320 KB of samples) stays in L2 between the two.
const SORT_CHUNK: usize = 1 << 13;

/// A stable sort of fresh samples by pixel, as two counting sorts whose every pass
/// reads and writes the samples in address order (or within a band's few hundred
/// kilobytes): each chunk of `chunk` samples places its samples and bins those that
/// enter by band of `band` of the `pixels` pixels, in its own part of a scratch
/// vector; then each band gathers its samples from every chunk, in chunk order, and
/// sorts them by pixel. Chunks, then bands, go in parallel; the order is the same on
/// any number of threads.
struct SortFresh {
    pixels: usize,
    band: usize,
    chunk: usize,
}

/// What one chunk binned: where each band's samples start in its part (and, last,
/// where they end), and the moving samples among them `(hit point, velocity, time)`,
/// in arrival order.
struct Chunk {
    starts: Vec<u32>,
    moving: Vec<(Vec3, Vec3, f64)>,
}

impl SortFresh {
    /// The samples `fresh` (traced at `traced`) that `place` puts on a pixel
    /// (`u32::MAX`: none), each with its pixel, in pixel order into `sorted`, and
    /// their `(pixel, index)` into `order`; returns the moving ones, in arrival
    /// order. `binned` is scratch.
    fn run(
        &self,
        (fresh, traced): (&[Fresh], &[Traced]),
        place: &(impl Fn(&[Fresh], &[Traced], &mut [u32]) + Sync),
        binned: &mut Vec<Fresh>,
        (sorted, order): (&mut Vec<Fresh>, &mut Vec<(u32, u32)>),
    ) -> Vec<(Vec3, Vec3, f64)> {
        let (band, chunk) = (self.band.max(1), self.chunk.max(1));
        let bands = self.pixels.div_ceil(band);
        fit(binned, fresh.len());
        let chunks: Vec<Chunk> = fresh
            .par_chunks(chunk)
            .zip(traced.par_chunks(chunk))
            .zip(binned.par_chunks_mut(chunk))
            .map(|((f, tr), out)| bin_chunk((f, tr), place, (band, bands), out))
            .collect();
        let mut totals = vec![0usize; bands];
        for c in &chunks {
            for (b, n) in totals.iter_mut().enumerate() {
                *n += (c.starts[b + 1] - c.starts[b]) as usize;
            }
        }
        fit(sorted, totals.iter().sum());
        fit(order, sorted.len());
        let binned = &binned[..];
        band_parts(&totals, sorted, order).into_par_iter().for_each(
            |(b, part, part_order, first)| {
                let segments = chunks.iter().enumerate().map(|(c, ch)| {
                    let at = c * chunk;
                    &binned[at + ch.starts[b] as usize..at + ch.starts[b + 1] as usize]
                });
                let base = b * band;
                sort_band(segments, base, band.min(self.pixels - base), part);
                for (j, (o, f)) in part_order.iter_mut().zip(&*part).enumerate() {
                    *o = (f.pixel, (first + j) as u32);
                }
            },
        );
        chunks.into_iter().flat_map(|c| c.moving).collect()
    }
}

/// A band's part of the sorted samples and of their order, and where it starts.
type BandPart<'a> = (usize, &'a mut [Fresh], &'a mut [(u32, u32)], usize);

/// `sorted` and `order` split into the parts of bands of `totals` samples.
fn band_parts<'a>(
    totals: &[usize],
    sorted: &'a mut [Fresh],
    order: &'a mut [(u32, u32)],
) -> Vec<BandPart<'a>> {
    let mut parts = Vec::with_capacity(totals.len());
    let (mut rest, mut rest_order, mut first) = (sorted, order, 0);
    for (b, &len) in totals.iter().enumerate() {
        let (part, tail) = rest.split_at_mut(len);
        let (part_order, tail_order) = rest_order.split_at_mut(len);
        parts.push((b, part, part_order, first));
        (rest, rest_order, first) = (tail, tail_order, first + len);
    }
    parts
}

/// `v` with `n` elements, of which only those written next are read: growing fills
/// with copies of what is there, and shrinking keeps them, so that a reused vector is
/// not written twice.
fn fit<T: Copy + Default>(v: &mut Vec<T>, n: usize) {
    if v.len() < n {
        v.resize(n, T::default());
    } else {
        v.truncate(n);
    }
}

/// Place the samples `fresh` (traced at `traced`) and bin those that enter by band of
/// `band` pixels (`bands` of them) into `out`, each band's in arrival order.
fn bin_chunk(
    (fresh, traced): (&[Fresh], &[Traced]),
    place: &impl Fn(&[Fresh], &[Traced], &mut [u32]),
    (band, bands): (usize, usize),
    out: &mut [Fresh],
) -> Chunk {
    // Counted two places up, so that after the scan `starts[b + 1]` is where band
    // `b` starts, and after the binning where it ends.
    let mut starts = vec![0u32; bands + 2];
    let mut moving = Vec::new();
    let mut pixels = vec![0; fresh.len()];
    place(fresh, traced, &mut pixels);
    let entering = || {
        let placed = fresh.iter().zip(traced).zip(&pixels);
        placed.filter(|(_, &q)| q != u32::MAX)
    };
    for ((f, tr), &q) in entering() {
        starts[q as usize / band + 2] += 1;
        if !f.still && tr.velocity != Vec3::ZERO {
            moving.push((f.hit_point, tr.velocity, f.t));
        }
    }
    for k in 2..starts.len() {
        starts[k] += starts[k - 1];
    }
    for ((f, _), &q) in entering() {
        let slot = &mut starts[q as usize / band + 1];
        out[*slot as usize] = Fresh { pixel: q, ..*f };
        *slot += 1;
    }
    starts.truncate(bands + 1);
    Chunk { starts, moving }
}

/// The samples of `segments`, in that order, all in the band of `len` pixels from
/// pixel `base`, sorted stably by pixel into `out`: a counting sort over the band's
/// pixels, or for a few samples a stable comparison sort.
fn sort_band<'a>(
    segments: impl Iterator<Item = &'a [Fresh]> + Clone,
    base: usize,
    len: usize,
    out: &mut [Fresh],
) {
    if out.len() * 16 <= len {
        let mut k = 0;
        for s in segments {
            out[k..k + s.len()].copy_from_slice(s);
            k += s.len();
        }
        out.sort_by_key(|f| f.pixel);
        return;
    }
    let mut starts = vec![0u32; len + 1];
    for f in segments.clone().flatten() {
        starts[f.pixel as usize - base + 1] += 1;
    }
    for k in 1..starts.len() {
        starts[k] += starts[k - 1];
    }
    for f in segments.flatten() {
        let slot = &mut starts[f.pixel as usize - base];
        out[*slot as usize] = *f;
        *slot += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{reconstruction::RingSample, scene::Camera};

    fn camera(x: f32) -> CameraFrame {
        Camera {
            eye: Vec3::new(x, 0.0, 1.0),
            at: Vec3::new(x, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 90.0,
            hither: 1e-3,
        }
        .frame(4, 4)
    }

    /// A still sample of the plane z = 0 at pixel position `(x, y)` of `camera(0.0)`.
    fn sample(x: f32, y: f32, t: f64, c: f32) -> RingSample {
        let cam = camera(0.0);
        RingSample {
            x,
            y,
            t,
            color: Vec3::splat(c),
            hit_point: cam.eye + cam.direction(x, y),
            velocity: Vec3::ZERO,
            anchor: Default::default(),
        }
    }

    fn cutting() -> HistoryParams {
        HistoryParams {
            reproject: false,
            ..Default::default()
        }
    }

    /// Refresh over a flat reconstruction of colour `recon` (the clamp then allows
    /// `recon ± tolerance`).
    fn refresh(h: &mut History, t: f64, cam: &CameraFrame, recon: f32) -> Image {
        let mut img = Image::new(4, 4);
        img.pixels.fill(Vec3::splat(recon));
        let step = h.plan(t, cam, true);
        h.apply(step, &mut img, &mut [0.0; 16], None);
        img
    }

    /// What [`SortFresh::run`] must give: the samples that enter, stably sorted by
    /// pixel, and the moving ones in arrival order.
    fn sorted_reference(
        fresh: &[Fresh],
        traced: &[Traced],
        place: impl Fn(&Fresh, &Traced) -> u32,
    ) -> (Vec<Fresh>, Vec<(Vec3, Vec3, f64)>) {
        let placed = fresh
            .iter()
            .zip(traced)
            .map(|(f, tr)| (place(f, tr), f, tr));
        let entering: Vec<_> = placed.filter(|p| p.0 != u32::MAX).collect();
        let moving = entering
            .iter()
            .filter(|(_, f, tr)| !f.still && tr.velocity != Vec3::ZERO);
        let moving = moving
            .map(|(_, f, tr)| (f.hit_point, tr.velocity, f.t))
            .collect();
        let mut sorted: Vec<Fresh> = entering
            .iter()
            .map(|&(q, f, _)| Fresh { pixel: q, ..*f })
            .collect();
        sorted.sort_by_key(|f| f.pixel);
        (sorted, moving)
    }

    #[test]
    fn sorting_fresh_samples_by_pixel_is_stable_and_the_same_on_any_threads() {
        let mut rng = crate::sampling::Rng::new(&[5]);
        let cases = [
            (10, 1000, 64, 4),
            (5000, 1000, 64, 700),
            (3, 3, 2, 1),
            (0, 7, 64, 8),
            (20000, 4000, 300, 8192),
            (20000, 4000, 4000, 3),
            (9000, 1, 1, 1000),
        ];
        for (n, pixels, band, chunk) in cases {
            // A quarter off screen, many in a few pixels, some moving.
            let fresh: Vec<Fresh> = (0..n)
                .map(|i| Fresh {
                    t: i as f64,
                    color: Vec3::splat(rng.uniform()),
                    still: rng.uniform() < 0.8,
                    ..Default::default()
                })
                .collect();
            let traced: Vec<Traced> = (0..n)
                .map(|_| Traced {
                    x: rng.uniform() * 1.3 * pixels as f32,
                    y: rng.uniform(),
                    velocity: Vec3::X * (rng.uniform() < 0.5) as u32 as f32,
                })
                .collect();
            let place = |_: &Fresh, tr: &Traced| {
                let q = if tr.y < 0.3 {
                    tr.x as u32 % 5
                } else {
                    tr.x as u32
                };
                if q < pixels as u32 {
                    q
                } else {
                    u32::MAX
                }
            };
            let (want, want_moving) = sorted_reference(&fresh, &traced, place);
            let sort = SortFresh {
                pixels,
                band,
                chunk,
            };
            for threads in [1, 3] {
                let (mut binned, mut got, mut order) = (vec![], vec![Fresh::default(); 9], vec![]);
                let moving = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| {
                        sort.run(
                            (&fresh, &traced),
                            &|f: &[Fresh], tr: &[Traced], out: &mut [u32]| {
                                for ((f, tr), o) in f.iter().zip(tr).zip(out) {
                                    *o = place(f, tr);
                                }
                            },
                            &mut binned,
                            (&mut got, &mut order),
                        )
                    });
                let at = format!("{n} samples over {pixels} pixels, {threads} threads");
                let key = |v: &[Fresh]| {
                    v.iter()
                        .map(|f| (f.pixel, f.t.to_bits()))
                        .collect::<Vec<_>>()
                };
                assert_eq!(key(&got), key(&want), "{at}");
                let want_order: Vec<_> =
                    (0..want.len()).map(|k| (want[k].pixel, k as u32)).collect();
                assert_eq!(order, want_order, "{at}");
                assert_eq!(moving, want_moving, "{at}");
            }
        }
    }

    /// Many samples in few pixels of a `4 × 40` view `cam` (three bands of rows), a
    /// fifth far brighter than the rest (so that the order within a pixel decides
    /// what is held back and what is cut), some moving, some off the image.
    fn crowded_batch(
        rng: &mut crate::sampling::Rng,
        cam: &CameraFrame,
        t: f64,
    ) -> Vec<(RingSample, bool)> {
        (0..2000)
            .map(|i| {
                let (x, y) = (rng.uniform() * 4.4, rng.uniform() * 40.0);
                let c = if rng.uniform() < 0.2 {
                    0.9
                } else {
                    0.5 + 0.02 * rng.uniform()
                };
                let moving = i % 50 == 0;
                let s = RingSample {
                    x,
                    y,
                    t: t + 0.0001 * i as f64,
                    color: Vec3::splat(c),
                    hit_point: cam.eye + cam.direction(x.min(3.99), y),
                    velocity: if moving { Vec3::X } else { Vec3::ZERO },
                    anchor: Default::default(),
                };
                (s, moving)
            })
            .collect()
    }

    #[test]
    fn a_plan_in_arrival_order_comes_out_as_one_in_pixel_order() {
        // What a GPU is given, carried out on the CPU (a GPU that failed), against
        // the CPU's own plan: the same images, counts and cuts at every refresh.
        let mut rng = crate::sampling::Rng::new(&[3]);
        let mut cam = camera(0.0);
        cam = Camera {
            eye: cam.eye,
            at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 90.0,
            hither: 1e-3,
        }
        .frame(4, 40);
        let (w, h) = (4, 40);
        for params in [cutting(), HistoryParams::default()] {
            let mut sides = [History::new(w, h, params), History::new(w, h, params)];
            let (mut unsorted, mut grown) = (0, 0f32);
            for k in 0..6 {
                let t = 0.1 * k as f64;
                for (s, moving) in crowded_batch(&mut rng, &cam, t) {
                    sides.iter_mut().for_each(|h| h.push(&s, moving));
                }
                let [a, b] = &mut sides;
                let (sa, sb) = (a.plan(t + 0.05, &cam, true), b.plan(t + 0.05, &cam, false));
                assert!(!sb.in_pixel_order);
                assert_eq!(sa.order.len(), sb.order.len(), "refresh {k}");
                let pixels = |s: &Step| s.order.iter().map(|o| o.0).collect::<Vec<_>>();
                unsorted += pixels(&sb).windows(2).any(|w| w[0] > w[1]) as usize;
                let mut images = [Image::new(w, h), Image::new(w, h)];
                let mut ages = vec![0.0; (w * h) as usize];
                for (img, (h, step)) in images.iter_mut().zip([(a, sa), (b, sb)]) {
                    img.pixels.fill(Vec3::splat(0.5));
                    h.apply(step, img, &mut ages, None);
                }
                assert_eq!(images[0].pixels, images[1].pixels, "refresh {k}");
                assert_eq!(sides[0].counts(), sides[1].counts(), "refresh {k}");
                assert_eq!(sides[0].cuts, sides[1].cuts, "refresh {k}");
                assert_eq!(sides[0].moving, sides[1].moving, "refresh {k}");
                grown = grown.max(sides[0].counts().iter().copied().fold(0.0, f32::max));
            }
            assert!(
                sides[0].cuts > 0 && grown >= 3.0,
                "{} cuts, {grown}",
                sides[0].cuts
            );
            assert!(unsorted >= 5, "the arrival order should not come sorted");
        }
    }

    #[test]
    fn still_samples_accumulate_and_a_new_view_clears_them() {
        let mut h = History::new(4, 4, cutting());
        let cam = camera(0.0);
        refresh(&mut h, 0.0, &cam, 0.5);
        for k in 0..9 {
            h.push(&sample(1.5, 1.5, 0.01 * k as f64, 0.52), false);
        }
        let img = refresh(&mut h, 0.1, &cam, 0.5);
        assert_eq!(h.counts()[5], 9.0);
        // (0.5 · 1 + 0.52 · 9) / 10
        assert!(
            (img.get(1, 1).x - 0.518).abs() < 1e-5,
            "{:?}",
            img.get(1, 1)
        );
        assert_eq!(img.get(0, 0), Vec3::splat(0.5));
        refresh(&mut h, 0.2, &camera(0.1), 0.5);
        assert!(h.counts().iter().all(|&n| n == 0.0));
    }

    #[test]
    fn a_history_of_equal_samples_keeps_exactly_their_value() {
        // The premise: their sum divided by their count is a rounding off.
        let (c, n) = (0.3f32, 40);
        let summed = (0..n).fold(0f32, |s, _| s + c) / n as f32;
        assert_ne!(summed, c);
        let mut h = History::new(4, 4, cutting());
        let cam = camera(0.0);
        refresh(&mut h, 0.0, &cam, c);
        for k in 0..n {
            h.push(&sample(1.5, 1.5, 0.001 * k as f64, c), false);
        }
        // The reconstruction a rounding below: the history's mean is what is shown.
        let img = refresh(&mut h, 0.1, &cam, f32::from_bits(c.to_bits() - 1));
        assert_eq!(h.counts()[5], n as f32);
        let acc = &h.pixels.as_ref().unwrap().acc;
        assert_eq!([0, 1, 2].map(|k| acc.mean[k][5]), [c; 3]);
        assert_eq!(img.get(1, 1), Vec3::splat(c));
    }

    #[test]
    fn samples_from_before_the_view_settled_are_left_out() {
        let mut h = History::new(4, 4, cutting());
        let cam = camera(0.0);
        h.push(&sample(0.5, 0.5, 0.05, 0.5), false);
        h.push(&sample(0.5, 0.5, 0.15, 0.5), false);
        // Without being told, the first refresh trusts nothing.
        refresh(&mut h, 0.2, &cam, 0.5);
        assert_eq!(h.counts()[0], 0.0);
        h.push(&sample(0.5, 0.5, 0.05, 0.5), false);
        h.push(&sample(0.5, 0.5, 0.15, 0.5), false);
        h.set_view_since(0.1);
        refresh(&mut h, 0.3, &cam, 0.5);
        assert_eq!(h.counts()[0], 1.0);
    }

    #[test]
    fn a_new_view_moves_the_history_with_its_surface() {
        let mut h = History::new(4, 4, HistoryParams::default());
        let cam = camera(0.0);
        refresh(&mut h, 0.0, &cam, 0.5);
        for k in 0..12 {
            h.push(&sample(1.5, 1.5, 0.01 * k as f64, 0.5), false);
        }
        refresh(&mut h, 0.2, &cam, 0.5);
        assert_eq!(h.counts()[5], 12.0);
        // The camera moves by one pixel's width on the plane to the right (the pixel
        // footprint at distance 1 is 2·tan 45° / 4 = 0.5), so the surface point seen at
        // pixel (1, 1) is now seen at pixel (0, 1); its count is capped.
        refresh(&mut h, 0.3, &camera(0.5), 0.5);
        assert_eq!(h.counts()[4], 8.0);
        assert_eq!(h.counts().iter().filter(|&&n| n > 0.0).count(), 1);
    }

    #[test]
    fn moving_samples_and_changes_cut_the_pixel() {
        let mut h = History::new(4, 4, HistoryParams::default());
        let cam = camera(0.0);
        refresh(&mut h, 0.0, &cam, 0.5);
        for p in [0.5, 2.5] {
            for k in 0..8 {
                h.push(&sample(p, 0.5, 0.01 * k as f64, 0.5), false);
            }
        }
        refresh(&mut h, 0.1, &cam, 0.5);
        assert_eq!((h.counts()[0], h.counts()[2]), (8.0, 8.0));
        // Something moving covers pixel 0.
        h.push(&sample(0.5, 0.5, 0.11, 0.5), true);
        // Pixel 2 turns dark: one sample out of range is held back, two cut.
        h.push(&sample(2.5, 0.5, 0.12, 0.1), false);
        refresh(&mut h, 0.13, &cam, 0.5);
        assert_eq!((h.counts()[0], h.counts()[2]), (0.0, 8.0));
        h.push(&sample(2.5, 0.5, 0.14, 0.1), false);
        refresh(&mut h, 0.15, &cam, 0.5);
        // Cut, then restarted from the two dark samples; the clamp to the (bright)
        // reconstruction then keeps one sample's worth.
        assert!(h.counts()[2] <= 2.0, "{}", h.counts()[2]);
        assert!(h.cuts >= 2);
    }

    #[test]
    fn a_still_view_tests_the_range_with_its_own_slack() {
        // Eight samples of 0.5 in pixel (1, 1), then two of 0.65: 0.15 above the range,
        // inside the still view's slack (0.2) but outside the moving view's (0.1).
        let run = |second: CameraFrame| {
            let mut h = History::new(4, 4, HistoryParams::default());
            let cam = camera(0.0);
            refresh(&mut h, 0.0, &cam, 0.5);
            for k in 0..8 {
                h.push(&sample(1.5, 1.5, 0.01 * k as f64, 0.5), false);
            }
            refresh(&mut h, 0.1, &cam, 0.5);
            for k in 0..2 {
                h.push(&sample(1.5, 1.5, 0.11 + 0.01 * k as f64, 0.65), false);
            }
            refresh(&mut h, 0.2, &second, 0.5);
            h.counts().iter().copied().fold(0.0, f32::max)
        };
        // Still: both kept (and the mean, 0.53, stays within the clamp).
        assert_eq!(run(camera(0.0)), 10.0);
        // The view moves by a pixel: the history follows its surface (count capped at
        // 8), and the two samples cut it.
        assert!(run(camera(0.5)) <= 2.0);
    }

    #[test]
    fn bad_parameters_are_named() {
        let bad = HistoryParams {
            range_tolerance: f32::NAN,
            ..Default::default()
        };
        assert!(bad.check().unwrap_err().0.contains("range_tolerance"));
        let bad = HistoryParams {
            still_range_tolerance: -0.1,
            ..Default::default()
        };
        assert!(bad.check().unwrap_err().0.contains("still_range_tolerance"));
        assert!(HistoryParams::default().check().is_ok());
    }

    /// A `width × height` view from `eye` towards `at` moved half a unit down −z.
    fn looking(eye: [f32; 3], at: [f32; 3], width: u32, height: u32) -> CameraFrame {
        Camera {
            eye: Vec3::from(eye),
            at: Vec3::from(at) + Vec3::new(0.0, 0.0, -0.5),
            up: Vec3::Y,
            fov_y_deg: 70.0,
            hither: 1e-3,
        }
        .frame(width, height)
    }

    proptest::proptest! {
        /// Placed a lane at a time, samples go where each alone goes: on or off the
        /// image, behind the eye, moving or not, in runs that fill part of the lanes.
        #[test]
        fn placing_in_lanes_is_placing_each(
            eye in proptest::array::uniform3(-3.0..3.0f32),
            at in proptest::array::uniform3(-3.0..3.0f32),
            (width, height) in (1..300u32, 1..200u32),
            reproject in proptest::bool::ANY,
            samples in proptest::collection::vec(
                (
                    proptest::array::uniform3(-6.0..6.0f32),
                    proptest::array::uniform3(-2.0..2.0f32),
                    0.0..2.0f64,
                    (0.0..300.0f32, 0.0..200.0f32),
                ),
                0..40,
            ),
        ) {
            let camera = looking(eye, at, width, height);
            let place = Placing { t: 1.5, camera, since: 1.0, width, height, reproject };
            let fresh: Vec<Fresh> = samples
                .iter()
                .map(|&(p, _, t, _)| Fresh { t, hit_point: Vec3::from(p), ..Default::default() })
                .collect();
            let traced: Vec<Traced> = samples
                .iter()
                .map(|&(_, v, _, (x, y))| Traced {
                    x: x.min(width as f32 - 1.0),
                    y: y.min(height as f32 - 1.0),
                    velocity: Vec3::from(v),
                })
                .collect();
            let each: Vec<u32> = fresh.iter().zip(&traced).map(|(f, tr)| place.pixel(f, tr)).collect();
            let mut lanes = vec![7; fresh.len()];
            place.pixels(&fresh, &traced, &mut lanes);
            proptest::prop_assert_eq!(lanes, each);
        }

        /// Where the camera projects a point, its lanes give the same coordinates and
        /// depth to the bit.
        #[test]
        fn projecting_in_lanes_is_projecting_each(
            eye in proptest::array::uniform3(-3.0..3.0f32),
            at in proptest::array::uniform3(-3.0..3.0f32),
            points in proptest::collection::vec(proptest::array::uniform3(-6.0..6.0f32), 8),
        ) {
            let camera = looking(eye, at, 640, 480);
            let mut d = [[0.0; LANES]; 3];
            for (l, p) in points.iter().enumerate() {
                let e = Vec3::from(*p) - camera.eye;
                (d[0][l], d[1][l], d[2][l]) = (e.x, e.y, e.z);
            }
            let got = project_lanes(&camera, d);
            for (l, p) in points.iter().enumerate() {
                if let Some((x, y, z)) = camera.project(Vec3::from(*p)) {
                    let bits = |v: [f32; 3]| v.map(f32::to_bits);
                    proptest::prop_assert_eq!(bits([got[0][l], got[1][l], got[2][l]]), bits([x, y, z]));
                }
            }
        }
    }
}
