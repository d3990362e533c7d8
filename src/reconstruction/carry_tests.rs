//! Tests of the carried accumulators: each sample splatted once and decayed after,
//! sums moved with the view, cuts where a new sample disagrees, a cost that does not
//! follow the ring.

use super::*;
use crate::{scene::Camera, tiles::TilingSnapshot};

/// A camera at `eye_x` on the x axis, 1 unit in front of the plane `z = −1`... looking
/// down −z (a 90° vertical field of view).
fn cam_at(eye_x: f32, w: u32, h: u32) -> CameraFrame {
    Camera {
        eye: Vec3::new(eye_x, 0.0, 1.0),
        at: Vec3::new(eye_x, 0.0, 0.0),
        up: Vec3::Y,
        fov_y_deg: 90.0,
        hither: 1e-3,
    }
    .frame(w, h)
}

/// A still sample of the plane `z = 0` seen through `(x, y)` of `c` at time `t`.
fn on_plane(c: &CameraFrame, x: f32, y: f32, t: f64, color: Vec3) -> RingSample {
    let d = c.direction(x, y);
    RingSample {
        x,
        y,
        t,
        color,
        hit_point: c.eye + d * (-c.eye.z / d.z),
        velocity: Vec3::ZERO,
        anchor: Default::default(),
    }
}

/// Carried accumulators with a fixed filter and splat scale, and nothing else on top
/// (no fill, no history), so that sums can be evaluated directly.
fn bare(et: f64) -> ReconParams {
    ReconParams {
        fixed_filter: Some(Extents {
            ex: 1.2,
            ey: 0.9,
            et,
        }),
        scale_bounds: (1.0, 1.0),
        fill_weight: 0.0,
        history: None,
        visibility: None,
        // What is tested here is the carried sums' move with the view.
        resplat_moving_view: false,
        ..ReconParams::converging()
    }
}

/// Batches of random samples on the plane, pushed between refreshes at `times`.
fn batches(c: &CameraFrame, times: &[f64], per: usize, seed: u64) -> Vec<Vec<RingSample>> {
    let mut rng = crate::sampling::Rng::new(&[seed]);
    let mut prev = times[0] - 0.02;
    times
        .iter()
        .map(|&t| {
            let b = (0..per)
                .map(|k| {
                    let ts = prev + (t - prev) * (k + 1) as f64 / (per + 1) as f64;
                    let (x, y) = (
                        rng.uniform() * c.width as f32,
                        rng.uniform() * c.height as f32,
                    );
                    let col = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                    on_plane(c, x, y, ts, col)
                })
                .collect();
            prev = t;
            b
        })
        .collect()
}

#[test]
fn each_sample_is_splatted_once_then_decays_exponentially() {
    let (w, h) = (24, 18);
    let c = cam_at(0.0, w, h);
    let et = 0.03;
    let times = [1.0, 1.016, 1.05, 1.07, 1.09];
    let bs = batches(&c, &times, 60, 3);
    let params = bare(et);
    let tau = et * params.decay_scale as f64;
    let mut r = Reconstructor::new(w, h, 3000.0, params);
    let tiling = TilingSnapshot::whole(w, h);
    for (b, &t) in bs.iter().zip(&times) {
        for s in b {
            r.push(*s);
        }
        r.reconstruct(t, &c, &tiling);
        assert_eq!(r.placed(), b.len(), "only the new samples are placed");
    }
    // Direct: a sample's weight is its Gaussian at its first refresh (its age counted
    // from the newest sample then in hand), times e^(−Δ/τ) for the time since; its
    // shown age grows with the clock.
    let t_end = *times.last().unwrap();
    let (ex, ey, tc) = (1.2f64, 0.9f64, 2.5f64);
    let mut sums = vec![[0f64; 5]; (w * h) as usize];
    let mut newest = f64::NEG_INFINITY;
    for (b, &t1) in bs.iter().zip(&times) {
        newest = b.iter().fold(newest, |m, s| m.max(s.t));
        for s in b {
            let a = (newest.min(t1) - s.t) / et;
            if a > tc {
                continue;
            }
            let wt = (-0.5 * a * a).exp() * (-(t_end - t1) / tau).exp();
            for y in 0..h as usize {
                for x in 0..w as usize {
                    let (dx, dy) = (x as f64 + 0.5 - s.x as f64, y as f64 + 0.5 - s.y as f64);
                    if dx.abs() > tc * ex || dy.abs() > tc * ey {
                        continue;
                    }
                    let g = wt * (-0.5 * ((dx / ex).powi(2) + (dy / ey).powi(2))).exp();
                    let o = &mut sums[y * w as usize + x];
                    let col = s.color.as_dvec3();
                    for (k, v) in [col.x, col.y, col.z, 1.0, t_end - s.t].iter().enumerate() {
                        o[k] += g * v;
                    }
                }
            }
        }
    }
    let mut compared = 0;
    for (i, s) in sums.iter().enumerate() {
        if s[3] < 1e-6 {
            continue;
        }
        compared += 1;
        let px = r.image().pixels[i].to_array();
        for k in 0..3 {
            let want = s[k] / s[3];
            assert!(
                (px[k] as f64 - want).abs() < 1e-4,
                "pixel {i} channel {k}: {} vs {want}",
                px[k]
            );
        }
        let age = s[4] / s[3];
        assert!(
            (r.pixel_ages()[i] as f64 - age).abs() < 1e-4,
            "pixel {i} age"
        );
    }
    assert!(
        compared > sums.len() * 3 / 4,
        "only {compared} pixels compared"
    );
}

