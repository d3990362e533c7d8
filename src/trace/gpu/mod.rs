//! The tracer on a GPU (`--trace gpu`): wgpu compute, with BVH traversal in software
//! (`trace.wgsl`), since neither lavapipe nor the device machine's driver offers
//! ray-query extensions to wgpu.
//!
//! The CPU [`Tracer`] stays the reference and the owner of everything: it builds the
//! static world's and the rigid groups' trees once, and per 1 ms quantum the scene
//! state (instance transforms, the top level, the morphing triangles' refit tree,
//! lights, camera). This side uploads those as they are (`layout`) and traces a batch
//! of samples of one state in one dispatch, one invocation per sample: the primary
//! ray, shading as `shade.rs` does it (ambient, every light with a shadow ray,
//! textures filtered by ray cones), and the Whitted tree of reflections and
//! refractions to the maximum depth, depth first from a small stack.
//!
//! A sample of [`GpuTracer::trace_at`] is traced at its own time: samples are grouped
//! by their 1 ms quantum, one dispatch per quantum, exactly the states the CPU would
//! use. What it returns ([`GpuSample`]) is everything a CPU [`Sample`] holds (colour,
//! hit point, distance, velocity, anchor, the `dynamic` flag), computed in the shader
//! as the CPU computes it, and the hit's identity ([`HitId`]).

mod layout;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use glam::Vec3;

use super::{luminance, Anchor, HitId, Sample, SceneState, Tracer};
use crate::gpu::{GpuContext, GpuError};

/// Samples per workgroup (the shader's `@workgroup_size`).
const GROUP: u32 = 64;
/// Most workgroups of one dispatch along x (wgpu's default limit).
const MAX_GROUPS: u32 = 65_535;
/// Storage buffers the shader binds.
const STORAGE_BUFFERS: u32 = 5;
/// Bytes of one sample's output (the shader's `OUT_VEC4S` vec4s).
const OUT_BYTES: u64 = 80;
/// Bytes of one sample's output in [`Mode::Colours`]: one vec4, (colour, t).
const COLOUR_BYTES: u64 = 16;
/// Set in the secondary-ray count word of a sample in which something moved.
const DYNAMIC_BIT: u32 = 1 << 31;

/// Why a batch could not be traced on the GPU.
#[derive(Debug, thiserror::Error)]
pub enum GpuTraceError {
    /// The device failed or is too small.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The scene needs a buffer larger than the adapter binds.
    #[error("the GPU tracer's {what} buffer needs {bytes} bytes, over the adapter's limit of {limit} bytes per storage buffer")]
    TooLarge {
        /// Which buffer.
        what: &'static str,
        /// Its size.
        bytes: u64,
        /// The adapter's limit.
        limit: u64,
    },
}

/// What the GPU returns of one sample: a CPU [`Sample`]'s fields and the hit's identity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuSample {
    /// Linear RGB radiance, as [`Sample::color`].
    pub color: Vec3,
    /// Distance from the eye to the primary hit (`INFINITY` on a miss).
    pub depth: f32,
    /// What the primary ray hit.
    pub hit: HitId,
    /// Secondary rays traced for it: shadow rays, reflections, refractions.
    pub secondary_rays: u32,
    /// As [`Sample::hit_point`].
    pub hit_point: Vec3,
    /// As [`Sample::velocity`].
    pub velocity: Vec3,
    /// As [`Sample::dynamic`].
    pub dynamic: bool,
    /// As [`Sample::anchor`].
    pub anchor: Anchor,
}

impl GpuSample {
    /// The CPU tracer's form of it.
    pub fn sample(&self) -> Sample {
        Sample {
            color: self.color,
            luminance: luminance(self.color),
            hit_point: self.hit_point,
            depth: self.depth,
            velocity: self.velocity,
            hit: self.hit != HitId::Miss,
            dynamic: self.dynamic,
            anchor: self.anchor,
        }
    }
}

/// What one dispatch computes and reads back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Every field of a [`GpuSample`].
    Samples,
    /// The primary hits only, unshaded (the benchmark's primary rays).
    PrimaryHits,
    /// Only the colours (and distances): a fifth of the read-back, for ideal images.
    Colours,
}

