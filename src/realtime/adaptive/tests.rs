//! Tests of the real-time adaptive method's parts.

use std::sync::Arc;

use super::{
    bands,
    bench::record,
    builder::{next_live_limit, push_newest, restart_limit, BuildCost},
    controller::{band_samplers, ingest, snapshot_interval, SNAPSHOT_COST_RATIO, SNAPSHOT_EVERY},
    controllers,
    published::{Published, MIN_BAND_ROWS},
    sampling::{Batch, Visit},
    settings::AdaptiveSettings,
    THREADS_PER_CONTROLLER,
};
use crate::{
    methods::adaptive::SamplerParams,
    realtime::shared::Shared,
    realtime::{config::RtConfig, registry::RtMethod},
    reconstruction::Reconstructor,
    scene::builtin,
    trace::StreamSample,
    trace::{TraceOptions, Tracer},
};

#[test]
fn an_image_takes_in_only_the_samples_its_ring_holds() {
    // 8×4 pixels, ring of 2 samples per pixel: 64.
    let params = crate::reconstruction::ReconParams::realtime();
    let mut r = Reconstructor::new(8, 4, 1000.0, params);
    let cap = r.capacity();
    let stream = |from: usize, n: usize| -> Vec<StreamSample> {
        (from..from + n)
            .map(|i| StreamSample {
                x: (i % 8) as f32 + 0.5,
                y: (i / 8 % 4) as f32 + 0.5,
                t: i as f64,
                sample: Default::default(),
            })
            .collect()
    };
    // More than a ring's worth, over three batches: the newest `cap` are in it.
    let batches = vec![
        stream(0, cap),
        stream(cap, cap / 2),
        stream(cap + cap / 2, cap),
    ];
    push_newest(&mut r, &batches, None);
    let times: Vec<f64> = r.ring().iter().map(|s| s.t).collect();
    let total = 2 * cap + cap / 2;
    assert_eq!(
        times,
        ((total - cap)..total).map(|i| i as f64).collect::<Vec<_>>()
    );
    // Fewer than a ring's worth: all of them, after what was there.
    push_newest(&mut r, &[stream(total, 3)], None);
    assert_eq!(r.ring().back().unwrap().t, (total + 2) as f64);
    assert_eq!(r.ring().len(), cap);
    // Under a live limit, no more than it.
    let before = r.ring().back().unwrap().t;
    push_newest(&mut r, &[stream(total + 3, 10)], Some(4));
    let newest: Vec<f64> = r.ring().iter().map(|s| s.t).skip(cap - 5).collect();
    let from = (total + 3 + 6) as f64;
    assert_eq!(newest, [before, from, from + 1.0, from + 2.0, from + 3.0]);
}

#[test]
fn bands_are_whole_rows_that_cover_the_image_once() {
    let ours = SamplerParams::ours();
    for (w, h, n, expect) in [
        (640, 480, 1, 1),
        (640, 480, 4, 4),
        (640, 481, 3, 3),
        (256, 256, 16, 8), // bands of at least 32 rows
        (64, 20, 4, 1),
    ] {
        let b = bands(w, h, n, &ours);
        assert_eq!(b.len(), expect, "{w}x{h} for {n}");
        assert_eq!((b[0].y0, b[b.len() - 1].y1), (0, h));
        for (i, r) in b.iter().enumerate() {
            assert_eq!((r.x0, r.x1), (0, w));
            assert!(r.height() >= MIN_BAND_ROWS.min(h));
            if i > 0 {
                assert_eq!(r.y0, b[i - 1].y1);
                assert!(r.height().abs_diff(b[i - 1].height()) <= 1);
            }
        }
    }
    // Crosshairs that reproject could leave any band.
    assert_eq!(bands(640, 480, 4, &SamplerParams::paper()).len(), 1);
    assert_eq!((controllers(1), controllers(4), controllers(15)), (1, 1, 4));
}

