//! `frameless._frameless`: the library's scenes, stills, evaluations and sequences for
//! Python, images as numpy arrays. The `frameless` package wraps it with defaults,
//! progress bars and tables; see `docs/python.md`.
//!
//! Settings are checked by the same library code as the command line's, so a bad one
//! raises with the text `frameless` prints after `error: ` (see [`errors`]).

mod args;
mod cli;
mod errors;
mod eval;
mod metrics;
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
/// The displayed form of an image, as `frameless` writes it to PNG: clamped to [0, 1]
/// and rounded to 8 bits (`H×W×3` uint8).
#[pyfunction]
fn to_display<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let img = image_arg("to_display", image)?;
    let rgb = work::detach(py, || img.to_rgb8());
    Ok(
        Array3::from_shape_vec((img.height as usize, img.width as usize, 3), rgb)
            .expect("three bytes a pixel")
            .into_pyarray(py),
    )
}

/// to_linear(image)
/// --
///
/// An image's values in linear light, as `frameless` writes them to OpenEXR: the sRGB
/// decoding of each display value (docs/colour.md), `H×W×3` float32.
#[pyfunction]
fn to_linear<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let img = image_arg("to_linear", image)?;
    let linear = work::detach(py, || img.to_linear());
    Ok(to_array(py, &linear))
}

/// write_image(path, image)
/// --
///
/// Write an image as the command line writes its own: `.png` as displayed, `.exr` in
/// linear light (docs/colour.md); the file appears whole or not at all.
#[pyfunction]
fn write_image(py: Python<'_>, path: std::path::PathBuf, image: &Bound<'_, PyAny>) -> PyResult<()> {
    let img = image_arg("write_image", image)?;
    let format = frameless::image::ImageFormat::for_output(&path)
        .map_err(|e| errors::value(e.to_string()))?;
    work::detach(py, || img.save(&path, format)).map_err(|e| {
        pyo3::exceptions::PyOSError::new_err(format!("writing {}: {e}", path.display()))
    })
}

/// read_image(path)
/// --
///
/// An image file's display values, `H×W×3` float32: a PNG's bytes / 255, an OpenEXR
/// file's linear light encoded back (docs/colour.md).
#[pyfunction]
fn read_image<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    use frameless::image::{read_exr, read_png_rgb8, Image, ImageFormat};
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let format = ImageFormat::ALL
        .into_iter()
        .find(|(_, x, _)| extension.as_deref() == Some(*x))
        .map(|(f, _, _)| f)
        .ok_or_else(|| {
            errors::value(format!(
                "read_image reads .png and .exr files; {} is neither",
                path.display()
            ))
        })?;
    let read = work::detach(py, || -> std::io::Result<Image> {
        match format {
            ImageFormat::Exr => Ok(read_exr(&path)?.to_display_values()),
            ImageFormat::Png => {
                let (w, h, rgb) = read_png_rgb8(&path)?;
                let pixels = rgb
                    .chunks_exact(3)
                    .map(|p| glam::Vec3::new(p[0].into(), p[1].into(), p[2].into()) / 255.0)
                    .collect();
                Ok(Image {
                    width: w,
                    height: h,
                    pixels,
                })
            }
        }
    });
    let img = read.map_err(|e| {
        pyo3::exceptions::PyOSError::new_err(format!("reading {}: {e}", path.display()))
    })?;
    Ok(to_array(py, &img))
}

/// An `H×W×3` float32 array argument of `function` as an image.
fn image_arg(function: &str, image: &Bound<'_, PyAny>) -> PyResult<frameless::image::Image> {
    let array: PyReadonlyArray3<'_, f32> =
        image.extract().map_err(|_| not_an_image(function, image))?;
    from_array(&array)
}

/// The error of a function taking an image for anything but an `H×W×3` float32 array,
/// saying what it was given: numpy's own says only that an `ndarray` cannot be cast as
/// an `ndarray`.
fn not_an_image(function: &str, given: &Bound<'_, PyAny>) -> PyErr {
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
        "{function} takes an image, an H×W×3 float32 array (as Scene.still returns); \
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
    m.add_function(wrap_pyfunction!(to_linear, m)?)?;
    m.add_function(wrap_pyfunction!(write_image, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    cli::register(m)?;
    metrics::register(m)?;
    scene::register(m)?;
    eval::register(m)?;
    sequence::register(m)?;
    args::register(m)?;
    Ok(())
}
