//! `frameless still --out x.exr` writes the image in linear light (HDR) as OpenEXR,
//! `.png` the displayed one, the two agreeing through docs/colour.md's transform; any
//! other extension is refused before work.

use std::{path::PathBuf, process::Command, sync::Arc};

use frameless::{
    render::still,
    scene::builtin,
    trace::{TraceOptions, Tracer},
};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-hdr-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn still(out: &std::path::Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args([
            "still", "--scene", "toycar", "--time", "1", "--size", "48x32", "--spp", "4", "--seed",
            "3", "--out",
        ])
        .arg(out)
        .output()
        .unwrap()
}

/// Read the first RGB layer with the `exr` crate itself, not through our reader.
fn read_with_exr_crate(path: &std::path::Path) -> (usize, usize, Vec<[f32; 3]>) {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| (size.0, size.1, vec![[0f32; 3]; size.0 * size.1]),
        |px: &mut (usize, usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = px.0;
            px.2[pos.1 * w + pos.0] = [r, g, b];
        },
    )
    .expect("the exr crate reads the file");
    img.layer_data.channel_data.pixels
}

#[test]
fn still_exr_holds_linear_light_and_png_the_display_values() {
    let d = scratch("still");
    let (exr_path, png_path) = (d.join("x.exr"), d.join("x.png"));
    for p in [&exr_path, &png_path] {
        let o = still(p);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // The same render in this process, with the command's defaults: the still renderer
    // is deterministic for any thread count.
    let scene = Arc::new(builtin::load("toycar").expect("built-in scene"));
    let options = TraceOptions::default();
    let tracer = Tracer::new(scene, 48, 32, options);
    let shown = still::render(&tracer, 1.0, 4, 3, &|_| {});

    let (w, h, pixels) = read_with_exr_crate(&exr_path);
    assert_eq!((w, h), (48, 32));
    for (i, (got, want)) in pixels.iter().zip(&shown.to_linear().pixels).enumerate() {
        assert_eq!(*got, want.to_array(), "pixel {i}");
    }
    // What the PNG cannot hold: values between its 256 steps (4 samples a pixel
    // average to them).
    let off_grid = shown
        .pixels
        .iter()
        .flat_map(|p| p.to_array())
        .filter(|v| ((v * 255.0) - (v * 255.0).round()).abs() > 1e-3)
        .count();
    assert!(
        off_grid > pixels.len(),
        "{off_grid} values off the 8-bit grid"
    );
    let (_, _, rgb) = frameless::image::read_png_rgb8(&png_path).unwrap();
    assert_eq!(rgb, shown.to_rgb8(), "the PNG is the image as displayed");
    // The files agree through the documented transform alone: each PNG byte is the
    // sRGB encoding of the EXR's linear value, clamped and rounded (to within the
    // float rounding of the decode and encode, at a rounding boundary).
    for (i, (e, b)) in pixels.iter().flatten().zip(&rgb).enumerate() {
        let v = frameless::image::linear_to_display(*e).clamp(0.0, 1.0) * 255.0;
        assert!(
            (v - f32::from(*b)).abs() <= 0.5 + 1e-3,
            "value {i}: {e} -> {v} vs {b}"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn other_extensions_are_refused_before_work() {
    let d = scratch("ext");
    for name in ["x.jpg", "x", "x.exr.txt"] {
        let p = d.join(name);
        let o = still(&p);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains(".png") && err.contains(".exr"),
            "{name}: {err}"
        );
        assert!(!p.exists(), "{name} written");
    }
    let _ = std::fs::remove_dir_all(&d);
}