impl Mode {
    fn out_bytes(self) -> u64 {
        match self {
            Mode::Colours => COLOUR_BYTES,
            Mode::Samples | Mode::PrimaryHits => OUT_BYTES,
        }
    }
}

/// Where the GPU tracer's time went, summed over its dispatches.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct GpuTraceTimes {
    /// Dispatches and the samples they traced.
    pub dispatches: u64,
    /// Samples traced.
    pub samples: u64,
    /// Seconds spent uploading the scene state, the points and the parameters, and
    /// submitting the work.
    pub upload_s: f64,
    /// Seconds from the submission until the results were mapped for reading: the
    /// shader, the copy to the read-back buffer and the wait for both.
    pub wait_s: f64,
    /// Seconds spent reading the mapped results into samples on the CPU.
    pub read_s: f64,
}

impl GpuTraceTimes {
    /// What was spent after `earlier`, a reading of the same tracer.
    pub fn since(&self, earlier: &Self) -> Self {
        Self {
            dispatches: self.dispatches - earlier.dispatches,
            samples: self.samples - earlier.samples,
            upload_s: self.upload_s - earlier.upload_s,
            wait_s: self.wait_s - earlier.wait_s,
            read_s: self.read_s - earlier.read_s,
        }
    }
}

/// What every [`GpuTracer`] of one scene shares: the compiled shader and the static
/// world's and groups' buffers.
struct Kernel {
    ctx: Arc<GpuContext>,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    words: wgpu::Buffer,
    data: wgpu::Buffer,
    statics: layout::StaticOffsets,
}

/// The tracer's GPU side: the shared kernel, the state it uploaded last and its own
/// dispatch buffers. Tracers forked from one another ([`GpuTracer::fork`]) trace on
/// the same device at once, each from its own thread.
pub struct GpuTracer {
    kernel: Arc<Kernel>,
    /// The state uploaded last: its time quantum and camera generation, the buffer.
    state: Option<((i64, u64), wgpu::Buffer, layout::StateOffsets)>,
    /// The per-dispatch buffers, kept between dispatches.
    io: Option<Io>,
    times: GpuTraceTimes,
}

/// One dispatch's buffers, kept and grown rather than made anew for every batch: a
/// new buffer is zero-filled before its first use, which for a 1080p batch's output
/// and read-back copies is 130 MB of writes.
struct Io {
    /// Samples the buffers hold.
    cap: usize,
    uniform: wgpu::Buffer,
    points: wgpu::Buffer,
    out: wgpu::Buffer,
    back: wgpu::Buffer,
}

impl Io {
    fn new(device: &wgpu::Device, cap: usize) -> Self {
        let buffer = |label, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(OUT_BYTES),
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let cap64 = cap as u64;
        Self {
            cap,
            uniform: buffer(
                "trace params",
                std::mem::size_of::<layout::Params>() as u64,
                U::UNIFORM | U::COPY_DST,
            ),
            points: buffer("trace points", cap64 * 8, U::STORAGE | U::COPY_DST),
            out: buffer("trace out", cap64 * OUT_BYTES, U::STORAGE | U::COPY_SRC),
            back: buffer(
                "trace readback",
                cap64 * OUT_BYTES,
                U::MAP_READ | U::COPY_DST,
            ),
        }
    }
}

impl std::fmt::Debug for GpuTracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuTracer")
            .field("adapter", &self.kernel.ctx.describe())
            .finish()
    }
}

/// The shader for Whitted trees `max_depth` deep and traversal stacks as deep as
/// `stacks` says. Every private array costs each invocation its size (zero-filled at
/// every call), so the stacks are as deep as this tracer's trees need, no deeper:
/// on lavapipe, Bvh2 stacks of 24 instead of 96 entries traced toycar's primary rays
/// 50% faster.
fn shader_source(max_depth: u32, stacks: layout::Stacks) -> String {
    format!(
        "const STACK: u32 = {}u;\nconst TRAVERSAL: u32 = {}u;\n\
         const STACK2: u32 = {}u;\nconst NONE: u32 = {}u;\nconst FAR: f32 = 3.0e38;\n\
         const ANALYTIC_BIT: u32 = {}u;\nconst NODE_EPSILON: f32 = {:e};\n\
         const MIN_COS: f32 = {:e};\n{}",
        max_depth + 2,
        stacks.cw,
        stacks.b2,
        layout::NONE,
        layout::ANALYTIC_BIT,
        NODE_EPSILON,
        super::cones::MIN_COS,
        include_str!("trace.wgsl")
    )
}

