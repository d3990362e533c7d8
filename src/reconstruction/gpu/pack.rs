//! What is shown, repacked on the GPU into the read-back's planes (`pack.wgsl`): the
//! CPU then copies each plane into its array whole (the image, the ages, the
//! coverage, the splat scales) instead of picking six floats a pixel apart, which was
//! most of a refresh's read-back on one thread.

use rayon::prelude::*;

use super::{buffer_entry, compute_pipeline, storage, ReadInto, GROUP, PER_PIXEL};

/// Pixels per task of [`unpack`].
const CHUNK: usize = 1 << 14;

/// The repacking pass, from the reconstruction's image or from what the history
/// shows.
pub(super) struct ReadPack {
    pipeline: wgpu::ComputePipeline,
    /// The planes, for the copy to the read-back.
    pub(super) planes: wgpu::Buffer,
    from_image: wgpu::BindGroup,
    from_shown: Option<wgpu::BindGroup>,
    pixels: u32,
}

impl ReadPack {
    /// Over `pixels` pixels of the reconstruction's `image`, and of the history's
    /// `shown` where there is one.
    pub(super) fn new(
        device: &wgpu::Device,
        pixels: u64,
        image: &wgpu::Buffer,
        shown: Option<&wgpu::Buffer>,
    ) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("pack.wgsl"),
            source: wgpu::ShaderSource::Wgsl(source().into()),
        });
        let read_only = wgpu::BufferBindingType::Storage { read_only: true };
        let write = wgpu::BufferBindingType::Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pack"),
            entries: &[
                buffer_entry(0, read_only, false),
                buffer_entry(1, write, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pack"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let bytes = pixels * PER_PIXEL as u64 * 4;
        let planes = storage(device, "shown planes", bytes, wgpu::BufferUsages::COPY_SRC);
        let bind =
            |from: &wgpu::Buffer| super::bind_buffers(device, &layout, "pack", &[from, &planes]);
        Self {
            pipeline: compute_pipeline(device, &pipeline_layout, &module, "pack"),
            from_image: bind(image),
            from_shown: shown.map(bind),
            planes,
            pixels: pixels as u32,
        }
    }

    /// Encode the repacking of what is shown: the history's (`shown`) or the image.
    pub(super) fn encode(&self, enc: &mut wgpu::CommandEncoder, shown: bool) {
        let bind = match (&self.from_shown, shown) {
            (Some(b), true) => b,
            _ => &self.from_image,
        };
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(self.pixels.div_ceil(GROUP), 1, 1);
    }
}

/// `pack.wgsl` after the constant it shares with the reconstruction's side.
fn source() -> String {
    format!(
        "const PER_PIXEL: u32 = {PER_PIXEL}u;\n{}",
        include_str!("pack.wgsl")
    )
}

/// Planes of what is shown, which come back at every refresh: red, green and blue (a
/// pixel after another), then the ages. The coverage and the splat scales follow them
/// (the planes' [`PER_PIXEL`] in all).
pub(super) const SHOWN_PLANES: u64 = 4;

/// The read-back planes `src` into `into`'s image and ages, and where `src` holds all
/// the planes, its coverage and splat scales.
pub(super) fn unpack(src: &[f32], into: &mut ReadInto) {
    let n = into.age.len();
    let (rgb, rest) = src.split_at(3 * n);
    let (age, extras) = rest.split_at(n);
    copy(rgb, bytemuck::cast_slice_mut(into.image));
    copy(age, into.age);
    if !extras.is_empty() {
        unpack_extras(extras, into.coverage, into.scale);
    }
}

/// The read-back coverage and splat scale planes `src` into `coverage` and `scale`.
pub(super) fn unpack_extras(src: &[f32], coverage: &mut [u32], scale: &mut [f32]) {
    let (c, s) = src.split_at(coverage.len());
    copy(bytemuck::cast_slice(c), coverage);
    copy(s, scale);
}

/// `src` into `dst` (of the same length) on every thread.
fn copy<T: Copy + Send + Sync>(src: &[T], dst: &mut [T]) {
    dst.par_chunks_mut(CHUNK)
        .zip(src.par_chunks(CHUNK))
        .for_each(|(d, s)| d.copy_from_slice(s));
}