#[test]
fn carried_sums_follow_the_view() {
    // The view slides right by exactly 3 pixels at the plane's depth: what was at
    // pixel x + 3 is now at pixel x, sums decayed alike (so the same colours).
    let (w, h) = (24, 18);
    let c0 = cam_at(0.0, w, h);
    let step = 3.0 * c0.du.length() * 1.0;
    let c1 = cam_at(step, w, h);
    let tiling = TilingSnapshot::whole(w, h);
    let mut r = Reconstructor::new(w, h, 3000.0, bare(0.05));
    for s in &batches(&c0, &[1.0], 800, 5)[0] {
        r.push(*s);
    }
    let before = r.reconstruct(1.0, &c0, &tiling).clone();
    let after = r.reconstruct(1.02, &c1, &tiling).clone();
    let mut compared = 0;
    for y in 0..h as usize {
        for x in 0..w as usize - 3 {
            let (a, b) = (
                after.pixels[y * w as usize + x],
                before.pixels[y * w as usize + x + 3],
            );
            assert!((a - b).abs().max_element() < 1e-4, "({x}, {y}): {a} vs {b}");
            compared += 1;
        }
    }
    assert!(compared > 300);
}

#[test]
fn a_nearer_new_sample_cuts_what_was_carried_at_its_pixel() {
    let (w, h) = (16, 12);
    let c = cam_at(0.0, w, h);
    let tiling = TilingSnapshot::whole(w, h);
    let mut r = Reconstructor::new(w, h, 3000.0, bare(0.2));
    for s in &batches(&c, &[1.0], 400, 7)[0] {
        r.push(RingSample {
            color: Vec3::splat(0.2),
            ..*s
        });
    }
    r.reconstruct(1.0, &c, &tiling);
    // Half the way to the eye, at pixel (8, 6): something arrived in front.
    let (x, y) = (8.5, 6.5);
    let red = Vec3::new(1.0, 0.0, 0.0);
    r.push(RingSample {
        hit_point: c.eye + c.direction(x, y) * 0.5,
        color: red,
        ..on_plane(&c, x, y, 1.01, red)
    });
    let img = r.reconstruct(1.016, &c, &tiling);
    let at = img.pixels[6 * w as usize + 8];
    assert!(
        (at - red).abs().max_element() < 1e-5,
        "the cut pixel shows {at}"
    );
    // Its neighbours keep the plane, mixed with the new sample's splat.
    let next = img.pixels[6 * w as usize + 10];
    assert!(next.y > 0.05, "a neighbour lost the carried plane: {next}");
}

