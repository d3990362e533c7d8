//! Tests of the whole refresh: the fast path (stale cut, blocks, bands, lanes, fast
//! exp) against direct evaluation of the Gaussian, the stale cut, hole filling.

use super::{place::STALE_MARGIN, ring::TIME_BLOCK, *};
use crate::scene::Camera;

fn cam(w: u32, h: u32) -> CameraFrame {
    Camera {
        eye: Vec3::new(0.0, 0.0, 1.0),
        at: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 90.0,
        hither: 1e-3,
    }
    .frame(w, h)
}

/// Ages count from the newest sample in hand, not from the refresh: a refresh made
/// long after its newest sample (as live images are, for the moment they are shown)
/// weighs the samples as a refresh made at that sample does. Counted from the refresh,
/// every sample here would be past the temporal cutoff.
#[test]
fn a_refresh_after_its_newest_sample_weighs_the_samples_as_one_at_it() {
    use crate::tiles::{Rect, TileGradients};
    let (w, h) = (24, 16);
    let c = cam(w, h);
    let tiling = TilingSnapshot {
        tiles: vec![TileGradients {
            rect: Rect {
                x0: 0,
                y0: 0,
                x1: w,
                y1: h,
            },
            gx: 0.05,
            gy: 0.05,
            gt: 30.0,
        }],
    };
    let mut rng = crate::sampling::Rng::new(&[5]);
    let n = 400;
    let samples: Vec<RingSample> = (0..n)
        .map(|i| {
            let (x, y) = (rng.uniform() * w as f32, rng.uniform() * h as f32);
            RingSample {
                x,
                y,
                t: 0.95 + 0.05 * i as f64 / (n - 1) as f64,
                color: Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()),
                hit_point: c.eye + c.direction(x, y) * 2.0,
                velocity: Vec3::ZERO,
                anchor: Default::default(),
            }
        })
        .collect();
    let image_at = |t: f64| {
        let mut r = Reconstructor::new(w, h, n as f64 / 0.05, ReconParams::paper());
        samples.iter().for_each(|s| r.push(*s));
        let img = r.reconstruct(t, &c, &tiling).clone();
        (img, r.holes(), r.filter_map()[0][2] as f64)
    };
    let (at_newest, holes, et) = image_at(1.0);
    assert!(holes < (w * h) as usize / 2, "{holes} holes");
    // Ten temporal sigmas later: four beyond the cutoff.
    let (after, late_holes, _) = image_at(1.0 + 10.0 * et);
    assert_eq!(holes, late_holes);
    for (a, b) in at_newest.pixels.iter().zip(&after.pixels) {
        assert!((*a - *b).abs().max_element() < 1e-4, "{a} vs {b}");
    }
}

#[test]
fn single_sample_fills_the_image_with_its_color() {
    let (w, h) = (16, 16);
    let c = cam(w, h);
    let mut r = Reconstructor::new(w, h, 1000.0, ReconParams::paper());
    let p = c.eye + c.direction(3.2, 5.7) * 2.0;
    r.push(RingSample {
        x: 3.2,
        y: 5.7,
        t: 0.0,
        color: Vec3::new(0.25, 0.5, 0.75),
        hit_point: p,
        velocity: Vec3::ZERO,
        anchor: Default::default(),
    });
    let img = r
        .reconstruct(0.01, &c, &TilingSnapshot::whole(w, h))
        .clone();
    for px in &img.pixels {
        assert!((*px - Vec3::new(0.25, 0.5, 0.75)).abs().max_element() < 1e-6);
    }
    assert!(r.holes() > 0);
    // Splats grew where undersampled.
    assert!(r.splat_scale().iter().all(|&s| s > 1.0));
}

/// A reconstructor at `w × h` with `n` random samples over `span` seconds before
/// `t = 1` (slowly moving, some behind or beside the view), samples pushed in order
/// unless `shuffle`, and a tiling of 16 tiles with spatial gradients of every kind
/// and the temporal gradients `gts`.
pub(super) fn random_setup(
    w: u32,
    h: u32,
    n: usize,
    span: f64,
    shuffle: bool,
    params: ReconParams,
    gts: [f64; 4],
) -> (Reconstructor, CameraFrame, TilingSnapshot) {
    use crate::tiles::{Rect, TileGradients};
    let c = cam(w, h);
    let mut rng = crate::sampling::Rng::new(&[11, n as u64]);
    let mut r = Reconstructor::new(w, h, n as f64 / span, params);
    let mut samples: Vec<RingSample> = (0..n)
        .map(|i| {
            let x = rng.uniform() * (w as f32 + 4.0) - 2.0;
            let y = rng.uniform() * (h as f32 + 4.0) - 2.0;
            let depth = if rng.uniform() < 0.02 {
                -1.0
            } else {
                1.0 + rng.uniform()
            };
            RingSample {
                x,
                y,
                t: 1.0 - span + span * i as f64 / n as f64,
                color: Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()),
                hit_point: c.eye + c.direction(x, y) * depth,
                // A quarter of them still (front depths of any age).
                velocity: Vec3::new(rng.uniform() - 0.5, rng.uniform() - 0.5, 0.0)
                    * if i % 4 == 0 { 0.0 } else { 0.3 },
                anchor: Default::default(),
            }
        })
        .collect();
    if shuffle {
        samples.swap(n / 3, n / 2);
    }
    for s in samples {
        r.push(s);
    }
    // A 4 × 4 grid of tiles.
    let mut tiling = TilingSnapshot::default();
    for k in 0..16u32 {
        let (i, j) = (k % 4, k / 4);
        let g = (k % 4) as f64 / 3.0;
        tiling.tiles.push(TileGradients {
            rect: Rect {
                x0: w * i / 4,
                y0: h * j / 4,
                x1: w * (i + 1) / 4,
                y1: h * (j + 1) / 4,
            },
            gx: 0.2 * g,
            gy: 0.2 * (1.0 - g),
            gt: gts[k as usize / 4],
        });
    }
    (r, c, tiling)
}

