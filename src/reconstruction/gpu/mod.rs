//! The reconstructor's refresh on a GPU (`--recon gpu|auto`), in compute shaders
//! (`recon.wgsl`).
//!
//! The CPU [`Reconstructor`](super::Reconstructor) stays the reference and keeps
//! everything between refreshes but the splat scale map: its ring, the filter table it
//! builds from the sampler's tiling, the stale cut. At a refresh this side uploads the
//! samples pushed since the last one (into a ring of the same layout on the GPU) and
//! the per-tile filters with their rectangles (the shaders paint the pixel → tile map
//! from those), submits its work at once, and reads back the image, ages, coverage and
//! splat scale. Splatting becomes a gather: each footprint is listed in
//! the 16×16-pixel bins it touches, each bin's list is sorted into ring order, and each
//! pixel adds the weights of its bin's splats in that order. The arithmetic is the
//! CPU's, but for `exp` and the pyramid sums (f32 here, f64 there), so images agree
//! to rounding (`MAX_DIFF` in `reconstruction/gpu_tests.rs` states the tolerance).
//!
//! Which steps run here: reprojection (by velocity; exact motion rewrites the
//! velocities of the live moving samples on the CPU first, which are uploaded again),
//! the adaptive (or fixed) filter, adaptive splat size, the visibility pass, the
//! hole-filling pyramid and the pull-push fill, and the still-region history
//! (`history`), whose per-pixel arrays stay here too: the CPU only plans each of its
//! refreshes from the samples pushed since the last.
//!
//! With [`ReconParams::carry`] the accumulators are carried between refreshes: the
//! CPU decays, moves and cuts its copy as it would for itself (where only which pixels
//! hold sums comes back, `SumsBack::Holds`, it does not decay it: a weight that holds
//! still holds decayed), the GPU adds only the new samples' splats onto its own, and
//! they come back for the CPU's next carry.
//! While the view holds, the GPU carries the sums it kept from its last refresh itself
//! by replaying the CPU's list of what its carry did (`carry`: a factor per tile,
//! the pixels whose sums moved, the pixels cut); otherwise (the first refresh, sums
//! moved with the view or started afresh, or sums not kept) every pixel's sums go up
//! (`carried`). With the visibility pass the initial front depths are kept here too
//! (`fronts`): while the view holds, only the pixels whose front changed go up.

pub(super) mod carried;
mod carry;
mod fronts;
mod history;
#[cfg(test)]
mod layout_tests;
mod pack;

use std::sync::Arc;

pub use crate::gpu::{GpuContext, GpuError};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::carry_edits::CarryEdits;
use super::{
    filter_table::TileFilter,
    history::Step,
    ring::{field, Ring},
    splat::MIN_WEIGHT,
    spread::EyeTrack,
    HistoryParams, ReconParams,
};
use crate::{scene::CameraFrame, tiles::Rect};
use carried::{CarriedIn, CarriedSums, FrontsIn, HoldsKept};

/// Storage buffers the shaders bind at once.
const STORAGE_BUFFERS: u32 = 13;
/// Side of a bin of pixels (the shaders' `BIN`).
const BIN: u32 = 16;
/// Floats per ring sample on the GPU: the CPU ring's fields and the time.
const RING_FIELDS: usize = field::COUNT + 1;
/// Floats per pixel of the accumulators and of the read-back image.
const PER_PIXEL: usize = 6;
/// Floats per pyramid block.
const PER_BLOCK: usize = 5;
/// Workgroup size of the one-dimensional passes.
const GROUP: u32 = 256;
/// Most workgroups a dispatch may have along a side (WebGPU's least limit).
const MAX_GROUPS: u32 = 65535;

