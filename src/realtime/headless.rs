//! The headless mode: the real-time pipeline for a number of wall-clock seconds with
//! a display loop that presents at the refresh rate but draws nowhere; writes a few
//! displayed images and `stats.json`. Input is the scene's own animation or a camera
//! path given to the tracer.

use std::{path::PathBuf, sync::Arc, time::Instant};

use super::{
    config::{RealtimeError, RtConfig},
    machine::{load_average, process_cpu_seconds},
    pacing::{DisplayStats, Pacer},
    pipeline::{Frame, Pipeline, PipelineStats},
    registry::RtSettings,
};
use crate::trace::Tracer;

/// Settings of a headless run.
#[derive(Clone, Debug)]
pub struct HeadlessOptions {
    /// Wall-clock seconds to run.
    pub seconds: f64,
    /// Output directory.
    pub out: PathBuf,
    /// Displayed images to write, evenly spaced over the run.
    pub images: usize,
    /// Scene name (recorded in the statistics).
    pub scene: String,
    /// Turn the camera by [`STEP_YAW_DEG`] this many seconds into the run, to measure
    /// how long the display takes to show it ([`CameraStep`]).
    pub camera_step_s: Option<f64>,
}

/// How far the scripted camera step turns the view, degrees about its up vector.
pub const STEP_YAW_DEG: f32 = 20.0;

/// The latency of a scripted camera step: from the moment the camera turned (wall
/// clock) to the display showing it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CameraStep {
    /// Seconds into the run when the camera turned.
    pub at_s: f64,
    /// How far it turned, degrees.
    pub yaw_deg: f32,
    /// Until the first displayed image built after the step, ms: the pipeline's delay
    /// (`null`: none within the run).
    pub first_image_ms: Option<f64>,
    /// Until the first displayed image seen from the turned camera, ms (`null`: none
    /// within the run, or a method whose pixels each keep their own sample's camera,
    /// as traditional frameless).
    pub view_ms: Option<f64>,
    /// Until the first displayed image in which at least half the pixels show
    /// information traced after the step, ms: when the change is what the viewer sees
    /// (`null`: not within the run).
    pub half_new_ms: Option<f64>,
    /// Samples delivered between the step and that image (`null` with
    /// `half_new_ms`): the same latency in the run's own progress, which a machine
    /// busy with other work slows in wall time but not in samples.
    pub half_new_samples: Option<u64>,
}

/// The camera `cam` turned by `deg` about its up vector.
fn yawed(cam: crate::scene::Camera, deg: f32) -> crate::scene::Camera {
    let axis = cam.up.normalize_or(glam::Vec3::Y);
    let turn = glam::Quat::from_axis_angle(axis, deg.to_radians());
    crate::scene::Camera {
        at: cam.eye + turn * (cam.at - cam.eye),
        ..cam
    }
}

/// What `stats.json` holds.
#[derive(Clone, Debug, serde::Serialize)]
pub struct HeadlessStats {
    /// Scene.
    pub scene: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Scene time at the start.
    pub start: f64,
    /// Seconds asked for.
    pub seconds_requested: f64,
    /// Wall time from start to all threads joined.
    pub wall_s: f64,
    /// Samples per second (shaded samples delivered to the display side).
    pub samples_per_s: f64,
    /// New images shown per second.
    pub display_fps: f64,
    /// The pipeline's figures.
    pub pipeline: PipelineStats,
    /// The display's figures.
    pub display: DisplayStats,
    /// Image files written.
    pub images: Vec<String>,
    /// CPU seconds this process used during the run (Linux; `null` elsewhere).
    pub process_cpu_s: Option<f64>,
    /// `process_cpu_s / (seconds × cores)`: the share of the machine the run got. Far
    /// below 1 with every thread busy means other processes held the cores.
    pub machine_share: Option<f64>,
    /// The 1-minute load average before the run (Linux), for judging contention.
    pub load_average_before: Option<f64>,
    /// The scripted camera step's latency, when one was asked for.
    pub camera_step: Option<CameraStep>,
}

/// Most displayed images a headless run writes.
pub const MAX_IMAGES: usize = 100;

/// Run the pipeline of the method `settings` are for for `opts.seconds`, then write
/// images and `stats.json` to `opts.out` (replaced whole, as every command's output
/// folder).
pub fn run_headless(
    tracer: Arc<Tracer>,
    config: RtConfig,
    settings: RtSettings,
    opts: &HeadlessOptions,
) -> Result<HeadlessStats, RealtimeError> {
    check_options(opts)?;
    // The folder is built beside `out` and swapped in whole at the end: `out` holds
    // this run or the previous one, never files of both.
    let staging =
        crate::output::OutputDir::begin(&opts.out).map_err(|source| RealtimeError::Io {
            path: opts.out.clone(),
            source,
        })?;
    let (w, h) = tracer.size();
    let load_average_before = load_average();
    let cpu0 = process_cpu_seconds();
    let t_start = Instant::now();
    let pipeline = Pipeline::start(tracer, config.clone(), settings)?;
    let shown = display_loop(&pipeline, &config, opts);
    let pipeline_stats = pipeline.stop()?;
    let wall_s = t_start.elapsed().as_secs_f64();
    let process_cpu_s = cpu0.zip(process_cpu_seconds()).map(|(a, b)| b - a);
    let machine_share = process_cpu_s.map(|c| c / (wall_s * pipeline_stats.cores as f64));
    let images = write_images(&shown.kept, staging.path())?;
    let stats = HeadlessStats {
        scene: opts.scene.clone(),
        width: w,
        height: h,
        start: config.start,
        seconds_requested: opts.seconds,
        wall_s,
        samples_per_s: pipeline_stats.samples_per_s,
        display_fps: shown.display.display_fps,
        pipeline: pipeline_stats,
        display: shown.display,
        images,
        process_cpu_s,
        machine_share,
        load_average_before,
        camera_step: shown.step.map(|s| s.figures),
    };
    let p = staging.path().join("stats.json");
    let text = serde_json::to_string_pretty(&stats).expect("plain data serialises");
    std::fs::write(&p, text).map_err(|source| RealtimeError::Io { path: p, source })?;
    staging.commit().map_err(|source| RealtimeError::Io {
        path: opts.out.clone(),
        source,
    })?;
    Ok(stats)
}

