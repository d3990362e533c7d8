//! The carry on the GPU (`carry.wgsl`): the accumulators stay where the last refresh
//! left them, and the CPU's list of what its own carry did ([`CarryEdits`]) is
//! replayed on them, so that a carrying refresh whose view held uploads a few factors
//! and pixel lists instead of every pixel's sums. What the CPU's carry decides from
//! can come back as a bit per pixel ([`GpuCarry::encode_holds`]) instead of the sums.

use bytemuck::{Pod, Zeroable};

use super::{buffer_entry, compute_pipeline, readback, storage, GpuContext, GROUP, PER_PIXEL};
use crate::reconstruction::{carry_edits::CarryEdits, splat::MIN_WEIGHT};

/// The shader's `CarryParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct CarryParams {
    pixels: u32,
    takes: u32,
    lands: u32,
    cuts: u32,
    dt: f32,
    pad: [u32; 3],
}

/// `carry.wgsl` after the constants it shares with this side.
fn carry_source() -> String {
    format!(
        "const PER_PIXEL: u32 = {PER_PIXEL}u;\nconst MIN_WEIGHT: f32 = {MIN_WEIGHT:e};\n{}",
        include_str!("carry.wgsl")
    )
}

/// The carry's pipelines and the buffers its lists go up in (grown as needed).
pub(super) struct GpuCarry {
    decay: wgpu::ComputePipeline,
    take: wgpu::ComputePipeline,
    land: wgpu::ComputePipeline,
    cut: wgpu::ComputePipeline,
    mask: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    factors: wgpu::Buffer,
    edits: wgpu::Buffer,
    taken: wgpu::Buffer,
    /// A bit per pixel: its weight holds sums; and where it is read back.
    holds: wgpu::Buffer,
    read_holds: wgpu::Buffer,
    bind: Option<wgpu::BindGroup>,
    words: Vec<u32>,
    pixels: u32,
}

/// Words of a bit mask over `pixels` pixels.
fn mask_words(pixels: u32) -> u64 {
    pixels.div_ceil(32) as u64
}

