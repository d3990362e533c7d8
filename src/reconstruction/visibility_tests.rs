//! The visibility pass on analytic scenes: a red square in front of a checkered wall,
//! sampled at random positions and times as the sampler's stream would be, and
//! reconstructed with and without the pass.

use super::*;
use crate::scene::Camera;

const W: u32 = 64;
const H: u32 = 64;
/// Depth planes (the eye looks down −z from z = 5).
const FRONT_Z: f32 = 3.0;
const WALL_Z: f32 = -5.0;
/// Half the square's side, world units.
const HALF: f32 = 0.4;
const RED: Vec3 = Vec3::new(0.9, 0.1, 0.1);

fn camera(eye_x: f32) -> CameraFrame {
    Camera {
        eye: Vec3::new(eye_x, 0.0, 5.0),
        at: Vec3::new(eye_x, 0.0, 0.0),
        up: Vec3::Y,
        fov_y_deg: 60.0,
        hither: 1e-3,
    }
    .frame(W, H)
}

/// The scene at time `t`: the square's centre moves along x at `speed`.
struct Scene {
    speed: f32,
}

impl Scene {
    /// Colour, hit point and velocity of the ray through `(x, y)` of `c` at time `t`.
    fn cast(&self, c: &CameraFrame, x: f32, y: f32, t: f64) -> (Vec3, Vec3, Vec3) {
        let d = c.direction(x, y);
        let p = c.eye + d * ((FRONT_Z - c.eye.z) / d.z);
        let cx = self.speed * t as f32;
        if (p.x - cx).abs() <= HALF && p.y.abs() <= HALF {
            return (RED, p, Vec3::new(self.speed, 0.0, 0.0));
        }
        let q = c.eye + d * ((WALL_Z - c.eye.z) / d.z);
        // Checks of 0.5 units: about 3 pixels on the wall.
        let odd = ((q.x * 2.0).floor() + (q.y * 2.0).floor()).rem_euclid(2.0) == 1.0;
        let grey = if odd { 0.8 } else { 0.2 };
        (Vec3::splat(grey), q, Vec3::ZERO)
    }

    /// The image at `t` seen by `c`, 4 × 4 samples per pixel, and each pixel's share of
    /// the square.
    fn truth(&self, c: &CameraFrame, t: f64) -> (Vec<Vec3>, Vec<f32>) {
        let mut img = vec![Vec3::ZERO; (W * H) as usize];
        let mut cover = vec![0.0; img.len()];
        for y in 0..H {
            for x in 0..W {
                let i = (y * W + x) as usize;
                for k in 0..16 {
                    let (sx, sy) = ((k % 4) as f32 + 0.5, (k / 4) as f32 + 0.5);
                    let (col, _, _) = self.cast(c, x as f32 + sx / 4.0, y as f32 + sy / 4.0, t);
                    img[i] += col / 16.0;
                    // Only the square is red.
                    cover[i] += (col == RED) as u32 as f32 / 16.0;
                }
            }
        }
        (img, cover)
    }
}

/// `n` samples at random positions over `t ∈ [0, 1)`, in time order, seen by
/// `camera_at(t)` and reconstructed at every refresh of a 60 Hz display as they come;
/// the image at `t = 1`, seen by `camera_at(1)`.
fn reconstruct(
    scene: &Scene,
    camera_at: impl Fn(f64) -> CameraFrame,
    params: ReconParams,
    n: usize,
) -> Vec<Vec3> {
    reconstructed(
        scene,
        camera_at,
        Reconstructor::new(W, H, n as f64, params),
        n,
    )
    .image
    .pixels
}

/// [`reconstruct`] with the reconstructor `r`, which it gives back.
fn reconstructed(
    scene: &Scene,
    camera_at: impl Fn(f64) -> CameraFrame,
    mut r: Reconstructor,
    n: usize,
) -> Reconstructor {
    let mut rng = crate::sampling::Rng::new(&[7, n as u64]);
    // Tiles as the sampler would measure them: a still wall, so long temporal filters.
    let mut tiling = TilingSnapshot::whole(W, H);
    tiling.tiles[0].gx = 0.1;
    tiling.tiles[0].gy = 0.1;
    tiling.tiles[0].gt = 0.05;
    let mut refresh = 1;
    for i in 0..n {
        let t = i as f64 / n as f64;
        while t >= refresh as f64 / 60.0 {
            let tr = refresh as f64 / 60.0;
            r.reconstruct(tr, &camera_at(tr), &tiling);
            refresh += 1;
        }
        let c = camera_at(t);
        let (x, y) = (rng.uniform() * W as f32, rng.uniform() * H as f32);
        let (color, hit_point, velocity) = scene.cast(&c, x, y, t);
        r.push(RingSample {
            x,
            y,
            t,
            color,
            hit_point,
            velocity,
            anchor: Default::default(),
        });
    }
    r.reconstruct(1.0, &camera_at(1.0), &tiling);
    r
}

