//! The sampling threads' completions while the view moves: a still point the view
//! carried out of its tile is probed where it is now and its crosshair traced where it
//! started, on the CPU threads ([`complete`]) and from a GPU batch ([`fill`]).

use std::sync::Arc;

use crossbeam_channel::bounded;

use super::{complete, fill, Batch, Outbox, Planned, Visit};
use crate::{
    methods::adaptive::{
        sampler::{crosshair_points, temporal_gradient, Completion},
        tiling::{Pending, Rect},
    },
    realtime::{
        adaptive::{published::Published, settings::AdaptiveSettings},
        config::RtConfig,
        registry::RtMethod,
        shared::Shared,
    },
    scene::builtin,
    trace::{Sample, TraceOptions, Tracer},
};

const SIZE: u32 = 64;
const T0: f64 = 1.0;
const T1: f64 = 1.5;

/// The room's moving camera, and a pending crosshair initiated at `T0` in an 8×8 tile
/// whose still surface point the camera has carried out of the tile, but not off
/// screen, by `T1`: the pending crosshair, its tile and where its point is at `T1`.
fn carried_out() -> (Arc<Shared>, Pending, Rect, (f32, f32)) {
    let tracer = Arc::new(Tracer::new(
        Arc::new(builtin::room()),
        SIZE,
        SIZE,
        TraceOptions::default(),
    ));
    let (before, after) = (tracer.state_at(T0), tracer.state_at(T1));
    let s = Arc::new(Shared::new(
        tracer.clone(),
        RtConfig::new(RtMethod::Adaptive),
    ));
    for (tx, ty) in (0..SIZE / 8).flat_map(|j| (0..SIZE / 8).map(move |i| (i * 8, j * 8))) {
        let rect = Rect {
            x0: tx,
            y0: ty,
            x1: tx + 8,
            y1: ty + 8,
        };
        let (x, y) = (tx as f32 + 4.5, ty as f32 + 4.5);
        let hit = tracer.sample(&before, x, y);
        if !hit.hit || hit.velocity != glam::Vec3::ZERO {
            continue;
        }
        let Some((px, py, _)) = after.camera.project(hit.hit_point) else {
            continue;
        };
        let on_screen = px >= 1.0 && py >= 1.0 && px < SIZE as f32 - 1.0 && py < SIZE as f32 - 1.0;
        if on_screen && !rect.contains_point(px, py) {
            let p = Pending {
                x,
                y,
                t: T0,
                lum: hit.luminance,
                hit_point: hit.hit_point,
                velocity: glam::Vec3::ZERO,
                anchor: Default::default(),
            };
            return (s, p, rect, (px, py));
        }
    }
    panic!(
        "the room's camera carries no still point out of its tile in {} s",
        T1 - T0
    );
}

#[test]
fn a_cpu_thread_probes_a_point_carried_out_of_its_tile_and_traces_in_place() {
    let (s, p, rect, (px, py)) = carried_out();
    let published = Published::new(&s, AdaptiveSettings::default());
    let state = s.tracer.state_at(T1);
    let mut batch = Batch::default();
    assert!(complete(&s, &published, &state, p, rect, T1, &mut batch));
    let Some(Visit::Completed {
        crosshair: c, rays, ..
    }) = batch.visits.first()
    else {
        panic!("no completed crosshair");
    };
    assert_eq!(
        (c.x, c.y),
        (p.x, p.y),
        "the crosshair is traced where it started"
    );
    let probe = &batch.stream[0];
    assert!(
        (probe.x - px).abs() < 1e-3 && (probe.y - py).abs() < 1e-3,
        "probe at {}, {}",
        probe.x,
        probe.y
    );
    assert_eq!(
        *rays as usize,
        batch.stream.len(),
        "the probe is one of the visit's rays"
    );
    assert_eq!(
        c.gt,
        temporal_gradient((probe.sample.luminance, T1), (p.lum, p.t))
    );
}

#[test]
fn a_gpu_batch_takes_the_probe_first_and_the_crosshair_after() {
    let (s, p, _, (px, py)) = carried_out();
    let (tx, _rx) = bounded(1);
    let mut out = Outbox::new(vec![tx]);
    let arms = (2.0, 2.0);
    let plan = Planned::Complete {
        band: 0,
        pending: p,
        done: Completion {
            at: (p.x, p.y),
            probe: Some((px, py)),
        },
        points: crosshair_points((p.x, p.y), arms),
        arms,
        first: 0,
    };
    // Six samples as a batch traced them: the probe's, then the crosshair's, told apart
    // by their luminances.
    let got: Vec<Sample> = (0..6)
        .map(|k| Sample {
            luminance: 0.1 * (k + 1) as f32,
            ..Default::default()
        })
        .collect();
    assert_eq!(fill(&s, &plan, &got, T1, &mut out), 0);
    let batch = &out.batches[0];
    let Some(Visit::Completed {
        crosshair: c, rays, ..
    }) = batch.visits.first()
    else {
        panic!("no completed crosshair");
    };
    assert_eq!(*rays, 6);
    assert_eq!((batch.stream[0].x, batch.stream[0].y), (px, py));
    assert_eq!((c.x, c.y), (p.x, p.y));
    assert_eq!(
        c.lum[0], got[1].luminance,
        "the centre is the sample after the probe"
    );
    assert_eq!(
        c.gt,
        temporal_gradient((got[0].luminance, T1), (p.lum, p.t))
    );
}
