//! Traditional frameless rendering (Bishop et al. 1994): pixels in random order, each
//! sample traced at its own time, the display shows the newest sample at every pixel.
//!
//! The order is a fresh random permutation of all pixels per pass (keyed by the seed and
//! the pass number), so every pixel is refreshed once per `W·H/R` seconds. Samples go
//! through pixel centers.

use rayon::prelude::*;

use super::{mean_age, Displayed, Method, MethodContext};
use crate::{image::Image, sampling::Rng, trace::Tracer};

/// The traditional frameless renderer.
pub struct Traditional {
    ctx: MethodContext,
    image: Image,
    info_time: Vec<f64>,
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
            image: Image::new(w, h),
            info_time: vec![ctx.clock.start; n as usize],
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

/// Trace a batch of `(pixel, time)` samples that share one scene state.
pub(crate) fn trace_batch(tracer: &Tracer, time: f64, pixels: &[u32]) -> Vec<glam::Vec3> {
    let state = tracer.state_at(time);
    let w = tracer.size().0;
    pixels
        .par_iter()
        .with_min_len(256)
        .map(|&p| {
            tracer
                .sample(&state, (p % w) as f32 + 0.5, (p / w) as f32 + 0.5)
                .color
        })
        .collect()
}

impl Method for Traditional {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        let end = self.ctx.clock.samples_until(t);
        // Samples are traced in batches sharing a quantized scene state; results are
        // written in sample order, so a later sample of the same pixel wins.
        let mut batch: Vec<(u32, f64)> = Vec::new();
        let mut batch_key = None;
        let tracer = self.ctx.tracer.clone();
        let mut trace_s = 0.0;
        let mut flush = |batch: &mut Vec<(u32, f64)>, image: &mut Image, info: &mut [f64]| {
            if batch.is_empty() {
                return;
            }
            let pixels: Vec<u32> = batch.iter().map(|(p, _)| *p).collect();
            let t0 = std::time::Instant::now();
            let colors = trace_batch(&tracer, batch[0].1, &pixels);
            trace_s += t0.elapsed().as_secs_f64();
            for ((p, ts), c) in batch.iter().zip(colors) {
                image.pixels[*p as usize] = c;
                info[*p as usize] = *ts;
            }
            batch.clear();
        };
        while self.next_sample < end {
            let i = self.next_sample;
            let ts = self.ctx.clock.sample_time(i);
            let key = Tracer::quantize(ts);
            if batch_key != Some(key) {
                flush(&mut batch, &mut self.image, &mut self.info_time);
                batch_key = Some(key);
            }
            let p = self.pixel_of(i);
            batch.push((p, ts));
            self.next_sample += 1;
        }
        flush(&mut batch, &mut self.image, &mut self.info_time);
        self.trace_s += trace_s;
        Displayed {
            image: &self.image,
            mean_age: mean_age(&self.info_time, t),
        }
    }

    fn samples_used(&self) -> u64 {
        self.next_sample
    }
    fn trace_seconds(&self) -> f64 {
        self.trace_s
    }
}
