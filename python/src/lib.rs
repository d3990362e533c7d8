//! `frameless._frameless`: the library's scenes, stills, evaluations and sequences for
//! Python, images as numpy arrays. The `frameless` package wraps it with defaults,
//! progress bars and tables; see `docs/python.md`.
//!
//! Settings are checked by the same library code as the command line's, so a bad one
//! raises with the text `frameless` prints after `error: ` (see [`errors`]).

mod args;
mod errors;
mod eval;
mod scene;
mod sequence;
mod work;

use numpy::{ndarray::Array3, IntoPyArray, PyArray3, PyReadonlyArray3};
use pyo3::{exceptions::PyTypeError, prelude::*};

/// A linear image as an `H×W×3` float32 array.
fn to_array<'py>(py: Python<'py>, img: &frameless::image::Image) -> Bound<'py, PyArray3<f32>> {
    let data: Vec<f32> = img.pixels.iter().flat_map(|p| p.to_array()).collect();
    Array3::from_shape_vec((img.height as usize, img.width as usize, 3), data)
        .expect("an image holds width × height pixels")
        .into_pyarray(py)
}

/// An `H×W×3` float32 array as a linear image.
fn from_array(a: &PyReadonlyArray3<'_, f32>) -> PyResult<frameless::image::Image> {
    let view = a.as_array();
    let (h, w, c) = view.dim();
    if c != 3 || h == 0 || w == 0 {
        return Err(errors::value(format!(
            "an image is an H×W×3 array with H, W ≥ 1; this one is {h}×{w}×{c}"
        )));
    }
    let pixels = view
        .rows()
        .into_iter()
        .map(|p| glam::Vec3::new(p[0], p[1], p[2]))
        .collect();
    Ok(frameless::image::Image {
        width: w as u32,
        height: h as u32,
        pixels,
    })
}

/// to_display(image)
/// --
///
/// The displayed form of a linear image, as `frameless` writes it to PNG: clamped to
/// [0, 1] and rounded to 8 bits (`H×W×3` uint8).
#[pyfunction]
fn to_display<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let image: PyReadonlyArray3<'py, f32> = image.extract().map_err(|_| not_an_image(image))?;
    let img = from_array(&image)?;
    let rgb = work::detach(py, || img.to_rgb8());
    Ok(
        Array3::from_shape_vec((img.height as usize, img.width as usize, 3), rgb)
            .expect("three bytes a pixel")
            .into_pyarray(py),
    )
}

/// The error of `to_display` for anything but an `H×W×3` float32 array, saying what it
/// was given: numpy's own says only that an `ndarray` cannot be cast as an `ndarray`.
fn not_an_image(given: &Bound<'_, PyAny>) -> PyErr {
    let text = |name: &str| {
        given
            .getattr(name)
            .and_then(|v| v.str())
            .map(|s| s.to_string())
    };
    let given = match (text("shape"), text("dtype")) {
        (Ok(shape), Ok(dtype)) => format!("an array of shape {shape} and dtype {dtype}"),
        _ => match given.get_type().name() {
            Ok(name) => format!("a {name}"),
            Err(_) => "something else".into(),
        },
    };
    PyTypeError::new_err(format!(
        "to_display takes a linear image, an H×W×3 float32 array (as Scene.still returns); \
         it was given {given} (numpy converts the type with image.astype(numpy.float32))"
    ))
}

#[pymodule]
fn _frameless(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // Before the interpreter finalises, no thread of ours may still want the GIL back.
    m.py()
        .import("atexit")?
        .call_method1("register", (wrap_pyfunction!(work::at_exit, m)?,))?;
    m.add_function(wrap_pyfunction!(to_display, m)?)?;
    scene::register(m)?;
    eval::register(m)?;
    sequence::register(m)?;
    args::register(m)?;
    Ok(())
}