/// `recon.wgsl` after the constants it shares with this side.
fn recon_source() -> String {
    format!(
        "const BIN: u32 = {BIN}u;\nconst MIN_WEIGHT: f32 = {MIN_WEIGHT:e};\n\
         const PER_PIXEL: u32 = {PER_PIXEL}u;\n{}",
        include_str!("recon.wgsl")
    )
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Params {
    eye: [f32; 3],
    t: f32,
    forward: [f32; 3],
    reproject: u32,
    u: [f32; 3],
    ou: f32,
    v: [f32; 3],
    ov: f32,
    width: u32,
    height: u32,
    cap: u32,
    first: u32,
    count: u32,
    bins_x: u32,
    bins_y: u32,
    items_cap: u32,
    temporal_cutoff: f32,
    max_r: f32,
    grow: f32,
    shrink: f32,
    undersampled: u32,
    oversampled: u32,
    scale_lo: f32,
    scale_hi: f32,
    levels: u32,
    keep: f32,
    setter_age: f32,
    fill_weight: f32,
    carry: u32,
    /// Tiles of this refresh's filter table.
    tiles: u32,
    /// [`crate::reconstruction::Visibility::moving_view_spread`] where this refresh
    /// spreads the fronts, else 0.
    spread: f32,
    /// Refreshes in the eye track ([`GpuRecon::set_eye_track`]).
    track: u32,
    /// [`crate::reconstruction::Visibility::spread_parallax`].
    parallax: f32,
    /// [`crate::reconstruction::Visibility::footprint_spread`] (0: none), its
    /// parallax and its reach.
    footprint: f32,
    footprint_parallax: f32,
    footprint_reach: f32,
    /// When the newest sample in hand was traced (relative to the epoch, as `t`): the
    /// temporal filter measures ages from it
    /// ([`crate::reconstruction::Reconstructor`]'s `sample_lag`).
    t_newest: f32,
    /// To the uniform's 16-byte size.
    pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuTile {
    inv_et: f32,
    ax: f32,
    ay: f32,
    cx: f32,
    cy: f32,
    /// The tile's rectangle on the image, clipped to it (right and bottom exclusive).
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    pad: [f32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Level {
    src: u32,
    dst: u32,
    src_w: u32,
    src_h: u32,
    dst_w: u32,
    dst_h: u32,
    from_acc: u32,
    pad: u32,
}

/// Bytes of one splat in the shaders' `Splat`.
const SPLAT_BYTES: u64 = 64;

/// What a refresh reads back besides the arrays it writes in place ([`ReadInto`]).
pub(super) struct Readback {
    /// Pixels no splat reached.
    pub(super) holes: usize,
    /// The history's counts and cuts, with one.
    pub(super) history: Option<history::HistoryBack>,
}

/// The reconstructor's arrays a refresh's read-back is unpacked into, straight from
/// the mapped buffers (tens of megabytes at 1920×1080: one copy, on every thread).
pub(super) struct ReadInto<'a> {
    pub(super) image: &'a mut [Vec3],
    pub(super) age: &'a mut [f32],
    pub(super) coverage: &'a mut [u32],
    pub(super) scale: &'a mut [f32],
    /// The planar accumulators (channel stride `cs`) and the carried coverage, which
    /// a GPU side made for carrying fills with its final sums, before any fill.
    pub(super) sums: (&'a mut [f32], usize, &'a mut [f32]),
    /// The vector the history's counts came back in last time, to take them again.
    pub(super) counts: Vec<f32>,
    /// Where only the holds mask comes back and the CPU's weights are the last mask's
    /// but where this carry edited them: that carry, so that only the weights that
    /// changed are written ([`carried::unpack_holds_since`]).
    pub(super) edited: Option<&'a CarryEdits>,
}

/// Seconds a GPU reconstructor has spent in each part of its refreshes.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct GpuReconTimes {
    /// Uploads, encoding and submission.
    pub(super) upload_s: f64,
    /// From the submissions until the read-back buffers were mapped.
    pub(super) wait_s: f64,
    /// Unpacking the mapped buffers into the reconstructor's arrays.
    pub(super) read_s: f64,
}

/// The GPU side of one reconstructor (see the module doc).
pub struct GpuRecon {
    ctx: Arc<GpuContext>,
    width: u32,
    height: u32,
    cap: usize,
    bins: (u32, u32),
    levels: Vec<Level>,
    pipelines: Pipelines,
    buffers: Buffers,
    bind: wgpu::BindGroup,
    level_bind: wgpu::BindGroup,
    level_stride: u64,
    /// Samples of the CPU ring uploaded so far (its push count then).
    uploaded: u64,
    /// Time that ring times are uploaded relative to (f32 keeps microseconds over
    /// hours of scene time only relative to a nearby origin).
    epoch: Option<f64>,
    history: Option<history::GpuHistory>,
    /// What is shown, repacked for the read-back.
    pack: pack::ReadPack,
    times: GpuReconTimes,
    /// The carried sums of the next refresh are in the accumulators.
    carried_uploaded: bool,
    /// The carried sums packed for the upload, kept between refreshes.
    packed: Vec<f32>,
    /// With carrying: the carry's replay on the accumulators.
    carry: Option<carry::GpuCarry>,
    /// The accumulators hold the sums the last refresh carried to the CPU (it
    /// succeeded, and carried), so that the next may replay the CPU's carry on them.
    acc_carried: bool,
    /// The CPU's carry, to replay at the next refresh once its filters are up.
    replay: Option<wgpu::CommandBuffer>,
    /// This refresh's work to submit ahead of its next encoder's (the tile map's
    /// painting, the carry's replay), in order: one submission instead of three.
    ahead: Vec<wgpu::CommandBuffer>,
    /// Bytes the bins' items may take where sized by their bound
    /// ([`GpuRecon::items_bound`]): the adapter's limit on a storage buffer.
    items_limit: u64,
    /// Carrying refreshes whose sums were uploaded, and those whose carry was
    /// replayed here.
    carried_by: CarriedBy,
    /// With carrying: what comes back of the sums after each refresh.
    sums_back: Option<SumsBack>,
    /// The holds mask the CPU's weights were last set from, and which that changed.
    holds_kept: HoldsKept,
    /// With the visibility pass and carrying: the initial front depths kept between
    /// refreshes (made at the first that sends them).
    fronts: Option<fronts::GpuFronts>,
    /// The last refresh succeeded and left its coverage and splat scales here, not
    /// read back ([`GpuRecon::read_extras`]).
    extras_left: bool,
    /// Refreshes in the eye track uploaded ([`GpuRecon::set_eye_track`]).
    track: u32,
    /// This refresh pulls the own fronts' pyramid (a footprint's spread).
    front_levels: bool,
}

/// What a carrying GPU side gives back of its sums after each refresh, for the CPU's
/// next carry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum SumsBack {
    /// Every pixel's sums (24 bytes a pixel): where a moving view moves them on the
    /// CPU ([`ReconParams::resplat_moving_view`] off), which needs them all.
    All,
    /// A bit per pixel, whether its weight holds sums: all the CPU's carry decides
    /// from when the GPU replays it ([`carry`]). The CPU's copy of the sums then
    /// holds weight 1 where the GPU's hold sums and 0 elsewhere, and nothing else
    /// of use: a refresh that fails on the GPU starts the CPU's sums afresh.
    Holds,
}

/// How carrying refreshes got their carried sums on a GPU.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct CarriedBy {
    /// Every pixel's sums uploaded.
    pub(super) upload: u64,
    /// The CPU's carry replayed on the sums kept here.
    pub(super) replay: u64,
}

struct Pipelines {
    paint: wgpu::ComputePipeline,
    place: wgpu::ComputePipeline,
    count: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    fill: wgpu::ComputePipeline,
    sort: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    pull: wgpu::ComputePipeline,
    front_pull: wgpu::ComputePipeline,
    holes: wgpu::ComputePipeline,
    pp_pull: wgpu::ComputePipeline,
    pp_top: wgpu::ComputePipeline,
    pp_push: wgpu::ComputePipeline,
    pp_final: wgpu::ComputePipeline,
    layout0: wgpu::BindGroupLayout,
    layout1: wgpu::BindGroupLayout,
}

struct Buffers {
    params: wgpu::Buffer,
    ring: wgpu::Buffer,
    tiles: wgpu::Buffer,
    pix_tile: wgpu::Buffer,
    scale: wgpu::Buffer,
    splats: wgpu::Buffer,
    bins: wgpu::Buffer,
    bin_start: wgpu::Buffer,
    items: wgpu::Buffer,
    acc: wgpu::Buffer,
    out: wgpu::Buffer,
    pyramid: wgpu::Buffer,
    levels: wgpu::Buffer,
    /// The front depths, then (while they spread) the pixels' own.
    front: wgpu::Buffer,
    /// The eye's track, `(age, position)` newest first.
    eyes: wgpu::Buffer,
    read_out: wgpu::Buffer,
    read_counts: wgpu::Buffer,
    /// Where the accumulators are read back to, when carrying.
    read_acc: Option<wgpu::Buffer>,
    /// Tiles and items the buffers hold.
    tiles_cap: usize,
    items_cap: usize,
}

fn storage(
    device: &wgpu::Device,
    label: &str,
    bytes: u64,
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
        mapped_at_creation: false,
    })
}

