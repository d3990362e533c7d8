//! Still images by stratified supersampling: the reference ("ideal") renderer.
//!
//! Each pixel averages `spp` stratified samples with a box filter, all at the same
//! instant (no motion blur). Sample positions depend only on `(seed, pixel)`, so the
//! image is identical whatever the thread count.

use rayon::prelude::*;

use crate::{
    image::Image,
    sampling::{stratified, Rng},
    trace::{SceneState, Tracer},
};

/// Render the image at time `t` with `spp` samples per pixel. `progress` is called with
/// the number of rows finished so far (from any thread).
pub fn render(
    tracer: &Tracer,
    t: f64,
    spp: u32,
    seed: u64,
    progress: &(dyn Fn(u32) + Sync),
) -> Image {
    let (w, h) = tracer.size();
    let state = tracer.state_at(t);
    let done = std::sync::atomic::AtomicU32::new(0);
    let rows: Vec<Vec<glam::Vec3>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let row = (0..w)
                .map(|x| pixel(tracer, &state, x, y, spp, seed))
                .collect();
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            row
        })
        .collect();
    Image {
        width: w,
        height: h,
        pixels: rows.into_iter().flatten().collect(),
    }
}

/// [`render`] on a run's tracer: on the GPU tracer `rays` where there is one and it
/// works, else on the CPU's threads; and whether the GPU traced it.
pub fn render_on(
    tracer: &Tracer,
    rays: Option<&crate::trace::batch::GpuRays>,
    t: f64,
    spp: u32,
    seed: u64,
) -> (Image, bool) {
    #[cfg(feature = "gpu")]
    if let Some(img) = rays.and_then(|g| g.with(|gpu| render_gpu(gpu, tracer, t, spp, seed))) {
        return (img, true);
    }
    #[cfg(not(feature = "gpu"))]
    let _ = rays;
    (render(tracer, t, spp, seed, &|_| {}), false)
}

/// Samples of one GPU dispatch of [`render_gpu`], about.
#[cfg(feature = "gpu")]
const GPU_BATCH: usize = 1 << 22;

/// [`render`] on the GPU tracer: the same samples of every pixel, traced in batches of
/// whole rows and averaged in the same order, so the image differs from the CPU's only
/// where a sample's colour does.
#[cfg(feature = "gpu")]
pub fn render_gpu(
    gpu: &mut crate::trace::gpu::GpuTracer,
    tracer: &Tracer,
    t: f64,
    spp: u32,
    seed: u64,
) -> Result<Image, crate::trace::gpu::GpuTraceError> {
    use rayon::prelude::*;
    let (w, h) = tracer.size();
    let state = tracer.state_at(t);
    let rows = (GPU_BATCH / (w as usize * spp.max(1) as usize)).max(1) as u32;
    let mut pixels = Vec::with_capacity(w as usize * h as usize);
    for y0 in (0..h).step_by(rows as usize) {
        // Each row's points and each pixel's count of them, made on every thread.
        let made: Vec<(Vec<[f32; 2]>, Vec<usize>)> = (y0..(y0 + rows).min(h))
            .into_par_iter()
            .map(|y| {
                let (mut points, mut counts) = (Vec::new(), Vec::with_capacity(w as usize));
                for x in 0..w {
                    let pts = pixel_samples(x, y, spp, seed);
                    counts.push(pts.len());
                    points.extend(pts.iter().map(|(dx, dy)| [x as f32 + dx, y as f32 + dy]));
                }
                (points, counts)
            })
            .collect();
        let points: Vec<[f32; 2]> = made.iter().flat_map(|(p, _)| p.iter().copied()).collect();
        let got = gpu.colours(tracer, &state, &points)?;
        let mut starts = Vec::with_capacity(made.len());
        let mut at = 0;
        for (p, _) in &made {
            starts.push(at);
            at += p.len();
        }
        let rows_px: Vec<Vec<glam::Vec3>> = made
            .par_iter()
            .zip(starts)
            .map(|((_, counts), mut at)| {
                counts
                    .iter()
                    .map(|&n| {
                        let sum: glam::Vec3 = got[at..at + n].iter().sum();
                        at += n;
                        sum / n as f32
                    })
                    .collect()
            })
            .collect();
        pixels.extend(rows_px.into_iter().flatten());
    }
    Ok(Image {
        width: w,
        height: h,
        pixels,
    })
}

/// The sub-pixel positions of pixel `(x, y)`'s samples.
fn pixel_samples(x: u32, y: u32, spp: u32, seed: u64) -> Vec<(f32, f32)> {
    let mut rng = Rng::new(&[seed, 0x5717, x as u64, y as u64]);
    stratified::unit_square(spp, &mut rng)
}

/// Pixel `(x, y)` of [`render`]'s image, for callers that schedule the rows themselves
/// (to stop between them): the same samples, so the same value.
pub fn pixel(
    tracer: &Tracer,
    state: &SceneState,
    x: u32,
    y: u32,
    spp: u32,
    seed: u64,
) -> glam::Vec3 {
    let pts = pixel_samples(x, y, spp, seed);
    let sum: glam::Vec3 = pts
        .iter()
        .map(|(dx, dy)| tracer.sample(state, x as f32 + dx, y as f32 + dy).color)
        .sum();
    sum / pts.len() as f32
}

/// The GPU tracer's ideal image against the CPU's (needs a GPU adapter; lavapipe in CI).
#[cfg(all(test, feature = "gpu"))]
mod gpu_tests {
    use std::sync::Arc;

    use super::*;
    use crate::{
        gpu::GpuContext,
        settings::{ReconDevice, IDEAL_SPP},
        trace::{gpu::GpuTracer, TraceOptions},
    };

    /// A quarter of an 8-bit level, on at least 99.9% of the pixels: issue 48's
    /// criteria for samples, held to pixels here.
    const MAX_DIFF: f32 = 0.25 / 255.0;
    const SAME: f64 = 0.999;

    #[test]
    #[ignore = "needs a GPU adapter (lavapipe in CI)"]
    fn gpu_trace_ideal_image_matches_the_cpu() {
        let ctx = match GpuContext::acquire(ReconDevice::Gpu) {
            Ok(Some(c)) => c,
            Ok(None) => panic!("--trace gpu gave no adapter"),
            Err(e) => panic!("{e}"),
        };
        let scene = crate::scene::builtin::load("toycar").expect("built-in");
        let tracer = Tracer::new(Arc::new(scene), 64, 48, TraceOptions::default());
        let mut gpu = GpuTracer::new(ctx, &tracer).expect("GPU tracer");
        let got = render_gpu(&mut gpu, &tracer, 1.5, IDEAL_SPP, 7).expect("GPU ideal");
        let want = render(&tracer, 1.5, IDEAL_SPP, 7, &|_| {});
        let off = got
            .pixels
            .iter()
            .zip(&want.pixels)
            .filter(|(g, c)| (**g - **c).abs().max_element() > MAX_DIFF)
            .count();
        let allowed = ((1.0 - SAME) * want.pixels.len() as f64).floor() as usize;
        assert!(
            off <= allowed,
            "{off} of {} pixels differ",
            want.pixels.len()
        );
    }
}
