//! Scenes and still images (`frameless still`).

use std::{path::PathBuf, sync::Arc};

use frameless::{
    evaluation::Progress,
    image::Image,
    render::still,
    scene::{self, builtin, CameraPath, Scene},
    trace::{TraceOptions, Tracer},
};
use numpy::PyArray3;
use pyo3::prelude::*;

use crate::{args, errors, work};

/// A loaded scene and the camera path that overrides its camera, if any.
#[pyclass(name = "NativeScene", module = "frameless._frameless", frozen)]
pub struct NativeScene {
    pub scene: Arc<Scene>,
    pub camera_path: Option<CameraPath>,
    /// How the user named it (reports and summaries carry the name).
    #[pyo3(get)]
    pub name: String,
}

/// Load a scene as `--scene` does (a built-in name, else a file), then the camera path.
fn load(name: &str, camera_path: Option<PathBuf>) -> PyResult<NativeScene> {
    if let Some(why) = builtin::unknown_name(name) {
        return Err(errors::value(why));
    }
    let scene = scene::load(name).map_err(errors::scene)?;
    let camera_path = camera_path
        .map(|p| CameraPath::load(&p).map_err(errors::scene))
        .transpose()?;
    Ok(NativeScene {
        scene: Arc::new(scene),
        camera_path,
        name: name.to_string(),
    })
}

#[pymethods]
impl NativeScene {
    /// load(name, camera_path=None)
    /// --
    ///
    /// A built-in scene by name or a scene file, with the GIL released while it loads.
    #[staticmethod]
    #[pyo3(signature = (name, camera_path=None))]
    fn load(py: Python<'_>, name: String, camera_path: Option<PathBuf>) -> PyResult<Self> {
        crate::work::detach(py, || load(&name, camera_path))
    }

    /// The scene's animation range, seconds.
    #[getter]
    fn time_range(&self) -> (f32, f32) {
        self.scene.time_range()
    }

    /// Triangles, spheres and cones.
    #[getter]
    fn primitives(&self) -> usize {
        self.scene.primitive_count()
    }

    /// Whether a camera path overrides the scene's camera.
    #[getter]
    fn has_camera_path(&self) -> bool {
        self.camera_path.is_some()
    }

    /// still(time, size, spp, seed, max_depth, texture_filter, progress=None)
    /// --
    ///
    /// `frameless still`'s image at `time`, linear, `H×W×3` float32.
    #[pyo3(signature = (time, size, spp, seed, max_depth, texture_filter, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn still<'py>(
        &self,
        py: Python<'py>,
        time: f64,
        size: &str,
        spp: u64,
        seed: u64,
        max_depth: u64,
        texture_filter: &str,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let time = args::finite("t", time)?;
        let (w, h) = args::size(size)?;
        args::in_range("spp", spp, 1, frameless::limits::MAX_STILL_SPP as u64)?;
        let quality = args::quality(seed, max_depth, texture_filter)?;
        let options = TraceOptions::from(&quality);
        let scene = self.scene.clone();
        let path = self.camera_path.clone();
        let img = work::run(py, progress.as_ref(), move |work| {
            let tracer = Tracer::new(scene, w, h, options).with_camera_path(path);
            Ok(render_still(&tracer, time, spp as u32, seed, work))
        })?;
        Ok(crate::to_array(py, &img))
    }
}

/// `still::render`'s image, each row started only if the caller has not cancelled, so
/// that Ctrl-C stops a long render within one row's time. `still::render` reports only
/// after a row, and a panic in a rayon job does not stop the rows queued beside it:
/// stopping there still rendered the whole image.
fn render_still(tracer: &Tracer, time: f64, spp: u32, seed: u64, work: &work::Work) -> Image {
    use rayon::prelude::*;
    let (w, h) = tracer.size();
    work.checkpoint();
    work.total(h as u64);
    let state = tracer.state_at(time);
    let rows: Vec<Vec<glam::Vec3>> = (0..h)
        .into_par_iter()
        .map(|y| {
            work.checkpoint();
            let row = (0..w)
                .map(|x| still::pixel(tracer, &state, x, y, spp, seed))
                .collect();
            work.advance("", 1);
            row
        })
        .collect();
    Image {
        width: w,
        height: h,
        pixels: rows.into_iter().flatten().collect(),
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeScene>()
}
