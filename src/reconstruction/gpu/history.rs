//! The still-region history on the GPU (`history.wgsl`): the per-pixel arrays live
//! there, and a refresh uploads only the CPU's plan of it ([`Step`]): the view change,
//! the fresh samples with their pixels in the order they came (sorted by pixel here,
//! so that the CPU does not move them) and the pixels moving surfaces cut. What comes back
//! is the shown image (through the reconstructor's read-back) and the counts the
//! sampler reads.

use bytemuck::{Pod, Zeroable};

use super::{
    compute_pipeline, readback, storage, uniform_and_storage, GpuContext, BIN, GROUP, PER_PIXEL,
};
use crate::reconstruction::{
    history::{self, refs, Step, ViewChange},
    HistoryParams,
};

/// Floats per pixel of the history, per held sample and per fresh sample (the
/// shader's `ACC`, `HELD`, `FRESH`).
const ACC: u64 = 12;
const HELD: u64 = 8;
const FRESH: usize = 10;
/// Storage buffers the history's shaders bind.
const BUFFERS: u32 = 11;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct HParams {
    eye: [f32; 3],
    t: f32,
    forward: [f32; 3],
    n_fresh: u32,
    corner: [f32; 3],
    n_cuts: u32,
    du: [f32; 3],
    du2: f32,
    dv: [f32; 3],
    dv2: f32,
    width: u32,
    height: u32,
    slack: f32,
    keep: f32,
    recon_weight: f32,
    max_count: f32,
    box_scale: f32,
    tolerance: f32,
    clamped_count: f32,
    min_count_to_test: f32,
    reprojected_count: f32,
    bins_x: u32,
}

struct Pipelines {
    reset: wgpu::ComputePipeline,
    depth: wgpu::ComputePipeline,
    pick: wgpu::ComputePipeline,
    refs: wgpu::ComputePipeline,
    take: wgpu::ComputePipeline,
    count: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    fill: wgpu::ComputePipeline,
    sort: wgpu::ComputePipeline,
    fresh: wgpu::ComputePipeline,
    cut: wgpu::ComputePipeline,
    blend: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

/// The history's side of a GPU reconstructor.
pub(super) struct GpuHistory {
    params: HistoryParams,
    width: u32,
    height: u32,
    pipelines: Pipelines,
    uniform: wgpu::Buffer,
    acc: wgpu::Buffer,
    scratch: wgpu::Buffer,
    held: wgpu::Buffer,
    pick: wgpu::Buffer,
    fresh: wgpu::Buffer,
    /// The fresh samples sorted by bin: per bin a count, a cursor and a start, then
    /// an index a sample (`history.wgsl`'s `order`).
    order: wgpu::Buffer,
    cut_list: wgpu::Buffer,
    /// What is shown: the reconstruction's read-back layout.
    pub(super) shown: wgpu::Buffer,
    counts: wgpu::Buffer,
    read_counts: wgpu::Buffer,
    read_cuts: wgpu::Buffer,
    /// The fresh samples packed for the upload, kept between refreshes.
    fresh_packed: Vec<f32>,
    /// Fresh samples and cut pixels the buffers hold.
    fresh_cap: usize,
    cuts_cap: usize,
    bind: Option<wgpu::BindGroup>,
}

/// What a history refresh reads back.
pub(in crate::reconstruction) struct HistoryBack {
    pub(in crate::reconstruction) counts: Vec<f32>,
    pub(in crate::reconstruction) cuts: u64,
}

impl GpuHistory {
    /// Over a `width × height` reconstruction whose image and front depths are in
    /// `image` and `front`.
    pub(super) fn new(
        ctx: &GpuContext,
        width: u32,
        height: u32,
        params: HistoryParams,
        image: &wgpu::Buffer,
        front: &wgpu::Buffer,
    ) -> Self {
        let d = &ctx.device;
        let n = width as u64 * height as u64;
        let none = wgpu::BufferUsages::empty();
        let src = wgpu::BufferUsages::COPY_SRC;
        let pipelines = Pipelines::new(d);
        let fresh = storage(d, "fresh samples", 1024 * FRESH as u64 * 4, none);
        let order = storage(d, "fresh order", order_bytes(width, height, 1024), none);
        let cut_list = storage(d, "cut pixels", 1024 * 4, none);
        let acc = storage(d, "history", n * ACC * 4, wgpu::BufferUsages::COPY_DST);
        let scratch = storage(d, "history scratch", n * ACC * 4, src);
        let blocks = ref_blocks(width, height);
        let held = storage(d, "held samples", (n * HELD + 3 * blocks) * 4, none);
        // No block has a reference colour yet.
        let nan = vec![f32::NAN; 3 * blocks as usize];
        ctx.queue
            .write_buffer(&held, n * HELD * 4, bytemuck::cast_slice(&nan));
        let pick = storage(d, "history picks", (2 * n + 1 + blocks) * 4, src);
        let shown = storage(d, "shown image", n * PER_PIXEL as u64 * 4, src);
        let counts = storage(d, "history counts", n * 4, src);
        let mut h = Self {
            params,
            width,
            height,
            uniform: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("history params"),
                size: std::mem::size_of::<HParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            read_counts: readback(d, "history count readback", n * 4),
            read_cuts: readback(d, "history cut readback", 4),
            fresh_packed: Vec::new(),
            fresh_cap: 1024,
            cuts_cap: 1024,
            bind: None,
            acc,
            scratch,
            held,
            pick,
            fresh,
            order,
            cut_list,
            shown,
            counts,
            pipelines,
        };
        h.rebind(d, image, front);
        h
    }

