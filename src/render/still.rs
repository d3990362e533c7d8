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
    let mut rng = Rng::new(&[seed, 0x5717, x as u64, y as u64]);
    let pts = stratified::unit_square(spp, &mut rng);
    let sum: glam::Vec3 = pts
        .iter()
        .map(|(dx, dy)| tracer.sample(state, x as f32 + dx, y as f32 + dy).color)
        .sum();
    sum / pts.len() as f32
}
