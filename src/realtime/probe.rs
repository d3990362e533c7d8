//! The smallest real-time method, compiled for the tests only: its sampling threads
//! trace nothing and count batches, and every image is a flat grey of the level its one
//! setting asks for. It is what adding a method takes (this file, its settings type
//! included, its line in the registry and its `mod` line) and shows that the pipeline
//! runs a method it knows nothing about.

use std::{sync::atomic::Ordering, time::Duration};

use crossbeam_channel::{bounded, Receiver};
use glam::Vec3;

use super::{
    config::RealtimeError,
    shared::{display_only, BuildAt, Built, ImageBuilder, MethodInfo, MethodSettings, Spawner},
};
use crate::image::Image;

/// The probe's own setting.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeSettings {
    /// The grey every image shows, 0 to 1.
    pub grey: f32,
}

impl Default for ProbeSettings {
    fn default() -> Self {
        Self { grey: 0.25 }
    }
}

impl MethodSettings for ProbeSettings {
    fn validate(&self) -> Result<(), RealtimeError> {
        if !(0.0..=1.0).contains(&self.grey) {
            return Err(RealtimeError::Config(format!(
                "probe grey {} out of range 0..=1",
                self.grey
            )));
        }
        Ok(())
    }
}

pub(crate) const METHOD: MethodInfo<ProbeSettings> = MethodInfo {
    name: "probe",
    about: "a flat grey image (tests only)",
    default_sampling_threads: |cores| cores.min(2),
    extra_threads: |_| 0,
    overlays: &[],
    traces_on_gpu: false,
    check_size: display_only,
    start,
};

fn start(
    sp: &mut Spawner<'_>,
    settings: &ProbeSettings,
) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
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
        grey: settings.grey,
        batches: 0,
        spare: None,
        recycled: 0,
    }))
}

struct Builder {
    rx: Receiver<u64>,
    size: (u32, u32),
    grey: f32,
    batches: u64,
    /// An image the pipeline gave back, built in again; how many came back.
    spare: Option<Image>,
    recycled: u64,
}

impl ImageBuilder for Builder {
    fn build(&mut self, at: BuildAt) -> Option<Built> {
        self.batches += self.rx.try_iter().sum::<u64>();
        let mut image = self
            .spare
            .take()
            .unwrap_or_else(|| Image::new(self.size.0, self.size.1));
        image.pixels.fill(Vec3::splat(self.grey));
        Some(Built {
            image,
            mean_age: 0.0,
            overlays: None,
            ages: vec![0.0],
            view_time: at.now,
        })
    }

    fn recycle(&mut self, image: Image) {
        self.recycled += 1;
        self.spare = Some(image);
    }

    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![
            ("probe_batches", self.batches.into()),
            ("probe_recycled", self.recycled.into()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::{
        realtime::{config::RtConfig, pipeline::Pipeline, registry::RtSettings},
        scene::builtin,
        trace::{TraceOptions, Tracer},
    };

    fn tracer() -> Arc<Tracer> {
        let scene = Arc::new(builtin::load("toycar").unwrap());
        Arc::new(Tracer::new(scene, 16, 8, TraceOptions::default()))
    }

    fn config() -> RtConfig {
        let mut config = RtConfig::new(crate::realtime::registry::RtMethod::Probe);
        config.sampling_threads = 2;
        config
    }

    #[test]
    fn the_pipeline_runs_a_method_it_knows_nothing_about() {
        let settings = RtSettings::Probe(ProbeSettings { grey: 0.5 });
        let p = Pipeline::start(tracer(), config(), settings).unwrap();
        std::thread::sleep(Duration::from_millis(300));
        let frame = p.latest().expect("an image within 0.3 s");
        assert!(frame.image.pixels.iter().all(|&c| c == Vec3::splat(0.5)));
        let stats = p.stop().unwrap();
        assert_eq!(stats.method, "probe");
        assert!(stats.samples > 0 && stats.images_per_s > 0.0, "{stats:?}");
        // Its own figure, under its own name, beside every method's.
        let batches = stats.method_stats["probe_batches"].as_u64().unwrap();
        assert!(batches > 0 && batches <= stats.samples, "{batches}");
        // Images nothing shows any more come back to be built in again.
        let recycled = stats.method_stats["probe_recycled"].as_u64().unwrap();
        let images = (stats.images_per_s * stats.seconds).round() as u64;
        assert!(recycled > 0 && recycled < images, "{recycled} of {images}");
    }

    #[test]
    fn its_setting_is_checked_before_a_thread_starts() {
        let settings = RtSettings::Probe(ProbeSettings { grey: 2.0 });
        let err = Pipeline::start(tracer(), config(), settings).err().unwrap();
        assert!(
            err.to_string().contains("probe grey 2 out of range"),
            "{err}"
        );
    }
}