/// Each band of the cut builds its next geometry in a scratch band its thread reuses
/// for the next band: every pixel new samples land on must take the nearest one's
/// geometry, whatever pixel of an earlier band the same scratch entry served.
#[test]
fn every_band_takes_its_nearest_new_geometry_on_one_thread() {
    let (w, h) = (24, 5 * 16 + 3);
    let c = cam_at(0.0, w, h);
    let tiling = TilingSnapshot::whole(w, h);
    let proj = super::place::Projector::new(&c);
    let mut r = Reconstructor::new(w, h, 3000.0, bare(0.2));
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let times = [1.0, 1.016, 1.033, 1.05];
    for (i, (b, &t)) in batches(&c, &times, 300, 11).iter().zip(&times).enumerate() {
        // Each batch nearer than the last, so that it cuts what was carried.
        let nearest = b
            .iter()
            .map(|s| {
                let hit = c.eye + (s.hit_point - c.eye) * (1.0 - 0.2 * i as f32);
                RingSample {
                    hit_point: hit,
                    ..*s
                }
            })
            .collect::<Vec<_>>();
        let mut want = vec![f32::INFINITY; (w * h) as usize];
        for s in &nearest {
            r.push(*s);
            let (x, y, z) = proj.project(s.hit_point);
            let q = y as usize * w as usize + x as usize;
            want[q] = want[q].min(z);
        }
        one.install(|| r.reconstruct(t, &c, &tiling));
        let geo = &r.carried.as_ref().unwrap().geo;
        let landed = want.iter().filter(|z| z.is_finite()).count();
        assert!(
            landed > 150,
            "refresh {i}: only {landed} pixels got samples"
        );
        for (q, z) in want.iter().enumerate().filter(|(_, z)| z.is_finite()) {
            assert_eq!(
                geo[q].z, *z,
                "refresh {i}, pixel {q}: not its nearest new sample's depth"
            );
        }
    }
}

#[test]
fn images_do_not_depend_on_the_ring_size() {
    // Only the samples since the previous refresh are placed: a ring that holds them
    // gives the same images however long it is.
    let (w, h) = (20, 16);
    let c = cam_at(0.0, w, h);
    let tiling = TilingSnapshot::whole(w, h);
    let times: Vec<f64> = (0..6).map(|k| 1.0 + k as f64 / 60.0).collect();
    let bs = batches(&c, &times, 150, 9);
    let images: Vec<Vec<Vec3>> = [0.5, 1.0, 4.0]
        .iter()
        .map(|&ring_factor| {
            let mut r = Reconstructor::new(
                w,
                h,
                9000.0,
                ReconParams {
                    ring_factor,
                    ..ReconParams::converging()
                },
            );
            for (b, &t) in bs.iter().zip(&times) {
                for s in b {
                    r.push(*s);
                }
                r.reconstruct(t, &c, &tiling);
                assert_eq!(r.placed(), b.len());
            }
            r.image().pixels.clone()
        })
        .collect();
    assert_eq!(images[0], images[1]);
    assert_eq!(images[1], images[2]);
}

#[test]
fn an_image_handed_over_leaves_a_spare_whose_pixels_are_never_read() {
    // `take_image` swaps the image for a spare instead of copying it: the refreshes
    // after must not read what the spare held. Garbage spares, a view that holds
    // (carried, with the history) and then moves (the ring re-splatted), must give
    // the images of a reconstructor whose image stays.
    let (w, h) = (20, 36);
    let tiling = TilingSnapshot::whole(w, h);
    let times: Vec<f64> = (0..8).map(|k| 1.0 + k as f64 / 60.0).collect();
    let cams: Vec<CameraFrame> = (0..times.len())
        .map(|k| cam_at(0.02 * k.saturating_sub(4) as f32, w, h))
        .collect();
    let bs = batches(&cams[0], &times, 200, 5);
    let run = |hand_over: bool| {
        let mut r = Reconstructor::new(w, h, 12000.0, ReconParams::realtime());
        let mut images = Vec::new();
        for (k, (b, &t)) in bs.iter().zip(&times).enumerate() {
            for s in b {
                r.push(*s);
            }
            r.reconstruct(t, &cams[k], &tiling);
            images.push(if hand_over {
                let mut spare = Image::new(w, h);
                spare.pixels.fill(Vec3::splat(f32::NAN));
                r.take_image(Some(spare)).pixels
            } else {
                r.image().pixels.clone()
            });
        }
        images
    };
    let (kept, handed) = (run(false), run(true));
    for (k, (a, b)) in kept.iter().zip(&handed).enumerate() {
        let same = a
            .iter()
            .zip(b)
            .all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits));
        assert!(same, "refresh {k}: a spare's pixels showed through");
    }
    // A spare of another size is not taken: the image is copied.
    let mut r = Reconstructor::new(w, h, 12000.0, ReconParams::realtime());
    r.reconstruct(1.0, &cams[0], &tiling);
    let before = r.image().pixels.clone();
    assert_eq!(r.take_image(Some(Image::new(w + 1, h))).pixels, before);
    assert_eq!(r.image().pixels, before);
}