/// Static, slow and fast tiles.
pub(super) const GTS: [f64; 4] = [0.0, 0.3, 3.0, 30.0];

/// Sums `[r, g, b, w, w·age]` and coverage per pixel by direct evaluation of the
/// Gaussian in f64 for every sample of the ring (no stale-prefix cut, no bands), with
/// the filters and splat scale the next refresh will use.
fn direct(
    r: &mut Reconstructor,
    t: f64,
    c: &CameraFrame,
    tiling: &TilingSnapshot,
) -> Vec<([f64; 5], u32)> {
    r.update_filters(tiling);
    let placer = r.placer(t, c);
    let w = r.width as usize;
    let mut out = vec![([0f64; 5], 0u32); w * r.height as usize];
    // The visibility pass: each pixel's nearest recent sample landing in it.
    let mut front = vec![f32::INFINITY; out.len()];
    let keep = r.visibility_keep();
    let landed = |q: &super::place::Placed| placer.inside(q.x, q.y);
    if let (Some(max_a), Some(_)) = (placer.setter_age, keep) {
        for s in r.ring.iter() {
            let Some(q) = placer.place(&s) else { continue };
            let p = landed(&q);
            let setter = s.velocity == Vec3::ZERO || q.a <= max_a;
            if setter && p != super::splat::OUTSIDE {
                front[p as usize] = front[p as usize].min(q.z);
            }
        }
    }
    for s in r.ring.iter() {
        let Some(q) = placer.place(&s) else { continue };
        if let (Some(keep), Some(_)) = (keep, placer.setter_age) {
            let p = landed(&q);
            if p != super::splat::OUTSIDE
                && super::splat::behind_front(front[p as usize], q.z, keep)
            {
                // Hidden behind a nearer recent sample: no splat, no coverage.
                continue;
            }
        }
        let [ex, ey, _] = q.filter.e.map(|e| e as f64);
        for y in q.y0..=q.y1 {
            for x in q.x0..=q.x1 {
                let dx = (x as f64 + 0.5 - q.x as f64) / ex;
                let dy = (y as f64 + 0.5 - q.y as f64) / ey;
                let a = q.a as f64;
                let wgt = (-0.5 * (dx * dx + dy * dy + a * a)).exp();
                let o = &mut out[y as usize * w + x as usize];
                let col = s.color.as_dvec3();
                for (k, v) in [col.x, col.y, col.z, 1.0, q.age as f64].iter().enumerate() {
                    o.0[k] += wgt * v;
                }
                o.1 += 1;
            }
        }
    }
    out
}

/// The fast path (bands, lanes, fast exp, stale cut) against direct evaluation.
fn check_against_direct(r: &mut Reconstructor, c: &CameraFrame, tiling: &TilingSnapshot) {
    for _ in 0..3 {
        let d = direct(r, 1.0, c, tiling);
        r.reconstruct(1.0, c, tiling);
        let mut compared = 0;
        for (i, (sums, cov)) in d.iter().enumerate() {
            assert_eq!(r.coverage()[i], *cov, "coverage of pixel {i}");
            if sums[3] < 1e-20 {
                continue;
            }
            compared += 1;
            let px = r.image().pixels[i];
            for (k, v) in px.to_array().iter().enumerate() {
                let want = sums[k] / sums[3];
                assert!(
                    (*v as f64 - want).abs() <= 1e-4 * (1.0 + want.abs()),
                    "pixel {i} channel {k}: {v} vs {want}"
                );
            }
        }
        assert!(compared > d.len() / 2, "only {compared} pixels compared");
    }
}

#[test]
fn fast_path_matches_direct_evaluation() {
    for params in [
        ReconParams::paper(),
        // With the visibility pass.
        ReconParams::converging(),
        ReconParams::no_reprojection(),
        ReconParams::fixed_filter(),
    ] {
        // The splats' sums of a whole ring; the pull-push fill of thin pixels, the
        // history's blend and the carried accumulators are tested on their own.
        let params = ReconParams {
            fill_weight: 0.0,
            history: None,
            carry: false,
            ..params
        };
        for (w, h) in [(40, 30), (67, 41)] {
            let (mut r, c, tiling) = random_setup(w, h, 3000, 1.0, false, params, GTS);
            check_against_direct(&mut r, &c, &tiling);
        }
    }
}

