//! What the glTF and OBJ loaders share: the scene settings and limits neither format
//! declares, PNG/JPEG/PPM decoding for their image textures, and the camera and light a
//! scene gets when its file defines none. Kept apart so that neither loader depends on
//! the other.

use ::gltf::json;
use glam::{Mat4, Vec3};

use super::{error::ImageError, texture::MAX_TEXTURE_SIDE, Camera, Light, Scene, Texture};

/// Background color of scenes from formats that do not declare one.
pub(crate) const BACKGROUND: Vec3 = Vec3::new(0.2, 0.22, 0.25);

pub(crate) use super::limits::MAX_TRIANGLES;

/// The scene a loader fills in for the file at `path`: named after the file, with the
/// default background and white ambient light.
pub(crate) fn empty_scene(path: &std::path::Path) -> Scene {
    Scene {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        source: Some(path.to_path_buf()),
        background: BACKGROUND,
        ambient: Vec3::ONE,
        ..Default::default()
    }
}

/// Which image container some bytes hold, by their magic number.
fn sniff_image(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else if bytes.starts_with(b"P6") {
        Some("image/x-portable-pixmap")
    } else {
        None
    }
}

/// Decode a PNG, JPEG or binary PPM image into a texture; the error does not name the
/// file, which the caller knows. PNG and JPEG go through the `gltf` crate's image decoding (the `image`
/// crate it brings), fed through a one-image in-memory document so that no further
/// dependency is needed.
pub(crate) fn decode_image(name: &str, bytes: &[u8]) -> Result<Texture, ImageError> {
    let mime = sniff_image(bytes).ok_or(ImageError::UnknownFormat)?;
    if mime == "image/x-portable-pixmap" {
        return Texture::parse_ppm(name, bytes);
    }
    let value = serde_json::json!({
        "asset": { "version": "2.0" },
        "buffers": [{ "byteLength": bytes.len() }],
        "bufferViews": [{ "buffer": 0, "byteLength": bytes.len() }],
        "images": [{ "bufferView": 0, "mimeType": mime }],
    });
    let root: json::Root = serde_json::from_value(value).map_err(ImageError::DecodingDocument)?;
    let document = ::gltf::Document::from_json_without_validation(root);
    let image = document
        .images()
        .next()
        .ok_or(ImageError::NoDecodingImage)?;
    let data = ::gltf::image::Data::from_source(
        image.source(),
        None,
        &[::gltf::buffer::Data(bytes.to_vec())],
    )
    .map_err(|source| ImageError::Decode {
        mime,
        source: Box::new(source),
    })?;
    decoded_to_texture(name, &data)
}

fn decoded_to_texture(name: &str, data: &::gltf::image::Data) -> Result<Texture, ImageError> {
    use ::gltf::image::Format;
    let (w, h) = (data.width, data.height);
    if w == 0 || h == 0 || w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
        return Err(ImageError::Size {
            width: w,
            height: h,
        });
    }
    // (channels, bytes per channel)
    let (ch, bpc) = match data.format {
        Format::R8 => (1, 1),
        Format::R8G8 => (2, 1),
        Format::R8G8B8 => (3, 1),
        Format::R8G8B8A8 => (4, 1),
        Format::R16 => (1, 2),
        Format::R16G16 => (2, 2),
        Format::R16G16B16 => (3, 2),
        Format::R16G16B16A16 => (4, 2),
        Format::R32G32B32FLOAT => (3, 4),
        Format::R32G32B32A32FLOAT => (4, 4),
    };
    let texels = (w as usize) * (h as usize);
    if data.pixels.len() != texels * ch * bpc {
        return Err(ImageError::DecodedSize {
            got: data.pixels.len(),
            width: w,
            height: h,
            format: format!("{:?}", data.format),
        });
    }
    let p = &data.pixels;
    let comp = |i: usize| -> f32 {
        let at = i * bpc;
        match bpc {
            1 => p[at] as f32 / 255.0,
            2 => u16::from_ne_bytes([p[at], p[at + 1]]) as f32 / 65535.0,
            _ => {
                let v = f32::from_ne_bytes([p[at], p[at + 1], p[at + 2], p[at + 3]]);
                if v.is_finite() {
                    v
                } else {
                    0.0
                }
            }
        }
    };
    let texels = (0..texels)
        .map(|i| {
            let base = i * ch;
            if ch < 3 {
                Vec3::splat(comp(base))
            } else {
                Vec3::new(comp(base), comp(base + 1), comp(base + 2))
            }
        })
        .collect();
    Ok(Texture::new(name, w, h, texels))
}

/// World-space bounds of every triangle at time `t`.
pub(crate) fn world_bounds(scene: &Scene, t: f32) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for g in &scene.groups {
        let m = g.node.map_or(Mat4::IDENTITY, |n| scene.node_world(n, t));
        for tri in &g.triangles {
            for p in tri.p {
                let q = m.transform_point3(p);
                if q.is_finite() {
                    lo = lo.min(q);
                    hi = hi.max(q);
                }
            }
        }
    }
    (lo.cmple(hi).all()).then_some((lo, hi))
}

/// A camera on the +Z side of the bounds, looking at their center with a 45° vertical
/// field of view, far enough for the bounding sphere to fit vertically.
pub(crate) fn default_camera(bounds: Option<(Vec3, Vec3)>) -> Camera {
    let Some((lo, hi)) = bounds else {
        return Camera::default();
    };
    let center = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-3);
    let fov = 45.0f32;
    let dist = radius / (fov.to_radians() * 0.5).sin();
    Camera {
        eye: center + Vec3::Z * dist,
        at: center,
        up: Vec3::Y,
        fov_y_deg: fov,
        hither: (dist * 1e-4).max(1e-5),
    }
}

/// A white light above and to the right of the camera, for scenes that define none.
pub(crate) fn default_light(cam: &Camera) -> Light {
    let to_eye = cam.eye - cam.at;
    let d = to_eye.length().max(1e-3);
    let forward = (-to_eye).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(cam.up).normalize_or(Vec3::X);
    let up = right.cross(forward);
    Light {
        position: cam.eye + (up * 0.5 + right * 0.5) * d,
        color: Vec3::ONE,
        track: None,
        name: Some("default".into()),
    }
}