/// obvhs's `cwbvh::node::EPSILON`: the nearest entry distance its node test accepts.
const NODE_EPSILON: f32 = 0.0001;

impl GpuTracer {
    /// Upload `tracer`'s static world and groups to `ctx`'s device.
    pub fn new(ctx: Arc<GpuContext>, tracer: &Tracer) -> Result<Self, GpuTraceError> {
        ctx.require_storage_buffers(STORAGE_BUFFERS)?;
        let statics = layout::Statics::new(tracer);
        let device = &ctx.device;
        let words = storage_init(&ctx, "trace words", bytemuck::cast_slice(&statics.words))?;
        let data = storage_init(&ctx, "trace data", bytemuck::cast_slice(&statics.data))?;
        let layout = bind_layout(device);
        let pipeline = pipeline(device, &layout, tracer.options.max_depth, statics.stacks);
        let kernel = Kernel {
            ctx,
            pipeline,
            layout,
            words,
            data,
            statics: statics.at,
        };
        Ok(Self::on(Arc::new(kernel)))
    }

    fn on(kernel: Arc<Kernel>) -> Self {
        Self {
            kernel,
            state: None,
            io: None,
            times: GpuTraceTimes::default(),
        }
    }

    /// Another tracer of the same scene on the same device, sharing this one's shader
    /// and static buffers, with buffers of its own for the state and the dispatches:
    /// a second thread traces with it while this one waits for its results.
    pub fn fork(&self) -> Self {
        Self::on(self.kernel.clone())
    }

