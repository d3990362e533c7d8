//! The controller thread of the adaptive method: the one owner of the tiling and the
//! deep buffer (afr-optix keeps "the hierarchy on one processor").
//!
//! It holds an ordinary [`Sampler`] and feeds it what the sampling threads traced:
//! completed crosshairs (inserted, with tile statistics updated and the tiling adjusted
//! after every chunk, exactly as in a sequential visit) and initiating samples (which
//! become their tile's pending crosshair). The reprojection step of each visit runs
//! here too, occlusion rays included — but only while the controller keeps up with
//! its input: when batches queue up it skips reprojection for that batch, so that the
//! tiling never lags behind the samples (the share that ran is reported). About every
//! millisecond it publishes the tile selection (rectangles and pending crosshairs) for
//! the sampling threads, and at the display rate a copy of the tiling for the image
//! thread's filters.

use std::{
    sync::{atomic::Ordering, Arc},
    time::{Duration, Instant},
};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};

use super::{
    pipeline::{lock, Shared},
    sampling::AdaptiveBatch,
};
use crate::{
    clock::Clock,
    methods::adaptive::{
        deep_buffer::Crosshair,
        tiling::{Pending, Rect},
        Sampler,
    },
    trace::StreamSample,
};

/// What a sampling thread did on one visit.
pub(crate) enum Visit {
    /// It completed the crosshair `pending` initiated.
    Completed {
        crosshair: Crosshair,
        rays: u32,
        pending: Pending,
    },
    /// It initiated a crosshair.
    Initiated(Pending),
}

/// The tile selection the sampling threads read.
pub struct TileSnapshot {
    /// The tiles.
    pub rects: Vec<Rect>,
    /// Each tile's pending crosshair.
    pub pending: Vec<Option<Pending>>,
}

impl TileSnapshot {
    /// One tile, nothing pending.
    pub fn whole(w: u32, h: u32) -> Self {
        Self {
            rects: vec![Rect {
                x0: 0,
                y0: 0,
                x1: w,
                y1: h,
            }],
            pending: vec![None],
        }
    }

    fn of(sampler: &Sampler) -> Self {
        let t = sampler.tiling();
        let leaves = t.leaves();
        Self {
            rects: leaves.iter().map(|&l| t.node(l).rect).collect(),
            pending: leaves.iter().map(|&l| t.node(l).pending).collect(),
        }
    }
}

/// How often the sampling threads' snapshot is republished.
const SNAPSHOT_EVERY: Duration = Duration::from_millis(1);

pub(crate) fn run(s: &Shared, rx: Receiver<AdaptiveBatch>, tx: Sender<Vec<StreamSample>>) {
    let clock = Clock {
        start: s.config.start,
        rate: 1.0, // unused: the real-time sampler is fed, it does not run a budget
        first_refresh: s.config.start,
        refresh_hz: s.config.refresh_hz,
    };
    let mut sampler = match Sampler::new(s.tracer.clone(), clock, s.config.sampler, s.config.seed) {
        Ok(x) => x,
        Err(_) => return, // validated by the pipeline before it started
    };
    let tiling_every = Duration::from_secs_f64(0.5 / s.config.refresh_hz);
    let (mut snap_at, mut tiling_at) = (Instant::now(), Instant::now() - tiling_every);
    publish_tiling(s, &sampler);
    while !s.stopped() {
        match rx.recv_timeout(Duration::from_millis(2)) {
            Ok(batch) => {
                // Behind: more batches are waiting than the one in hand.
                let reproject = rx.is_empty();
                let rays_before = sampler.counters().rays;
                let mut own_rays = 0u64;
                for v in batch.visits {
                    match v {
                        Visit::Completed {
                            crosshair,
                            rays,
                            pending,
                        } => {
                            sampler.clear_pending(pending.x, pending.y, pending.t);
                            let t = crosshair.t;
                            let (px, py) = (crosshair.x as u32, crosshair.y as u32);
                            sampler.ingest_crosshair(crosshair, rays as u64, t);
                            if reproject {
                                let before = sampler.counters().rays;
                                sampler.reproject_visit(px, py, s.clock.now());
                                own_rays += sampler.counters().rays - before;
                                s.reprojected_visits.fetch_add(1, Ordering::Relaxed);
                            } else {
                                s.skipped_reprojections.fetch_add(1, Ordering::Relaxed);
                            }
                        }
                        Visit::Initiated(p) => sampler.ingest_pending(p),
                    }
                }
                let _ = rays_before;
                let mut stream = batch.stream;
                let extra = sampler.drain_stream(); // replacement crosshairs
                s.samples.fetch_add(extra.len() as u64, Ordering::Relaxed);
                s.rays.fetch_add(own_rays, Ordering::Relaxed);
                stream.extend(extra);
                if tx.send(stream).is_err() {
                    return;
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
        if snap_at.elapsed() >= SNAPSHOT_EVERY {
            *lock(&s.snapshot) = Arc::new(TileSnapshot::of(&sampler));
            s.snapshot_seq.fetch_add(1, Ordering::Release);
            s.tiles
                .store(sampler.tiling().len() as u64, Ordering::Relaxed);
            snap_at = Instant::now();
        }
        if tiling_at.elapsed() >= tiling_every {
            publish_tiling(s, &sampler);
            tiling_at = Instant::now();
        }
    }
}

fn publish_tiling(s: &Shared, sampler: &Sampler) {
    *lock(&s.tiling) = Some(Arc::new(sampler.tiling().clone()));
}
