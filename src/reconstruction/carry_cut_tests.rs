//! The cut of one band checked against the same rule stated without an order of
//! visits: what a GPU, whose threads take the samples in any order, would compute.
//!
//! The cut visits each pixel's new samples in ring order, and a sample's fate depends
//! on those before it only through whether the pixel still holds its carried sums:
//! they go at the first sample that cuts them. So, per pixel, with the carried
//! geometry `g` (which the cut reads but does not change) and whether it held sums:
//! the first cutting sample is the lowest index among those that would cut while
//! held; every sample up to it sees the sums held, every later one sees them gone;
//! what is offered is the rest, and the nearest offered wins, ties to the lowest
//! index. These tests hold the cut to that statement on random bands, with depths
//! drawn from a few values so that ties and the tolerance's edges come up often.

use super::*;
use crate::reconstruction::RingSample;
use proptest::prelude::*;

/// Carried depths and new samples' depths: equal ones, ones within the tolerance of
/// each other (10%) and ones beyond it.
const CARRIED_Z: [f32; 4] = [1.0, 1.05, 1.2, 2.0];
const SAMPLE_Z: [f32; 8] = [0.85, 0.9, 1.0, 1.05, 1.1, 1.2, 2.0, 3.0];

/// A pixel's carried state: none, still or moving geometry (depth index, offsets),
/// and whether its weight holds sums.
fn carried() -> impl Strategy<Value = (u8, usize, (f32, f32), bool)> {
    (
        0u8..3,
        0..CARRIED_Z.len(),
        (-0.4f32..0.4, -0.4f32..0.4),
        any::<bool>(),
    )
}

/// A new sample: its pixel (below `n`), depth index and whether it moves.
fn sample(n: usize) -> impl Strategy<Value = (usize, usize, bool)> {
    (0..n, 0..SAMPLE_Z.len(), any::<bool>())
}

/// What the cut leaves, in a form both sides give.
#[derive(Debug, PartialEq)]
struct Outcome {
    /// Pixels cut, ascending.
    cuts: Vec<u32>,
    /// Every pixel's geometry after the cut, as bits.
    geo: Vec<[u32; 6]>,
    /// `(sample, pixel)` of each moving sample offered, by sample.
    moving: Vec<(u32, u32)>,
    /// Pixels whose new geometry moves, each with the index of the sample it came from.
    anchored: Vec<(u32, u32)>,
    /// Pixels whose old geometry moved and got new samples, ascending.
    unanchored: Vec<u32>,
}

fn bits(g: &Geo) -> [u32; 6] {
    [g.z, g.ox, g.oy, g.v.x, g.v.y, g.v.z].map(f32::to_bits)
}

/// The velocity of a moving sample `k`.
fn velocity(k: usize) -> Vec3 {
    Vec3::new(1.0 + k as f32, 0.0, -0.5)
}

/// The band's carried geometry and weights from `pixels`.
fn carried_state(pixels: &[(u8, usize, (f32, f32), bool)]) -> (Vec<Geo>, Vec<f32>) {
    let geo = pixels
        .iter()
        .map(|&(kind, zi, (ox, oy), _)| match kind {
            0 => Geo::NONE,
            _ => Geo {
                z: CARRIED_Z[zi],
                ox,
                oy,
                v: if kind == 2 { Vec3::Y } else { Vec3::ZERO },
            },
        })
        .collect();
    let weight = pixels.iter().map(|p| if p.3 { 1.0 } else { 0.0 }).collect();
    (geo, weight)
}

/// The samples in a ring (each moving one anchored to an instance whose group is its
/// index), and where each lands.
fn ring_of(samples: &[(usize, usize, bool)]) -> (super::super::ring::Ring, Vec<Ahead>) {
    let mut ring = super::super::ring::Ring::new(samples.len().max(1));
    let mut ahead = Vec::new();
    for (k, &(q, zi, moves)) in samples.iter().enumerate() {
        ring.push(&RingSample {
            x: 0.0,
            y: 0.0,
            t: k as f64,
            color: Vec3::ONE,
            hit_point: Vec3::ZERO,
            velocity: if moves { velocity(k) } else { Vec3::ZERO },
            anchor: if moves {
                Anchor::Instance {
                    group: k as u32,
                    local: Vec3::ZERO,
                }
            } else {
                Anchor::Still
            },
        });
        ahead.push(Ahead::new(q, SAMPLE_Z[zi], moves));
    }
    (ring, ahead)
}