/// The controller's sampler traces nothing itself, so it sees the camera only when a
/// batch comes in: it must, or the prior a change of view sets for the tiles' errors
/// (`SamplerParams::new_view_prior_s`) never holds live, and a moving view's tiling
/// concentrates on what varies most as a still view's does (on a wall of equal
/// luminance, tiles of 1,024 pixels and splats four times as wide as the evaluation's).
#[test]
fn a_controller_sees_the_view_move_though_it_traces_nothing() {
    let (w, h) = (32, 32);
    let scene = Arc::new(builtin::room());
    let tracer = Arc::new(Tracer::new(scene, w, h, TraceOptions::default()));
    let s = Arc::new(Shared::new(tracer, RtConfig::new(RtMethod::Adaptive)));
    let published = Arc::new(Published::new(&s, AdaptiveSettings::default()));
    let mut sampler = band_samplers(&s, &published).unwrap().remove(0);
    assert_eq!(sampler.camera_since(), f64::NEG_INFINITY);
    for t in [0.5, 1.0] {
        ingest(&mut sampler, Batch::default(), false, t);
        assert_eq!(
            sampler.camera_since(),
            t,
            "the room's camera moves at {t} s"
        );
    }
}

#[test]
fn each_controller_adapts_its_own_band() {
    let (w, h) = (64, 96);
    let scene = Arc::new(builtin::toycar());
    let tracer = Arc::new(Tracer::new(scene, w, h, TraceOptions::default()));
    let mut config = RtConfig::new(RtMethod::Adaptive);
    config.sampling_threads = 2 * THREADS_PER_CONTROLLER; // two controllers
    config.start = 1.0;
    let s = Arc::new(Shared::new(tracer, config));
    let published = Arc::new(Published::new(&s, AdaptiveSettings::default()));
    assert_eq!(published.bands.len(), 2);
    let samplers = band_samplers(&s, &published).unwrap();
    let (samplers, recorded) = record(&s, &published, samplers, 0.5);
    for (b, sampler) in samplers.iter().enumerate() {
        published.tiling(b, sampler);
        sampler.validate().unwrap();
        let band = published.bands[b].rect;
        assert!(!recorded[b].is_empty(), "band {b} got no batch");
        assert!(sampler.buffer().total() > 0, "band {b} holds no crosshair");
        assert!(sampler.tiling().len() > 1, "band {b} never split a tile");
        // Its crosshairs and pending samples were traced in its band.
        for (batch, _) in &recorded[b] {
            for v in &batch.visits {
                let (x, y) = match v {
                    Visit::Completed { pending, .. } | Visit::Initiated(pending) => {
                        (pending.x, pending.y)
                    }
                };
                assert!(band.contains_point(x, y), "{x}, {y} outside band {b}");
            }
        }
    }
    // The reconstructor's tiling covers every pixel exactly once.
    let whole = published.whole_tiling().unwrap();
    let mut covered = vec![0u8; (w * h) as usize];
    for t in &whole.tiles {
        for y in t.rect.y0..t.rect.y1 {
            for x in t.rect.x0..t.rect.x1 {
                covered[(y * w + x) as usize] += 1;
            }
        }
    }
    assert!(covered.iter().all(|&c| c == 1));
    assert_eq!(
        whole.tiles.len(),
        samplers.iter().map(|s| s.tiling().len()).sum::<usize>()
    );
}

#[test]
fn an_image_that_restarts_the_carried_sums_places_half_what_the_one_before_placed() {
    assert_eq!(restart_limit(None, 131_072), Some(65_536));
    // A live limit below that half stays; one above it gives way.
    assert_eq!(restart_limit(Some(30_000), 131_072), Some(30_000));
    assert_eq!(restart_limit(Some(100_000), 131_072), Some(65_536));
    // Never nothing at all.
    assert_eq!(restart_limit(None, 0), Some(1));
}