#[test]
fn the_decay_left_to_the_splat_is_the_decay_done_at_once_bit_for_bit() {
    // The moving square's carried sums are moved, landed and cut at every refresh,
    // the wall's decay: every step that reads the sums between the carry and the
    // splat.
    let scene = Scene { speed: 0.6 };
    let c = camera(0.0);
    let n = (W * H * 3) as usize;
    let run = |late: bool| {
        let mut r = Reconstructor::new(W, H, n as f64, ReconParams::converging());
        r.decay_late = late;
        reconstructed(&scene, |_| c, r, n)
    };
    let (late, at_once) = (run(true), run(false));
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&late.acc), bits(&at_once.acc), "the sums");
    assert_eq!(bits(&late.cover), bits(&at_once.cover), "the coverage");
    let px = |r: &Reconstructor| {
        r.image
            .pixels
            .iter()
            .flat_map(|p| p.to_array())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&px(&late)), bits(&px(&at_once)), "the image");
    let moving = late.carried.as_ref().map_or(0, |c| c.moving_count());
    assert!(moving > 0, "nothing moved");
}

/// The reconstructor that splats the whole ring at every refresh, with the pass.
fn resplat() -> ReconParams {
    ReconParams {
        carry: false,
        ..ReconParams::converging()
    }
}

/// The converging preset with its visibility pass changed by `f`.
fn with_visibility(f: impl FnOnce(Visibility) -> Visibility) -> ReconParams {
    let mut p = ReconParams::converging();
    p.visibility = p.visibility.map(f);
    p
}

/// The same without the pass: every sample reaches every pixel of its footprint.
fn without_visibility() -> ReconParams {
    ReconParams {
        visibility: None,
        ..resplat()
    }
}

/// Mean absolute error (all channels) over the pixels `keep` selects.
fn mean_error(img: &[Vec3], truth: &[Vec3], keep: impl Fn(usize) -> bool) -> f32 {
    let (mut sum, mut n) = (0.0, 0);
    for i in (0..img.len()).filter(|&i| keep(i)) {
        sum += (img[i] - truth[i]).abs().element_sum() / 3.0;
        n += 1;
    }
    assert!(n > 20, "only {n} pixels selected");
    sum / n as f32
}

/// Pixels within `r` pixels of one the square partly covers.
fn near_edge(cover: &[f32], r: i32) -> Vec<bool> {
    let partial = |x: i32, y: i32| {
        (0..W as i32).contains(&x)
            && (0..H as i32).contains(&y)
            && cover[(y * W as i32 + x) as usize] > 0.0
            && cover[(y * W as i32 + x) as usize] < 1.0
    };
    (0..(W * H) as i32)
        .map(|i| {
            let (x, y) = (i % W as i32, i / W as i32);
            (-r..=r).any(|dy| (-r..=r).any(|dx| partial(x + dx, y + dy)))
        })
        .collect()
}

#[test]
fn a_moving_square_keeps_its_silhouette() {
    // The square crosses the wall at 0.6 units/s (about 17 px/s at its depth): the
    // wall samples traced before it arrived lie where it is now.
    let scene = Scene { speed: 0.6 };
    let c = camera(0.0);
    let (truth, cover) = scene.truth(&c, 1.0);
    let edge = near_edge(&cover, 1);
    let n = (W * H * 6) as usize;
    let error = |p: ReconParams| mean_error(&reconstruct(&scene, |_| c, p, n), &truth, |i| edge[i]);
    let (e_carried, e_with, e_without) = (
        error(ReconParams::converging()),
        error(resplat()),
        error(without_visibility()),
    );
    eprintln!(
        "edge error: {e_carried} carried, {e_with} re-splatted with the visibility pass, \
         {e_without} without"
    );
    // Measured: 0.086 with the pass, 0.125 without (0.69×). Carried
    // accumulators cut what a nearer new sample covers, and still carried sums hide
    // what lies behind them (0.102, 0.82× the error without the pass).
    for (what, e, bar) in [
        ("re-splatted with the pass", e_with, 0.8),
        ("carried", e_carried, 0.85),
    ] {
        assert!(
            e < bar * e_without,
            "edge error {e} {what}, {e_without} without the pass"
        );
    }
}