    /// The largest buffer this history needs over `pixels` pixels, in bytes.
    pub(super) fn largest_buffer(pixels: u64) -> u64 {
        pixels * ACC * 4
    }

    /// Encode `step` after the reconstruction's passes (uploading its samples and
    /// cuts first), and the copies of the counts and cuts to their read-backs.
    pub(super) fn encode(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        step: &Step,
        epoch: f64,
        keep: f32,
        buffers: (&wgpu::Buffer, &wgpu::Buffer),
    ) {
        let n_cuts = self.upload(ctx, step, epoch, buffers);
        let hp = self.params_of(step, epoch, keep, n_cuts);
        ctx.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&hp));
        let n = self.width * self.height;
        let pixels = n.div_ceil(GROUP);
        let pl = &self.pipelines;
        enc.clear_buffer(&self.pick, 0, None);
        let bins = bins(self.width, self.height);
        enc.clear_buffer(&self.order, 0, Some(bins.0 as u64 * bins.1 as u64 * 4));
        match step.view {
            ViewChange::Same => {}
            ViewChange::Reset => self.dispatch(enc, &pl.reset, pixels),
            ViewChange::Reproject => {
                self.dispatch(enc, &pl.depth, pixels);
                self.dispatch(enc, &pl.pick, pixels);
                self.dispatch(enc, &pl.take, pixels);
                enc.copy_buffer_to_buffer(&self.scratch, 0, &self.acc, 0, n as u64 * ACC * 4);
            }
        }
        if hp.n_fresh > 0 {
            let samples = hp.n_fresh.div_ceil(GROUP);
            self.dispatch(enc, &pl.count, samples);
            self.dispatch(enc, &pl.scan, 1);
            self.dispatch(enc, &pl.fill, samples);
            self.dispatch_2d(enc, &pl.sort, bins);
            self.dispatch(enc, &pl.fresh, samples);
            let blocks = ref_blocks(self.width, self.height) as u32;
            self.dispatch(enc, &pl.refs, blocks.div_ceil(GROUP));
        }
        self.dispatch(enc, &pl.cut, (hp.n_cuts).div_ceil(GROUP));
        self.dispatch(enc, &pl.blend, pixels);
        enc.copy_buffer_to_buffer(&self.counts, 0, &self.read_counts, 0, n as u64 * 4);
        enc.copy_buffer_to_buffer(&self.pick, 2 * n as u64 * 4, &self.read_cuts, 0, 4);
    }

    /// The read-back buffers of the refresh just submitted, for
    /// [`GpuContext::read_mapped_all`]: the counts, then the cuts.
    pub(super) fn read_buffers(&self) -> [(&wgpu::Buffer, u64); 2] {
        let n = self.width as u64 * self.height as u64;
        [(&self.read_counts, n * 4), (&self.read_cuts, 4)]
    }

    /// What [`GpuHistory::read_buffers`] mapped, as the CPU history takes it: the
    /// counts into `into` (the vector the last refresh's came in, so that no refresh
    /// allocates and faults in a new one).
    pub(super) fn back(counts: &[u8], cuts: &[u8], mut into: Vec<f32>) -> HistoryBack {
        super::copy_par_into(bytemuck::cast_slice(counts), &mut into);
        HistoryBack {
            counts: into,
            cuts: bytemuck::cast_slice::<u8, u32>(cuts)[0] as u64,
        }
    }

    /// Upload the step's fresh samples (in its order, times relative to `epoch`)
    /// and cut pixels (each once: a second cut of a pixel does nothing), growing
    /// their buffers if needed.
    fn upload(
        &mut self,
        ctx: &GpuContext,
        step: &Step,
        epoch: f64,
        buffers: (&wgpu::Buffer, &wgpu::Buffer),
    ) -> u32 {
        let mut fresh = std::mem::take(&mut self.fresh_packed);
        fresh.clear();
        for &(q, i) in &step.order {
            let f = &step.fresh[i as usize];
            fresh.extend_from_slice(&[f32::from_bits(q), f.still as u32 as f32]);
            fresh.extend_from_slice(&f.color.to_array());
            fresh.push((f.t - epoch) as f32);
            fresh.extend_from_slice(&f.hit_point.to_array());
            fresh.push(0.0);
        }
        let mut cuts = step.cuts.clone();
        cuts.sort_unstable();
        cuts.dedup();
        let d = &ctx.device;
        let mut grown = false;
        if step.order.len() > self.fresh_cap {
            self.fresh_cap = step.order.len().next_power_of_two();
            let bytes = self.fresh_cap as u64 * FRESH as u64 * 4;
            self.fresh = storage(d, "fresh samples", bytes, wgpu::BufferUsages::empty());
            let bytes = order_bytes(self.width, self.height, self.fresh_cap);
            self.order = storage(d, "fresh order", bytes, wgpu::BufferUsages::empty());
            grown = true;
        }
        if cuts.len() > self.cuts_cap {
            self.cuts_cap = cuts.len().next_power_of_two();
            let bytes = self.cuts_cap as u64 * 4;
            self.cut_list = storage(d, "cut pixels", bytes, wgpu::BufferUsages::empty());
            grown = true;
        }
        if grown {
            self.rebind(d, buffers.0, buffers.1);
        }
        ctx.queue
            .write_buffer(&self.fresh, 0, bytemuck::cast_slice(&fresh));
        self.fresh_packed = fresh;
        ctx.queue
            .write_buffer(&self.cut_list, 0, bytemuck::cast_slice(&cuts));
        cuts.len() as u32
    }

    fn params_of(&self, step: &Step, epoch: f64, keep: f32, n_cuts: u32) -> HParams {
        let (c, p) = (&step.camera, &self.params);
        HParams {
            eye: c.eye.to_array(),
            t: (step.t - epoch) as f32,
            forward: c.forward.to_array(),
            n_fresh: step.order.len() as u32,
            corner: c.corner.to_array(),
            n_cuts,
            du: c.du.to_array(),
            du2: c.du.length_squared(),
            dv: c.dv.to_array(),
            dv2: c.dv.length_squared(),
            width: self.width,
            height: self.height,
            slack: step.slack,
            keep,
            recon_weight: p.recon_weight,
            max_count: p.max_count,
            box_scale: p.box_scale,
            tolerance: p.tolerance,
            clamped_count: p.clamped_count,
            min_count_to_test: p.min_count_to_test,
            reprojected_count: p.reprojected_count,
            bins_x: bins(self.width, self.height).0,
        }
    }

    fn dispatch(&self, enc: &mut wgpu::CommandEncoder, pipe: &wgpu::ComputePipeline, groups: u32) {
        if groups == 0 {
            return;
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(pipe);
        pass.set_bind_group(0, self.bind.as_ref(), &[]);
        pass.dispatch_workgroups(groups, 1, 1);
    }

    fn dispatch_2d(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipe: &wgpu::ComputePipeline,
        (x, y): (u32, u32),
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(pipe);
        pass.set_bind_group(0, self.bind.as_ref(), &[]);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// The bind group again, over the reconstruction's `image` and `front` buffers.
    fn rebind(&mut self, d: &wgpu::Device, image: &wgpu::Buffer, front: &wgpu::Buffer) {
        let bufs = [
            &self.uniform,
            &self.acc,
            &self.scratch,
            &self.held,
            &self.pick,
            &self.fresh,
            &self.cut_list,
            image,
            front,
            &self.shown,
            &self.counts,
            &self.order,
        ];
        self.bind = Some(super::bind_buffers(
            d,
            &self.pipelines.layout,
            "history",
            &bufs,
        ));
    }
}

/// Bins of [`BIN`]×[`BIN`] pixels across and down a `width × height` image.
fn bins(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(BIN), height.div_ceil(BIN))
}