fn check_options(opts: &HeadlessOptions) -> Result<(), RealtimeError> {
    if let Err(e) = crate::limits::check_view_seconds(opts.seconds) {
        return Err(RealtimeError::Config(format!("seconds {e}")));
    }
    if opts.images > MAX_IMAGES {
        return Err(RealtimeError::Config(format!(
            "images {} out of range [0, {MAX_IMAGES}]",
            opts.images
        )));
    }
    Ok(())
}

/// What the display loop of a headless run saw.
struct DisplayRun {
    /// The display's figures.
    display: DisplayStats,
    /// The images kept for writing, spread over the run.
    kept: Vec<Arc<Frame>>,
    /// The camera step, once taken.
    step: Option<StepWatch>,
}

/// The scripted camera step once taken: when, and what the display has shown since.
struct StepWatch {
    /// Wall seconds into the run.
    wall: f64,
    /// Scene time of the step.
    scene_t: f64,
    /// Samples delivered before the step.
    samples: u64,
    /// The figures so far.
    figures: CameraStep,
}

impl StepWatch {
    /// Turn the pipeline's camera now.
    fn take(pipeline: &Pipeline, wall: f64) -> StepWatch {
        let tracer = pipeline.tracer();
        let now = pipeline.clock().now();
        tracer.set_live_camera(Some(yawed(tracer.camera_at(now), STEP_YAW_DEG)));
        StepWatch {
            wall,
            scene_t: now,
            samples: pipeline.samples(),
            figures: CameraStep {
                at_s: wall,
                yaw_deg: STEP_YAW_DEG,
                first_image_ms: None,
                view_ms: None,
                half_new_ms: None,
                half_new_samples: None,
            },
        }
    }

    /// Record what the image displayed `elapsed` wall seconds into the run, after
    /// `samples` samples in all, shows of the step.
    fn observe(&mut self, f: &Frame, elapsed: f64, samples: u64) {
        let (scene_t, figures) = (self.scene_t, &mut self.figures);
        let shown_ms = (elapsed - self.wall) * 1e3;
        // Built after the step: an image meant for a later refresh but begun before
        // the step shows the camera as it was.
        let after = f.began >= scene_t;
        if after && figures.first_image_ms.is_none() {
            figures.first_image_ms = Some(shown_ms);
        }
        if after && f.view_time >= scene_t && figures.view_ms.is_none() {
            figures.view_ms = Some(shown_ms);
        }
        if figures.half_new_ms.is_none() && after {
            let since = f.time - scene_t;
            let (informed, new) = f
                .ages
                .iter()
                .filter(|a| a.is_finite())
                .fold((0, 0), |(i, n), &a| {
                    (i + 1, n + (a as f64 <= since) as usize)
                });
            if new * 2 >= informed.max(1) {
                figures.half_new_ms = Some(shown_ms);
                figures.half_new_samples = Some(samples.saturating_sub(self.samples));
            }
        }
    }
}

/// Present the newest image at every refresh for `opts.seconds`, as a display that
/// draws nowhere, keeping `opts.images` of them and taking the camera step if asked.
fn display_loop(pipeline: &Pipeline, config: &RtConfig, opts: &HeadlessOptions) -> DisplayRun {
    let clock = pipeline.clock();
    let mut pacer = Pacer::new(clock, config.refresh_hz);
    let n_images = opts.images;
    let mut kept: Vec<Arc<Frame>> = Vec::new();
    let mut last_seq = 0;
    let mut step: Option<StepWatch> = None;
    while clock.elapsed() < opts.seconds {
        pacer.wait();
        if let (Some(at), None) = (opts.camera_step_s, &step) {
            if clock.elapsed() >= at {
                step = Some(StepWatch::take(pipeline, clock.elapsed()));
            }
        }
        let frame = pipeline.latest();
        let seq = frame.as_ref().map_or(0, |f| f.seq);
        if let Some(f) = &frame {
            // What a display does with a new image, at its cost: quantize it to 8 bits
            // (the viewer draws that; here it is only paid for, so that a headless run
            // loads the machine as a window does).
            if f.seq != last_seq {
                std::hint::black_box(f.image.to_rgb8());
                last_seq = f.seq;
            }
            let due = (kept.len() + 1) as f64 * opts.seconds / n_images.max(1) as f64;
            if kept.len() < n_images && clock.elapsed() + 1.0 / config.refresh_hz >= due {
                kept.push(f.clone());
            }
        }
        pacer.present(seq);
        if let (Some(watch), Some(f)) = (&mut step, &frame) {
            watch.observe(f, clock.elapsed(), pipeline.samples());
        }
    }
    DisplayRun {
        display: pacer.stats(clock.elapsed()),
        kept,
        step,
    }
}

/// Write the kept images into `dir`; their file names.
fn write_images(kept: &[Arc<Frame>], dir: &std::path::Path) -> Result<Vec<String>, RealtimeError> {
    let mut images = Vec::new();
    for (i, f) in kept.iter().enumerate() {
        let name = format!("display_{i}_t{:.2}.png", f.time);
        let p = dir.join(&name);
        f.image
            .save_png(&p)
            .map_err(|source| RealtimeError::Io { path: p, source })?;
        images.push(name);
    }
    Ok(images)
}