#[test]
fn wrapped_ring_matches_direct_evaluation() {
    // More pushes than the capacity: the live range wraps around the ring's
    // arrays, and a refresh must read it in ring order across the wrap.
    for ring_factor in [1.0, 1.7] {
        let params = ReconParams {
            ring_factor,
            ..ReconParams::paper()
        };
        let (mut r, c, tiling) = random_setup(40, 30, 3000, 1.0, false, params, GTS);
        assert_eq!(r.ring().len(), r.capacity());
        let runs = r.ring.runs(0);
        assert!(!runs[1].is_empty(), "the ring should wrap");
        check_against_direct(&mut r, &c, &tiling);
    }
}

#[test]
fn out_of_order_ring_matches_direct_evaluation() {
    let (mut r, c, tiling) = random_setup(40, 30, 3000, 1.0, true, ReconParams::paper(), GTS);
    check_against_direct(&mut r, &c, &tiling);
}

#[test]
fn stale_cut_never_drops_a_sample_that_counts() {
    // Ages up to 3 s against e_t of at most a fraction of that: the cut skips most
    // of the ring and must give exactly the image of the full per-sample test.
    // In order, and with two samples far apart swapped (as interleaved batches of
    // sampling threads would be, only more so).
    let run = |skip: bool, shuffle: bool| {
        let (mut r, c, tiling) = random_setup(
            48,
            32,
            6000,
            3.0,
            shuffle,
            ReconParams::paper(),
            [3.0, 10.0, 30.0, 100.0],
        );
        r.skip_stale = skip;
        let mut out = Vec::new();
        for k in 0..3 {
            r.update_filters(&tiling);
            let start = r.live_start(1.0);
            if skip && k == 0 {
                assert!(start > 1000, "the cut skipped only {start} samples");
                // Everything cut is beyond the cutoff of every tile.
                let max_et = r.tiles.iter().fold(0f32, |m, f| m.max(f.e[2]));
                for s in r.ring.iter().take(start) {
                    assert!((1.0 - s.t) as f32 > r.params.temporal_cutoff * max_et);
                }
            }
            r.reconstruct(1.0, &c, &tiling);
            out.push((
                r.image().clone(),
                r.coverage().to_vec(),
                r.mean_age(),
                r.holes(),
            ));
        }
        out
    };
    for shuffle in [false, true] {
        let (a, b) = (run(true, shuffle), run(false, shuffle));
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.0.pixels, y.0.pixels);
            assert_eq!(x.1, y.1);
            assert_eq!(x.2.to_bits(), y.2.to_bits());
            assert_eq!(x.3, y.3);
        }
    }
}

#[test]
fn sparse_and_dense_hole_filling_agree() {
    // A narrow filter (1 px) over the last 0.3 s: most pixels are holes with 3
    // samples, few with 100.
    for n in [3, 30, 100] {
        let (mut r, c, tiling) =
            random_setup(37, 29, n, 0.3, false, ReconParams::fixed_filter(), GTS);
        r.reconstruct(1.0, &c, &tiling);
        assert!(r.holes() > 0, "{n} samples should leave holes");
        let mut ages = Vec::new();
        let mut images = Vec::new();
        for dense in [false, true] {
            ages.push(r.fill_holes(dense).to_bits());
            images.push(r.image().pixels.clone());
        }
        assert_eq!(ages[0], ages[1]);
        assert_eq!(images[0], images[1]);
        assert!(images[0].iter().all(|p| p.is_finite() && *p != Vec3::ZERO));
    }
}

#[test]
fn stale_cut_follows_the_ring_as_it_wraps() {
    // A ring of 1000 samples fed 5000, one per ms, with some late arrivals: the cut
    // must stay within the ring and skip only samples older than the cutoff time.
    let mut r = Reconstructor::new(
        10,
        10,
        1000.0,
        ReconParams {
            ring_factor: 10.0,
            ..ReconParams::paper()
        },
    );
    r.tiles = vec![TileFilter::new([1.0, 1.0, 0.1], 2.5)];
    for i in 0..5000u32 {
        let t = if i % 97 == 0 {
            i as f64 * 1e-3 - 0.2
        } else {
            i as f64 * 1e-3
        };
        r.push(RingSample {
            x: 1.0,
            y: 1.0,
            t,
            color: Vec3::ONE,
            hit_point: Vec3::ZERO,
            velocity: Vec3::ZERO,
            anchor: Default::default(),
        });
        if i % 250 == 0 || i > 4990 {
            let now = i as f64 * 1e-3;
            let start = r.live_start(now);
            assert!(start <= r.ring().len());
            let tc = now - 0.3 * (1.0 + STALE_MARGIN);
            assert!(r.ring().iter().take(start).all(|s| s.t < tc), "push {i}");
            // Blocks are 256 pushes: at most two blocks' worth of stale samples stay.
            let stale = r.ring().iter().filter(|s| s.t < tc - 0.2).count();
            assert!(
                stale <= start + 2 * TIME_BLOCK as usize,
                "push {i}: {stale} stale, cut {start}"
            );
        }
    }
    assert_eq!(
        r.ring.block_max_t.len() as u64,
        r.ring.pushed.div_ceil(TIME_BLOCK) - r.ring.first_block
    );
}

