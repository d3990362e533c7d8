//! Batches of samples traced on a run's tracer (`--trace cpu|gpu|auto`): the one
//! interface through which the methods and the ideal images trace on the GPU.
//!
//! A batch is a list of samples, each with its own position and time: frameless
//! semantics are kept, and no sample is moved to another instant. The GPU traces one
//! scene state per dispatch, so [`trace_at`] groups a batch's samples by their 1 ms
//! time quantum ([`super::TIME_QUANTUM`]), the grid on which the CPU tracer evaluates
//! the scene too: a sample is traced in exactly the state the CPU would use. What a
//! batch costs in latency is the time from its first sample's time to its return:
//! the caller decides how many samples to gather (see `docs/performance.md`).
//!
//! When the GPU fails part way, the failure is kept ([`GpuRays::failure`]) and every
//! later batch is traced on the CPU, so that a run finishes and says why.

use std::sync::Arc;

use rayon::prelude::*;

use super::{Sample, SceneState, Tracer};
use crate::gpu::DeviceUsed;

/// Smallest run of samples one CPU thread takes: below it, splitting costs more than it
/// saves.
const MIN_PER_THREAD: usize = 256;

/// Threads that feed one GPU tracer with batches in a real-time run: while one waits
/// for its dispatch, the others make their batches and read theirs back, so the GPU
/// is not idle between dispatches.
pub const GPU_FEEDERS: u64 = 4;

/// The GPU tracer of a run, shared by its methods and its ideal images. Threads that
/// trace at once each take a tracer of their own from a pool (forked from the first:
/// one shader and one copy of the scene), so that one thread's upload and read-back
/// overlap another's wait for the GPU.
#[cfg(feature = "gpu")]
pub struct GpuRays {
    idle: std::sync::Mutex<Vec<super::gpu::GpuTracer>>,
    /// Forked for each thread that finds the pool empty; never traces itself.
    template: super::gpu::GpuTracer,
    failure: std::sync::Mutex<Option<String>>,
    used: DeviceUsed,
}

/// The GPU tracer of a run; this build has none (built without the `gpu` feature).
#[cfg(not(feature = "gpu"))]
pub enum GpuRays {}

#[cfg(feature = "gpu")]
impl GpuRays {
    /// Upload `tracer`'s scene to the GPU of `ctx`.
    pub fn new(
        ctx: Arc<crate::gpu::GpuContext>,
        tracer: &Tracer,
    ) -> Result<Self, super::gpu::GpuTraceError> {
        let used = ctx.used();
        let template = super::gpu::GpuTracer::new(ctx, tracer)?;
        Ok(Self {
            idle: std::sync::Mutex::new(Vec::new()),
            template,
            failure: std::sync::Mutex::new(None),
            used,
        })
    }

    /// The device, as results record it.
    pub fn used(&self) -> DeviceUsed {
        self.used.clone()
    }

    /// Why the GPU stopped tracing part way, if it did.
    pub fn failure(&self) -> Option<String> {
        self.failure
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// `f` on a GPU tracer of the pool, one no other thread is using; `None` (and the
    /// first failure kept) once one has failed.
    pub fn with<R>(
        &self,
        f: impl FnOnce(&mut super::gpu::GpuTracer) -> Result<R, super::gpu::GpuTraceError>,
    ) -> Option<R> {
        if self.failure().is_some() {
            return None;
        }
        let idle = || self.idle.lock().unwrap_or_else(|e| e.into_inner());
        let taken = idle().pop();
        let mut gpu = taken.unwrap_or_else(|| self.template.fork());
        let got = f(&mut gpu);
        idle().push(gpu);
        match got {
            Ok(r) => Some(r),
            Err(e) => {
                *self.failure.lock().unwrap_or_else(|e| e.into_inner()) = Some(e.to_string());
                None
            }
        }
    }

    fn trace(
        &self,
        tracer: &Tracer,
        state: &SceneState,
        points: &[[f32; 2]],
    ) -> Option<Vec<Sample>> {
        self.with(|g| g.trace(tracer, state, points))
            .map(|got| got.iter().map(|s| s.sample()).collect())
    }

    fn colours(
        &self,
        tracer: &Tracer,
        state: &SceneState,
        points: &[[f32; 2]],
    ) -> Option<Vec<glam::Vec3>> {
        self.with(|g| g.colours(tracer, state, points))
    }
}

#[cfg(not(feature = "gpu"))]
impl GpuRays {
    /// The device, as results record it.
    pub fn used(&self) -> DeviceUsed {
        match *self {}
    }

