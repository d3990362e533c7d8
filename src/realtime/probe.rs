//! The smallest real-time method, compiled for the tests only: its sampling threads
//! trace nothing and count batches, and every image is a flat grey. It is what adding
//! a method takes (this file and its line in the registry) and shows that the pipeline
//! runs a method it knows nothing about.

use std::{sync::atomic::Ordering, time::Duration};

use crossbeam_channel::{bounded, Receiver};
use glam::Vec3;

use super::{
    config::RealtimeError,
    shared::{display_only, Built, ImageBuilder, MethodInfo, Spawner},
};
use crate::image::Image;

/// The grey every image shows.
const GREY: f32 = 0.25;

pub(crate) const METHOD: MethodInfo = MethodInfo {
    name: "probe",
    about: "a flat grey image (tests only)",
    default_sampling_threads: |cores| cores.min(2),
    extra_threads: |_| 0,
    check_size: display_only,
    start,
};

fn start(sp: &mut Spawner<'_>) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
    let s = sp.shared().clone();
    let (tx, rx) = bounded(64);
    let s1 = s.clone();
    sp.sampling_threads(tx, move |_, tx| {
        while !s1.stopped() {
            s1.samples.fetch_add(1, Ordering::Relaxed);
            if tx.send(1u64).is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    })?;
    let (w, h) = s.tracer.size();
    Ok(Box::new(Builder {
        rx,
        size: (w, h),
        batches: 0,
    }))
}

struct Builder {
    rx: Receiver<u64>,
    size: (u32, u32),
    batches: u64,
}

impl ImageBuilder for Builder {
    fn build(&mut self, t: f64) -> Option<Built> {
        self.batches += self.rx.try_iter().sum::<u64>();
        let mut image = Image::new(self.size.0, self.size.1);
        image.pixels.fill(Vec3::splat(GREY));
        Some(Built {
            image,
            mean_age: 0.0,
            tiling: None,
            ages: vec![0.0],
            view_time: t,
        })
    }

    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![("probe_batches", self.batches.into())]
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::{
        realtime::{Pipeline, RtConfig, RtMethod},
        scene::builtin,
        trace::{TraceOptions, Tracer},
    };

    #[test]
    fn the_pipeline_runs_a_method_it_knows_nothing_about() {
        let scene = Arc::new(builtin::load("toycar").unwrap());
        let tracer = Arc::new(Tracer::new(scene, 16, 8, TraceOptions::default()));
        let mut config = RtConfig::new(RtMethod::Probe);
        config.sampling_threads = 2;
        let p = Pipeline::start(tracer, config).unwrap();
        std::thread::sleep(Duration::from_millis(300));
        let frame = p.latest().expect("an image within 0.3 s");
        assert!(frame.image.pixels.iter().all(|&c| c == Vec3::splat(GREY)));
        let stats = p.stop().unwrap();
        assert_eq!(stats.method, "probe");
        assert!(stats.samples > 0 && stats.images_per_s > 0.0, "{stats:?}");
        // Its own figure, under its own name, beside every method's.
        let batches = stats.method_stats["probe_batches"].as_u64().unwrap();
        assert!(batches > 0 && batches <= stats.samples, "{batches}");
    }
}
