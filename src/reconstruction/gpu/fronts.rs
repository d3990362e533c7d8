//! The carried initial front depths kept on the GPU between refreshes
//! (`fronts.wgsl`). With the visibility pass, a carrying refresh starts its front
//! depths from the carried geometry of still surfaces ([`super::carried`]); while the
//! view holds they change at few pixels, so this side keeps the last refresh's, the
//! CPU sends only the pixels whose front changed ([`FrontsIn::Changes`]), and they are
//! written into the kept copy here, which each refresh copies into the front depths
//! its new samples lower (every pixel's 4 bytes went up at every refresh before).

use bytemuck::{Pod, Zeroable};

use super::{
    carried::FrontsIn, compute_pipeline, storage, uniform_and_storage, GpuContext, GpuError, GROUP,
    MAX_GROUPS,
};

/// The shader's `FrontParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct FrontParams {
    count: u32,
    pixels: u32,
    pad: [u32; 2],
}

/// The kept front depths, and the pipeline and buffers that bring them up to date.
pub(super) struct GpuFronts {
    scatter: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    changes: wgpu::Buffer,
    /// Each pixel's initial front depth as the CPU last sent it.
    pub(super) kept: wgpu::Buffer,
    bind: Option<wgpu::BindGroup>,
    pixels: u32,
    /// `kept` holds what the CPU sent for a refresh that succeeded: the next may send
    /// only the changes.
    pub(super) valid: bool,
}

impl GpuFronts {
    pub(super) fn new(ctx: &GpuContext, pixels: u32) -> Self {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("fronts.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("fronts.wgsl").into()),
        });
        // The changes are only read.
        let layout = uniform_and_storage(device, "fronts", 2, &[1]);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("fronts"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let none = wgpu::BufferUsages::empty();
        Self {
            scatter: compute_pipeline(device, &pipeline_layout, &module, "scatter_fronts"),
            layout,
            params: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("front params"),
                size: std::mem::size_of::<FrontParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            changes: storage(device, "front changes", 1024 * 8, none),
            kept: storage(
                device,
                "kept fronts",
                pixels as u64 * 4,
                wgpu::BufferUsages::COPY_SRC,
            ),
            bind: None,
            pixels,
            valid: false,
        }
    }

    /// Bring the kept fronts to `front`: every pixel's written, or the changes
    /// written and their scatter returned, to run before the fronts are copied. The
    /// kept fronts are not [`valid`](Self::valid) again until the refresh succeeds.
    pub(super) fn upload(
        &mut self,
        ctx: &GpuContext,
        front: FrontsIn,
    ) -> Result<Option<wgpu::CommandBuffer>, GpuError> {
        let was_valid = std::mem::take(&mut self.valid);
        let changes = match front {
            FrontsIn::All(bits) => {
                ctx.queue
                    .write_buffer(&self.kept, 0, bytemuck::cast_slice(bits));
                return Ok(None);
            }
            FrontsIn::Changes(c) => c,
        };
        let groups = (changes.len() as u32).div_ceil(GROUP);
        if !was_valid || groups > MAX_GROUPS {
            return Err(GpuError::Failed(format!(
                "{} front changes where the kept fronts cannot take them",
                changes.len()
            )));
        }
        if changes.is_empty() {
            return Ok(None);
        }
        self.fit(ctx, changes.len() as u64 * 8);
        let p = FrontParams {
            count: changes.len() as u32,
            pixels: self.pixels,
            pad: [0; 2],
        };
        let q = &ctx.queue;
        q.write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
        q.write_buffer(&self.changes, 0, bytemuck::cast_slice(changes));
        Ok(Some(self.encode_scatter(ctx, groups)))
    }

    /// The scatter of the changes written, `groups` workgroups.
    fn encode_scatter(&mut self, ctx: &GpuContext, groups: u32) -> wgpu::CommandBuffer {
        let bind = self.bind.get_or_insert_with(|| {
            super::bind_buffers(
                &ctx.device,
                &self.layout,
                "fronts",
                &[&self.params, &self.changes, &self.kept],
            )
        });
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.scatter);
            pass.set_bind_group(0, &*bind, &[]);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        enc.finish()
    }

    /// A changes buffer of at least `bytes` (a new bind group when it had to grow).
    fn fit(&mut self, ctx: &GpuContext, bytes: u64) {
        if self.changes.size() < bytes {
            let size = (bytes + bytes / 2).next_multiple_of(16);
            let none = wgpu::BufferUsages::empty();
            self.changes = storage(&ctx.device, "front changes", size, none);
            self.bind = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::FrontParams;
    use crate::reconstruction::gpu::layout_tests::{check_struct, parse, rust_fields};

    #[test]
    fn fronts_wgsl_lays_out_its_parameters_as_the_rust_side() {
        let m = parse(include_str!("fronts.wgsl"));
        let params = rust_fields!(FrontParams { count, pixels, pad });
        check_struct(
            &m,
            "FrontParams",
            params,
            std::mem::size_of::<FrontParams>(),
        );
    }
}
