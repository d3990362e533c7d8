//! A live refresh of a moving view in two parts, so that it shows the samples traced
//! while it was built.
//!
//! Live, an image is built from the samples in hand when its build starts, a build's
//! time before its refresh, and on a moving view the temporal filters are short: that
//! lag is most of what live loses against the same samples reconstructed at once. Most
//! of a moving view's build places and splats the ring, which the newest samples do
//! not change. So the first part places and splats the ring in hand; then the samples
//! that arrived meanwhile are taken in, placed and splatted over those sums (where one
//! of them lands in front of what the first part's fronts let through, the pixel's
//! first sums are dropped, as the visibility pass would have dropped them), and the
//! resolve, fill and history's blend follow. The temporal filter counts every sample's
//! age from the newest sample the refresh expects to have once the second part runs
//! (the first part's newest plus the usual gap, smoothed over refreshes). A still
//! view's refresh, which carries its sums and places only new samples, is not split.

use std::time::Instant;

use rayon::prelude::*;

use super::{
    splat::{BandSplats, CHANNELS},
    spread::Viewpoint,
    Reconstructor,
};
use crate::{scene::CameraFrame, tiles::TilingSnapshot, trace::StreamSample};

/// Weight of the newest gap in the smoothed gap between a first part's newest sample
/// and the newest the second part took in (about eight refreshes).
const GAP_WEIGHT: f64 = 0.125;

impl Reconstructor {
    /// [`Reconstructor::reconstruct`] for an image thread whose samples keep arriving
    /// while it builds: a moving view's refresh on the CPU takes `late()`'s samples
    /// in between placing the ring and resolving it (the module's note); any other
    /// refresh is made as `reconstruct` makes it and `late` is not called. Returns how
    /// many samples the second part took in.
    pub fn reconstruct_taking_late<F>(
        &mut self,
        t: f64,
        camera: &CameraFrame,
        tiling: &TilingSnapshot,
        late: F,
    ) -> usize
    where
        F: FnOnce() -> Vec<Vec<StreamSample>>,
    {
        let newest = self.ring.newest_time();
        let split = self.will_resplat(camera) && !self.refreshes_on_gpu() && newest.is_finite();
        if !split {
            self.reconstruct(t, camera, tiling);
            return 0;
        }
        self.eyes.push(t, camera.eye);
        self.eye_ages = self.eyes.ages();
        self.origin_ahead = Some(newest + self.late_gap);
        let (mut plan, first_fronts, first_pieces) = self.first_part(t, camera, tiling);
        let (m, lap) = self.take_late_in(t, camera, &late(), newest, &first_fronts);
        self.origin_ahead = None;
        self.splat_to_end(&mut plan, lap, Some(first_pieces));
        self.passes.count_refresh();
        self.motion = None;
        m
    }

    /// The plan of a split refresh, then its ring placed and splatted; the plan, the
    /// fronts the splat was tested against and the pieces it placed.
    fn first_part(
        &mut self,
        t: f64,
        camera: &CameraFrame,
        tiling: &TilingSnapshot,
    ) -> (super::plan::RefreshPlan, Vec<f32>, usize) {
        let plan = self.plan(t, camera, tiling);
        let lap = Instant::now();
        self.prepare_splats(&plan);
        let lap = self.passes.lap(1, lap);
        self.front_depths();
        let fronts = self.front.clone();
        let lap = self.passes.lap(2, lap);
        self.splat_only(camera);
        self.passes.lap(4, lap);
        (plan, fronts, self.pieces)
    }