#[test]
fn a_moving_view_resplats_the_ring_and_carrying_resumes_once_it_holds() {
    // While the view moves the refresh is the ring's (the same images as without
    // carrying); the first refresh after the view stops re-splats the ring too, onto
    // nothing, and carries on from there: only the new samples are placed after.
    let (w, h) = (24, 18);
    let tiling = TilingSnapshot::whole(w, h);
    let times: Vec<f64> = (0..7).map(|k| 1.0 + k as f64 / 60.0).collect();
    // The view moves for the first four refreshes, then holds.
    let eye = |k: usize| 0.02 * k.min(3) as f32;
    let bs: Vec<Vec<RingSample>> = times
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            batches(
                &cam_at(eye(k), w, h),
                &[t - 1.0 / 60.0, t],
                80,
                20 + k as u64,
            )
            .remove(1)
        })
        .collect();
    let hybrid = ReconParams {
        resplat_moving_view: true,
        ..bare(0.03)
    };
    let ring = ReconParams {
        carry: false,
        ..hybrid
    };
    let mut a = Reconstructor::new(w, h, 5000.0, hybrid);
    let mut b = Reconstructor::new(w, h, 5000.0, ring);
    for (k, (batch, &t)) in bs.iter().zip(&times).enumerate() {
        for s in batch {
            a.push(*s);
            b.push(*s);
        }
        let c = cam_at(eye(k), w, h);
        a.reconstruct(t, &c, &tiling);
        b.reconstruct(t, &c, &tiling);
        match k {
            // The first refresh carries from nothing: a re-splat as well.
            0..=4 => {
                assert_eq!(a.placed(), b.placed(), "refresh {k} places the live ring");
                assert_eq!(a.image().pixels, b.image().pixels, "refresh {k}");
            }
            _ => assert_eq!(a.placed(), batch.len(), "refresh {k} carries"),
        }
    }
    // And carrying changed the image from the ring's (its temporal weight differs).
    assert_ne!(a.image().pixels, b.image().pixels);
}

#[test]
fn only_the_first_refresh_where_the_view_holds_after_moving_restarts() {
    // The view moves for refreshes 1 to 3 and holds from 4: refresh 4 restarts the
    // carried sums (placing the live ring, or the newest samples a live limit allows),
    // and none other does.
    let (w, h) = (24, 18);
    let tiling = TilingSnapshot::whole(w, h);
    let eye = |k: usize| 0.02 * k.min(3) as f32;
    let params = ReconParams {
        resplat_moving_view: true,
        ..bare(0.03)
    };
    let mut r = Reconstructor::new(w, h, 5000.0, params);
    for k in 0..7 {
        let t = 1.0 + k as f64 / 60.0;
        let c = cam_at(eye(k), w, h);
        for s in batches(&c, &[t - 1.0 / 60.0, t], 80, 40 + k as u64).remove(1) {
            r.push(s);
        }
        assert_eq!(r.restarts_at(&c), k == 4, "refresh {k}");
        let limit = (k == 4).then_some(50);
        r.set_live_limit(limit);
        r.reconstruct(t, &c, &tiling);
        if k == 4 {
            assert_eq!(r.placed(), 50, "the restart keeps to the live limit");
        }
    }
}

/// Values in `[−0.5, 1.5)` from a fixed seed, for the lane tests.
fn values(n: usize, seed: u32) -> Vec<f32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1 << 24) as f32 * 2.0 - 0.5
        })
        .collect()
}