#[test]
fn ring_keeps_the_newest() {
    let mut r = Reconstructor::new(
        2,
        2,
        1.0,
        ReconParams {
            ring_factor: 1.0,
            ..ReconParams::paper()
        },
    );
    for k in 0..10 {
        r.push(RingSample {
            x: 0.0,
            y: 0.0,
            t: k as f64,
            color: Vec3::ZERO,
            hit_point: Vec3::ZERO,
            velocity: Vec3::ZERO,
            anchor: Default::default(),
        });
    }
    assert_eq!(r.ring().len(), 4);
    assert_eq!(r.ring().front().unwrap().t, 6.0);
}

/// A still ramp sampled once every 6 pixels along x (a region the camera has just
/// turned to): RMS error of the reconstruction against the ramp, and the image.
fn sparse_ramp(fill_weight: f32) -> (f64, Vec<Vec3>) {
    let (w, h) = (48, 24);
    let c = cam(w, h);
    let params = ReconParams {
        fill_weight,
        history: None,
        ..ReconParams::paper()
    };
    let mut r = Reconstructor::new(w, h, 1e4, params);
    let ramp = |x: f32| Vec3::splat(x / w as f32);
    let mut n = 0;
    for j in 0..h / 6 {
        for i in 0..w / 6 {
            // Jittered: the samples do not fall on a grid of cells.
            let x = i as f32 * 6.0 + 3.0 + ((i * 7 + j * 3) % 5) as f32 * 0.4 - 0.8;
            let y = j as f32 * 6.0 + 3.0 + ((i * 3 + j * 5) % 5) as f32 * 0.4 - 0.8;
            r.push(RingSample {
                x,
                y,
                t: 0.99,
                color: ramp(x),
                hit_point: c.eye + c.direction(x, y) * 2.0,
                velocity: Vec3::ZERO,
                anchor: Default::default(),
            });
            n += 1;
        }
    }
    assert_eq!(n, 32);
    let img = r.reconstruct(1.0, &c, &TilingSnapshot::whole(w, h)).clone();
    let mut se = 0.0;
    for y in 0..h as usize {
        for x in 0..w as usize {
            let d = img.pixels[y * w as usize + x] - ramp(x as f32 + 0.5);
            se += (d.x as f64).powi(2);
        }
    }
    ((se / (w * h) as f64).sqrt(), img.pixels)
}

#[test]
fn sparse_samples_are_interpolated_not_stepped() {
    let (flat, _) = sparse_ramp(0.0);
    let (smooth, img) = sparse_ramp(1.0);
    assert!(
        smooth < 0.6 * flat,
        "pull-push error {smooth} against the flat fill's {flat}"
    );
    // Along a row the fill rises with the ramp, with no flat run of 6 pixels (a
    // nearest-sample cell) away from the edges.
    let row = &img[12 * 48..13 * 48];
    for x in 3..42 {
        assert!(
            row[x + 6].x > row[x].x,
            "flat run at x = {x}: {} then {}",
            row[x].x,
            row[x + 6].x
        );
    }
}

#[test]
fn well_covered_pixels_are_not_filled() {
    // Pixels whose weight reaches the fill weight show exactly what the paper's
    // reconstructor shows; the others are completed.
    let run = |fill_weight| {
        let params = ReconParams {
            fill_weight,
            ..ReconParams::paper()
        };
        let (mut r, c, tiling) = random_setup(40, 30, 150, 1.0, false, params, GTS);
        let weights: Vec<f64> = direct(&mut r, 1.0, &c, &tiling)
            .iter()
            .map(|d| d.0[3])
            .collect();
        (weights, r.reconstruct(1.0, &c, &tiling).pixels.clone())
    };
    let (weights, flat) = run(0.0);
    let (_, filled) = run(1.0);
    let (mut same, mut changed) = (0, 0);
    for (i, &wt) in weights.iter().enumerate() {
        if wt >= 1.001 {
            assert_eq!(flat[i], filled[i], "pixel {i} of weight {wt}");
            same += 1;
        } else if wt < 0.999 && flat[i] != filled[i] {
            changed += 1;
        }
    }
    assert!(same > 100 && changed > 20, "{same} kept, {changed} filled");
}