    /// Take `batches` in (traced after the first part's newest sample, `newest`),
    /// place them after its pieces and make the fronts again over both, dropping the
    /// first part's sums behind a nearer front than `first_fronts`; how many the ring
    /// holds of them, and when this ended (each step timed as the pass it is).
    fn take_late_in(
        &mut self,
        t: f64,
        camera: &CameraFrame,
        batches: &[Vec<StreamSample>],
        newest: f64,
        first_fronts: &[f32],
    ) -> (usize, Instant) {
        let taken: usize = batches.iter().map(Vec::len).sum();
        for b in batches {
            self.push_stream(b);
        }
        let m = taken.min(self.ring.len());
        if m == 0 {
            return (0, Instant::now());
        }
        let gap = (self.ring.newest_time() - newest).max(0.0);
        self.late_gap += GAP_WEIGHT * (gap - self.late_gap);
        let from = self.ring.len() - m;
        self.follow_motion_if_asked(t, from);
        self.placed += m;
        let lap = Instant::now();
        self.place_pieces(t, camera, from, true);
        let lap = self.passes.lap(1, lap);
        self.front_depths();
        self.drop_sums_behind_new_fronts(first_fronts);
        (m, self.passes.lap(2, lap))
    }

    /// The splats of every binned piece into the sums and coverage differences, from
    /// zero, bands in parallel: a first part's splat, resolved later.
    fn splat_only(&mut self, camera: &CameraFrame) {
        let (w, h) = (self.width as usize, self.height as usize);
        let (cs, rows, cstride) = (self.cs, self.band_rows, w + 1);
        let (test, keep) = (self.spread_test(), self.visibility_keep());
        let splats = BandSplats {
            binned: &self.binned[..self.pieces],
            rows,
            h,
            cs,
            cstride,
            front: keep.map(|k| (&self.front[..], k)),
            spread: (self.spread).view(Viewpoint::new(camera, &self.eye_ages, test)),
            carried: false,
        };
        self.acc
            .par_chunks_mut(rows * CHANNELS * cs)
            .zip(self.cov.par_chunks_mut(rows * cstride))
            .enumerate()
            .for_each(|(b, (acc, cov))| splats.band(b, acc, cov));
    }