fn readback(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The pull pyramid's levels 1 and up over a `width × height` image.
fn pyramid_levels(width: u32, height: u32) -> Vec<Level> {
    let mut levels = Vec::new();
    let (mut w, mut h, mut src, mut dst) = (width, height, 0u32, 0u32);
    while w > 1 || h > 1 {
        let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
        levels.push(Level {
            src,
            dst,
            src_w: w,
            src_h: h,
            dst_w: nw,
            dst_h: nh,
            from_acc: levels.is_empty() as u32,
            pad: 0,
        });
        src = dst;
        dst += nw * nh;
        (w, h) = (nw, nh);
    }
    levels
}

/// What a reconstructor's GPU buffers hold.
struct Sizes {
    pixels: u64,
    cap: u64,
    bins: (u32, u32),
    levels: Vec<Level>,
    /// Blocks of all pyramid levels together.
    blocks: u64,
    history: bool,
    /// The sums come back whole after each refresh (not only the holds mask).
    sums_back: bool,
}

impl Sizes {
    fn new(width: u32, height: u32, cap: usize, history: bool, sums_back: bool) -> Self {
        let levels = pyramid_levels(width, height);
        Self {
            history,
            sums_back,
            pixels: width as u64 * height as u64,
            cap: cap as u64,
            bins: (width.div_ceil(BIN), height.div_ceil(BIN)),
            blocks: levels.iter().map(|l| l.dst_w as u64 * l.dst_h as u64).sum(),
            levels,
        }
    }

    fn bin_count(&self) -> u64 {
        self.bins.0 as u64 * self.bins.1 as u64
    }

    /// Whether the largest buffer fits the adapter's limit on one storage buffer.
    fn check(&self, ctx: &GpuContext) -> Result<(), GpuError> {
        let largest = [
            self.cap * RING_FIELDS as u64 * 4,
            self.cap * SPLAT_BYTES,
            self.pixels * PER_PIXEL as u64 * 4,
            self.blocks * PER_BLOCK as u64 * 4,
            if self.history {
                history::GpuHistory::largest_buffer(self.pixels)
            } else {
                0
            },
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        let lim = &ctx.limits;
        let most = lim.max_storage_buffer_binding_size.min(lim.max_buffer_size);
        if largest > most {
            return Err(GpuError::Limits {
                adapter: ctx.describe(),
                why: format!(
                    "a buffer of {largest} bytes, over its limit of {most} bytes per storage buffer"
                ),
            });
        }
        Ok(())
    }
}

impl GpuRecon {
    /// The GPU side of a `width × height` reconstructor with a ring of `cap` samples,
    /// every pixel's splat scale starting at `scale0`, and a still-region history with
    /// `history`; `sums_back`: refreshes carry their accumulators ([`ReconParams::carry`]),
    /// and this comes back of them ([`SumsBack`]).
    pub(super) fn new(
        ctx: Arc<GpuContext>,
        (width, height): (u32, u32),
        cap: usize,
        scale0: f32,
        history: Option<HistoryParams>,
        sums_back: Option<SumsBack>,
    ) -> Result<Self, GpuError> {
        ctx.require_storage_buffers(STORAGE_BUFFERS)?;
        let all_back = sums_back == Some(SumsBack::All);
        let sizes = Sizes::new(width, height, cap, history.is_some(), all_back);
        sizes.check(&ctx)?;
        let pipelines = Pipelines::new(&ctx.device);
        let level_stride = (ctx.limits.min_uniform_buffer_offset_alignment as u64).max(32);
        let buffers = Buffers::new(&ctx.device, &sizes, level_stride);
        let n = sizes.pixels as usize;
        let q = &ctx.queue;
        q.write_buffer(&buffers.scale, 0, bytemuck::cast_slice(&vec![scale0; n]));
        for (k, l) in sizes.levels.iter().enumerate() {
            q.write_buffer(
                &buffers.levels,
                k as u64 * level_stride,
                bytemuck::bytes_of(l),
            );
        }
        let bind = buffers.bind_group(&ctx.device, &pipelines.layout0);
        let level_bind = buffers.level_bind_group(&ctx.device, &pipelines.layout1);
        let history = history.map(|h| {
            history::GpuHistory::new(&ctx, width, height, h, &buffers.out, &buffers.front)
        });
        let carry = sums_back.map(|_| carry::GpuCarry::new(&ctx, width * height));
        let shown = history.as_ref().map(|h| &h.shown);
        let pack = pack::ReadPack::new(&ctx.device, sizes.pixels, &buffers.out, shown);
        let lim = &ctx.limits;
        let items_limit = lim.max_storage_buffer_binding_size.min(lim.max_buffer_size);
        Ok(Self {
            history,
            pack,
            ctx,
            width,
            height,
            cap,
            bins: sizes.bins,
            levels: sizes.levels,
            pipelines,
            buffers,
            bind,
            level_bind,
            level_stride,
            uploaded: 0,
            epoch: None,
            times: GpuReconTimes::default(),
            carried_uploaded: false,
            packed: Vec::new(),
            carry,
            acc_carried: false,
            replay: None,
            ahead: Vec::new(),
            items_limit,
            carried_by: CarriedBy::default(),
            sums_back,
            holds_kept: HoldsKept::default(),
            fronts: None,
            track: 0,
            front_levels: false,
            extras_left: false,
        })
    }

    /// The adapter.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// Where its refreshes' time went so far.
    pub(super) fn times(&self) -> GpuReconTimes {
        self.times
    }

    /// Upload the samples pushed into `ring` since the last upload.
    fn upload_ring(&mut self, ring: &Ring) {
        let epoch = *self
            .epoch
            .get_or_insert_with(|| ring.back().map_or(0.0, |s| s.t));
        let new = ring.pushed - self.uploaded;
        let cap = self.cap as u64;
        // The physical slots written since: one run, or two where they wrap.
        let ranges = if new >= cap {
            [0..self.cap, 0..0]
        } else {
            let p0 = (self.uploaded % cap) as usize;
            let p1 = p0 + new as usize;
            if p1 <= self.cap {
                [p0..p1, 0..0]
            } else {
                [p0..self.cap, 0..p1 - self.cap]
            }
        };
        for r in ranges.into_iter().filter(|r| !r.is_empty()) {
            for k in 0..field::COUNT {
                self.write_field(k, r.start, &ring.f[k][r.clone()]);
            }
            let times: Vec<f32> = ring.t[r.clone()]
                .iter()
                .map(|&t| (t - epoch) as f32)
                .collect();
            self.write_field(field::COUNT, r.start, &times);
        }
        self.uploaded = ring.pushed;
    }

    /// Upload the filter table of this refresh, each tile with its rectangle, and
    /// paint the pixel → tile map from them here (the rectangles cover the image
    /// without overlap): 48 bytes a tile go up, not 4 a pixel (tiles average tens of
    /// pixels). The painting goes ahead of the carry's replay, whose decay reads the
    /// map. The painting reads the tile count from this refresh's parameters, written
    /// before anything is submitted.
    fn upload_filters(&mut self, tiles: &[TileFilter], rects: &[Rect]) {
        if tiles.len() > self.buffers.tiles_cap {
            self.buffers.tiles_cap = tiles.len().next_power_of_two();
            self.buffers.tiles = storage(
                &self.ctx.device,
                "tiles",
                self.buffers.tiles_cap as u64 * std::mem::size_of::<GpuTile>() as u64,
                wgpu::BufferUsages::empty(),
            );
            self.rebind();
        }
        let gt: Vec<GpuTile> = tiles
            .iter()
            .zip(rects)
            .map(|(f, r)| GpuTile {
                inv_et: f.inv_et,
                ax: f.ax,
                ay: f.ay,
                cx: f.cx,
                cy: f.cy,
                x0: r.x0,
                y0: r.y0,
                x1: r.x1,
                y1: r.y1,
                pad: [0.0; 3],
            })
            .collect();
        self.ctx
            .queue
            .write_buffer(&self.buffers.tiles, 0, bytemuck::cast_slice(&gt));
        let mut enc = self.encoder();
        // A workgroup a tile, in rows of at most the largest dispatch a side.
        let n = gt.len() as u32;
        let across = n.min(MAX_GROUPS);
        let groups = (across, n.div_ceil(across.max(1)));
        self.dispatch(&mut enc, &self.pipelines.paint, groups, None);
        self.ahead.push(enc.finish());
    }

    /// One refresh at time `t` seen by `camera` (`None`: no reprojection) of the ring's
    /// logical samples `start..len`, with this refresh's filter table, and the
    /// history's `step` with one. `moved`: the hit points and velocities of live
    /// samples were rewritten since the last upload (exact motion). `carried`: the
    /// sums the new splats add to, when carrying (the GPU side must have been made
    /// with `carry`). The image and, when carrying, the sums are read back `into` the
    /// reconstructor's arrays, all of them or (on an error) none.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn refresh(
        &mut self,
        ring: &Ring,
        start: usize,
        moved: bool,
        t: f64,
        camera: Option<&CameraFrame>,
        tiles: &[TileFilter],
        rects: &[Rect],
        params: &ReconParams,
        max_r: f32,
        step: Option<&Step>,
        carried: Option<&CarriedIn>,
        into: ReadInto,
    ) -> Result<Readback, GpuError> {
        let (t0, before) = (std::time::Instant::now(), self.times);
        // Work left by a refresh that failed before submitting it is not this one's.
        self.ahead.clear();
        self.upload_ring(ring);
        if moved {
            self.upload_motion(ring, start);
        }
        let count = ring.len().saturating_sub(start);
        let t_newest = super::place::filter_origin(t, ring);
        let mut p = self.params((t, t_newest), camera, params, max_r);
        self.front_levels = p.footprint > 0.0;
        p.first = if count > 0 {
            ring.phys(start) as u32
        } else {
            0
        };
        p.count = count as u32;
        p.tiles = tiles.len() as u32;
        self.upload_filters(tiles, rects);
        // The accumulators change from here: only a carrying refresh that succeeds
        // leaves the CPU's carried sums in them.
        self.acc_carried = false;
        self.ahead.extend(self.replay.take());
        if carried.is_some() {
            if !std::mem::take(&mut self.carried_uploaded) {
                return Err(GpuError::Failed(
                    "a carrying refresh without its carried sums".into(),
                ));
            }
            p.carry = 1;
        }
        let front = self.upload_fronts(carried.and_then(|c| c.front))?;
        let enc = match self.items_bound(count, max_r) {
            // Room for every item the footprints can list: the bins go in the same
            // submission as the splats, with no wait for their count between.
            Some(bound) => {
                if bound > self.buffers.items_cap {
                    self.grow_items(bound);
                }
                p.items_cap = self.buffers.items_cap as u32;
                self.write_params(&p);
                let mut enc = self.encoder();
                self.encode_bins(&mut enc, count, front);
                enc
            }
            None => loop {
                p.items_cap = self.buffers.items_cap as u32;
                self.write_params(&p);
                let total = self.bin_pass(count, front)?;
                if total <= self.buffers.items_cap {
                    break self.encoder();
                }
                self.grow_items(total);
            },
        };
        let back = self.splat_pass(enc, params.fill_weight > 0.0, step, p.keep, into);
        self.acc_carried = p.carry == 1 && back.is_ok();
        if let Some(f) = &mut self.fronts {
            f.valid = front && back.is_ok();
        }
        let waited = (self.times.wait_s - before.wait_s) + (self.times.read_s - before.read_s);
        self.times.upload_s += t0.elapsed().as_secs_f64() - waited;
        back
    }

    /// Write the carried sums and coverage into the accumulators, which only the
    /// gather reads, before a carrying [`refresh`](Self::refresh) (the front depths
    /// are written at each bin pass, which may run again). Packed on every thread
    /// into a buffer kept between refreshes, then written to the queue.
    pub(super) fn upload_carried(&mut self, c: &CarriedSums<'_>) -> Result<(), GpuError> {
        let t0 = std::time::Instant::now();
        let n = self.width as usize * self.height as usize;
        if self.carry.is_none() {
            return Err(GpuError::Failed(
                "carried sums for a GPU side made without carrying".into(),
            ));
        }
        if c.cover.len() != n || c.w != self.width as usize {
            return Err(GpuError::Failed(format!(
                "carried sums of {} pixels, {} wide, for {n} pixels, {} wide",
                c.cover.len(),
                c.w,
                self.width
            )));
        }
        carried::pack_into(c, &mut self.packed);
        self.carried_by.upload += 1;
        self.replay = None;
        self.ctx
            .queue
            .write_buffer(&self.buffers.acc, 0, bytemuck::cast_slice(&self.packed));
        self.carried_uploaded = true;
        self.times.upload_s += t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// Carry the sums this side kept from the last refresh by replaying `e`, the
    /// CPU's carry of the same sums, at the next [`refresh`](Self::refresh) (after its
    /// filters are up: the decay reads their pixel → tile map). False, and nothing
    /// done, where the list is not the whole carry or the sums here are not the ones
    /// the CPU carried: then they must be uploaded
    /// ([`upload_carried`](Self::upload_carried)).
    pub(super) fn carry_by_replay(&mut self, e: &CarryEdits) -> bool {
        let t0 = std::time::Instant::now();
        let Some(carry) = self
            .carry
            .as_mut()
            .filter(|_| e.complete && self.acc_carried)
        else {
            return false;
        };
        let work = carry.encode(&self.ctx, e, &self.buffers.acc, &self.buffers.pix_tile);
        self.replay = Some(work);
        self.carried_uploaded = true;
        self.carried_by.replay += 1;
        self.times.upload_s += t0.elapsed().as_secs_f64();
        true
    }

    /// How the carrying refreshes so far got their sums.
    pub(super) fn carried_by(&self) -> CarriedBy {
        self.carried_by
    }

    /// The kept front depths, read back (`None`: none kept).
    #[cfg(test)]
    pub(super) fn kept_fronts(&self) -> Option<Vec<u32>> {
        let kept = &self.fronts.as_ref()?.kept;
        let read = readback(&self.ctx.device, "kept fronts readback", kept.size());
        let mut enc = self.encoder();
        enc.copy_buffer_to_buffer(kept, 0, &read, 0, kept.size());
        self.ctx.queue.submit([enc.finish()]);
        let got = self.ctx.read_mapped(&read, kept.size(), None, |b| {
            bytemuck::cast_slice::<u8, u32>(b).to_vec()
        });
        got.ok()
    }

    /// Bring the kept front depths to `front`, this refresh's (its changes' scatter
    /// goes ahead of the bins' passes, which copy them into the front depths). Whether
    /// there are any: without, the front depths start from none, and the kept ones are
    /// no longer the last refresh's.
    fn upload_fronts(&mut self, front: Option<FrontsIn>) -> Result<bool, GpuError> {
        let Some(front) = front else {
            if let Some(f) = &mut self.fronts {
                f.valid = false;
            }
            return Ok(false);
        };
        let pixels = self.width * self.height;
        let f = self
            .fronts
            .get_or_insert_with(|| fronts::GpuFronts::new(&self.ctx, pixels));
        self.ahead.extend(f.upload(&self.ctx, front)?);
        Ok(true)
    }

    /// The pixels whose weight the last refresh's read-back changed, where this side
    /// kept the front depths the CPU sent for that refresh: the CPU may then send only
    /// the fronts that changed ([`FrontsIn::Changes`]). `None`: every pixel's must go
    /// up.
    pub(super) fn fronts_since(&self) -> Option<&[u32]> {
        self.fronts.as_ref().filter(|f| f.valid)?;
        self.holds_kept.changed.as_deref()
    }

    /// Upload the hit points and velocities of the live samples `start..` again.
    fn upload_motion(&self, ring: &Ring, start: usize) {
        for r in ring.runs(start).into_iter().filter(|r| !r.is_empty()) {
            for k in [field::HX, field::VX, field::VY, field::VZ] {
                self.write_field(k, r.start, &ring.f[k][r.clone()]);
            }
        }
    }

    /// Write `values` into the GPU ring's field `k` from physical index `p0`.
    fn write_field(&self, k: usize, p0: usize, values: &[f32]) {
        let off = (k * self.cap + p0) as u64 * 4;
        self.ctx
            .queue
            .write_buffer(&self.buffers.ring, off, bytemuck::cast_slice(values));
    }

    /// The uniform of a refresh at `t` whose temporal filter counts ages from
    /// `t_newest`.
    fn params(
        &self,
        (t, t_newest): (f64, f64),
        camera: Option<&CameraFrame>,
        rp: &ReconParams,
        max_r: f32,
    ) -> Params {
        let epoch = self.epoch.unwrap_or(t);
        let mut p = Params {
            t: (t - epoch) as f32,
            t_newest: (t_newest - epoch) as f32,
            width: self.width,
            height: self.height,
            cap: self.cap as u32,
            bins_x: self.bins.0,
            bins_y: self.bins.1,
            temporal_cutoff: rp.temporal_cutoff,
            max_r,
            grow: rp.grow,
            shrink: rp.shrink,
            undersampled: rp.undersampled,
            oversampled: rp.oversampled,
            scale_lo: rp.scale_bounds.0,
            scale_hi: rp.scale_bounds.1,
            levels: self.levels.len() as u32,
            fill_weight: rp.fill_weight.max(0.0),
            ..Params::default()
        };
        if let Some(v) = rp.visibility_in_use() {
            p.keep = 1.0 / (1.0 + v.depth_tolerance);
            p.setter_age = v.setter_age_sigmas;
            p.spread = v.moving_view_spread.unwrap_or(0.0);
            p.parallax = v.spread_parallax;
            if let (Some(r), true) = (v.footprint_spread, p.spread > 0.0) {
                (p.footprint, p.footprint_parallax) = (r, v.footprint_parallax);
                p.footprint_reach = v.footprint_reach;
            }
            p.track = self.track;
        }
        if let Some(c) = camera {
            // The CPU placer's projector: the same constants, computed the same way.
            let u = c.du / c.du.length_squared();
            let v = c.dv / c.dv.length_squared();
            p.eye = c.eye.to_array();
            p.forward = c.forward.to_array();
            p.u = u.to_array();
            p.v = v.to_array();
            p.ou = c.corner.dot(u);
            p.ov = c.corner.dot(v);
            p.reproject = 1;
        }
        p
    }

    fn grow_items(&mut self, total: usize) {
        self.buffers.items_cap = total + total / 4 + 1024;
        self.buffers.items = storage(
            &self.ctx.device,
            "bin items",
            self.buffers.items_cap as u64 * 4,
            wgpu::BufferUsages::empty(),
        );
        self.rebind();
    }

    /// The bind group again, after a buffer was replaced by a larger one.
    fn rebind(&mut self) {
        self.bind = self
            .buffers
            .bind_group(&self.ctx.device, &self.pipelines.layout0);
    }

    fn dispatch(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipe: &wgpu::ComputePipeline,
        groups: (u32, u32),
        level: Option<usize>,
    ) {
        if groups.0 == 0 || groups.1 == 0 {
            return;
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(pipe);
        pass.set_bind_group(0, &self.bind, &[]);
        let off = level.map_or(0, |k| (k as u64 * self.level_stride) as u32);
        pass.set_bind_group(1, &self.level_bind, &[off]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }

    /// Items (a splat listed in a bin) that `count` splats of radius at most `max_r`
    /// can list, where a buffer of them fits the adapter's limit (`None`: the count
    /// must be read back first, [`GpuRecon::bin_pass`]). A footprint's first and last
    /// columns are at most `2 max_r` apart (`ceil(x − ½ − r)` to `floor(x − ½ + r)`),
    /// so it touches at most `ceil(2 max_r / BIN) + 1` bins across, and as many down.
    fn items_bound(&self, count: usize, max_r: f32) -> Option<usize> {
        let across = bins_across(max_r)?;
        let bound = (count as u64).checked_mul(across * across)?;
        // As `grow_items` grows it, four bytes an item.
        let bytes = bound.saturating_add(bound / 4 + 1024).saturating_mul(4);
        (bytes <= self.items_limit).then_some(bound as usize)
    }

    /// Always read the bins' item count back before the splats (as where the bound
    /// passes the adapter's limit), from a buffer of room for one item, so that the
    /// tests reach that way and its growing too.
    #[cfg(test)]
    pub(super) fn count_items_first(&mut self) {
        self.items_limit = 0;
        self.buffers.items_cap = 1;
        self.buffers.items = storage(
            &self.ctx.device,
            "bin items",
            4,
            wgpu::BufferUsages::empty(),
        );
        self.rebind();
    }

    /// The eye's track for the next refresh's parallax test, `(age, eye)` newest first
    /// ([`EyeTrack::ages`]; at most [`EyeTrack::KEPT`] of them are used).
    pub(super) fn set_eye_track(&mut self, track: &[(f32, Vec3)]) {
        let track = &track[..track.len().min(EyeTrack::KEPT)];
        let data: Vec<[f32; 4]> = track.iter().map(|&(a, e)| [a, e.x, e.y, e.z]).collect();
        if !data.is_empty() {
            let bytes = bytemuck::cast_slice(&data);
            self.ctx.queue.write_buffer(&self.buffers.eyes, 0, bytes);
        }
        self.track = track.len() as u32;
    }

    fn write_params(&self, p: &Params) {
        self.ctx
            .queue
            .write_buffer(&self.buffers.params, 0, bytemuck::bytes_of(p));
    }

    /// Submit the work waiting to go ahead of `enc`'s ([`GpuRecon::ahead`]), then its,
    /// in one submission.
    fn submit(&mut self, enc: wgpu::CommandEncoder) {
        let mut work = std::mem::take(&mut self.ahead);
        work.push(enc.finish());
        self.ctx.queue.submit(work);
    }

    fn encoder(&self) -> wgpu::CommandEncoder {
        let d = &self.ctx.device;
        d.create_command_encoder(&wgpu::CommandEncoderDescriptor::default())
    }

    /// Encode placing, counting, scanning and listing the splats by bin, the front
    /// depths starting from the kept ones where `front` (brought up to date by work
    /// that runs ahead of this encoder's, [`GpuRecon::upload_fronts`]), else from none.
    fn encode_bins(&self, enc: &mut wgpu::CommandEncoder, count: usize, front: bool) {
        let nb = self.bins.0 as u64 * self.bins.1 as u64;
        enc.clear_buffer(&self.buffers.bins, 0, Some(nb * 4));
        match self.fronts.as_ref().filter(|_| front) {
            Some(f) => {
                let bytes = self.buffers.front.size().min(f.kept.size());
                enc.copy_buffer_to_buffer(&f.kept, 0, &self.buffers.front, 0, bytes);
            }
            None => enc.clear_buffer(&self.buffers.front, 0, None),
        }
        let groups = (count as u32).div_ceil(GROUP);
        let pl = &self.pipelines;
        self.dispatch(enc, &pl.place, (groups, 1), None);
        if self.front_levels {
            for (k, l) in self.levels.iter().enumerate() {
                let cells = (l.dst_w * l.dst_h).div_ceil(GROUP);
                self.dispatch(enc, &pl.front_pull, (cells, 1), Some(k));
            }
        }
        self.dispatch(enc, &pl.count, (groups, 1), None);
        self.dispatch(enc, &pl.scan, (1, 1), None);
        self.dispatch(enc, &pl.fill, (groups, 1), None);
    }

    /// The bins' work ([`GpuRecon::encode_bins`]) on its own, with the items listed
    /// read back.
    fn bin_pass(&mut self, count: usize, front: bool) -> Result<usize, GpuError> {
        let nb = self.bins.0 as u64 * self.bins.1 as u64;
        let mut enc = self.encoder();
        self.encode_bins(&mut enc, count, front);
        enc.copy_buffer_to_buffer(
            &self.buffers.bins,
            2 * nb * 4,
            &self.buffers.read_counts,
            0,
            4,
        );
        self.submit(enc);
        let bufs = [(&self.buffers.read_counts, 4)];
        read_timed(&self.ctx, &mut self.times, &bufs, |v| {
            first_u32(v[0]) as usize
        })
    }

    /// Sort the bins, gather, resolve and fill, then the history's `step` with one;
    /// read the image (and the sums, when carrying) back `into` the reconstructor's
    /// arrays.
    fn splat_pass(
        &mut self,
        mut enc: wgpu::CommandEncoder,
        pull_push: bool,
        step: Option<&Step>,
        keep: f32,
        mut into: ReadInto,
    ) -> Result<Readback, GpuError> {
        let n = self.width as u64 * self.height as u64;
        let nb = self.bins.0 as u64 * self.bins.1 as u64;
        self.encode_image(&mut enc, pull_push);
        // Where a failed refresh starts the CPU afresh, its coverage and splat scales
        // are of no use to it: they stay here unless asked for.
        let extras_here = self.sums_back == Some(SumsBack::Holds);
        let planes = if extras_here {
            pack::SHOWN_PLANES
        } else {
            PER_PIXEL as u64
        };
        let bytes = n * planes * 4;
        self.extras_left = false;
        let mut shown = false;
        if let (Some(h), Some(step)) = (&mut self.history, step) {
            let epoch = self.epoch.unwrap_or(step.t);
            let image = (&self.buffers.out, &self.buffers.front);
            h.encode(&self.ctx, &mut enc, step, epoch, keep, image);
            shown = true;
        }
        self.pack.encode(&mut enc, shown);
        enc.copy_buffer_to_buffer(&self.pack.planes, 0, &self.buffers.read_out, 0, bytes);
        self.encode_sums_back(&mut enc);
        // The items listed, then the holes.
        enc.copy_buffer_to_buffer(
            &self.buffers.bins,
            2 * nb * 4,
            &self.buffers.read_counts,
            0,
            8,
        );
        self.submit(enc);
        let history = self.history.as_ref().filter(|_| step.is_some());
        let mut bufs = vec![
            (&self.buffers.read_counts, 8),
            (&self.buffers.read_out, bytes),
        ];
        bufs.extend(history.map(|h| h.read_buffers()).into_iter().flatten());
        // What `encode_sums_back` copied the sums' part into.
        bufs.extend(match self.sums_back {
            Some(SumsBack::All) => self.buffers.read_acc.as_ref().map(|r| (r, r.size())),
            Some(SumsBack::Holds) => self.carry.as_ref().map(carry::GpuCarry::holds_readback),
            None => None,
        });
        let (back, w) = (self.sums_back, self.width as usize);
        let holds_kept = &mut self.holds_kept;
        let cap = self.buffers.items_cap;
        let readback = read_timed(&self.ctx, &mut self.times, &bufs, |v| {
            let listed = first_u32(v[0]) as usize;
            if listed > cap {
                // Past the bound `items_bound` proves: the image lacks splats.
                return Err(GpuError::Failed(format!(
                    "{listed} bin items listed, over the {cap} there was room for"
                )));
            }
            pack::unpack(bytemuck::cast_slice(v[1]), &mut into);
            let rest = &v[2..];
            let counts = std::mem::take(&mut into.counts);
            let history = history.map(|_| history::GpuHistory::back(rest[0], rest[1], counts));
            if let (Some(back), Some(bytes)) = (back, rest.last()) {
                carried::unpack_back(back, bytes, into.sums, w, (into.edited, holds_kept));
            }
            Ok(Readback {
                holes: first_u32(&v[0][4..]) as usize,
                history,
            })
        })??;
        self.extras_left = extras_here;
        Ok(readback)
    }

    /// Read the coverage and splat scales the last refresh left here into `coverage`
    /// and `scale` (nothing done where it left none).
    pub(super) fn read_extras(
        &mut self,
        coverage: &mut [u32],
        scale: &mut [f32],
    ) -> Result<(), GpuError> {
        if !self.extras_left {
            return Ok(());
        }
        let n = self.width as u64 * self.height as u64;
        let (from, bytes) = (pack::SHOWN_PLANES * n * 4, 2 * n * 4);
        let mut enc = self.encoder();
        let (planes, read) = (&self.pack.planes, &self.buffers.read_out);
        enc.copy_buffer_to_buffer(planes, from, read, 0, bytes);
        self.ctx.queue.submit([enc.finish()]);
        read_timed(&self.ctx, &mut self.times, &[(read, bytes)], |v| {
            pack::unpack_extras(bytemuck::cast_slice(v[0]), coverage, scale)
        })?;
        self.extras_left = false;
        Ok(())
    }

    /// Encode the image from the listed splats: each bin's list sorted into ring
    /// order, gathered per pixel, resolved, then filled (by pull-push, or from the
    /// hole pyramid).
    fn encode_image(&self, enc: &mut wgpu::CommandEncoder, pull_push: bool) {
        let pl = &self.pipelines;
        let pixels = (self.width * self.height).div_ceil(GROUP);
        self.dispatch(enc, &pl.sort, self.bins, None);
        self.dispatch(enc, &pl.gather, self.bins, None);
        self.dispatch(enc, &pl.resolve, (pixels, 1), None);
        if pull_push {
            self.pull_push(enc);
        } else {
            for (k, l) in self.levels.iter().enumerate() {
                let groups = (l.dst_w * l.dst_h).div_ceil(GROUP);
                self.dispatch(enc, &pl.pull, (groups, 1), Some(k));
            }
            self.dispatch(enc, &pl.holes, (pixels, 1), None);
        }
    }

    /// Encode the copy of what comes back of the carried sums ([`SumsBack`]), after the
    /// fills (which write only the image, so the accumulators are still the sums).
    fn encode_sums_back(&mut self, enc: &mut wgpu::CommandEncoder) {
        let (acc, bytes) = (&self.buffers.acc, self.buffers.acc.size());
        match (self.sums_back, &self.buffers.read_acc, &mut self.carry) {
            (Some(SumsBack::All), Some(r), _) => enc.copy_buffer_to_buffer(acc, 0, r, 0, bytes),
            (Some(SumsBack::Holds), _, Some(c)) => {
                c.encode_holds(&self.ctx, enc, acc, &self.buffers.pix_tile)
            }
            _ => {}
        }
    }

    /// The pull-push fill's passes: pull up every level, normalise the top, push down
    /// to the image.
    fn pull_push(&self, enc: &mut wgpu::CommandEncoder) {
        let pl = &self.pipelines;
        let groups = |w: u32, h: u32| (w * h).div_ceil(GROUP);
        for (k, l) in self.levels.iter().enumerate() {
            self.dispatch(enc, &pl.pp_pull, (groups(l.dst_w, l.dst_h), 1), Some(k));
        }
        let Some(top) = self.levels.len().checked_sub(1) else {
            return;
        };
        self.dispatch(enc, &pl.pp_top, (1, 1), Some(top));
        for k in (1..self.levels.len()).rev() {
            let l = &self.levels[k];
            self.dispatch(enc, &pl.pp_push, (groups(l.src_w, l.src_h), 1), Some(k));
        }
        self.dispatch(
            enc,
            &pl.pp_final,
            (groups(self.width, self.height), 1),
            Some(0),
        );
    }
}

/// Most bins a footprint of radius at most `max_r` touches along a side (`None`: no
/// finite bound): its first and last pixels are at most `2 max_r` apart.
fn bins_across(max_r: f32) -> Option<u64> {
    (max_r.is_finite() && max_r >= 0.0)
        .then(|| (2.0 * f64::from(max_r) / f64::from(BIN)).ceil() as u64 + 1)
}

/// `take` of the mapped `bufs` ([`GpuContext::read_mapped_all`], after all work
/// submitted), with its wait and its own time added to `times`.
fn read_timed<R>(
    ctx: &GpuContext,
    times: &mut GpuReconTimes,
    bufs: &[(&wgpu::Buffer, u64)],
    take: impl FnOnce(&[&[u8]]) -> R,
) -> Result<R, GpuError> {
    let t0 = std::time::Instant::now();
    let mut mapped = None;
    let got = ctx.read_mapped_all(bufs, None, |v| {
        mapped = Some(std::time::Instant::now());
        take(v)
    });
    let end = std::time::Instant::now();
    let mapped = mapped.unwrap_or(end);
    times.wait_s += (mapped - t0).as_secs_f64();
    times.read_s += (end - mapped).as_secs_f64();
    got
}

/// The first word of a mapped buffer, as the shaders' counters write it.
fn first_u32(b: &[u8]) -> u32 {
    bytemuck::cast_slice::<u8, u32>(&b[..4])[0]
}

/// `src` copied into `out` on every thread, reusing `out` where it has `src`'s
/// length: a refresh reads back its history's counts, megabytes at 1920×1080, and one
/// thread's copy out of the mapping (and its page faults on a new vector) was a large
/// share of the GPU reconstructor's time.
fn copy_par_into(src: &[f32], out: &mut Vec<f32>) {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 16;
    if out.len() != src.len() {
        // Zeroed pages are mapped on first write, so each thread faults in its own part.
        *out = vec![0.0; src.len()];
    }
    out.par_chunks_mut(CHUNK)
        .zip(src.par_chunks(CHUNK))
        .for_each(|(d, s)| d.copy_from_slice(s));
}

impl Buffers {
    fn new(d: &wgpu::Device, z: &Sizes, level_stride: u64) -> Self {
        let none = wgpu::BufferUsages::empty();
        let src = wgpu::BufferUsages::COPY_SRC;
        let uniform = |label: &str, size: u64| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let (n, nb, cap) = (z.pixels, z.bin_count(), z.cap);
        let image = n * PER_PIXEL as u64 * 4;
        Self {
            params: uniform("params", std::mem::size_of::<Params>() as u64),
            ring: storage(d, "ring", cap * RING_FIELDS as u64 * 4, none),
            tiles: storage(d, "tiles", 64 * std::mem::size_of::<GpuTile>() as u64, none),
            pix_tile: storage(d, "pixel tiles", n * 4, none),
            scale: storage(d, "splat scale", n * 4, none),
            splats: storage(d, "splats", cap * SPLAT_BYTES, none),
            bins: storage(d, "bins", (2 * nb + 2) * 4, src),
            bin_start: storage(d, "bin starts", (nb + 1) * 4, none),
            items: storage(d, "bin items", cap * 4, none),
            acc: storage(d, "accumulators", image, src),
            out: storage(d, "image", image, src),
            pyramid: storage(d, "pyramid", z.blocks * PER_BLOCK as u64 * 4, none),
            levels: uniform("levels", level_stride * z.levels.len().max(1) as u64),
            front: storage(d, "front depths", (2 * n + z.blocks) * 4, src),
            eyes: storage(d, "eye track", EyeTrack::KEPT as u64 * 16, none),
            read_out: readback(d, "image readback", image),
            read_counts: readback(d, "count readback", 8),
            read_acc: z
                .sums_back
                .then(|| readback(d, "accumulator readback", image)),
            tiles_cap: 64,
            items_cap: cap as usize,
        }
    }

    /// The pyramid level's parameters, one at each dynamic offset.
    fn level_bind_group(
        &self,
        d: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
    ) -> wgpu::BindGroup {
        d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("level"),
            layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &self.levels,
                    offset: 0,
                    size: wgpu::BufferSize::new(std::mem::size_of::<Level>() as u64),
                }),
            }],
        })
    }

    fn bind_group(&self, device: &wgpu::Device, layout: &wgpu::BindGroupLayout) -> wgpu::BindGroup {
        let buffers = [
            &self.params,
            &self.ring,
            &self.tiles,
            &self.pix_tile,
            &self.scale,
            &self.splats,
            &self.bins,
            &self.bin_start,
            &self.items,
            &self.acc,
            &self.out,
            &self.pyramid,
            &self.front,
            &self.eyes,
        ];
        bind_buffers(device, layout, "reconstructor", &buffers)
    }
}