    /// The device it runs on.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.kernel.ctx
    }

    /// Where its time went since it was made.
    pub fn times(&self) -> GpuTraceTimes {
        self.times
    }

    /// Trace the samples `(x, y, t)`, each in the scene state of its own time (as
    /// [`Tracer::trace`] would): one dispatch per 1 ms quantum the batch touches.
    pub fn trace_at(
        &mut self,
        tracer: &Tracer,
        samples: &[(f32, f32, f64)],
    ) -> Result<Vec<GpuSample>, GpuTraceError> {
        let mut order: Vec<usize> = (0..samples.len()).collect();
        order.sort_by_key(|&i| Tracer::quantize(samples[i].2));
        let mut out = vec![None; samples.len()];
        for run in order
            .chunk_by(|&a, &b| Tracer::quantize(samples[a].2) == Tracer::quantize(samples[b].2))
        {
            let state = tracer.state_at(samples[run[0]].2);
            let points: Vec<[f32; 2]> = run.iter().map(|&i| [samples[i].0, samples[i].1]).collect();
            for (&i, s) in run.iter().zip(self.trace(tracer, &state, &points)?) {
                out[i] = Some(s);
            }
        }
        Ok(out.into_iter().flatten().collect())
    }

    /// Trace and shade the pixel positions `points` in `state` (one of `tracer`'s
    /// states).
    pub fn trace(
        &mut self,
        tracer: &Tracer,
        state: &SceneState,
        points: &[[f32; 2]],
    ) -> Result<Vec<GpuSample>, GpuTraceError> {
        self.run(tracer, state, points, Mode::Samples, unpack)
    }

    /// Only the colours of [`GpuTracer::trace`]'s samples, with a fifth of its
    /// read-back: what ideal images need.
    pub fn colours(
        &mut self,
        tracer: &Tracer,
        state: &SceneState,
        points: &[[f32; 2]],
    ) -> Result<Vec<Vec3>, GpuTraceError> {
        self.run(tracer, state, points, Mode::Colours, |c| {
            Vec3::new(
                f32::from_bits(c[0]),
                f32::from_bits(c[1]),
                f32::from_bits(c[2]),
            )
        })
    }

    /// Only the primary hits of `points` (colour: the background), as
    /// [`Tracer::primary_hit`]: the cheapest query, for benchmarks.
    pub fn primary_hits(
        &mut self,
        tracer: &Tracer,
        state: &SceneState,
        points: &[[f32; 2]],
    ) -> Result<Vec<GpuSample>, GpuTraceError> {
        self.run(tracer, state, points, Mode::PrimaryHits, unpack)
    }

    /// Trace `points` in `mode`, each sample's output words read into a `T` by `read`
    /// on every thread.
    fn run<T: Send>(
        &mut self,
        tracer: &Tracer,
        state: &SceneState,
        points: &[[f32; 2]],
        mode: Mode,
        read: impl Fn(&[u32]) -> T + Sync + Send,
    ) -> Result<Vec<T>, GpuTraceError> {
        let mut out = Vec::with_capacity(points.len());
        let t = std::time::Instant::now();
        self.upload_state(tracer, state)?;
        self.times.upload_s += t.elapsed().as_secs_f64();
        // One dispatch's output must fit one storage binding.
        let per_dispatch =
            u64::from(MAX_GROUPS * GROUP).min(binding_limit(&self.kernel.ctx) / OUT_BYTES);
        let per_dispatch = per_dispatch.max(1) as usize;
        for chunk in points.chunks(per_dispatch) {
            self.dispatch(tracer, state, chunk, mode, &mut |w| {
                out.extend(read_par(w, mode, &read))
            })?;
        }
        Ok(out)
    }

    fn upload_state(&mut self, tracer: &Tracer, state: &SceneState) -> Result<(), GpuTraceError> {
        let key = (Tracer::quantize(state.time), tracer.camera_generation());
        if self.state.as_ref().is_some_and(|(k, _, _)| *k == key) {
            return Ok(());
        }
        let (data, at) = layout::state(tracer, state);
        let buf = storage_init(&self.kernel.ctx, "trace state", bytemuck::cast_slice(&data))?;
        self.state = Some((key, buf, at));
        Ok(())
    }

    fn dispatch(
        &mut self,
        tracer: &Tracer,
        state: &SceneState,
        points: &[[f32; 2]],
        mode: Mode,
        take: &mut dyn FnMut(&[u32]),
    ) -> Result<(), GpuTraceError> {
        let t0 = std::time::Instant::now();
        let Some((_, state_buf, at)) = &self.state else {
            return Ok(());
        };
        let n = points.len() as u32;
        let params = layout::params(tracer, state, n, self.kernel.statics, *at, mode);
        let k = &*self.kernel;
        let device = &k.ctx.device;
        if self.io.as_ref().is_none_or(|io| io.cap < points.len()) {
            self.io = Some(Io::new(device, points.len()));
        }
        let Some(io) = &self.io else {
            return Ok(());
        };
        let queue = &k.ctx.queue;
        queue.write_buffer(&io.uniform, 0, bytemuck::bytes_of(&params));
        queue.write_buffer(&io.points, 0, bytemuck::cast_slice(points));
        let out_bytes = points.len() as u64 * mode.out_bytes();
        let (out, back) = (&io.out, &io.back);
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace"),
            layout: &k.layout,
            entries: &[&io.uniform, &k.words, &k.data, state_buf, &io.points, out]
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect::<Vec<_>>(),
        });
        let mut enc = device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&k.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(n.div_ceil(GROUP).max(1), 1, 1);
        }
        enc.copy_buffer_to_buffer(out, 0, back, 0, out_bytes.max(OUT_BYTES));
        let index = queue.submit([enc.finish()]);
        let t1 = std::time::Instant::now();
        // The copy and the mapping cover at least one sample's output, as the
        // buffers do: wgpu maps no empty range.
        let read = k
            .ctx
            .read_mapped(back, out_bytes.max(OUT_BYTES), Some(index), |b| {
                let t = std::time::Instant::now();
                take(&bytemuck::cast_slice::<u8, u32>(b)[..(out_bytes / 4) as usize]);
                t.elapsed()
            })?;
        let times = &mut self.times;
        times.upload_s += (t1 - t0).as_secs_f64();
        times.wait_s += (t1.elapsed() - read).as_secs_f64();
        times.read_s += read.as_secs_f64();
        times.dispatches += 1;
        times.samples += u64::from(n);
        Ok(())
    }
}

