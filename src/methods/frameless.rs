//! Traditional frameless rendering (Bishop et al. 1994): pixels in random order, each
//! sample traced at its own time, the display shows the newest sample at every pixel.
//!
//! The order is a fresh random permutation of all pixels per pass (keyed by the seed and
//! the pass number), so every pixel is refreshed once per `W·H/R` seconds. Samples go
//! through pixel centers.

use super::{any_rate, Budget, Displayed, Method, MethodContext, MethodInfo};
use crate::{
    image::Image,
    sampling::Rng,
    trace::{
        batch::{self, GpuRays},
        Tracer,
    },
};

/// `traditional-frameless`.
pub const TRADITIONAL_FRAMELESS: MethodInfo = MethodInfo {
    name: "traditional-frameless",
    description: "random pixel order, each sample at its own time, newest sample per pixel",
    budget: Budget::Rate,
    check_rate: any_rate,
    build: |ctx| Ok(Box::new(Traditional::new(ctx))),
};

/// The traditional frameless renderer.
pub struct Traditional {
    ctx: MethodContext,
    newest: NewestSamples,
    next_sample: u64,
    pass: u64,
    order: Vec<u32>,
    trace_s: f64,
}

/// The pixel permutation of pass `pass`.
fn permutation(n: u32, seed: u64, pass: u64) -> Vec<u32> {
    let mut order: Vec<u32> = (0..n).collect();
    Rng::new(&[seed, 0xf4a3e1e55, pass]).shuffle(&mut order);
    order
}

impl Traditional {
    /// Create for one run.
    pub fn new(ctx: &MethodContext) -> Self {
        let (w, h) = ctx.tracer.size();
        let n = w * h;
        Self {
            ctx: ctx.clone(),
            newest: NewestSamples::new(w, h, ctx.clock.start),
            next_sample: 0,
            pass: 0,
            order: permutation(n, ctx.seed, 0),
            trace_s: 0.0,
        }
    }

    fn pixel_of(&mut self, i: u64) -> u32 {
        let n = self.order.len() as u64;
        let pass = i / n;
        if pass != self.pass {
            self.pass = pass;
            self.order = permutation(n as u32, self.ctx.seed, pass);
        }
        self.order[(i % n) as usize]
    }
}

/// Trace a batch of `(pixel, time)` samples that share one scene state, on the GPU
/// tracer when there is one.
pub(crate) fn trace_batch(
    tracer: &Tracer,
    rays: Option<&GpuRays>,
    time: f64,
    pixels: &[u32],
) -> Vec<glam::Vec3> {
    let state = tracer.state_at(time);
    let w = tracer.size().0;
    let points: Vec<[f32; 2]> = pixels
        .iter()
        .map(|&p| [(p % w) as f32 + 0.5, (p / w) as f32 + 0.5])
        .collect();
    batch::trace_colours(tracer, rays, &state, &points)
}

impl Method for Traditional {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        let end = self.ctx.clock.samples_until(t);
        let n = self.order.len() as u64;
        let tracer = self.ctx.tracer.clone();
        let clock = self.ctx.clock;
        let mut trace_s = 0.0;
        // Batches share one quantized scene state and lie within one pass, so their
        // pixels are distinct and can be written in any order.
        while self.next_sample < end {
            let i0 = self.next_sample;
            let key = Tracer::quantize(clock.sample_time(i0));
            let pass_end = (i0 / n + 1) * n;
            let mut i1 = i0 + 1;
            let limit = end.min(pass_end);
            // Samples per state are few hundred at most at the paper's rates: a linear
            // scan is cheaper than solving for the boundary and exact about rounding.
            while i1 < limit && Tracer::quantize(clock.sample_time(i1)) == key {
                i1 += 1;
            }
            self.pixel_of(i0); // make sure `order` is this pass's permutation
            let (a, b) = ((i0 % n) as usize, ((i1 - 1) % n) as usize + 1);
            let t0 = std::time::Instant::now();
            let colors = trace_batch(
                &tracer,
                self.ctx.rays.as_deref(),
                clock.sample_time(i0),
                &self.order[a..b],
            );
            trace_s += t0.elapsed().as_secs_f64();
            for (k, (&p, c)) in self.order[a..b].iter().zip(colors).enumerate() {
                self.newest.set(p, c, clock.sample_time(i0 + k as u64));
            }
            self.next_sample = i1;
        }
        self.trace_s += trace_s;
        Displayed {
            image: &self.newest.image,
            mean_age: self.newest.mean_age(t),
        }
    }

    fn samples_used(&self) -> u64 {
        self.next_sample
    }
    fn trace_seconds(&self) -> f64 {
        self.trace_s
    }
}