/// The camera of the fast-move tests: the eye slides 0.6 units sideways in the last
/// 0.2 s.
fn slide_eye(t: f64) -> CameraFrame {
    camera(0.6 * ((t as f32 - 0.8) / 0.2).clamp(0.0, 1.0))
}

/// The image `scene` shows at the slide's end, and which pixels are the square's
/// inside, away from its outline.
fn slide_truth(scene: &Scene) -> (Vec<Vec3>, Vec<bool>) {
    let (truth, cover) = scene.truth(&slide_eye(1.0), 1.0);
    let edge = near_edge(&cover, 1);
    let inside = (0..cover.len())
        .map(|i| cover[i] == 1.0 && !edge[i])
        .collect();
    (truth, inside)
}

#[test]
fn a_fast_camera_move_shows_no_wall_through_the_square() {
    // A still scene; the eye slides 0.6 units sideways in the last 0.2 s, so the wall
    // seen beside the square from the old view now lies behind it.
    let scene = Scene { speed: 0.0 };
    let (truth, inside) = slide_truth(&scene);
    let inside = |i: usize| inside[i];
    let n = (W * H * 6) as usize;
    let worst = |p: ReconParams| {
        let img = reconstruct(&scene, slide_eye, p, n);
        (0..img.len())
            .filter(|&i| inside(i))
            .map(|i| (img[i] - truth[i]).abs().max_element())
            .fold(0f32, f32::max)
    };
    let (w_carried, w_with, w_without) = (
        worst(ReconParams::converging()),
        worst(resplat()),
        worst(without_visibility()),
    );
    eprintln!(
        "largest error inside: {w_carried} carried, {w_with} re-splatted with the visibility \
         pass, {w_without} without"
    );
    // Measured: 0.075 with the pass, 0.53 without. What is left comes
    // from the few pixels no sample of the square has landed in yet.
    assert!(
        w_without > 0.3,
        "the case should bleed without the pass: {w_without}"
    );
    for (what, w) in [
        ("re-splatted with the pass", w_with),
        ("carried", w_carried),
    ] {
        assert!(
            w < 0.25 * w_without,
            "the wall shows through the square {what}: error up to {w} (without the pass {w_without})"
        );
    }
}

#[test]
fn a_turn_hides_the_far_wall_where_the_square_has_few_samples_yet() {
    // As above, with a sample per pixel a second: few of the square's new samples have
    // landed in its pixels when the move ends, and the wall's, reprojected from the
    // old view, land between them. While the view moves, a front spreads to the pixels
    // around where it landed, and hides a surface more than three times farther (the
    // wall is five times the square's depth).
    let scene = Scene { speed: 0.0 };
    let (truth, inside) = slide_truth(&scene);
    let inside = |i: usize| inside[i];
    let n = (W * H) as usize;
    let errors = |spread: Option<f32>| {
        let p = with_visibility(|v| Visibility {
            moving_view_spread: spread,
            ..v
        });
        let img = reconstruct(&scene, slide_eye, p, n);
        let e: Vec<f32> = (0..img.len())
            .filter(|&i| inside(i))
            .map(|i| (img[i] - truth[i]).abs().max_element())
            .collect();
        let mean = e.iter().sum::<f32>() / e.len() as f32;
        (mean, e.iter().filter(|&&x| x > 0.2).count())
    };
    let ((m_own, n_own), (m_spread, n_spread)) = (errors(None), errors(Some(3.0)));
    eprintln!(
        "inside the square: mean error {m_own}, {n_own} pixels off by more than 0.2 \
         with each pixel's own front; {m_spread}, {n_spread} with the fronts spread"
    );
    assert!(n_own >= 5, "the case should show the wall: {n_own} pixels");
    assert!(
        m_spread < 0.7 * m_own && n_spread * 2 <= n_own,
        "spread: mean {m_spread}, {n_spread} pixels; own: {m_own}, {n_own}"
    );
}