/// `words`, the mapped output of a dispatch in `mode`, read into one `T` per sample on
/// every thread: at a million samples and more per dispatch the read is a large share
/// of the GPU tracer's time.
fn read_par<T: Send>(words: &[u32], mode: Mode, f: impl Fn(&[u32]) -> T + Sync + Send) -> Vec<T> {
    use rayon::prelude::*;
    words
        .par_chunks_exact((mode.out_bytes() / 4) as usize)
        .with_min_len(4096)
        .map(f)
        .collect()
}

/// One sample of the shader's output: (colour, t), (kind, group, primitive,
/// secondary rays | dynamic), (hit point, 0), (velocity, 0), (anchor, 0).
fn unpack(w: &[u32]) -> GpuSample {
    let vec3 = |k: usize| {
        Vec3::new(
            f32::from_bits(w[k]),
            f32::from_bits(w[k + 1]),
            f32::from_bits(w[k + 2]),
        )
    };
    let hit = HitId::from_parts(w[4], w[5], w[6]);
    let depth = if hit == HitId::Miss {
        f32::INFINITY
    } else {
        f32::from_bits(w[3])
    };
    let a = vec3(16);
    let anchor = match hit {
        HitId::Miss | HitId::Static(_) => Anchor::Still,
        HitId::Instance { group, .. } => Anchor::Instance { group, local: a },
        HitId::Morphing(index) => Anchor::Triangle {
            index,
            u: a.x,
            v: a.y,
        },
    };
    GpuSample {
        color: vec3(0),
        depth,
        hit,
        secondary_rays: w[7] & !DYNAMIC_BIT,
        hit_point: vec3(8),
        velocity: vec3(12),
        dynamic: w[7] & DYNAMIC_BIT != 0,
        anchor,
    }
}

fn init(
    device: &wgpu::Device,
    label: &str,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    // wgpu refuses empty bindings: pad to one vec4.
    let padded;
    let contents = if bytes.len() < 16 {
        padded = [bytes, &[0u8; 16][bytes.len()..]].concat();
        &padded[..]
    } else {
        bytes
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
}

/// The largest storage buffer the adapter binds, in bytes.
fn binding_limit(ctx: &GpuContext) -> u64 {
    ctx.limits
        .max_storage_buffer_binding_size
        .min(ctx.limits.max_buffer_size)
}

/// A read-only storage buffer holding `bytes`, checked against the adapter's limit.
fn storage_init(
    ctx: &GpuContext,
    label: &'static str,
    bytes: &[u8],
) -> Result<wgpu::Buffer, GpuTraceError> {
    let limit = binding_limit(ctx);
    if bytes.len() as u64 > limit {
        return Err(GpuTraceError::TooLarge {
            what: label,
            bytes: bytes.len() as u64,
            limit,
        });
    }
    Ok(init(&ctx.device, label, bytes, wgpu::BufferUsages::STORAGE))
}

fn bind_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let read = wgpu::BufferBindingType::Storage { read_only: true };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("trace"),
        entries: &[
            entry(0, wgpu::BufferBindingType::Uniform),
            entry(1, read),
            entry(2, read),
            entry(3, read),
            entry(4, read),
            entry(5, wgpu::BufferBindingType::Storage { read_only: false }),
        ],
    })
}

fn pipeline(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    max_depth: u32,
    stacks: layout::Stacks,
) -> wgpu::ComputePipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("trace.wgsl"),
        source: wgpu::ShaderSource::Wgsl(shader_source(max_depth, stacks).into()),
    });
    let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("trace"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("trace"),
        layout: Some(&pl),
        module: &module,
        entry_point: Some("trace"),
        compilation_options: Default::default(),
        cache: None,
    })
}