/// A bind group of whole `buffers` at bindings 0, 1, 2, …
fn bind_buffers(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A buffer at `binding` of a compute shader.
fn buffer_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
    dynamic: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

/// The layout of a uniform at binding 0 and `storage` buffers after it (read-only
/// where `read_only` lists them).
fn uniform_and_storage(
    device: &wgpu::Device,
    label: &str,
    storage: u32,
    read_only: &[u32],
) -> wgpu::BindGroupLayout {
    let mut entries = vec![buffer_entry(0, wgpu::BufferBindingType::Uniform, false)];
    for b in 1..=storage {
        let read_only = read_only.contains(&b);
        entries.push(buffer_entry(
            b,
            wgpu::BufferBindingType::Storage { read_only },
            false,
        ));
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

/// The compute pipeline of `module`'s entry point `name`.
fn compute_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    name: &str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(name),
        layout: Some(layout),
        module,
        entry_point: Some(name),
        compilation_options: Default::default(),
        cache: None,
    })
}

impl Pipelines {
    fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("recon.wgsl"),
            source: wgpu::ShaderSource::Wgsl(recon_source().into()),
        });
        // The ring and the tile filters are only read.
        let layout0 = uniform_and_storage(device, "reconstructor", STORAGE_BUFFERS, &[1, 2, 13]);
        let layout1 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("level"),
            entries: &[buffer_entry(0, wgpu::BufferBindingType::Uniform, true)],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("reconstructor"),
            bind_group_layouts: &[Some(&layout0), Some(&layout1)],
            immediate_size: 0,
        });
        let make = |name: &str| compute_pipeline(device, &layout, &module, name);
        Self {
            paint: make("paint_tiles"),
            place: make("place"),
            count: make("count"),
            scan: make("scan"),
            fill: make("fill"),
            sort: make("sort"),
            gather: make("gather"),
            resolve: make("resolve"),
            pull: make("pull"),
            front_pull: make("front_pull"),
            holes: make("holes"),
            pp_pull: make("pp_pull"),
            pp_top: make("pp_top"),
            pp_push: make("pp_push"),
            pp_final: make("pp_final"),
            layout0,
            layout1,
        }
    }
}

