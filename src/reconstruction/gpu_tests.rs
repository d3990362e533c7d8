//! The GPU reconstructor against the CPU one on the same samples: the same images to
//! rounding, the same coverage and splat scale. Needs a Vulkan (or Metal, DX12)
//! adapter; Mesa's lavapipe serves (`apt-get install mesa-vulkan-drivers libvulkan1`).

use std::sync::Arc;

use super::{
    device::ReconDevice,
    gpu::GpuContext,
    tests::{random_setup, GTS},
    *,
};

/// Largest difference of a colour channel or age allowed between the two images: a
/// quarter of one 8-bit level. The arithmetic is the same but for `exp` and the
/// rounding of sums added in another grouping (and the pyramid in f32, not f64).
const MAX_DIFF: f32 = 0.25 / 255.0;

fn context() -> Arc<GpuContext> {
    match GpuContext::acquire(ReconDevice::Gpu) {
        Ok(Some(c)) => c,
        Ok(None) => panic!("--recon gpu gave no adapter"),
        Err(e) => panic!("{e}"),
    }
}

/// What differs between two reconstructors' last images.
#[derive(Debug)]
struct Differences {
    max_colour: f32,
    max_age: f32,
    coverage: usize,
    scale: usize,
    holes: (usize, usize),
    /// Pixels whose history counts differ, and the cuts of each.
    counts: usize,
    cuts: (u64, u64),
}

fn differences(a: &mut Reconstructor, b: &mut Reconstructor) -> Differences {
    let (cov_a, cov_b) = (a.coverage().to_vec(), b.coverage().to_vec());
    let (scale_a, scale_b) = (a.splat_scale().to_vec(), b.splat_scale().to_vec());
    let max = |x: &[f32], y: &[f32]| {
        x.iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs())
            .fold(0f32, f32::max)
    };
    let ca: Vec<f32> = a.image().pixels.iter().flat_map(|p| p.to_array()).collect();
    let cb: Vec<f32> = b.image().pixels.iter().flat_map(|p| p.to_array()).collect();
    Differences {
        max_colour: max(&ca, &cb),
        max_age: max(a.pixel_ages(), b.pixel_ages()),
        coverage: cov_a.iter().zip(&cov_b).filter(|(p, q)| p != q).count(),
        scale: scale_a.iter().zip(&scale_b).filter(|(p, q)| p != q).count(),
        holes: (a.holes(), b.holes()),
        counts: match (a.history_counts(), b.history_counts()) {
            (Some(x), Some(y)) => x
                .iter()
                .zip(y)
                .filter(|(p, q)| (*p - *q).abs() > 1e-3 * p.abs().max(1.0))
                .count(),
            (x, y) => (x.is_some() != y.is_some()) as usize * cov_a.len(),
        },
        cuts: (a.history_cuts(), b.history_cuts()),
    }
}

fn check(d: &Differences, pixels: usize, what: &str) {
    assert!(
        d.max_colour <= MAX_DIFF && d.max_age <= 1e-4,
        "{what}: {d:?}"
    );
    // A footprint's bounds are floors and ceilings of the reprojected position, which
    // the GPU may round differently in the last bit: a pixel's coverage can then
    // differ by one, on a few pixels at most.
    assert!(
        d.coverage * 200 <= pixels && d.scale * 200 <= pixels,
        "{what}: {d:?}"
    );
    assert!(
        d.holes.0.abs_diff(d.holes.1) * 200 <= pixels,
        "{what}: {d:?}"
    );
    // The history's pixels are chosen on the CPU for both but for reprojected
    // histories, whose destination the GPU may round differently at a pixel's edge.
    assert!(
        d.counts * 200 <= pixels && d.cuts.0.abs_diff(d.cuts.1) * 200 <= pixels as u64,
        "{what}: {d:?}"
    );
}

