//! Adaptive frameless rendering (Dayal et al. 2005): the closed-loop sampler over a K-D
//! tiling of a temporally deep buffer. Until the adaptive reconstructor lands, the
//! display shows the newest sample at each pixel (holes filled from the nearest sampled
//! neighbour), i.e. traditional frameless display of adaptively placed samples.

pub mod deep_buffer;
pub mod params;
pub mod sampler;
pub mod tiling;
pub mod vis;

use super::{mean_age, Displayed, Method, MethodContext};
use crate::image::Image;
pub use params::SamplerParams;
pub use sampler::Sampler;

/// The `adaptive` method of the evaluation.
pub struct Adaptive {
    sampler: Sampler,
    image: Image,
    info_time: Vec<f64>,
    sampled: Vec<bool>,
    shown: Image,
}

impl Adaptive {
    /// Create for one run with the given sampler parameters.
    pub fn new(ctx: &MethodContext, params: SamplerParams) -> Result<Self, String> {
        let (w, h) = ctx.tracer.size();
        Ok(Self {
            sampler: Sampler::new(ctx.tracer.clone(), ctx.clock, params, ctx.seed)?,
            image: Image::new(w, h),
            info_time: vec![ctx.clock.start; (w * h) as usize],
            sampled: vec![false; (w * h) as usize],
            shown: Image::new(w, h),
        })
    }

    /// The sampler (for visualisations and statistics).
    pub fn sampler(&self) -> &Sampler {
        &self.sampler
    }
}

/// Fill unsampled pixels from the nearest sampled one (growing rings, up to `max_r`).
pub fn fill_holes(img: &Image, sampled: &[bool], max_r: i32) -> Image {
    let (w, h) = (img.width as i32, img.height as i32);
    let mut out = img.clone();
    for y in 0..h {
        for x in 0..w {
            if sampled[(y * w + x) as usize] {
                continue;
            }
            'search: for r in 1..=max_r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs() != r && dy.abs() != r {
                            continue;
                        }
                        let (sx, sy) = (x + dx, y + dy);
                        if sx >= 0 && sy >= 0 && sx < w && sy < h && sampled[(sy * w + sx) as usize]
                        {
                            out.pixels[(y * w + x) as usize] = img.pixels[(sy * w + sx) as usize];
                            break 'search;
                        }
                    }
                }
            }
        }
    }
    out
}

impl Method for Adaptive {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        self.sampler.run_until(t);
        let w = self.image.width;
        for s in self.sampler.drain_stream() {
            let (x, y) = (s.x as u32, s.y as u32);
            if x < w && y < self.image.height {
                let i = (y * w + x) as usize;
                if s.t >= self.info_time[i] || !self.sampled[i] {
                    self.image.pixels[i] = s.sample.color;
                    self.info_time[i] = s.t;
                    self.sampled[i] = true;
                }
            }
        }
        self.shown = fill_holes(&self.image, &self.sampled, 8);
        Displayed {
            image: &self.shown,
            mean_age: mean_age(&self.info_time, t),
        }
    }

    fn samples_used(&self) -> u64 {
        self.sampler.samples_used()
    }

    fn trace_seconds(&self) -> f64 {
        self.sampler.timing().0
    }
}