#[test]
fn a_live_limit_reconstructs_the_newest_samples_only() {
    // 3000 samples in a ring that holds them all (ring factor 4 × 1200 pixels).
    let params = ReconParams {
        ring_factor: 4.0,
        ..ReconParams::paper()
    };
    let (mut all, c, tiling) = random_setup(40, 30, 3000, 1.0, false, params, GTS);
    let newest: Vec<RingSample> = all.ring().iter().skip(2000).collect();
    all.set_live_limit(Some(1000));
    let limited = all.reconstruct(1.0, &c, &tiling).clone();
    assert_eq!(all.placed(), 1000);
    // The same image as a reconstructor that only ever saw the newest 1000.
    let mut short = Reconstructor::new(40, 30, all.rate, params);
    for s in newest {
        short.push(s);
    }
    let want = short.reconstruct(1.0, &c, &tiling);
    assert!(limited
        .pixels
        .iter()
        .zip(&want.pixels)
        .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
    // Lifted, every sample within the cutoff counts again, and the image changes.
    all.set_live_limit(None);
    let unlimited = all.reconstruct(1.0, &c, &tiling).clone();
    assert!(all.placed() > 2000, "{}", all.placed());
    assert_ne!(unlimited.pixels, limited.pixels);
}

/// The pull-push fill evaluated directly, a pixel at a time (Gortler et al.'s
/// pyramid as `pullpush.rs` describes it), from a resolved image's weights `wt`,
/// colours and ages: what the row-wise passes must reproduce exactly.
fn direct_pull_push(
    w: usize,
    h: usize,
    w0: f32,
    wt: &[f32],
    px: &[Vec3],
    age: &[f32],
) -> Vec<Vec3> {
    let pre = |i: usize| -> [f32; 5] {
        if wt[i] < splat::MIN_WEIGHT {
            return [0.0; 5];
        }
        let a = (wt[i] / w0).min(1.0);
        [px[i].x * a, px[i].y * a, px[i].z * a, age[i] * a, a]
    };
    let full: Vec<[f32; 5]> = (0..w * h).map(pre).collect();
    let mut levels = direct_pull(w, h, full.clone());
    direct_push(&mut levels);
    (0..w * h)
        .map(|i| {
            let v = levels[0].2[i];
            if full[i][4] >= 1.0 {
                px[i]
            } else {
                Vec3::new(v[0], v[1], v[2])
            }
        })
        .collect()
}

/// A direct pull-push level: width, height, premultiplied values and coverage.
type DirectLevel = (usize, usize, Vec<[f32; 5]>);

/// The pull of [`direct_pull_push`]: from the full level (`w × h`) up to 1×1, each
/// level the 2×2 sums of the finer one, normalised where their coverage passes 1, the
/// top normalised to full coverage.
fn direct_pull(w: usize, h: usize, full: Vec<[f32; 5]>) -> Vec<DirectLevel> {
    let mut levels: Vec<DirectLevel> = vec![(w, h, full)];
    while levels.last().is_some_and(|l| l.0 > 1 || l.1 > 1) {
        let (fw, fh, fine) = levels.last().unwrap().clone();
        let (nw, nh) = (fw.div_ceil(2), fh.div_ceil(2));
        let mut next = vec![[0f32; 5]; nw * nh];
        for by in 0..nh {
            for bx in 0..nw {
                let mut s = [0f32; 5];
                for (cx, cy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (x, y) = (2 * bx + cx, 2 * by + cy);
                    if x < fw && y < fh {
                        for c in 0..5 {
                            s[c] += fine[y * fw + x][c];
                        }
                    }
                }
                if s[4] > 1.0 {
                    let k = 1.0 / s[4];
                    s = s.map(|v| v * k);
                }
                next[by * nw + bx] = s;
            }
        }
        levels.push((nw, nh, next));
    }
    let top = &mut levels.last_mut().unwrap().2[0];
    if top[4] > 0.0 {
        let k = 1.0 / top[4];
        *top = top.map(|v| v * k);
    }
    levels
}

/// The push of [`direct_pull_push`]: each level, coarsest first, completes the finer
/// one's pixels below full coverage from its bilinear upsample (at the full level
/// only those; the others all).
fn direct_push(levels: &mut [DirectLevel]) {
    let tap = |i: usize, n: usize| {
        let f = ((i as f32 + 0.5) * 0.5 - 0.5).clamp(0.0, (n - 1) as f32);
        let i0 = f as usize;
        (i0, (i0 + 1).min(n - 1), f - i0 as f32)
    };
    for k in (0..levels.len() - 1).rev() {
        let (cw, ch, coarse) = levels[k + 1].clone();
        let (fw, fh, fine) = &mut levels[k];
        for y in 0..*fh {
            for x in 0..*fw {
                let ((x0, x1, tx), (y0, y1, ty)) = (tap(x, cw), tap(y, ch));
                let v = &mut fine[y * *fw + x];
                if k == 0 && v[4] >= 1.0 {
                    continue;
                }
                for c in 0..4 {
                    let (a, b) = (coarse[y0 * cw + x0][c], coarse[y0 * cw + x1][c]);
                    let (d, e) = (coarse[y1 * cw + x0][c], coarse[y1 * cw + x1][c]);
                    let top = a + (b - a) * tx;
                    let bottom = d + (e - d) * tx;
                    v[c] += (1.0 - v[4]) * (top + (bottom - top) * ty);
                }
                v[4] = 1.0;
            }
        }
    }
}

#[test]
fn pull_push_matches_direct_evaluation() {
    // Odd and even sizes (a coarser level with a half-filled last row or column), and
    // densities from mostly holes to mostly covered.
    for (w, h, n) in [(37, 23, 60), (40, 30, 300), (33, 34, 1500), (1, 9, 5)] {
        let run = |fill_weight| {
            let params = ReconParams {
                fill_weight,
                history: None,
                ..ReconParams::paper()
            };
            let (mut r, c, tiling) = random_setup(w, h, n, 1.0, false, params, GTS);
            r.reconstruct(1.0, &c, &tiling);
            r
        };
        let (plain, filled) = (run(0.0), run(1.0));
        let (wu, hu) = (w as usize, h as usize);
        let wt: Vec<f32> = (0..wu * hu)
            .map(|i| plain.sum_at(i % wu, i / wu, 3))
            .collect();
        let want = direct_pull_push(wu, hu, 1.0, &wt, &plain.image.pixels, &plain.age);
        let thin = wt.iter().filter(|&&v| v < 1.0).count();
        assert!(thin > 0, "{w}×{h}: nothing to fill");
        for (i, (a, b)) in filled.image.pixels.iter().zip(&want).enumerate() {
            assert_eq!(
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits),
                "{w}×{h}, pixel {i}: {a} against {b}"
            );
        }
    }
}