/// Refresh `k` of both sides at t = 1 + 0.01 k s (at and after the last sample of
/// [`random_setup`]: splat scales evolve), the GPU without failing, its images as the
/// CPU's (`what` names the case).
fn refresh_and_compare(
    (cpu, gpu): (&mut Reconstructor, &mut Reconstructor),
    k: usize,
    (cam, tiling): (&CameraFrame, &crate::tiles::TilingSnapshot),
    what: &str,
) {
    let t = 1.0 + 0.01 * k as f64;
    cpu.reconstruct(t, cam, tiling);
    gpu.reconstruct(t, cam, tiling);
    assert_eq!(gpu.gpu_failure(), None);
    check(&differences(cpu, gpu), cpu.image().pixels.len(), what);
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_refreshes_match_the_cpu() {
    let ctx = context();
    // The ablations with the paper's steps only.
    let paper_steps = |p: ReconParams| ReconParams {
        fill_weight: 0.0,
        history: None,
        visibility: None,
        exact_motion: false,
        ..p
    };
    for params in [
        ReconParams::paper(),
        paper_steps(ReconParams::no_reprojection()),
        paper_steps(ReconParams::fixed_filter()),
        // The visibility pass and the pull-push fill, then with the history over them.
        ReconParams {
            history: None,
            ..ReconParams::converging()
        },
        ReconParams::converging(),
        ReconParams::realtime(),
    ] {
        // Dense, and sparse enough for holes and pixels the pull-push fill completes.
        for (w, h, n) in [(40, 30, 3000), (67, 41, 3000), (67, 41, 300)] {
            let (mut cpu, c, tiling) = random_setup(w, h, n, 1.0, false, params, GTS);
            let (mut gpu, _, _) = random_setup(w, h, n, 1.0, false, params, GTS);
            gpu.use_gpu(ctx.clone())
                .expect("the paper's steps run on the GPU");
            for k in 0..3 {
                let what = format!(
                    "{w}x{h}, {n} samples, fill {}, refresh {k}",
                    params.fill_weight
                );
                refresh_and_compare((&mut cpu, &mut gpu), k, (&c, &tiling), &what);
                assert_eq!(cpu.placed(), gpu.placed());
            }
            assert_eq!(gpu.used().device, "gpu");
        }
    }
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_refreshes_that_count_their_bin_items_first_match_the_cpu() {
    // Where the items' bound passes the adapter's limit the count is read back and the
    // items buffer grown before the splats: forced here, from a buffer too small.
    let ctx = context();
    for params in [ReconParams::converging(), ReconParams::realtime()] {
        let (w, h, n) = (67, 41, 3000);
        let (mut cpu, c, tiling) = random_setup(w, h, n, 1.0, false, params, GTS);
        let (mut gpu, _, _) = random_setup(w, h, n, 1.0, false, params, GTS);
        gpu.use_gpu(ctx.clone())
            .expect("these steps run on the GPU");
        gpu.gpu.as_mut().expect("a GPU side").count_items_first();
        for k in 0..3 {
            let what = format!("{w}x{h}, {n} samples, counted first, refresh {k}");
            refresh_and_compare((&mut cpu, &mut gpu), k, (&c, &tiling), &what);
        }
        assert_eq!(gpu.used().device, "gpu");
    }
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_follows_pushes_across_the_ring_wrap() {
    // Samples pushed between refreshes, more than the ring holds in all: the GPU's
    // copy of the ring is updated from the pushes since the last refresh.
    let ctx = context();
    let params = ReconParams {
        ring_factor: 1.5,
        ..ReconParams::paper()
    };
    let (w, h) = (48, 32);
    let (mut cpu, c, tiling) = random_setup(w, h, 1000, 1.0, false, params, GTS);
    let (mut gpu, _, _) = random_setup(w, h, 1000, 1.0, false, params, GTS);
    gpu.use_gpu(ctx).expect("every step runs on the GPU");
    let mut rng = crate::sampling::Rng::new(&[5]);
    for k in 0..6 {
        let t = 1.0 + 0.05 * k as f64;
        for i in 0..700 {
            let (x, y) = (rng.uniform() * w as f32, rng.uniform() * h as f32);
            let s = RingSample {
                x,
                y,
                t: t - 0.05 + 0.05 * i as f64 / 700.0,
                color: Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()),
                hit_point: c.eye + c.direction(x, y) * (1.0 + rng.uniform()),
                velocity: Vec3::ZERO,
                anchor: Default::default(),
            };
            cpu.push(s);
            gpu.push(s);
        }
        cpu.reconstruct(t, &c, &tiling);
        gpu.reconstruct(t, &c, &tiling);
        assert_eq!(gpu.gpu_failure(), None);
        check(
            &differences(&mut cpu, &mut gpu),
            (w * h) as usize,
            &format!("refresh {k}"),
        );
    }
    assert!(
        cpu.ring().len() == cpu.capacity(),
        "the ring should have wrapped"
    );
}

/// Samples for the history test: still ones of a grey that steps at `t` = 1.4 in the
/// image's left half (a change the range test and the clamp must catch), and moving
/// ones, some marked as dynamic.
fn history_batch(
    rng: &mut crate::sampling::Rng,
    c: &CameraFrame,
    (w, h): (u32, u32),
    t: f64,
) -> Vec<(RingSample, bool)> {
    (0..1500)
        .map(|i| {
            let (x, y) = (rng.uniform() * w as f32, rng.uniform() * h as f32);
            let grey = if t > 1.4 && x < w as f32 / 2.0 {
                0.8
            } else {
                0.3
            };
            let moving = i % 5 == 0;
            let s = RingSample {
                x,
                y,
                t: t - 0.05 + 0.05 * i as f64 / 1500.0,
                color: Vec3::splat(grey) + Vec3::splat(0.05 * rng.uniform()),
                hit_point: c.eye + c.direction(x, y) * 1.5,
                velocity: if moving {
                    Vec3::new(0.2, 0.1, 0.0)
                } else {
                    Vec3::ZERO
                },
                anchor: Default::default(),
            };
            (s, i % 7 == 0)
        })
        .collect()
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_history_matches_the_cpu_through_view_changes() {
    // Still stretches, where the history grows, a change it must cut, and a moving
    // view: followed (reprojection) and, without it, dropped.
    let ctx = context();
    for reproject in [true, false] {
        let mut params = ReconParams::converging();
        if let Some(h) = &mut params.history {
            h.reproject = reproject;
        }
        let (w, h) = (48, 32);
        let (mut cpu, c0, tiling) = random_setup(w, h, 2000, 1.0, false, params, GTS);
        let (mut gpu, _, _) = random_setup(w, h, 2000, 1.0, false, params, GTS);
        gpu.use_gpu(ctx.clone())
            .expect("the history runs on the GPU");
        let mut rng = crate::sampling::Rng::new(&[9]);
        for k in 0..14 {
            let t = 1.0 + 0.05 * k as f64;
            // The view moves sideways on refreshes 5 to 7.
            let shift = 0.02 * (k as f32 - 4.0).clamp(0.0, 3.0);
            let mut cam = c0;
            cam.eye += Vec3::new(shift, 0.0, 0.0);
            for (s, dynamic) in history_batch(&mut rng, &cam, (w, h), t) {
                cpu.push_marked(s, dynamic);
                gpu.push_marked(s, dynamic);
            }
            if k == 2 {
                cpu.set_view_since(1.0);
                gpu.set_view_since(1.0);
            }
            cpu.reconstruct(t, &cam, &tiling);
            gpu.reconstruct(t, &cam, &tiling);
            assert_eq!(gpu.gpu_failure(), None);
            let what = format!("reproject {reproject}, refresh {k}");
            check(&differences(&mut cpu, &mut gpu), (w * h) as usize, &what);
        }
        let counts = cpu.history_counts().unwrap();
        assert!(
            counts.iter().any(|&n| n >= 6.0),
            "the still stretches should have grown histories: {counts:?}"
        );
        assert!(
            cpu.history_cuts() > 0,
            "the change should have cut histories"
        );
    }
}

/// The camera of refresh `k` of the carrying test: still for the first refreshes
/// (carried sums decay in place), then moving sideways and turning (they move).
fn carry_camera(k: usize, (w, h): (u32, u32)) -> CameraFrame {
    let m = k.saturating_sub(2) as f32;
    crate::scene::Camera {
        eye: Vec3::new(0.03 * m, 0.01 * m, 1.0),
        at: Vec3::new(0.05 * m, 0.0, 0.0),
        up: Vec3::Y,
        fov_y_deg: 90.0,
        hither: 1e-3,
    }
    .frame(w, h)
}

/// `per` samples traced through `c` over the 0.05 s before `t`: a square at `z` = 0.5
/// moving along x before a still plane at `z` = 0, so that with the view and the
/// square moving new samples land in front of carried sums and behind them; some
/// marked as dynamic.
fn carry_batch(
    rng: &mut crate::sampling::Rng,
    c: &CameraFrame,
    t: f64,
    per: usize,
) -> Vec<(RingSample, bool)> {
    let v = Vec3::new(0.2, 0.0, 0.0);
    (0..per)
        .map(|i| {
            let (x, y) = (
                rng.uniform() * c.width as f32,
                rng.uniform() * c.height as f32,
            );
            let ts = t - 0.05 + 0.05 * (i + 1) as f64 / per as f64;
            let d = c.direction(x, y);
            let on_square = c.eye + d * ((0.5 - c.eye.z) / d.z);
            let centre = v * (ts - 1.0) as f32;
            let near = (on_square - centre).x.abs() < 0.25 && on_square.y.abs() < 0.2;
            let (hit_point, velocity, grey) = if near {
                (on_square, v, 0.8)
            } else {
                (c.eye + d * (-c.eye.z / d.z), Vec3::ZERO, 0.2)
            };
            let s = RingSample {
                x,
                y,
                t: ts,
                color: Vec3::new(grey, 0.5, 1.0 - grey) + Vec3::splat(0.2 * rng.uniform()),
                hit_point,
                velocity,
                anchor: Default::default(),
            };
            (s, i % 7 == 0)
        })
        .collect()
}

/// A CPU and a GPU reconstructor with `params` on the same `w × h` setup, and its
/// tiling: the two sides of a carrying test.
fn carry_pair(
    ctx: &Arc<GpuContext>,
    params: ReconParams,
    (w, h): (u32, u32),
) -> (Reconstructor, Reconstructor, crate::tiles::TilingSnapshot) {
    let (cpu, _, tiling) = random_setup(w, h, 1000, 1.0, false, params, GTS);
    let (mut gpu, _, _) = random_setup(w, h, 1000, 1.0, false, params, GTS);
    gpu.use_gpu(ctx.clone()).expect("carrying runs on the GPU");
    (cpu, gpu, tiling)
}

/// Refresh `k` of a carrying test, at t = 1 + 0.05 k s seen by `cam`: `per` new
/// samples ([`carry_batch`]) to both sides but at the first, then both reconstruct,
/// the GPU without failing.
fn refresh_both(
    (cpu, gpu): (&mut Reconstructor, &mut Reconstructor),
    rng: &mut crate::sampling::Rng,
    (cam, tiling): (&CameraFrame, &crate::tiles::TilingSnapshot),
    k: usize,
    per: usize,
) {
    let t = 1.0 + 0.05 * k as f64;
    if k > 0 {
        for (s, dynamic) in carry_batch(rng, cam, t, per) {
            cpu.push_marked(s, dynamic);
            gpu.push_marked(s, dynamic);
        }
    }
    cpu.reconstruct(t, cam, tiling);
    gpu.reconstruct(t, cam, tiling);
    assert_eq!(gpu.gpu_failure(), None);
}

/// The converging preset with the fronts spread by 1.5 while the view moves, the
/// spread's parallax test at `parallax` pixels, and no footprint's spread.
fn spread(parallax: f32) -> ReconParams {
    footprint_spread(parallax, None)
}

/// [`spread`] with the footprint's spread `footprint` (ratio, parallax, reach).
fn footprint_spread(parallax: f32, footprint: Option<(f32, f32, f32)>) -> ReconParams {
    ReconParams {
        visibility: Some(crate::reconstruction::Visibility {
            moving_view_spread: Some(1.5),
            spread_parallax: parallax,
            footprint_spread: footprint.map(|f| f.0),
            footprint_parallax: footprint.map_or(0.0, |f| f.1),
            footprint_reach: footprint.map_or(0.0, |f| f.2),
            ..Default::default()
        }),
        ..ReconParams::converging()
    }
}

/// `p` with the footprint's reach at most `spacings` times a refresh's new samples'
/// spacing.
fn reach_spacings(mut p: ReconParams, spacings: f32) -> ReconParams {
    if let Some(v) = &mut p.visibility {
        v.footprint_reach_spacings = spacings;
    }
    p
}

#[test]
fn the_carrying_tests_spread_keeps_some_far_samples_and_hides_others() {
    // On the CPU, the images of the carrying test's last refresh with the parallax
    // test at 0 (every far sample behind a spread front hidden), at 2 and 0.5 pixels,
    // with no spread, and with a footprint's spread at two parallaxes: each differs
    // from the others, so the GPU's equivalence covers both of each test's outcomes.
    let (w, h, per) = (48, 32, 1500);
    let image = |p: ReconParams| {
        let (mut r, _, tiling) = random_setup(w, h, 1000, 1.0, false, p, GTS);
        let mut rng = crate::sampling::Rng::new(&[13, per as u64]);
        for k in 0..8 {
            let cam = carry_camera(k, (w, h));
            let t = 1.0 + 0.05 * k as f64;
            if k > 0 {
                for (s, dynamic) in carry_batch(&mut rng, &cam, t, per) {
                    r.push_marked(s, dynamic);
                }
            }
            r.reconstruct(t, &cam, &tiling);
        }
        r.image().pixels.clone()
    };
    let not_spread = ReconParams {
        visibility: Some(crate::reconstruction::Visibility {
            moving_view_spread: None,
            ..Default::default()
        }),
        ..ReconParams::converging()
    };
    let images = [
        image(spread(0.0)),
        image(spread(0.5)),
        image(spread(2.0)),
        image(not_spread),
        // Where a footprint's box reaches a front 1.5 times nearer, at two parallaxes,
        // and widened by the parallax up to one and up to sixteen pixels.
        image(footprint_spread(2.0, Some((1.5, 0.5, 0.0)))),
        image(footprint_spread(2.0, Some((1.5, 1.0, 0.0)))),
        image(footprint_spread(2.0, Some((1.5, 0.5, 1.0)))),
        image(footprint_spread(2.0, Some((1.5, 0.5, 16.0)))),
        image(reach_spacings(
            footprint_spread(2.0, Some((1.5, 0.5, 16.0))),
            0.6,
        )),
    ];
    for i in 0..images.len() {
        for j in i + 1..images.len() {
            assert!(images[i] != images[j], "images {i} and {j} are the same");
        }
    }
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_carried_refreshes_match_the_cpu() {
    // The carrying presets over several refreshes, with new samples between them:
    // each GPU refresh adds its splats to sums carried (and read back) from the last.
    let ctx = context();
    let converging = ReconParams::converging();
    for params in [
        converging,
        ReconParams::realtime(),
        // The sums moved with the view (where the presets re-splat the ring).
        ReconParams {
            resplat_moving_view: false,
            ..converging
        },
        ReconParams {
            history: None,
            resplat_moving_view: false,
            ..converging
        },
        ReconParams {
            visibility: None,
            history: None,
            ..converging
        },
        // Fronts spread while the view moves by less than the plane's depth over the
        // square's (two), so that the spread hides samples: the eye's step of a
        // refresh moves the plane about half a pixel across the square, so the
        // parallax test keeps some of the plane's samples and hides others.
        spread(2.0),
        spread(0.5),
        footprint_spread(2.0, Some((1.5, 0.5, 0.0))),
        footprint_spread(2.0, Some((1.5, 1.0, 0.0))),
        footprint_spread(2.0, Some((1.5, 0.5, 1.0))),
        footprint_spread(2.0, Some((1.5, 0.5, 16.0))),
        // The reach bounded by the spacing of a refresh's new samples (here about 3.3
        // pixels), which the CPU works out and the GPU is given.
        reach_spacings(footprint_spread(2.0, Some((1.5, 0.5, 16.0))), 0.6),
    ] {
        assert!(params.carry);
        for (w, h, per) in [(48, 32, 1500), (67, 41, 300)] {
            let (mut cpu, mut gpu, tiling) = carry_pair(&ctx, params, (w, h));
            let mut rng = crate::sampling::Rng::new(&[13, per as u64]);
            for k in 0..8 {
                let cam = carry_camera(k, (w, h));
                refresh_both((&mut cpu, &mut gpu), &mut rng, (&cam, &tiling), k, per);
                assert_eq!(cpu.placed(), gpu.placed());
                if k > 0 && !params.resplat_moving_view {
                    assert!(cpu.placed() <= per, "only the new samples are placed");
                }
                let what = format!(
                    "{w}x{h}, {per} per refresh, visibility {}, history {}, re-splat while moving {}, refresh {k}",
                    params.visibility.is_some(),
                    params.history.is_some(),
                    params.resplat_moving_view
                );
                check(&differences(&mut cpu, &mut gpu), (w * h) as usize, &what);
            }
        }
    }
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_carry_replayed_on_kept_sums_matches_the_cpu() {
    // A still view over a moving square: every refresh after the first two replays
    // the CPU's carry (decay, moved sums, cuts) on the sums the GPU kept, instead of
    // uploading them; the images stay the CPU's.
    let ctx = context();
    let converging = ReconParams::converging();
    for params in [
        converging,
        ReconParams::realtime(),
        ReconParams {
            visibility: None,
            ..converging
        },
    ] {
        for (w, h, per) in [(48, 32, 1500), (67, 41, 300)] {
            let (mut cpu, mut gpu, tiling) = carry_pair(&ctx, params, (w, h));
            let mut rng = crate::sampling::Rng::new(&[17, per as u64]);
            let cam = carry_camera(0, (w, h));
            let mut listed = [0usize; 4];
            let refreshes = 10;
            for k in 0..refreshes {
                refresh_both((&mut cpu, &mut gpu), &mut rng, (&cam, &tiling), k, per);
                tally_edits(&gpu, &mut listed);
                let what = format!("{w}x{h}, {per} per refresh, {params:?}, refresh {k}");
                check(&differences(&mut cpu, &mut gpu), (w * h) as usize, &what);
            }
            let (uploaded, replayed) = gpu.gpu_carried_sums().unwrap();
            assert!(
                replayed as usize >= refreshes - 3 && uploaded <= 2,
                "{w}x{h}: {uploaded} uploads, {replayed} replays"
            );
            assert!(
                listed[..3].iter().all(|&n| n > 0),
                "{w}x{h}: takes, landings and cuts listed {:?}",
                &listed[..3]
            );
        }
    }
}

/// Add the takes, landings, cuts and settled pixels of `gpu`'s last carry, where it
/// was listed whole, to `listed`.
fn tally_edits(gpu: &Reconstructor, listed: &mut [usize; 4]) {
    let e = gpu.carried.as_ref().and_then(|c| c.edits.as_ref()).unwrap();
    if e.complete {
        listed[0] += e.takes.len();
        listed[1] += e.lands.len();
        listed[2] += e.cuts.len();
        listed[3] += e.settled.len();
    }
}

/// The camera of refresh `k` of the kept fronts' test: still, then moving for two
/// refreshes (the carry restarts after them, or moves the sums with the view), then
/// still again.
fn fronts_camera(k: usize, size: (u32, u32)) -> CameraFrame {
    carry_camera(
        match k {
            0..5 => 0,
            5..7 => k,
            _ => 6,
        },
        size,
    )
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_kept_fronts_match_a_full_recompute() {
    // A still view over a moving square (cuts, moved sums taken and landing, new
    // geometry settled, holds bits that change), a moving view, then still again:
    // the initial front depths brought up to date at the pixels that may have changed
    // are a full recompute's at every refresh (`check_kept_fronts`, in the tests),
    // the GPU's kept copy is the CPU's, and the images stay the CPU's. Where the sums
    // come back whole, every refresh sends every pixel's.
    let ctx = context();
    let converging = ReconParams::converging();
    let whole_back = ReconParams {
        resplat_moving_view: false,
        ..converging
    };
    for params in [converging, ReconParams::realtime(), whole_back] {
        for (w, h, per) in [(48, 32, 1500), (67, 41, 300)] {
            let (mut cpu, mut gpu, tiling) = carry_pair(&ctx, params, (w, h));
            // Every pixel may be dirty in these small images.
            gpu.few_fronts = None;
            let mut rng = crate::sampling::Rng::new(&[19, per as u64]);
            let mut listed = [0usize; 4];
            let refreshes = 12;
            for k in 0..refreshes {
                let cam = fronts_camera(k, (w, h));
                refresh_both((&mut cpu, &mut gpu), &mut rng, (&cam, &tiling), k, per);
                tally_edits(&gpu, &mut listed);
                let kept = gpu.gpu.as_ref().and_then(|g| g.kept_fronts()).unwrap();
                let n = gpu.gpu_front.len();
                assert_eq!(n, (w * h) as usize);
                assert!(
                    kept[..n] == gpu.gpu_front,
                    "{w}x{h}, refresh {k}: the GPU's kept fronts are not the CPU's"
                );
                let what = format!("{w}x{h}, {per} per refresh, {params:?}, refresh {k}");
                check(&differences(&mut cpu, &mut gpu), n, &what);
            }
            let checked = gpu.kept_fronts_checked;
            if params.resplat_moving_view {
                // The first two refreshes of a still stretch send every pixel's: the
                // carry of the first (0, and 7, which restarts) is not listed whole,
                // and the read-back after it writes every weight.
                assert!(checked >= refreshes - 6, "{w}x{h}: {checked} kept");
                assert!(listed.iter().all(|&n| n > 0), "{w}x{h}: listed {listed:?}");
            } else {
                assert_eq!(checked, 0, "{w}x{h}: sums back whole, fronts kept");
            }
        }
    }
}

#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_shows_a_flat_surface_at_a_half_code_at_exactly_its_value() {
    // As the CPU does (`a_flat_surface_at_a_half_code_is_shown_at_exactly_its_value`):
    // the GPU's history keeps means and shows each block's reference colour.
    let ctx = context();
    let (_, _, tiling) = random_setup(48, 32, 10, 1.0, false, ReconParams::realtime(), GTS);
    let on_gpu = |w, h| {
        let mut gpu = Reconstructor::new(w, h, 20000.0, ReconParams::realtime());
        gpu.use_gpu(ctx.clone())
            .expect("the history runs on the GPU");
        gpu
    };
    super::tests::assert_flat_surface_exact(on_gpu, &tiling, |gpu| {
        assert_eq!(gpu.gpu_failure(), None)
    });
}