impl GpuCarry {
    pub(super) fn new(ctx: &GpuContext, pixels: u32) -> Self {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("carry.wgsl"),
            source: wgpu::ShaderSource::Wgsl(carry_source().into()),
        });
        use wgpu::BufferBindingType::{Storage, Uniform};
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("carry"),
            entries: &[
                buffer_entry(0, Uniform, false),
                buffer_entry(1, Storage { read_only: false }, false),
                buffer_entry(2, Storage { read_only: true }, false),
                buffer_entry(3, Storage { read_only: true }, false),
                buffer_entry(4, Storage { read_only: true }, false),
                buffer_entry(5, Storage { read_only: false }, false),
                buffer_entry(6, Storage { read_only: false }, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("carry"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let make = |name: &str| compute_pipeline(device, &pipeline_layout, &module, name);
        let none = wgpu::BufferUsages::empty();
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("carry params"),
            size: std::mem::size_of::<CarryParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // The pixel count, which the mask reads, before any replay writes the rest.
        let p = CarryParams {
            pixels,
            ..Default::default()
        };
        ctx.queue.write_buffer(&params, 0, bytemuck::bytes_of(&p));
        let words = mask_words(pixels) * 4;
        Self {
            decay: make("decay_sums"),
            take: make("take_sums"),
            land: make("land_sums"),
            cut: make("cut_sums"),
            mask: make("holds_mask"),
            layout,
            params,
            holds: storage(device, "holds mask", words, wgpu::BufferUsages::COPY_SRC),
            read_holds: readback(device, "holds mask readback", words.max(16)),
            factors: storage(device, "decay factors", 64 * 8, none),
            edits: storage(device, "carry edits", 256 * 4, none),
            taken: storage(device, "taken sums", 64 * PER_PIXEL as u64 * 4, none),
            bind: None,
            words: Vec::new(),
            pixels,
        }
    }

    /// Upload `e` and encode its replay on `acc` (the accumulators, with
    /// `pix_tile` the pixel → tile map of the refresh `e` was made for, uploaded
    /// before the returned work runs).
    pub(super) fn encode(
        &mut self,
        ctx: &GpuContext,
        e: &CarryEdits,
        acc: &wgpu::Buffer,
        pix_tile: &wgpu::Buffer,
    ) -> wgpu::CommandBuffer {
        e.words(&mut self.words);
        let factors: &[f32] = bytemuck::cast_slice(&e.decay);
        let taken = (e.takes.len() * PER_PIXEL * 4) as u64;
        self.fit(
            ctx,
            factors.len() as u64 * 4,
            self.words.len() as u64 * 4,
            taken,
        );
        let p = CarryParams {
            pixels: self.pixels,
            takes: e.takes.len() as u32,
            lands: e.lands.len() as u32,
            cuts: e.cuts.len() as u32,
            dt: e.dt,
            pad: [0; 3],
        };
        let q = &ctx.queue;
        q.write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
        // The buffers are never empty (16 bytes at least); the lists may be.
        let edits: &[u8] = bytemuck::cast_slice(&self.words);
        for (b, bytes) in [
            (&self.factors, bytemuck::cast_slice(factors)),
            (&self.edits, edits),
        ] {
            if !bytes.is_empty() {
                q.write_buffer(b, 0, bytes);
            }
        }
        let bind = self.bind(ctx, acc, pix_tile);
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        let groups = |n: u32| n.div_ceil(GROUP);
        // Separate passes, so that each step sees the last one's writes.
        for (pipe, n) in [
            (&self.decay, groups(p.pixels)),
            (&self.take, groups(p.takes)),
            (&self.land, (p.lands > 0) as u32),
            (&self.cut, groups(p.cuts)),
        ] {
            if n == 0 {
                continue;
            }
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(pipe);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(n, 1, 1);
        }
        enc.finish()
    }

    /// Encode into `enc` the mask of the pixels of `acc` whose weight holds sums, and
    /// its copy to [`GpuCarry::read_holds`].
    pub(super) fn encode_holds(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        acc: &wgpu::Buffer,
        pix_tile: &wgpu::Buffer,
    ) {
        let bind = self.bind(ctx, acc, pix_tile);
        let words = mask_words(self.pixels);
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.mask);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((words as u32).div_ceil(GROUP), 1, 1);
        }
        enc.copy_buffer_to_buffer(&self.holds, 0, &self.read_holds, 0, words * 4);
    }

    /// Where [`GpuCarry::encode_holds`] copies the mask to, and its bytes.
    pub(super) fn holds_readback(&self) -> (&wgpu::Buffer, u64) {
        (&self.read_holds, mask_words(self.pixels) * 4)
    }

    /// The bind group over `acc` and `pix_tile` and the carry's own buffers (made
    /// again after one of those grew).
    fn bind(
        &mut self,
        ctx: &GpuContext,
        acc: &wgpu::Buffer,
        pix_tile: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        self.bind
            .get_or_insert_with(|| {
                super::bind_buffers(
                    &ctx.device,
                    &self.layout,
                    "carry",
                    &[
                        &self.params,
                        acc,
                        pix_tile,
                        &self.factors,
                        &self.edits,
                        &self.taken,
                        &self.holds,
                    ],
                )
            })
            .clone()
    }

    /// Buffers at least `factors`, `edits` and `taken` bytes long (a new bind group
    /// when one had to grow).
    fn fit(&mut self, ctx: &GpuContext, factors: u64, edits: u64, taken: u64) {
        let none = wgpu::BufferUsages::empty();
        let grow = |b: &mut wgpu::Buffer, bytes: u64, label: &str| {
            if b.size() < bytes {
                *b = storage(
                    &ctx.device,
                    label,
                    (bytes + bytes / 2).next_multiple_of(16),
                    none,
                );
                true
            } else {
                false
            }
        };
        let grew = [
            grow(&mut self.factors, factors, "decay factors"),
            grow(&mut self.edits, edits, "carry edits"),
            grow(&mut self.taken, taken, "taken sums"),
        ];
        if grew.contains(&true) {
            self.bind = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{carry_source, CarryParams};
    use crate::reconstruction::gpu::layout_tests::{check_struct, parse, rust_fields};

    #[test]
    fn carry_wgsl_lays_out_its_parameters_as_the_rust_side() {
        let m = parse(&carry_source());
        let params = rust_fields!(CarryParams {
            pixels,
            takes,
            lands,
            cuts,
            dt,
            pad
        });
        check_struct(
            &m,
            "CarryParams",
            params,
            std::mem::size_of::<CarryParams>(),
        );
    }
}