    /// Where a late sample's front lies in front of `first`'s (the first part's fronts)
    /// beyond the visibility pass's tolerance, the first part's sums there were made
    /// of samples it now hides: drop them.
    fn drop_sums_behind_new_fronts(&mut self, first: &[f32]) {
        let Some(keep) = self.visibility_keep() else {
            return;
        };
        let (w, cs) = (self.width as usize, self.cs);
        let front = &self.front;
        self.acc
            .par_chunks_mut(CHANNELS * cs)
            .enumerate()
            .for_each(|(y, row)| {
                let (now, was) = (&front[y * w..][..w], &first[y * w..][..w]);
                for x in 0..w {
                    if was[x].is_finite() && super::splat::behind_front(now[x], was[x], keep) {
                        for ch in 0..CHANNELS {
                            row[ch * cs + x] = 0.0;
                        }
                    }
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::{
        image::Image,
        reconstruction::ReconParams,
        scene::Camera,
        tiles::{Rect, TileGradients},
        trace::Sample,
    };

    const W: u32 = 48;
    const H: u32 = 32;

    fn camera(x: f32) -> CameraFrame {
        Camera {
            eye: Vec3::new(x, 0.0, 2.0),
            at: Vec3::new(x, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 60.0,
            hither: 1e-3,
        }
        .frame(W, H)
    }

    fn tiling() -> TilingSnapshot {
        TilingSnapshot {
            tiles: vec![TileGradients {
                rect: Rect {
                    x0: 0,
                    y0: 0,
                    x1: W,
                    y1: H,
                },
                gx: 0.05,
                gy: 0.05,
                gt: 2.0,
            }],
        }
    }

    /// Samples of a plane at z = 0 striped in x, traced through `c` at times from `t0`
    /// to `t1`; the stripes bright from `bright_from` on (a change the late ones show).
    fn traced(
        c: &CameraFrame,
        n: usize,
        (t0, t1): (f64, f64),
        seed: u64,
        bright: bool,
    ) -> Vec<StreamSample> {
        let mut rng = crate::sampling::Rng::new(&[seed]);
        (0..n)
            .map(|i| {
                let (x, y) = (rng.uniform() * W as f32, rng.uniform() * H as f32);
                let d = c.direction(x, y);
                let hit_point = c.eye + d * (c.eye.z / -d.z);
                let stripe = ((hit_point.x * 4.0).floor() as i32).rem_euclid(2) as f32;
                let color = Vec3::splat(0.2 + 0.3 * stripe + if bright { 0.4 } else { 0.0 });
                StreamSample {
                    x,
                    y,
                    t: t0 + (t1 - t0) * i as f64 / n as f64,
                    sample: Sample {
                        color,
                        luminance: crate::trace::luminance(color),
                        hit_point,
                        depth: (hit_point - c.eye).length(),
                        velocity: Vec3::ZERO,
                        hit: true,
                        dynamic: false,
                        anchor: Default::default(),
                    },
                }
            })
            .collect()
    }

    /// A reconstructor after one refresh at t = 0.1 from `camera(0)`, fed `first`.
    fn after_one_refresh(first: &[StreamSample]) -> Reconstructor {
        let mut r = Reconstructor::new(W, H, 40_000.0, ReconParams::realtime());
        r.push_stream(first);
        r.reconstruct(0.1, &camera(0.0), &tiling());
        r
    }

    fn mean_abs_diff(a: &Image, b: &Image) -> f64 {
        let sum: f64 = (a.pixels.iter().zip(&b.pixels))
            .map(|(p, q)| (*p - *q).abs().element_sum() as f64 / 3.0)
            .sum();
        sum / a.pixels.len() as f64
    }

    #[test]
    fn a_split_refresh_with_nothing_late_is_the_plain_refresh() {
        let first = traced(&camera(0.0), 3000, (0.0, 0.1), 1, false);
        let second = traced(&camera(0.05), 600, (0.1, 0.116), 2, false);
        let mut plain = after_one_refresh(&first);
        let mut split = after_one_refresh(&first);
        plain.push_stream(&second);
        split.push_stream(&second);
        plain.reconstruct(0.12, &camera(0.05), &tiling());
        let mut called = false;
        let taken = split.reconstruct_taking_late(0.12, &camera(0.05), &tiling(), || {
            called = true;
            Vec::new()
        });
        assert!(called, "a moving view's refresh asks for the late samples");
        assert_eq!(taken, 0);
        assert_eq!(plain.image().pixels, split.image().pixels);
        assert_eq!(plain.pixel_ages(), split.pixel_ages());
    }

    #[test]
    fn a_still_view_is_refreshed_whole_without_asking_for_late_samples() {
        let first = traced(&camera(0.0), 3000, (0.0, 0.1), 1, false);
        let mut r = after_one_refresh(&first);
        r.push_stream(&traced(&camera(0.0), 600, (0.1, 0.116), 2, false));
        let taken = r.reconstruct_taking_late(0.12, &camera(0.0), &tiling(), || {
            panic!("a carried refresh takes nothing late")
        });
        assert_eq!(taken, 0);
    }

    #[test]
    fn a_split_refresh_shows_its_late_samples_as_one_that_had_them_in_hand() {
        let first = traced(&camera(0.0), 3000, (0.0, 0.1), 1, false);
        let second = traced(&camera(0.05), 600, (0.1, 0.11), 2, false);
        // The scene brightens; only the late samples show it.
        let late = traced(&camera(0.05), 600, (0.11, 0.118), 3, true);
        let mut early = after_one_refresh(&first);
        let mut whole = after_one_refresh(&first);
        let mut split = after_one_refresh(&first);
        for r in [&mut early, &mut whole, &mut split] {
            r.push_stream(&second);
        }
        whole.push_stream(&late);
        // As after a few such refreshes: it expects the samples about this much newer.
        split.late_gap = late.last().unwrap().t - second.last().unwrap().t;
        early.reconstruct(0.12, &camera(0.05), &tiling());
        whole.reconstruct(0.12, &camera(0.05), &tiling());
        let taken =
            split.reconstruct_taking_late(0.12, &camera(0.05), &tiling(), || vec![late.clone()]);
        assert_eq!(taken, late.len());
        let gained = mean_abs_diff(early.image(), whole.image());
        let off = mean_abs_diff(split.image(), whole.image());
        assert!(gained > 0.05, "the late samples change the image: {gained}");
        // Most of the way: the still-region history takes the late samples in at the
        // next refresh, not this one (without a history the split is 90% of the way).
        assert!(
            off < 0.25 * gained,
            "split {off} from the whole refresh, which moved {gained}"
        );
    }
}
