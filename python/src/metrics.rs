//! The evaluation's image metrics on any two images, as displayed (8-bit RGB bytes,
//! what a PNG holds): the numbers `frameless eval` reports for the same pair.

use frameless::evaluation::metrics;
use numpy::{ndarray::Array2, IntoPyArray, PyArray2, PyReadonlyArray3};
use pyo3::prelude::*;

use crate::errors::value;

/// Two `H×W×3` byte images of one size, as `(width, height, reference, test)`.
fn pair(
    reference: &PyReadonlyArray3<'_, u8>,
    test: &PyReadonlyArray3<'_, u8>,
) -> PyResult<(u32, u32, Vec<u8>, Vec<u8>)> {
    let (r, t) = (reference.as_array(), test.as_array());
    if r.dim() != t.dim() {
        return Err(value(format!(
            "the images differ in shape: reference {:?}, test {:?}",
            r.dim(),
            t.dim()
        )));
    }
    let (h, w, c) = r.dim();
    if c != 3 || h == 0 || w == 0 {
        return Err(value(format!(
            "an image is an H×W×3 array with H, W ≥ 1; these are {h}×{w}×{c}"
        )));
    }
    let bytes = |a: numpy::ndarray::ArrayView3<'_, u8>| a.iter().copied().collect();
    Ok((w as u32, h as u32, bytes(r), bytes(t)))
}

/// rms(reference, test)
/// --
///
/// RMS error over all channels, 0–255.
#[pyfunction]
fn rms(reference: PyReadonlyArray3<'_, u8>, test: PyReadonlyArray3<'_, u8>) -> PyResult<f64> {
    let (_, _, r, t) = pair(&reference, &test)?;
    Ok(metrics::rms(&r, &t))
}

/// psnr(reference, test)
/// --
///
/// PSNR in dB (peak 255), capped for identical images.
#[pyfunction]
fn psnr(reference: PyReadonlyArray3<'_, u8>, test: PyReadonlyArray3<'_, u8>) -> PyResult<f64> {
    let (_, _, r, t) = pair(&reference, &test)?;
    Ok(metrics::psnr(metrics::rms(&r, &t)))
}

/// flip(reference, test)
/// --
///
/// Mean LDR-FLIP error (67 pixels per degree), as the evaluation reports it.
#[pyfunction]
fn flip(
    py: Python<'_>,
    reference: PyReadonlyArray3<'_, u8>,
    test: PyReadonlyArray3<'_, u8>,
) -> PyResult<f64> {
    let (w, h, r, t) = pair(&reference, &test)?;
    Ok(crate::work::detach(py, || metrics::flip_mean(&r, &t, w, h)))
}

/// flip_map(reference, test)
/// --
///
/// The FLIP error of every pixel, `H×W` float32 in [0, 1].
#[pyfunction]
fn flip_map<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray3<'py, u8>,
    test: PyReadonlyArray3<'py, u8>,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let (w, h, r, t) = pair(&reference, &test)?;
    let values = crate::work::detach(py, || metrics::flip_values(&r, &t, w, h))
        .ok_or_else(|| value("FLIP could not compare these images"))?;
    let map = Array2::from_shape_vec((h as usize, w as usize), values).expect("one value a pixel");
    Ok(map.into_pyarray(py))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(rms, m)?)?;
    m.add_function(wrap_pyfunction!(psnr, m)?)?;
    m.add_function(wrap_pyfunction!(flip, m)?)?;
    m.add_function(wrap_pyfunction!(flip_map, m)?)
}