#[cfg(test)]
mod bound_tests {
    use super::{bins_across, BIN};
    use proptest::prelude::*;

    proptest! {
        /// A footprint spans `ceil(x − ½ − r)` to `floor(x − ½ + r)` in f32, as the
        /// placing shader computes it, clipped to the image: the bins it lists along a
        /// side never outnumber the bound the one-submission refresh sizes its items by.
        #[test]
        fn no_footprint_touches_more_bins_than_the_bound(
            x in -20.0f32..5000.0,
            max_r in 0.0f32..80.0,
            share in 0.0f32..=1.0,
        ) {
            let r = max_r * share;
            let w = 4096.0f32;
            let x0 = (x - 0.5 - r).ceil().max(0.0);
            let x1 = (x - 0.5 + r).floor().min(w);
            prop_assume!(x0 <= x1);
            let bins = (x1 as u32 / BIN - x0 as u32 / BIN + 1) as u64;
            prop_assert!(bins <= bins_across(max_r).unwrap(), "{bins} bins");
        }
    }

    #[test]
    fn no_bound_without_a_finite_radius() {
        assert_eq!(bins_across(f32::INFINITY), None);
        assert_eq!(bins_across(f32::NAN), None);
        assert_eq!(bins_across(8.0), Some(2));
    }
}

#[cfg(test)]
mod copy_tests {
    #[test]
    fn a_parallel_copy_keeps_every_float_in_order() {
        // Chunks of 2^16 floats, the last one short.
        let src: Vec<f32> = (0..(3 << 16) + 123).map(|i| i as f32 * 0.5).collect();
        let mut out = Vec::new();
        super::copy_par_into(&src, &mut out);
        assert_eq!(out, src);
        // Reused at the same length: every float written again.
        let again: Vec<f32> = src.iter().map(|x| x + 1.0).collect();
        super::copy_par_into(&again, &mut out);
        assert_eq!(out, again);
        super::copy_par_into(&[], &mut out);
        assert!(out.is_empty());
    }
}
