//! The controllers' throughput against one sampling thread (`frameless bench`'s
//! `controller_*` figures).

use std::{
    sync::{atomic::Ordering, Arc},
    time::{Duration, Instant},
};

use crossbeam_channel::bounded;

use super::{
    controller::{band_samplers, ingest},
    published::Published,
    sampling::{sample, Batch},
    settings::AdaptiveSettings,
};
use crate::{
    methods::adaptive::Sampler,
    realtime::{
        config::{RealtimeError, RtConfig},
        shared::Shared,
    },
};

/// Run one sampling thread for `seconds` of wall time, its batches taken in by the
/// bands' `samplers` as they come (as live, with every reprojection step); returns the
/// samplers and each band's batches with the times they were taken in.
pub(super) fn record(
    s: &Arc<Shared>,
    published: &Arc<Published>,
    mut samplers: Vec<Sampler>,
    seconds: f64,
) -> (Vec<Sampler>, Vec<Vec<(Batch, f64)>>) {
    let (tx, rx): (Vec<_>, Vec<_>) = published.bands.iter().map(|_| bounded(256)).unzip();
    let (s1, p1) = (s.clone(), published.clone());
    let thread = std::thread::spawn(move || sample(&s1, &p1, 0, tx));
    let mut recorded: Vec<Vec<(Batch, f64)>> = vec![Vec::new(); rx.len()];
    let t0 = Instant::now();
    while t0.elapsed().as_secs_f64() < seconds {
        let mut any = false;
        for (b, rx) in rx.iter().enumerate() {
            let Ok(batch) = rx.try_recv() else { continue };
            any = true;
            let now = s.clock.now();
            recorded[b].push((batch.clone(), now));
            ingest(&mut samplers[b], batch, true, now);
            published.snapshot(b, &samplers[b]);
        }
        if !any {
            std::thread::sleep(Duration::from_micros(100));
        }
    }
    s.stop.store(true, Ordering::Relaxed);
    drop(rx);
    let _ = thread.join();
    (samplers, recorded)
}

/// The controllers against one sampling thread ([`controller_bench`]).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ControllerBench {
    /// Controller threads (bands of the image).
    pub controllers: usize,
    /// Samples one sampling thread traced in the recording.
    pub samples: u64,
    /// Its samples per second of tracing (busy) time.
    pub tracing_samples_per_s: f64,
    /// Samples per second the controllers take in together, each fed its band's
    /// recorded batches one after another on its own thread with nothing else to do.
    pub controller_samples_per_s: f64,
}

impl ControllerBench {
    /// How many sampling threads the controllers could keep up with.
    pub fn margin(&self) -> f64 {
        self.controller_samples_per_s / self.tracing_samples_per_s
    }
}

/// Record what one sampling thread sends the controllers for `seconds` of wall time
/// (the controllers taking it in as it comes, as live), then feed each band's recorded
/// batches in order to a fresh controller, all bands at once on threads of their own,
/// and time only that. Real-time adaptive with `config` and `settings` on `tracer`'s
/// scene and image, with the controllers `config.sampling_threads` would have. The
/// replay does every visit's reprojection step (live, a controller that falls behind
/// skips it).
pub fn controller_bench(
    tracer: Arc<crate::trace::Tracer>,
    config: RtConfig,
    settings: AdaptiveSettings,
    seconds: f64,
) -> Result<ControllerBench, RealtimeError> {
    let s = Arc::new(Shared::new(tracer, config));
    let published = Arc::new(Published::new(&s, settings));
    let replay = band_samplers(&s, &published)?;
    let (_, recorded) = record(&s, &published, band_samplers(&s, &published)?, seconds);
    let samples = s.samples.load(Ordering::Relaxed);
    let busy = s.busy_ns.load(Ordering::Relaxed) as f64 * 1e-9;
    let recorded_samples: usize = recorded.iter().flatten().map(|(b, _)| b.stream.len()).sum();
    let t1 = Instant::now();
    std::thread::scope(|scope| {
        for (mut sampler, batches) in replay.into_iter().zip(recorded) {
            scope.spawn(move || {
                for (batch, now) in batches {
                    std::hint::black_box(ingest(&mut sampler, batch, true, now).stream.len());
                }
            });
        }
    });
    let controller_s = t1.elapsed().as_secs_f64();
    Ok(ControllerBench {
        controllers: published.bands.len(),
        samples,
        tracing_samples_per_s: samples as f64 / busy.max(1e-9),
        controller_samples_per_s: recorded_samples as f64 / controller_s.max(1e-9),
    })
}