/// The newest sample at every pixel, and when the information each pixel shows was
/// traced: what a frameless display shows. Used by [`Traditional`] and by the real-time
/// traditional frameless method.
pub struct NewestSamples {
    /// The newest sample's colour at every pixel.
    pub image: Image,
    info_time: Vec<f64>,
}

impl NewestSamples {
    /// A black `w × h` image whose pixels all show information from time `info_time`
    /// (NaN: no information yet).
    pub fn new(w: u32, h: u32, info_time: f64) -> Self {
        Self {
            image: Image::new(w, h),
            info_time: vec![info_time; (w * h) as usize],
        }
    }

    /// Pixel `p` (row-major) now shows colour `c`, traced at time `t`.
    #[inline]
    pub fn set(&mut self, p: u32, c: glam::Vec3, t: f64) {
        self.image.pixels[p as usize] = c;
        self.info_time[p as usize] = t;
    }

    /// Every sample of `batches` (pixel, colour, time), leaving each pixel as
    /// [`NewestSamples::set`] called on them one after another in their order would:
    /// the image is split into as many bands of pixels as the thread pool has
    /// threads, and each band takes, in order, the samples that fall in it (a
    /// real-time display gets hundreds of thousands a refresh from a GPU tracer; each
    /// band reads every sample, so the caller decides when there are enough).
    pub fn set_batches(&mut self, batches: &[Vec<(u32, glam::Vec3, f64)>]) {
        use rayon::prelude::*;
        let n = self.info_time.len();
        let threads = rayon::current_num_threads();
        if threads <= 1 {
            for &(p, c, t) in batches.iter().flatten() {
                self.set(p, c, t);
            }
            return;
        }
        let band = n.div_ceil(threads).max(1);
        self.image
            .pixels
            .par_chunks_mut(band)
            .zip(self.info_time.par_chunks_mut(band))
            .enumerate()
            .for_each(|(b, (colour, time))| {
                let lo = b * band;
                for &(p, c, t) in batches.iter().flatten() {
                    if let Some(i) = (p as usize).checked_sub(lo).filter(|&i| i < time.len()) {
                        colour[i] = c;
                        time[i] = t;
                    }
                }
            });
    }

    /// When pixel `p`'s information was traced (NaN before its first sample).
    pub fn info_time(&self, p: usize) -> f64 {
        self.info_time.get(p).copied().unwrap_or(f64::NAN)
    }

    /// [`NewestSamples::mean_age`] on every thread of the pool, summed in chunks (so
    /// not to the same rounding, nor the same on every run): for a real-time display.
    pub fn mean_age_on_every_core(&self, t: f64) -> f64 {
        use rayon::prelude::*;
        const CHUNK: usize = 1 << 16;
        let (count, sum) = self
            .info_time
            .par_chunks(CHUNK)
            .map(|c| {
                let informed = c.iter().filter(|s| s.is_finite());
                informed.fold((0usize, 0.0), |(k, a), &s| (k + 1, a + (t - s)))
            })
            .reduce(|| (0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        if count == 0 {
            return f64::NAN;
        }
        sum / count as f64
    }

    /// Mean age at time `t` of the information of the pixels that have some (NaN when
    /// none has), summed in pixel order.
    pub fn mean_age(&self, t: f64) -> f64 {
        let informed = || self.info_time.iter().filter(|s| s.is_finite());
        let n = informed().count();
        if n == 0 {
            return f64::NAN;
        }
        informed().map(|&s| t - s).sum::<f64>() / n as f64
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::NewestSamples;

    #[test]
    fn batches_set_on_many_threads_leave_what_one_after_another_leaves() {
        // Enough samples to go parallel, many on the same pixels, on 1, 2 and 3
        // threads (the bands then end mid-row).
        let (w, h) = (37, 23);
        let n = w * h;
        let mut rng = crate::sampling::Rng::new(&[5]);
        let batches: Vec<Vec<(u32, Vec3, f64)>> = (0..40)
            .map(|b| {
                (0..1000)
                    .map(|i| {
                        let p = rng.below(n);
                        let t = (b * 1000 + i) as f64 * 1e-3;
                        (p, Vec3::splat(rng.uniform()), t)
                    })
                    .collect()
            })
            .collect();
        let mut one = NewestSamples::new(w, h, f64::NAN);
        for &(p, c, t) in batches.iter().flatten() {
            one.set(p, c, t);
        }
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut many = NewestSamples::new(w, h, f64::NAN);
            pool.install(|| many.set_batches(&batches));
            assert_eq!(many.image.pixels, one.image.pixels, "{threads} threads");
            for i in 0..n as usize {
                let (a, b) = (many.info_time(i), one.info_time(i));
                assert_eq!(a.to_bits(), b.to_bits(), "{threads} threads, pixel {i}");
            }
        }
    }
}