    /// Why the GPU stopped tracing part way, if it did.
    pub fn failure(&self) -> Option<String> {
        match *self {}
    }

    fn trace(&self, _: &Tracer, _: &SceneState, _: &[[f32; 2]]) -> Option<Vec<Sample>> {
        match *self {}
    }

    fn colours(&self, _: &Tracer, _: &SceneState, _: &[[f32; 2]]) -> Option<Vec<glam::Vec3>> {
        match *self {}
    }
}

impl std::fmt::Debug for GpuRays {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "GpuRays({})", self.used())
    }
}

/// Why a run's GPU tracer could not be made: the scene does not fit the adapter, or
/// the device failed.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct OpenError(String);

/// The GPU tracer of `tracer`'s scene on `ctx` (`None`: none asked for).
pub fn open(
    ctx: Option<Arc<crate::gpu::GpuContext>>,
    tracer: &Tracer,
) -> Result<Option<Arc<GpuRays>>, OpenError> {
    let Some(ctx) = ctx else {
        return Ok(None);
    };
    #[cfg(feature = "gpu")]
    {
        GpuRays::new(ctx, tracer)
            .map(|g| Some(Arc::new(g)))
            .map_err(|e| OpenError(e.to_string()))
    }
    #[cfg(not(feature = "gpu"))]
    {
        let _ = tracer;
        match *ctx {}
    }
}

/// The tracer a run's results come from: the GPU's, else the CPU.
pub fn used(gpu: Option<&Arc<GpuRays>>) -> DeviceUsed {
    gpu.map_or_else(DeviceUsed::cpu, |g| g.used())
}

/// Only the colours of [`trace_points`]'s samples: on the GPU a fifth of the
/// read-back, for the methods that keep nothing else of a sample.
pub fn trace_colours(
    tracer: &Tracer,
    gpu: Option<&GpuRays>,
    state: &SceneState,
    points: &[[f32; 2]],
) -> Vec<glam::Vec3> {
    if let Some(got) = gpu.and_then(|g| g.colours(tracer, state, points)) {
        return got;
    }
    points
        .par_iter()
        .with_min_len(MIN_PER_THREAD)
        .map(|p| tracer.sample(state, p[0], p[1]).color)
        .collect()
}

/// Trace the pixel positions `points`, all in `state`: on the GPU when there is one
/// (and it has not failed), else on the CPU's threads.
pub fn trace_points(
    tracer: &Tracer,
    gpu: Option<&GpuRays>,
    state: &SceneState,
    points: &[[f32; 2]],
) -> Vec<Sample> {
    if let Some(got) = gpu.and_then(|g| g.trace(tracer, state, points)) {
        return got;
    }
    points
        .par_iter()
        .with_min_len(MIN_PER_THREAD)
        .map(|p| tracer.sample(state, p[0], p[1]))
        .collect()
}

/// Trace the samples `(x, y, t)`, each at its own time, in the order given: grouped by
/// time quantum, one [`trace_points`] batch per quantum.
pub fn trace_at(
    tracer: &Tracer,
    gpu: Option<&GpuRays>,
    samples: &[(f32, f32, f64)],
) -> Vec<Sample> {
    let mut order: Vec<usize> = (0..samples.len()).collect();
    order.sort_by_key(|&i| Tracer::quantize(samples[i].2));
    let mut out = vec![Sample::default(); samples.len()];
    for run in
        order.chunk_by(|&a, &b| Tracer::quantize(samples[a].2) == Tracer::quantize(samples[b].2))
    {
        let state = tracer.state_at(samples[run[0]].2);
        let points: Vec<[f32; 2]> = run.iter().map(|&i| [samples[i].0, samples[i].1]).collect();
        for (&i, s) in run.iter().zip(trace_points(tracer, gpu, &state, &points)) {
            out[i] = s;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::TraceOptions;

    #[test]
    fn trace_at_on_the_cpu_is_each_sample_at_its_own_time() {
        let scene = crate::scene::builtin::load("toycar").expect("built-in");
        let tracer = Tracer::new(Arc::new(scene), 32, 24, TraceOptions::default());
        // Times out of order and four quanta apart: the car moves between them.
        let samples: Vec<(f32, f32, f64)> = (0..32 * 24)
            .map(|i| {
                (
                    (i % 32) as f32 + 0.5,
                    (i / 32) as f32 + 0.5,
                    1.0 + 0.004 * ((i * 7) % 5) as f64,
                )
            })
            .collect();
        let got = trace_at(&tracer, None, &samples);
        for ((x, y, t), s) in samples.iter().zip(&got) {
            assert_eq!(*s, tracer.trace(*x, *y, *t));
        }
    }
}