/// Bytes of the fresh samples' order for `cap` samples: per bin a count, a cursor and
/// a start, one start more, and an index a sample.
fn order_bytes(width: u32, height: u32, cap: usize) -> u64 {
    let (x, y) = bins(width, height);
    (3 * x as u64 * y as u64 + 1 + cap as u64) * 4
}

/// Blocks of pixels that share a reference colour over a `width × height` image.
fn ref_blocks(width: u32, height: u32) -> u64 {
    refs::block_count(width as usize, height as usize) as u64
}

/// `history.wgsl` after the constants it shares with the reconstruction's side and
/// the CPU's history.
fn source() -> String {
    format!(
        "const IMAGE: u32 = {}u;\nconst BIN: u32 = {BIN}u;\nconst REF_BLOCK: u32 = {}u;\n\
         const REF_TOLERANCE: f32 = {:e};\nconst CLAMP_ROUNDING: f32 = {:e};\n{}",
        super::PER_PIXEL,
        refs::BLOCK,
        refs::TOLERANCE,
        history::CLAMP_ROUNDING,
        include_str!("history.wgsl")
    )
}

impl Pipelines {
    fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("history.wgsl"),
            source: wgpu::ShaderSource::Wgsl(source().into()),
        });
        // The fresh samples, cut pixels, image and front depths are only read.
        let layout = uniform_and_storage(device, "history", BUFFERS, &[5, 6, 7, 8]);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("history"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let make = |name: &str| compute_pipeline(device, &pipeline_layout, &module, name);
        Self {
            reset: make("reset"),
            depth: make("depth"),
            pick: make("pick_winner"),
            take: make("take"),
            count: make("count_fresh"),
            scan: make("scan_fresh"),
            fill: make("fill_fresh"),
            sort: make("sort_fresh"),
            fresh: make("take_fresh"),
            refs: make("refs"),
            cut: make("cut_moving"),
            blend: make("blend"),
            layout,
        }
    }
}

#[cfg(test)]
mod layout_tests {
    use super::{HParams, ACC, FRESH, HELD};
    use crate::reconstruction::gpu::layout_tests::{check_struct, parse, rust_fields, wgsl_u32};

    #[test]
    fn history_wgsl_lays_out_the_params_and_arrays_as_the_rust_side() {
        let m = parse(&super::source());
        let p = rust_fields!(HParams {
            eye,
            t,
            forward,
            n_fresh,
            corner,
            n_cuts,
            du,
            du2,
            dv,
            dv2,
            width,
            height,
            slack,
            keep,
            recon_weight,
            max_count,
            box_scale,
            tolerance,
            clamped_count,
            min_count_to_test,
            reprojected_count,
            bins_x,
        });
        check_struct(&m, "H", p, std::mem::size_of::<HParams>());
        assert_eq!(wgsl_u32(&m, "ACC") as u64, ACC);
        assert_eq!(wgsl_u32(&m, "HELD") as u64, HELD);
        assert_eq!(wgsl_u32(&m, "FRESH") as usize, FRESH);
    }
}