#[test]
fn a_new_rate_gives_the_filters_of_a_reconstructor_built_for_it() {
    let params = ReconParams::converging();
    let (r, c, tiling) = random_setup(40, 30, 1500, 1.0, false, params, GTS);
    let samples: Vec<RingSample> = r.ring().iter().collect();
    let image = |rate: f64, set: &[f64]| {
        let mut r = Reconstructor::new(40, 30, rate, params);
        for &s in &samples {
            r.push(s);
        }
        for &v in set {
            r.set_rate(v);
        }
        r.reconstruct(1.0, &c, &tiling).pixels.clone()
    };
    let rate = r.rate;
    let at_rate = image(rate, &[]);
    assert!(
        image(4.0 * rate, &[]) != at_rate,
        "the rate changes nothing"
    );
    assert!(image(rate, &[4.0 * rate]) == image(4.0 * rate, &[]));
    // Not finite or not positive: ignored.
    assert!(image(rate, &[f64::NAN, 0.0, -1.0, f64::INFINITY]) == at_rate);
}

/// Samples a live limit leaves out of the ring still reach the still-region history:
/// two reconstructors given the same stream, one all of it and one its newest sample
/// plus the rest history-only, count the same samples in every pixel's history.
#[test]
fn samples_left_unplaced_still_reach_the_history() {
    use crate::trace::{Sample, StreamSample};
    let (w, h) = (8, 4);
    let c = cam(w, h);
    let stream: Vec<StreamSample> = (0..24)
        .map(|i| {
            let (x, y) = ((i % 8) as f32 + 0.5, (i / 8 % 4) as f32 + 0.5);
            StreamSample {
                x,
                y,
                t: 0.001 * i as f64,
                sample: Sample {
                    color: Vec3::splat(0.5),
                    hit_point: c.eye + c.direction(x, y) * 2.0,
                    ..Default::default()
                },
            }
        })
        .collect();
    let tiling = TilingSnapshot::whole(w, h);
    let mut all = Reconstructor::new(w, h, 1000.0, ReconParams::realtime());
    all.push_stream(&stream);
    all.reconstruct(0.1, &c, &tiling);
    let mut newest = Reconstructor::new(w, h, 1000.0, ReconParams::realtime());
    newest.push_history_only(&stream[..23]);
    newest.push_stream(&stream[23..]);
    newest.reconstruct(0.1, &c, &tiling);
    assert_eq!(newest.ring().len(), 1);
    let counts = all.history_counts().expect("a history");
    assert!(counts.iter().sum::<f32>() >= 24.0, "{counts:?}");
    assert_eq!(newest.history_counts(), Some(counts));
}

/// The stream taken in a run at a time is the stream taken in one sample at a time:
/// the same ring, pending samples, history and images, over more than one run, with
/// samples marked dynamic and moving ones among them.
#[test]
fn a_stream_pushed_at_once_is_the_stream_pushed_one_by_one() {
    use crate::trace::{Sample, StreamSample};
    let (w, h) = (16, 12);
    let c = cam(w, h);
    let stream: Vec<StreamSample> = (0..700)
        .map(|i| {
            let (x, y) = ((i * 7 % 16) as f32 + 0.25, (i * 5 / 16 % 12) as f32 + 0.5);
            StreamSample {
                x,
                y,
                t: 0.0001 * i as f64,
                sample: Sample {
                    color: Vec3::splat((i % 9) as f32 / 9.0),
                    hit_point: c.eye + c.direction(x, y) * 2.0,
                    velocity: if i % 11 == 0 { Vec3::X } else { Vec3::ZERO },
                    dynamic: i % 13 == 0,
                    ..Default::default()
                },
            }
        })
        .collect();
    let tiling = TilingSnapshot::whole(w, h);
    let params = ReconParams::realtime();
    let mut at_once = Reconstructor::new(w, h, 1000.0, params);
    let mut one_by_one = Reconstructor::new(w, h, 1000.0, params);
    at_once.push_stream(&stream);
    for s in &stream {
        one_by_one.push_marked(RingSample::from(s), s.sample.dynamic);
    }
    let ring = |r: &Reconstructor| r.ring().iter().collect::<Vec<_>>();
    assert_eq!(ring(&at_once), ring(&one_by_one));
    assert_eq!(at_once.pending_start(), one_by_one.pending_start());
    at_once.reconstruct(0.1, &c, &tiling);
    one_by_one.reconstruct(0.1, &c, &tiling);
    assert_eq!(at_once.image().pixels, one_by_one.image().pixels);
    assert_eq!(at_once.history_counts(), one_by_one.history_counts());
}