/// The cut as the reconstructor makes it: one band of `w × h` pixels.
fn by_the_cut(
    w: usize,
    pixels: &[(u8, usize, (f32, f32), bool)],
    samples: &[(usize, usize, bool)],
) -> Outcome {
    let n = pixels.len();
    let (mut geo, weight) = carried_state(pixels);
    let mut still_z: Vec<f32> = geo.iter().map(Geo::still_z).collect();
    // Rows of `CHANNELS` planes of `w`, the weight the fourth.
    let mut acc = vec![0f32; n * CHANNELS];
    for (q, &wt) in weight.iter().enumerate() {
        for ch in 0..CHANNELS {
            acc[((q / w) * CHANNELS + ch) * w + q % w] = wt;
        }
    }
    let mut cover = vec![1f32; n];
    let mut next_geo = vec![Geo::NONE; n];
    let (ring, ahead) = ring_of(samples);
    let (mut starts, mut ks) = (Vec::new(), Vec::new());
    sort_by_group(&ahead, n.div_ceil(GROUP), &mut starts, &mut ks);
    let ctx = CutContext {
        late: None,
        keep: 1.0 / 1.1,
        list_edits: true,
        w,
        cs: w,
        start: 0,
    };
    let mut band = CutBand {
        base: 0,
        acc: &mut acc,
        cover: &mut cover,
        next_geo: &mut next_geo,
        geo: &mut geo,
        still_z: &mut still_z,
        touched: Vec::new(),
        next_anchor: HashMap::default(),
        out: BandOut::default(),
    };
    band.cut_and_offer(&ctx, &ks, &ring);
    band.settle(&ctx);
    let out = std::mem::take(&mut band.out);
    assert!(band.next_anchor.is_empty(), "an anchor left unsettled");
    assert!(
        next_geo.iter().all(Geo::is_untouched),
        "scratch geometry left set"
    );
    // A cut empties every channel of the pixel and its coverage.
    for q in 0..n {
        let row = |ch: usize| acc[((q / w) * CHANNELS + ch) * w + q % w];
        let emptied = (0..CHANNELS).all(|ch| row(ch) == 0.0) && cover[q] == 0.0;
        assert_eq!(emptied, out.cuts.contains(&(q as u32)), "pixel {q}");
    }
    let mut cuts = out.cuts.clone();
    cuts.sort_unstable();
    let mut moving = out.moving.clone();
    moving.sort_unstable();
    let mut anchored: Vec<(u32, u32)> = out
        .anchored
        .iter()
        .map(|&(q, a)| match a {
            Anchor::Instance { group, .. } => (q, group),
            other => panic!("pixel {q} anchored to {other:?}"),
        })
        .collect();
    anchored.sort_unstable();
    let mut unanchored = out.unanchored.clone();
    unanchored.sort_unstable();
    Outcome {
        cuts,
        geo: geo.iter().map(bits).collect(),
        moving,
        anchored,
        unanchored,
    }
}

/// The same outcome by the rule stated per pixel, without an order of visits.
fn by_the_rule(
    pixels: &[(u8, usize, (f32, f32), bool)],
    samples: &[(usize, usize, bool)],
) -> Outcome {
    let keep = 1.0 / 1.1;
    let (geo, weight) = carried_state(pixels);
    let z = |k: usize| SAMPLE_Z[samples[k].1];
    let held0 = |q: usize| geo[q].is_some() && weight[q] >= MIN_WEIGHT;
    let still = |q: usize| geo[q].v == Vec3::ZERO;
    // Would sample `k` cut its pixel's sums, were they held: in front of them, or
    // behind moving ones.
    let cuts_if_held = |k: usize| {
        let g = geo[samples[k].0];
        behind_front(z(k), g.z, keep) || (g.v != Vec3::ZERO && behind_front(g.z, z(k), keep))
    };
    let n = pixels.len();
    let mut first_cut = vec![usize::MAX; n];
    for (k, &(q, _, _)) in samples.iter().enumerate() {
        if held0(q) && cuts_if_held(k) {
            first_cut[q] = first_cut[q].min(k);
        }
    }
    let mut nearest: Vec<Option<(f32, usize, Geo)>> = vec![None; n];
    let mut moving = Vec::new();
    for (k, &(q, _, moves)) in samples.iter().enumerate() {
        let held = held0(q) && k <= first_cut[q];
        if held && still(q) && behind_front(geo[q].z, z(k), keep) {
            continue;
        }
        let kept_offsets = held && k != first_cut[q];
        let g = Geo {
            z: z(k),
            ox: if kept_offsets { geo[q].ox } else { 0.0 },
            oy: if kept_offsets { geo[q].oy } else { 0.0 },
            v: if moves { velocity(k) } else { Vec3::ZERO },
        };
        if moves {
            moving.push((k as u32, q as u32));
        }
        // Ties to the lowest index: offered in index order, a later equal depth loses.
        if nearest[q].is_none_or(|(zn, kn, _)| (z(k), k) < (zn, kn)) {
            nearest[q] = Some((z(k), k, g));
        }
    }
    let mut new_geo = geo.clone();
    let (mut anchored, mut unanchored) = (Vec::new(), Vec::new());
    for (q, near) in nearest.iter().enumerate() {
        let Some((_, k, g)) = *near else {
            continue;
        };
        if geo[q].v != Vec3::ZERO {
            unanchored.push(q as u32);
        }
        if g.v != Vec3::ZERO {
            anchored.push((q as u32, k as u32));
        }
        new_geo[q] = g;
    }
    let cuts = (0..n)
        .filter(|&q| first_cut[q] != usize::MAX)
        .map(|q| q as u32)
        .collect();
    moving.sort_unstable();
    Outcome {
        cuts,
        geo: new_geo.iter().map(bits).collect(),
        moving,
        anchored,
        unanchored,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// The band's cut is the order-free rule, pixel by pixel.
    #[test]
    fn the_cut_is_the_rule_stated_without_an_order(
        (w, pixels, samples) in (1usize..7, 1usize..5).prop_flat_map(|(w, h)| {
            let n = w * h;
            (
                Just(w),
                prop::collection::vec(carried(), n),
                prop::collection::vec(sample(n), 0..40),
            )
        }),
    ) {
        prop_assert_eq!(by_the_cut(w, &pixels, &samples), by_the_rule(&pixels, &samples));
    }
}