#[test]
fn a_footprints_reach_hides_the_wall_where_the_squares_samples_are_pixels_apart() {
    // The slide at a quarter of a sample per pixel a second: when the move ends, the
    // square's new samples lie several pixels apart, farther than the wall's
    // footprints reach, and the wall's samples, carried across the square by the move,
    // show between them. Looking for the square's fronts as far around a wall sample
    // as the move carried it (up to the reach) hides them.
    let scene = Scene { speed: 0.0 };
    let (truth, inside) = slide_truth(&scene);
    let n = (W * H / 4) as usize;
    let error = |reach: f32| {
        let p = with_visibility(|v| Visibility {
            // The wall is five times the square's depth: a ratio below that.
            footprint_spread: Some(3.0),
            footprint_reach: reach,
            ..v
        });
        mean_error(&reconstruct(&scene, slide_eye, p, n), &truth, |i| inside[i])
    };
    let (e_box, e_reach) = (error(0.0), error(16.0));
    eprintln!("inside the square: mean error {e_box} within the footprint's box, {e_reach} with the reach");
    assert!(
        e_reach < 0.8 * e_box,
        "the reach should hide more of the wall: {e_reach} against {e_box} without"
    );
}

#[test]
fn a_panning_view_keeps_the_wall_beside_the_square() {
    // The eye pans all along, so the fronts spread at every refresh, but slowly: a wall
    // sample traced beside the square's edge is still beside it, and hiding it (as
    // the spread did before its parallax test) widens the square by a pixel.
    let scene = Scene { speed: 0.0 };
    let pan = |t: f64| camera(0.3 * t as f32);
    let (truth, cover) = scene.truth(&pan(1.0), 1.0);
    let edge = near_edge(&cover, 1);
    let beside = |i: usize| edge[i] && cover[i] == 0.0;
    let n = (W * H * 6) as usize;
    let error = |v: Option<Visibility>| {
        let p = ReconParams {
            visibility: v,
            ..ReconParams::converging()
        };
        mean_error(&reconstruct(&scene, pan, p, n), &truth, beside)
    };
    let rule = Visibility::default();
    let (e_rule, e_any, e_own) = (
        error(Some(rule)),
        error(Some(Visibility {
            spread_parallax: 0.0,
            ..rule
        })),
        error(Some(Visibility {
            moving_view_spread: None,
            ..rule
        })),
    );
    eprintln!(
        "beside the edge: mean error {e_rule} with the parallax test, {e_any} hiding every \
         far sample, {e_own} with each pixel's own front"
    );
    assert!(
        e_rule < 0.6 * e_any && e_rule < 1.1 * e_own,
        "beside the edge: {e_rule} with the test, {e_any} without, {e_own} not spread"
    );
}

proptest::proptest! {
    /// The spread fronts are each pixel's own or the ratio times the nearest of its
    /// eight neighbours' (inside the image), whichever is nearer, stated pixel by pixel,
    /// and the own fronts are kept; fronts drawn from a few depths and none, so that
    /// ties and empty pixels come up.
    #[test]
    fn spread_fronts_are_the_nearest_neighbours_times_the_ratio(
        w in 1usize..9,
        h in 1usize..9,
        depths in proptest::collection::vec(0usize..4, 81),
        ratio in 1.0f32..4.0,
    ) {
        let pick = [f32::INFINITY, 1.0, 2.5, 7.0];
        let own: Vec<f32> = depths[..w * h].iter().map(|&d| pick[d]).collect();
        let mut spread = own.clone();
        let mut state = super::spread::Spread::default();
        state.apply(&mut spread, w, ratio, false);
        for y in 0..h {
            for x in 0..w {
                let mut near = f32::INFINITY;
                for (dx, dy) in (-1i32..=1).flat_map(|dy| (-1i32..=1).map(move |dx| (dx, dy))) {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if (dx, dy) != (0, 0) && (0..w as i32).contains(&nx) && (0..h as i32).contains(&ny) {
                        near = near.min(own[ny as usize * w + nx as usize]);
                    }
                }
                let want = own[y * w + x].min(ratio * near);
                proptest::prop_assert_eq!(spread[y * w + x].to_bits(), want.to_bits(), "pixel ({}, {})", x, y);
            }
        }
        proptest::prop_assert_eq!(state.own_fronts(), &own[..]);
    }
}