/// Backing the buffers with memory up front ([`Reconstructor::prepare`]) allocates
/// the history before any refresh and changes no result: the same images, ages and
/// history counts, carried refreshes included, as a reconstructor left to allocate
/// as it goes.
#[test]
fn a_prepared_reconstructor_makes_the_same_images() {
    let params = ReconParams::realtime();
    let (w, h) = (40, 30);
    let (mut lazy, c, tiling) = random_setup(w, h, 3000, 1.0, false, params, GTS);
    let (mut prepared, _, _) = random_setup(w, h, 3000, 1.0, false, params, GTS);
    assert_eq!(lazy.history_counts().map(<[f32]>::len), Some(0));
    prepared.prepare();
    assert_eq!(
        prepared.history_counts().map(<[f32]>::len),
        Some((w * h) as usize)
    );
    let bits = |r: &Reconstructor| -> Vec<u32> {
        let px = r.image().pixels.iter().flat_map(|p| p.to_array());
        let rest = r
            .pixel_ages()
            .iter()
            .chain(r.history_counts().unwrap_or(&[]));
        px.chain(rest.copied()).map(f32::to_bits).collect()
    };
    for k in 0..3 {
        let t = 1.0 + 0.02 * k as f64;
        if k > 0 {
            let s = RingSample {
                x: 3.5,
                y: 2.5,
                t,
                color: Vec3::ONE,
                hit_point: c.eye + c.direction(3.5, 2.5) * 1.5,
                velocity: Vec3::ZERO,
                anchor: Default::default(),
            };
            lazy.push(s);
            prepared.push(s);
        }
        lazy.reconstruct(t, &c, &tiling);
        prepared.reconstruct(t, &c, &tiling);
        assert_eq!(bits(&lazy), bits(&prepared), "refresh {k}");
    }
}

/// The mean age a refresh reports is the mean of the ages of its pixels, whichever
/// step sets it last: the resolve (no history; with and without the fill), or the
/// still-region history, which blends every pixel's age after the resolve (which then
/// leaves the sum to it).
#[test]
fn the_mean_age_is_the_mean_of_the_pixel_ages() {
    let no_fill = ReconParams {
        fill_weight: 0.0,
        ..ReconParams::converging()
    };
    let presets = [
        ("paper", ReconParams::paper()),
        ("converging", ReconParams::converging()),
        ("realtime", ReconParams::realtime()),
        (
            "no history, fill",
            ReconParams {
                history: None,
                ..ReconParams::converging()
            },
        ),
        ("history, no fill", no_fill),
    ];
    for (name, params) in presets {
        let (mut r, c, tiling) = random_setup(40, 24, 600, 0.5, false, params, [0.1; 4]);
        for k in 0..3 {
            r.reconstruct(1.0 + 0.01 * k as f64, &c, &tiling);
            let ages = r.pixel_ages();
            let mean = ages.iter().map(|&a| a as f64).sum::<f64>() / ages.len() as f64;
            assert!(mean > 0.0, "{name}: no ages");
            assert!(
                (r.mean_age() - mean).abs() <= 1e-6 * mean,
                "{name}, refresh {k}: mean age {} against {mean}",
                r.mean_age()
            );
        }
    }
}

#[test]
fn a_stale_pixel_tile_map_is_made_again_from_the_tile_rectangles_when_read() {
    let (w, h) = (61u32, 47u32);
    let (mut r, _, tiling) = random_setup(w, h, 500, 1.0, false, ReconParams::realtime(), GTS);
    r.update_filters(&tiling);
    let check_but = |r: &Reconstructor, tiling: &TilingSnapshot, skip: usize| {
        for (q, l) in r.lookup.iter().enumerate().filter(|(q, _)| *q != skip) {
            let (x, y) = ((q % w as usize) as u32, (q / w as usize) as u32);
            let rect = tiling.tiles[l.tile as usize].rect;
            assert!(
                (rect.x0..rect.x1).contains(&x) && (rect.y0..rect.y1).contains(&y),
                "pixel ({x}, {y}) mapped to tile {} at {rect:?}",
                l.tile
            );
        }
    };
    let check = |r: &Reconstructor, tiling: &TilingSnapshot| check_but(r, tiling, usize::MAX);
    check(&r, &tiling);
    // As a GPU refresh leaves it: not made for this refresh, whose tiles moved.
    // The top row's four tiles merged into one, the others in reverse order.
    let mut moved = tiling.clone();
    moved.tiles.drain(1..4);
    moved.tiles[0].rect.x1 = w;
    moved.tiles.reverse();
    r.tile_rects = moved.tiles.iter().map(|t| t.rect).collect();
    r.lookup_stale = true;
    r.ensure_lookup();
    check(&r, &moved);
    assert!(!r.lookup_stale);
    // Two tiles swapped in the list, the rest where they were: only theirs change.
    moved.tiles.swap(2, 7);
    let far = moved.tiles[11].rect;
    let q = (far.y0 * w + far.x0) as usize;
    r.lookup[q].tile = u32::MAX;
    r.update_filters(&moved);
    check_but(&r, &moved, q);
    assert_eq!(
        r.lookup[q].tile,
        u32::MAX,
        "an unmoved tile's pixel was made again"
    );
    // The same tiles again: the map is kept as it is.
    r.lookup[q].tile = 11;
    r.lookup[0].tile = u32::MAX;
    r.update_filters(&moved);
    assert_eq!(r.lookup[0].tile, u32::MAX, "the map was made again");
}