/// The row decay, [`LANES`](super::lanes::LANES) pixels at a time, gives the bits of
/// the same operations pixel by pixel, on widths that leave a partial span, and leaves
/// the row's padding alone.
#[test]
fn a_row_decays_bit_for_bit_as_pixel_by_pixel() {
    use super::carry::decay_row;
    let decay = [[0.9f32, 0.97], [0.5, 0.8], [0.0, 0.25]];
    let dt = 0.033f32;
    for w in [1usize, 7, 8, 9, 17, 30] {
        let cs = w.next_multiple_of(8) + 8;
        let row = values(CHANNELS * cs, w as u32);
        let cover = values(w, 99);
        let lookup: Vec<Lookup> = (0..w)
            .map(|x| Lookup {
                tile: (x * 7 % 3) as u32,
            })
            .collect();
        let (mut r, mut c) = (row.clone(), cover.clone());
        decay_row(&mut r, &mut c, cs, &lookup, &decay, dt);
        for x in 0..cs {
            let [k, kc] = decay[lookup.get(x).map_or(0, |l| l.tile as usize)];
            let (k, kc) = if x < w { (k, kc) } else { (1.0, 1.0) };
            let at = |ch: usize| ch * cs + x;
            let mut want: Vec<f32> = (0..CHANNELS).map(|ch| row[at(ch)] * k).collect();
            want[4] = k * dt.mul_add(row[at(3)], row[at(4)]);
            if x >= w {
                want = (0..CHANNELS).map(|ch| row[at(ch)]).collect();
            }
            for (ch, v) in want.iter().enumerate() {
                assert_eq!(r[at(ch)].to_bits(), v.to_bits(), "w {w} x {x} ch {ch}");
            }
            if x < w {
                assert_eq!(c[x].to_bits(), (cover[x] * kc).to_bits(), "w {w} x {x}");
            }
        }
    }
}

/// Fronts lowered without branches match the test pixel by pixel: held still
/// geometry lowers the front, moving geometry and weights that hold nothing (NaN
/// included) do not.
#[test]
fn fronts_are_lowered_as_pixel_by_pixel() {
    use super::carry::{lower_fronts, Geo};
    for w in [1usize, 7, 9, 17] {
        let z = values(w, 3);
        let front = values(w, 4);
        let geo: Vec<Geo> = (0..w)
            .map(|x| Geo {
                z: z[x] + 0.5,
                v: if x % 3 == 1 { Vec3::X } else { Vec3::ZERO },
                ..Geo::NONE
            })
            .collect();
        let weight: Vec<f32> = (0..w).map(|x| [1.0, 0.0, f32::NAN, 1e-30][x % 4]).collect();
        let still_z: Vec<f32> = geo.iter().map(Geo::still_z).collect();
        let mut got = front.clone();
        lower_fronts(&mut got, &still_z, &weight);
        for x in 0..w {
            let lowers = weight[x] >= super::splat::MIN_WEIGHT && geo[x].v == Vec3::ZERO;
            let want = if lowers {
                front[x].min(geo[x].z)
            } else {
                front[x]
            };
            assert_eq!(got[x].to_bits(), want.to_bits(), "w {w} x {x}");
        }
    }
}

#[cfg(feature = "gpu")]
#[test]
fn front_bits_are_those_of_fronts_lowered_from_none() {
    use super::carry::{lower_fronts, lowered_front_bits, Geo};
    for w in [1usize, 7, 9, 17] {
        let z = values(w, 5);
        let geo: Vec<Geo> = (0..w)
            .map(|x| Geo {
                z: [z[x] + 0.5, f32::INFINITY, z[x] + 1.0][x % 3],
                v: if x % 5 == 2 { Vec3::Y } else { Vec3::ZERO },
                ..Geo::NONE
            })
            .collect();
        let weight: Vec<f32> = (0..w).map(|x| [1.0, 0.0, f32::NAN, 1e-30][x % 4]).collect();
        let still_z: Vec<f32> = geo.iter().map(Geo::still_z).collect();
        let mut front = vec![f32::INFINITY; w];
        lower_fronts(&mut front, &still_z, &weight);
        let mut got = vec![7u32; w];
        lowered_front_bits(&mut got, &still_z, &weight);
        assert_eq!(got, super::gpu::carried::front_bits(&front), "w {w}");
    }
}