#[test]
fn the_live_limit_follows_the_build_time_budget() {
    let (floor, cap) = (1000, 100_000);
    // Within budget and unlimited: stays unlimited; no budget: never limited.
    assert_eq!(next_live_limit(None, 50_000, 10.0, 13.0, floor, cap), None);
    assert_eq!(
        next_live_limit(Some(5000), 5000, 90.0, 0.0, floor, cap),
        None
    );
    // Over budget: a limit below what was placed, by at most half.
    let k = next_live_limit(None, 80_000, 26.0, 13.0, floor, cap).unwrap();
    assert!((40_000..80_000).contains(&k), "{k}");
    assert_eq!(
        next_live_limit(None, 80_000, 1e6, 13.0, floor, cap),
        Some(40_000)
    );
    // Over budget under a limit the arrivals did not reach: cut from what was placed.
    assert_eq!(
        next_live_limit(Some(60_000), 20_000, 1e6, 13.0, floor, cap),
        Some(10_000)
    );
    // Never below the floor.
    assert_eq!(
        next_live_limit(Some(1500), 1500, 1e3, 13.0, floor, cap),
        Some(floor)
    );
    // A cost linear in the samples settles near the budget: 2 ms fixed plus
    // 0.2 µs per sample, budget 13 ms (55K samples).
    let mut limit = None;
    let mut placed = cap;
    for _ in 0..60 {
        let ms = 2.0 + placed as f64 * 2e-4;
        limit = next_live_limit(limit, placed, ms, 13.0, floor, cap);
        placed = limit.unwrap_or(cap).min(cap);
    }
    let ms = 2.0 + placed as f64 * 2e-4;
    assert!((12.0..=13.5).contains(&ms), "{ms} ms with {placed}");
    // Time to spare grows it back until the limit is lifted.
    for _ in 0..60 {
        limit = next_live_limit(limit, placed, 5.0, 13.0, floor, cap);
        placed = limit.unwrap_or(cap).min(cap);
    }
    assert_eq!(limit, None);
}

/// Images built under the live limit, with the floor raised by the fitted build cost
/// as the builder does: `cost(k)` ms for `k` samples placed, `arrivals` per image.
fn settle(cost: impl Fn(f64) -> f64, arrivals: usize, budget: f64) -> (usize, f64) {
    let (pixel_floor, cap) = (1000, 1_000_000);
    let (mut limit, mut fit) = (None, BuildCost::default());
    let mut placed = arrivals;
    for _ in 0..200 {
        let ms = cost(placed as f64);
        fit.add(placed, ms);
        let floor = pixel_floor.max(fit.deepest_cut(budget).unwrap_or(0));
        limit = next_live_limit(limit, placed, ms, budget, floor, cap);
        placed = limit.unwrap_or(cap).min(arrivals);
    }
    (placed, cost(placed as f64))
}

#[test]
fn the_live_limit_cuts_no_deeper_than_pays_nor_holds_a_build_over_its_budget() {
    // Fixed part 2 ms, 0.2 µs a sample, budget 13 ms: the budget decides (55K).
    let (placed, ms) = settle(|k| 2.0 + k * 2e-4, 300_000, 13.0);
    assert!((12.0..=13.5).contains(&ms), "{ms} ms with {placed}");
    // Fixed part 8 ms: cutting below 40K samples would buy at most twice the images,
    // but the budget's room beside the fixed part (25K) decides first.
    let (placed, ms) = settle(|k| 8.0 + k * 2e-4, 300_000, 13.0);
    assert!((12.0..=13.5).contains(&ms), "{ms} ms with {placed}");
    // Fixed part 40 ms, over the budget on its own: no cut makes the build fit, and
    // holding 200K samples would keep each build at six budgets instead of three, so
    // the limit goes down to the pixel floor.
    let (placed, _) = settle(|k| 40.0 + k * 2e-4, 300_000, 13.0);
    assert_eq!(placed, 1000);
    // The fit needs spread sample counts and a positive fixed part and slope.
    let mut c = BuildCost::default();
    for _ in 0..20 {
        c.add(50_000, 30.0);
    }
    assert_eq!(c.fit(), None);
    let mut c = BuildCost::default();
    for k in 0..20 {
        let placed = 10_000 + 5_000 * k;
        c.add(placed, 4.0 + placed as f64 * 1e-4);
    }
    let (fixed, per) = c.fit().expect("a fit");
    assert!((fixed - 4.0).abs() < 1e-6 && (per - 1e-4).abs() < 1e-12);
    assert_eq!(c.deepest_cut(100.0), Some(40_000));
    assert_eq!(c.deepest_cut(6.0), Some(20_000));
    assert_eq!(c.deepest_cut(3.0), Some(0));
}

#[test]
fn a_costly_snapshot_waits_in_proportion_and_a_cheap_one_every_millisecond() {
    use std::time::Duration;
    assert_eq!(snapshot_interval(Duration::ZERO), SNAPSHOT_EVERY);
    assert_eq!(snapshot_interval(Duration::from_micros(20)), SNAPSHOT_EVERY);
    let slow = Duration::from_micros(300);
    assert_eq!(snapshot_interval(slow), slow * SNAPSHOT_COST_RATIO);
    assert!(snapshot_interval(slow) > SNAPSHOT_EVERY);
}