#[test]
fn a_refresh_whose_view_moved_filters_with_the_moving_views_volume() {
    let (w, h) = (16, 16);
    let moved = Camera {
        eye: Vec3::new(0.05, 0.0, 1.0),
        at: Vec3::new(0.05, 0.0, 0.0),
        up: Vec3::Y,
        fov_y_deg: 90.0,
        hither: 1e-3,
    }
    .frame(w, h);
    let mut tiling = TilingSnapshot::whole(w, h);
    (tiling.tiles[0].gx, tiling.tiles[0].gy, tiling.tiles[0].gt) = (0.1, 0.1, 0.05);
    // The product of a tile's extents is its volume over the local rate; `e_t` is
    // within its bounds for these gradients, so no clamp moves it.
    let volumes = |params: ReconParams| {
        let mut r = Reconstructor::new(w, h, 10_000.0, params);
        let mut volume = |t: f64, camera: &CameraFrame| {
            r.reconstruct(t, camera, &tiling);
            r.tiles[0].e.iter().map(|&e| e as f64).product::<f64>()
        };
        let held = [volume(0.1, &cam(w, h)), volume(0.2, &cam(w, h))];
        (held, volume(0.3, &moved))
    };
    let ours = ReconParams::realtime();
    let (held, moving) = volumes(ours);
    let ratio = ours.moving_view_volume.unwrap() / ours.filter_volume;
    assert!((held[1] / held[0] - 1.0).abs() < 1e-6, "{held:?}");
    assert!(
        (moving / held[1] / ratio - 1.0).abs() < 1e-4,
        "{moving} against {held:?}"
    );
    let one_volume = ReconParams {
        moving_view_volume: None,
        ..ours
    };
    let (held, moving) = volumes(one_volume);
    assert!(
        (moving / held[1] - 1.0).abs() < 1e-6,
        "{moving} against {held:?}"
    );
}

/// Samples of one flat colour at random positions over `w × h`, at times from `t0` to
/// `t1`, every `k`-th marked dynamic (a moving thing took part: no history).
fn flat_field(
    rng: &mut crate::sampling::Rng,
    c: &CameraFrame,
    (w, h): (u32, u32),
    (t0, t1): (f64, f64),
    (colour, n, dynamic_every): (Vec3, usize, usize),
) -> Vec<(RingSample, bool)> {
    (0..n)
        .map(|i| {
            let (x, y) = (rng.uniform() * w as f32, rng.uniform() * h as f32);
            let s = RingSample {
                x,
                y,
                t: t0 + (t1 - t0) * i as f64 / n as f64,
                color: colour,
                hit_point: c.eye + c.direction(x, y) * 2.0,
                velocity: Vec3::ZERO,
                anchor: Default::default(),
            };
            (s, dynamic_every > 0 && i % dynamic_every == 0)
        })
        .collect()
}

/// A flat surface of (0.3, 0.5, 0.7), each value half-way between two display codes,
/// reconstructed by the reconstructors `make(w, h)` gives over 20 refreshes with the
/// history and without it (every sample dynamic, every third): from the sixth refresh
/// on, every pixel shows exactly its value. `check` runs after each refresh.
pub(super) fn assert_flat_surface_exact(
    make: impl Fn(u32, u32) -> Reconstructor,
    tiling: &TilingSnapshot,
    check: impl Fn(&Reconstructor),
) {
    let (w, h) = (48, 32);
    let c = cam(w, h);
    let colour = Vec3::new(0.3, 0.5, 0.7);
    for dynamic_every in [0, 1, 3] {
        let mut r = make(w, h);
        let mut rng = crate::sampling::Rng::new(&[5, dynamic_every as u64]);
        let mut off = Vec::new();
        for k in 0..20 {
            let t = 0.05 * k as f64;
            let batch = flat_field(
                &mut rng,
                &c,
                (w, h),
                (t - 0.05, t),
                (colour, 400, dynamic_every),
            );
            for (s, dynamic) in batch {
                r.push_marked(s, dynamic);
            }
            r.reconstruct(t, &c, tiling);
            check(&r);
            off.push(r.image().pixels.iter().filter(|p| **p != colour).count());
        }
        assert!(
            off[5..].iter().all(|&n| n == 0),
            "every {dynamic_every}th dynamic: pixels off per refresh {off:?}"
        );
    }
}

/// A flat surface whose value lies half-way between two display codes (0.3 · 255 =
/// 76.5, scene files' decimals) is shown at exactly its value, with the history and
/// without it (every sample dynamic): a rounding of the weighted means below it would
/// show the code below. Without the blocks' reference colours, hundreds of the pixels
/// are a rounding off.
#[test]
fn a_flat_surface_at_a_half_code_is_shown_at_exactly_its_value() {
    assert_flat_surface_exact(
        |w, h| Reconstructor::new(w, h, 20000.0, ReconParams::realtime()),
        &TilingSnapshot::whole(48, 32),
        |_| {},
    );
}
