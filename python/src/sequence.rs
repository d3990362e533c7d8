//! `frameless render` as an iterator: one `(time, image)` pair per refresh, the linear
//! image its OpenEXR frame holds. The method runs on a thread of its own, one refresh
//! ahead of the consumer; dropping the iterator stops it after that refresh.

use std::{sync::Arc, time::Duration};

use crossbeam_channel as mpsc;

use frameless::{
    evaluation::sequence::{self, SequenceConfig},
    image::{Image, ImageFormat},
};
use numpy::PyArray3;
use pyo3::{exceptions::PyRuntimeError, prelude::*};

use crate::{args, errors, scene::NativeScene};

/// What the method's thread sends: a refresh, or why it cannot run.
type Frame = PyResult<(f64, Image)>;

/// The displayed images of one method at every refresh of a window.
#[pyclass(name = "NativeRender", module = "frameless._frameless")]
pub struct NativeRender {
    frames: mpsc::Receiver<Frame>,
    /// Refreshes in the window.
    #[pyo3(get)]
    len: u64,
}

/// Trace the method refresh by refresh, sending each image (as `render_sequence`
/// builds the method and steps it, without the files).
fn produce(scene: Arc<frameless::scene::Scene>, cfg: SequenceConfig, tx: mpsc::Sender<Frame>) {
    let ctx = sequence::method_context(scene, &cfg);
    let mut method = match cfg.method.build(&ctx) {
        Ok(m) => m,
        Err(e) => {
            let _ = tx.send(Err(errors::method(e)));
            return;
        }
    };
    for k in 0..cfg.frames() {
        let t = cfg.start + k as f64 / cfg.display.refresh_hz;
        let image = method.display(t).image.clone();
        if tx.send(Ok((t, image))).is_err() {
            return; // The iterator is gone.
        }
    }
}

#[pymethods]
impl NativeRender {
    /// NativeRender(scene, method, rate, start, duration, warmup, size, refresh_hz, seed,
    ///              max_depth, texture_filter, recon="cpu", trace="cpu")
    /// --
    ///
    /// Checks the settings as `frameless render` does, then starts the method.
    #[new]
    #[pyo3(signature = (scene, method, rate, start, duration, warmup, size, refresh_hz, seed,
                        max_depth, texture_filter, recon="cpu", trace="cpu"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        scene: &NativeScene,
        method: String,
        rate: String,
        start: f64,
        duration: f64,
        warmup: f64,
        size: &str,
        refresh_hz: f64,
        seed: u64,
        max_depth: u64,
        texture_filter: &str,
        recon: &str,
        trace: &str,
    ) -> PyResult<Self> {
        // A sequence has no ideal images: the reference group is unused.
        let (display, quality, _) =
            args::groups(size, refresh_hz, seed, 1, max_depth, texture_filter, None)?;
        let mut cfg = SequenceConfig {
            scene_name: scene.name.clone(),
            camera_path: scene.camera_path.clone(),
            method: args::methods(&[method])?[0],
            rate: args::rates(&[rate])?[0],
            start: args::finite("start", start)?,
            duration: args::finite("duration", duration)?,
            warmup: args::finite("warmup", warmup)?,
            display,
            quality,
            format: ImageFormat::Exr,
            devices: Default::default(),
        };
        cfg.validate().map_err(errors::eval)?;
        // This module is CPU-only: `trace` is checked (gpu refused, auto the CPU), and
        // the sequence traces on the CPU as `sequence::method_context` sets it up.
        cfg.devices = args::devices(recon, trace)?;
        let len = cfg.frames();
        // One refresh traced ahead of the one being looked at.
        let (tx, rx) = mpsc::bounded(1);
        let scene = scene.scene.clone();
        std::thread::Builder::new()
            .name("frameless-render".into())
            .spawn(move || produce(scene, cfg, tx))
            .map_err(|e| PyRuntimeError::new_err(format!("starting a worker thread: {e}")))?;
        Ok(Self { frames: rx, len })
    }

    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next `(time, image)`, waiting with the GIL released and Ctrl-C heard.
    fn __next__<'py>(
        &mut self,
        py: Python<'py>,
    ) -> PyResult<Option<(f64, Bound<'py, PyArray3<f32>>)>> {
        loop {
            let rx = &self.frames;
            match crate::work::detach(py, || rx.recv_timeout(Duration::from_millis(100))) {
                Ok(frame) => {
                    let (t, image) = frame?;
                    return Ok(Some((t, crate::to_array(py, &image))));
                }
                Err(mpsc::RecvTimeoutError::Timeout) => py.check_signals()?,
                Err(mpsc::RecvTimeoutError::Disconnected) => return Ok(None),
            }
        }
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeRender>()
}
