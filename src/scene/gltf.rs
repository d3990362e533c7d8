//! glTF 2.0 scene loader: `.gltf` (JSON with external files or embedded `data:` URIs)
//! and `.glb` (binary container).
//!
//! The file is read into the `gltf` crate's JSON model only; every index, byte range and
//! count is checked here before use, so a malformed file is a [`SceneError`] naming the
//! file, never a panic (the crate's own validation and readers index without checking in
//! places, so neither is used). Images are decoded through the crate's `image` support
//! after their bytes have been located and checked here.
//!
//! # What is read, and how it maps to this renderer
//!
//! - **Scene.** The `scene` named by the file, else the first scene, else every node that
//!   is nobody's child. Nodes outside it are ignored.
//! - **Nodes.** Each glTF node becomes one [`Node`], parents before children. A node that
//!   no animation channel targets is [`NodeKind::Static`] with its local matrix. A node
//!   targeted by translation, rotation or scale channels is [`NodeKind::Sampled`] with a
//!   [`NodeAnimation`]: its rest TRS and the glTF samplers, evaluated exactly as the glTF
//!   specification (appendix C) says — `STEP`, `LINEAR` (rotation by the specification's
//!   shortest-arc slerp) and `CUBICSPLINE` (Hermite with tangents scaled by the key
//!   interval), values held constant before the first and after the last key. All
//!   animations of the file play together from `t = 0`; when two channels target the same
//!   property of a node, the later one in the file wins. A node with both a matrix and
//!   animation (the specification forbids it) animates from the matrix's decomposition.
//!   A node reached twice (two parents, or a cycle) is an error.
//! - **Meshes.** Primitives in `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` mode,
//!   indexed or not, become [`Triangle`]s in a [`Group`] of their node (a mesh used by
//!   several nodes is copied into each). Strips and fans follow the specification's vertex
//!   order; triangles repeating a vertex index (strip restarts) are dropped, as are the
//!   vertices after the last whole triangle of a `TRIANGLES` primitive. `POINTS` and
//!   `LINE*` primitives have no surface to ray trace: they are skipped with a warning on
//!   stderr. Positions, normals and texture coordinates may be floats or (as
//!   `KHR_mesh_quantization` allows) integers, normalised when the accessor says so;
//!   sparse accessors are applied. Non-finite values and indices past the vertex count
//!   are errors. When a primitive has no normals, its triangles get none, which makes the
//!   tracer shade with the geometric normal: the specification's "flat normals". The
//!   texture coordinate set is the one the material's base-color texture names
//!   (`TEXCOORD_0` by default); `v` is flipped (`v → 1 − v`), since glTF puts `v = 0` at
//!   the top of the image and this renderer at the bottom. Skins and morph targets are ignored: meshes keep their
//!   rest shape and follow their node.
//! - **Materials** (metallic–roughness → Phong), with base color `b` (factor times
//!   texture; the texture is applied by the tracer, which multiplies diffuse and ambient
//!   by it), metallic `m`, roughness `r` and transmission `τ`:
//!   - transmission `τ = transmissionFactor·(1 − m)` from `KHR_materials_transmission`
//!     (metals do not transmit), or `τ = 1 − alpha` for `alphaMode: BLEND` when larger
//!     (see-through without a separate alpha channel in this renderer); `ior` from
//!     `KHR_materials_ior`, default 1.5 — but 1 for the alpha-blend case, which must not
//!     refract;
//!   - specular (Phong highlight *and* mirror reflectance, one field in this renderer)
//!     `F0·(1 − r)²` with `F0 = lerp(0.04, b, m)`: smooth surfaces mirror their Fresnel
//!     reflectance at normal incidence, rough ones do not mirror at all;
//!   - diffuse `b·(1 − m)·(1 − τ) + b·m·(1 − (1 − r)²)`: the dielectric base plus the
//!     part of a metal's reflection too rough to be a mirror, so a rough metal looks like
//!     a matte surface of its color rather than black;
//!   - shininess `2/r⁴ − 2` (the Blinn–Phong exponent matching a GGX lobe of width `r²`),
//!     clamped to `[1, 10000]`;
//!   - ambient `0.1·diffuse + emissiveFactor` (the scene's global ambient is 1), so
//!     emissive surfaces glow without lighting anything else.
//!
//!   Metallic–roughness, normal, occlusion, emissive and transmission textures, sampler
//!   wrap and filter modes (lookups always repeat and filter bilinearly) and texture
//!   transforms are ignored. Colors and texels are used as stored, without transfer
//!   curves, like the rest of this pipeline. A primitive without a material gets
//!   [`Material::default`] (matte light grey) rather than glTF's default, a rough white
//!   metal that this mapping would render as flat white.
//! - **Images.** PNG and JPEG (by content, whatever the MIME type says), and, beyond the
//!   specification, binary PPM; from a buffer view, a `data:` URI or a file relative to
//!   the glTF file. A missing image file is an error naming it.
//! - **Cameras.** The first perspective camera met in depth-first node order, or with
//!   [`load_with_camera`] the one whose node or camera name matches. Its node's world
//!   matrix at `t = 0` gives the eye (origin), view direction (−Z) and up (+Y); `yfov`
//!   gives the field of view and `znear` the near plane; the aspect ratio is ignored (the
//!   image size decides). Orthographic cameras are skipped with a warning. When the camera
//!   node or an ancestor is animated, the camera follows it through a keyframe track
//!   sampled from the node's world transform at 120 Hz over the animation range (at most
//!   20 000 samples): exact at the samples, Catmull–Rom in between, so step changes are
//!   softened over one sample interval. With no usable camera, one is placed on the +Z
//!   side of the scene's bounds at `t = 0`, looking down −Z at their center with a 45°
//!   vertical field of view, far enough for the bounding sphere to fit vertically.
//! - **Lights** (`KHR_lights_punctual`). This renderer's lights have no falloff, so a
//!   light's unitless color is the illuminance it delivers at a reference distance:
//!   `color·intensity/d²` for point and spot lights, with `d` the distance from the light
//!   to the center of the scene bounds at `t = 0` but at least a quarter of the bounding
//!   radius; `color·intensity` (already lux) for directional lights. Spot cones and
//!   `range` are ignored (spots shine as points). A directional light becomes a point
//!   light 1000 bounding radii from the center, against its direction. Point and spot
//!   lights on animated nodes follow them the way the camera does (position only); a
//!   directional light keeps its direction at `t = 0`. With no lights, one white light of
//!   color 1 is placed above and to the right of the camera at `t = 0`.
//! - **Extensions.** A file requiring an extension other than `KHR_lights_punctual`,
//!   `KHR_materials_ior`, `KHR_materials_transmission` or `KHR_mesh_quantization` is
//!   rejected, since it cannot be shown as intended.
//! - **Scene settings.** Background `(0.2, 0.22, 0.25)`, global ambient 1, animation
//!   range from `min(0, first key)` to the last key of any channel that moves a node of
//!   the scene (nominally 30 frames per second).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ::gltf::json;
use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use json::validation::Checked;

use super::{
    animation::{KeyframeTrack, RotationSpline, TcbKey, VectorSpline},
    texture::MAX_TEXTURE_SIDE,
    AnimationRange, Camera, CameraTrack, Group, Light, Material, MaterialId, Node, NodeId,
    NodeKind, Scene, SceneError, Texture, TextureId, Triangle,
};

/// Background color of scenes from formats that do not declare one.
pub(crate) const BACKGROUND: Vec3 = Vec3::new(0.2, 0.22, 0.25);

/// Largest element count of an accessor without a buffer view (its data are zeros, so no
/// file size bounds it).
const MAX_ZERO_ELEMENTS: u64 = 1 << 24;

/// Largest number of triangles a scene may expand to (meshes are copied per node).
pub(crate) const MAX_TRIANGLES: usize = 1 << 26;

/// Rate at which animated camera and light nodes are sampled into keyframe tracks, Hz.
const BAKE_RATE: f32 = 120.0;

/// Most samples in one baked track.
const MAX_BAKE_SAMPLES: usize = 20_000;

/// Extensions whose requirement this loader can honour.
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_mesh_quantization",
];

/// How a glTF animation sampler interpolates between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// The value of the latest key at or before `t`.
    Step,
    /// Linear interpolation; spherical (slerp) for rotations.
    Linear,
    /// Cubic Hermite spline with explicit in- and out-tangents per key.
    CubicSpline,
}

/// Which node property a sampler drives; decides how values are interpolated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SamplerTarget {
    /// Translation, a 3-vector.
    Translation,
    /// Rotation, a unit quaternion `(x, y, z, w)`.
    Rotation,
    /// Scale, a 3-vector.
    Scale,
}

/// One glTF animation sampler bound to a node property.
///
/// Values are stored as 4-vectors (`w = 0` for translation and scale; `(x, y, z, w)` for
/// rotations) so one evaluator serves all three properties.
#[derive(Clone, Debug, PartialEq)]
pub struct Sampler {
    target: SamplerTarget,
    interpolation: Interpolation,
    times: Vec<f32>,
    values: Vec<Vec4>,
}

impl Sampler {
    /// Build a sampler. `values` holds one value per key, or for
    /// [`Interpolation::CubicSpline`] three per key (in-tangent, value, out-tangent).
    /// Key times must be finite and non-decreasing, values finite, and there must be at
    /// least one key; the error says what is wrong.
    pub fn new(
        target: SamplerTarget,
        interpolation: Interpolation,
        times: Vec<f32>,
        values: Vec<Vec4>,
    ) -> Result<Self, String> {
        if times.is_empty() {
            return Err("sampler has no keys".into());
        }
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            return Err(format!("key time {i} is not finite"));
        }
        if let Some(i) = times.windows(2).position(|w| w[1] < w[0]) {
            return Err(format!(
                "key times decrease at key {}: {} after {}",
                i + 1,
                times[i + 1],
                times[i]
            ));
        }
        let per_key = if interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        if values.len() != times.len() * per_key {
            return Err(format!(
                "{} output values for {} keys ({} expected)",
                values.len(),
                times.len(),
                times.len() * per_key
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("output value {i} is not finite"));
        }
        Ok(Self {
            target,
            interpolation,
            times,
            values,
        })
    }

    /// The property this sampler drives.
    pub fn target(&self) -> SamplerTarget {
        self.target
    }

    /// The interpolation mode.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Key times, seconds.
    pub fn times(&self) -> &[f32] {
        &self.times
    }

    /// The value at time `t`, held constant outside the key range. Rotations come back
    /// normalised (a degenerate result becomes the identity).
    pub fn eval(&self, t: f32) -> Vec4 {
        let times = &self.times;
        let n = times.len();
        let cubic = self.interpolation == Interpolation::CubicSpline;
        let key = |k: usize| {
            if cubic {
                self.values[3 * k + 1]
            } else {
                self.values[k]
            }
        };
        let v = if t.is_nan() || t <= times[0] {
            key(0)
        } else if t >= times[n - 1] {
            key(n - 1)
        } else {
            // first < t < last, so the first key after t exists and is not key 0.
            let k1 = times.partition_point(|&x| x <= t);
            let k0 = k1 - 1;
            let dt = times[k1] - times[k0];
            let u = ((t - times[k0]) / dt).clamp(0.0, 1.0);
            match self.interpolation {
                Interpolation::Step => key(k0),
                Interpolation::Linear if self.target == SamplerTarget::Rotation => {
                    slerp(key(k0), key(k1), u)
                }
                Interpolation::Linear => key(k0).lerp(key(k1), u),
                Interpolation::CubicSpline => {
                    let (v0, b0) = (self.values[3 * k0 + 1], self.values[3 * k0 + 2]);
                    let (a1, v1) = (self.values[3 * k1], self.values[3 * k1 + 1]);
                    let (u2, u3) = (u * u, u * u * u);
                    v0 * (2.0 * u3 - 3.0 * u2 + 1.0)
                        + b0 * (dt * (u3 - 2.0 * u2 + u))
                        + v1 * (-2.0 * u3 + 3.0 * u2)
                        + a1 * (dt * (u3 - u2))
                }
            }
        };
        if self.target == SamplerTarget::Rotation {
            v.try_normalize().unwrap_or(Vec4::W)
        } else {
            v
        }
    }
}

/// The glTF specification's slerp: along the shorter arc, with a linear fallback where
/// the two rotations (nearly) coincide and the formula divides by zero.
fn slerp(a: Vec4, b: Vec4, u: f32) -> Vec4 {
    let d = a.dot(b);
    let s = if d < 0.0 { -1.0 } else { 1.0 };
    let angle = d.abs().min(1.0).acos();
    let sin = angle.sin();
    if sin < 1e-6 {
        return a.lerp(b * s, u);
    }
    a * (((1.0 - u) * angle).sin() / sin) + b * (s * (u * angle).sin() / sin)
}

/// A node whose transform glTF animation channels drive: its rest TRS and the samplers
/// that override parts of it.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeAnimation {
    /// The glTF node's name, or `node N` when it has none.
    pub name: String,
    /// Rest translation, used when no translation sampler is set.
    pub translation: Vec3,
    /// Rest rotation, used when no rotation sampler is set.
    pub rotation: Quat,
    /// Rest scale, used when no scale sampler is set.
    pub scale: Vec3,
    /// Translation sampler.
    pub translation_sampler: Option<Sampler>,
    /// Rotation sampler.
    pub rotation_sampler: Option<Sampler>,
    /// Scale sampler.
    pub scale_sampler: Option<Sampler>,
}

impl NodeAnimation {
    /// Translation at time `t`.
    pub fn translation_at(&self, t: f32) -> Vec3 {
        self.translation_sampler
            .as_ref()
            .map_or(self.translation, |s| s.eval(t).truncate())
    }

    /// Rotation at time `t` (unit quaternion).
    pub fn rotation_at(&self, t: f32) -> Quat {
        let q = self
            .rotation_sampler
            .as_ref()
            .map_or(Vec4::from(self.rotation), |s| s.eval(t));
        Quat::from_vec4(q.try_normalize().unwrap_or(Vec4::W))
    }

    /// Scale at time `t`.
    pub fn scale_at(&self, t: f32) -> Vec3 {
        self.scale_sampler
            .as_ref()
            .map_or(self.scale, |s| s.eval(t).truncate())
    }

    /// Local matrix `T(t)·R(t)·S(t)`.
    pub fn matrix(&self, t: f32) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            self.scale_at(t),
            self.rotation_at(t),
            self.translation_at(t),
        )
    }
}

/// Load a glTF scene, viewed through its first perspective camera.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with_camera(path, None)
}

/// Load a glTF scene, viewed through the camera whose node or camera object is named
/// `camera_name` (the first perspective camera when `None`). Naming a camera that does
/// not exist, or an orthographic one, is an error.
pub fn load_with_camera(path: &Path, camera_name: Option<&str>) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| SceneError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let (root, blob) = parse_container(&file, &bytes)?;
    let dir = path
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let mut doc = Doc {
        file,
        dir,
        root,
        buffers: Vec::new(),
    };
    doc.check_required_extensions()?;
    doc.load_buffers(blob)?;
    let mut b = Build::new(&doc, path);
    b.run(camera_name)?;
    Ok(b.scene)
}

/// Split a file into its JSON document and, for `.glb`, the binary chunk.
fn parse_container(file: &str, bytes: &[u8]) -> Result<(json::Root, Option<Vec<u8>>), SceneError> {
    let invalid = |message: String| SceneError::Invalid {
        name: file.to_string(),
        message,
    };
    let (json_bytes, blob, where_) = if bytes.starts_with(b"glTF") {
        let (j, b) = parse_glb(bytes).map_err(|m| invalid(format!("malformed .glb: {m}")))?;
        (j, b, " (in the .glb JSON chunk)")
    } else {
        // A UTF-8 byte order mark is not allowed, but harmless.
        (
            bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes),
            None,
            "",
        )
    };
    let root: json::Root = serde_json::from_slice(json_bytes).map_err(|e| {
        let text = e.to_string();
        let message = match text.rfind(" at line ") {
            Some(i) => text[..i].to_string(),
            None => text,
        };
        SceneError::Parse {
            file: file.to_string(),
            line: e.line().max(1),
            column: e.column().max(1),
            message: format!("{message}{where_}"),
        }
    })?;
    if !root.asset.version.starts_with("2.") {
        return Err(invalid(format!(
            "glTF version {} is not supported (2.x expected)",
            root.asset.version
        )));
    }
    Ok((root, blob.map(<[u8]>::to_vec)))
}

fn le_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// The JSON and BIN chunks of a binary glTF file.
fn parse_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    if bytes.len() < 12 {
        return Err(format!(
            "truncated: {} bytes, the header alone needs 12",
            bytes.len()
        ));
    }
    let version = le_u32(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(format!("container version {version} (2 expected)"));
    }
    let length = le_u32(bytes, 8).unwrap_or(0) as usize;
    if length > bytes.len() {
        return Err(format!(
            "truncated: the header declares {length} bytes, the file has {}",
            bytes.len()
        ));
    }
    if length < 12 {
        return Err(format!("the header declares a length of {length} bytes"));
    }
    let data = &bytes[..length];
    let mut pos = 12usize;
    let mut json_chunk = None;
    let mut bin_chunk = None;
    while pos < data.len() {
        let (Some(len), Some(kind)) = (le_u32(data, pos), le_u32(data, pos + 4)) else {
            return Err(format!("truncated chunk header at byte {pos}"));
        };
        let start = pos + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                format!(
                    "truncated: chunk at byte {pos} declares {len} bytes, {} remain",
                    data.len() - start.min(data.len())
                )
            })?;
        let chunk = &data[start..end];
        match kind {
            JSON if json_chunk.is_none() && pos == 12 => json_chunk = Some(chunk),
            JSON => return Err(format!("unexpected second JSON chunk at byte {pos}")),
            _ if json_chunk.is_none() => return Err("the first chunk is not JSON".into()),
            BIN if bin_chunk.is_none() => bin_chunk = Some(chunk),
            // Unknown chunk types must be ignored.
            _ => {}
        }
        // Chunks are 4-byte aligned; tolerate writers that forgot the padding at the end.
        pos = end.saturating_add(3) & !3;
    }
    let json_chunk = json_chunk.ok_or("no JSON chunk")?;
    Ok((json_chunk, bin_chunk))
}

/// Decode standard or URL-safe base64, with or without padding.
fn base64_decode(text: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    let mut padding = false;
    for (i, c) in text.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => {
                padding = true;
                continue;
            }
            c if c.is_ascii_whitespace() => continue,
            _ => return Err(format!("invalid base64 character at offset {i}")),
        };
        if padding {
            return Err(format!("base64 data continues after padding at offset {i}"));
        }
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// Decode `%XX` escapes of a relative URI into a path string.
fn percent_decode(uri: &str) -> Result<String, String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("bad percent escape at offset {i}"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| "percent escapes do not decode to UTF-8".to_string())
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

/// Decode a PNG, JPEG or binary PPM image into a texture; the error is a plain
/// description. PNG and JPEG go through the `gltf` crate's image decoding (the `image`
/// crate it brings), fed through a one-image in-memory document so that no further
/// dependency is needed.
pub(crate) fn decode_image(name: &str, bytes: &[u8]) -> Result<Texture, String> {
    let mime =
        sniff_image(bytes).ok_or("unsupported image format (PNG, JPEG or binary PPM expected)")?;
    if mime == "image/x-portable-pixmap" {
        return Texture::parse_ppm(name, bytes);
    }
    let value = serde_json::json!({
        "asset": { "version": "2.0" },
        "buffers": [{ "byteLength": bytes.len() }],
        "bufferViews": [{ "buffer": 0, "byteLength": bytes.len() }],
        "images": [{ "bufferView": 0, "mimeType": mime }],
    });
    let root: json::Root = serde_json::from_value(value).map_err(|e| e.to_string())?;
    let document = ::gltf::Document::from_json_without_validation(root);
    let image = document
        .images()
        .next()
        .ok_or("internal: no image in the decoding document")?;
    let data = ::gltf::image::Data::from_source(
        image.source(),
        None,
        &[::gltf::buffer::Data(bytes.to_vec())],
    )
    .map_err(|e| format!("cannot decode {mime}: {e}"))?;
    decoded_to_texture(name, &data)
}

fn decoded_to_texture(name: &str, data: &::gltf::image::Data) -> Result<Texture, String> {
    use ::gltf::image::Format;
    let (w, h) = (data.width, data.height);
    if w == 0 || h == 0 || w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
        return Err(format!("absurd size {w}x{h}"));
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
        return Err(format!(
            "decoder returned {} bytes for {w}x{h} {:?}",
            data.pixels.len(),
            data.format
        ));
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
    Ok(Texture {
        name: name.to_string(),
        width: w,
        height: h,
        texels,
    })
}

/// The parsed file: JSON model and buffer contents, with checked access to both.
struct Doc {
    file: String,
    dir: PathBuf,
    root: json::Root,
    buffers: Vec<Vec<u8>>,
}

/// Decoded accessor contents: `count × comps` values, row by row.
struct Elements {
    values: Vec<f64>,
    comps: usize,
}

fn type_name(t: json::accessor::Type) -> &'static str {
    use json::accessor::Type::*;
    match t {
        Scalar => "SCALAR",
        Vec2 => "VEC2",
        Vec3 => "VEC3",
        Vec4 => "VEC4",
        Mat2 => "MAT2",
        Mat3 => "MAT3",
        Mat4 => "MAT4",
    }
}

fn component_size(c: json::accessor::ComponentType) -> usize {
    use json::accessor::ComponentType::*;
    match c {
        I8 | U8 => 1,
        I16 | U16 => 2,
        U32 | F32 => 4,
    }
}

/// One component, as stored (no normalisation). `b` holds exactly its bytes.
fn component(b: &[u8], c: json::accessor::ComponentType) -> f64 {
    use json::accessor::ComponentType::*;
    match c {
        I8 => b[0] as i8 as f64,
        U8 => b[0] as f64,
        I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

/// The specification's normalised-integer decoding.
fn normalize(v: f64, c: json::accessor::ComponentType) -> f64 {
    use json::accessor::ComponentType::*;
    match c {
        I8 => (v / 127.0).max(-1.0),
        U8 => v / 255.0,
        I16 => (v / 32767.0).max(-1.0),
        U16 => v / 65535.0,
        U32 => v / 4_294_967_295.0,
        F32 => v,
    }
}

impl Doc {
    fn invalid(&self, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            name: self.file.clone(),
            message: message.into(),
        }
    }

    fn check_required_extensions(&self) -> Result<(), SceneError> {
        for e in &self.root.extensions_required {
            if !SUPPORTED_REQUIRED.contains(&e.as_str()) {
                return Err(self.invalid(format!(
                    "requires extension {e}, which this loader does not support (supported: {})",
                    SUPPORTED_REQUIRED.join(", ")
                )));
            }
        }
        Ok(())
    }

    /// Bytes behind a URI: `data:` (base64), `file:` or a path relative to the file.
    fn read_uri(&self, uri: &str, what: &str) -> Result<Vec<u8>, SceneError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let (_, payload) = rest
                .split_once(";base64,")
                .ok_or_else(|| self.invalid(format!("{what}: data URI is not base64")))?;
            return base64_decode(payload)
                .map_err(|m| self.invalid(format!("{what}: bad data URI: {m}")));
        }
        let path = if let Some(rest) = uri.strip_prefix("file:") {
            let rest = rest.strip_prefix("//").unwrap_or(rest);
            PathBuf::from(percent_decode(rest).map_err(|m| self.invalid(format!("{what}: {m}")))?)
        } else if uri.split('/').next().is_some_and(|s| s.contains(':')) {
            return Err(self.invalid(format!(
                "{what}: URI scheme of `{uri}` is not supported (relative paths, file: and data: are)"
            )));
        } else {
            self.dir
                .join(percent_decode(uri).map_err(|m| self.invalid(format!("{what}: {m}")))?)
        };
        std::fs::read(&path).map_err(|e| SceneError::Io {
            path: path.clone(),
            message: format!("{e} ({what} of {})", self.file),
        })
    }

    fn load_buffers(&mut self, mut blob: Option<Vec<u8>>) -> Result<(), SceneError> {
        let mut buffers = Vec::with_capacity(self.root.buffers.len());
        for (i, b) in self.root.buffers.iter().enumerate() {
            let what = format!("buffer {i}");
            let mut data = match &b.uri {
                Some(uri) => self.read_uri(uri, &what)?,
                None => blob.take().ok_or_else(|| {
                    self.invalid(format!(
                        "{what} has no uri, and the file has no (unclaimed) binary chunk"
                    ))
                })?,
            };
            let len = b.byte_length.0;
            if (data.len() as u64) < len {
                return Err(self.invalid(format!(
                    "{what} holds {} bytes, but its byteLength is {len} (truncated file?)",
                    data.len()
                )));
            }
            data.truncate(len as usize);
            buffers.push(data);
        }
        self.buffers = buffers;
        Ok(())
    }

    /// The bytes of a buffer view, checked against its buffer.
    fn view_bytes(&self, index: usize, ctx: &str) -> Result<&[u8], SceneError> {
        let v = self.root.buffer_views.get(index).ok_or_else(|| {
            self.invalid(format!(
                "{ctx}: bufferView {index} does not exist ({} defined)",
                self.root.buffer_views.len()
            ))
        })?;
        let bi = v.buffer.value();
        let buf = self.buffers.get(bi).ok_or_else(|| {
            self.invalid(format!(
                "{ctx}: bufferView {index} refers to buffer {bi}, which does not exist ({} defined)",
                self.buffers.len()
            ))
        })?;
        let off = v.byte_offset.map_or(0, |o| o.0);
        let len = v.byte_length.0;
        let end = off
            .checked_add(len)
            .filter(|&e| e <= buf.len() as u64)
            .ok_or_else(|| {
                self.invalid(format!(
                "{ctx}: bufferView {index} (bytes {off}..{}) lies outside buffer {bi} ({} bytes)",
                off.saturating_add(len),
                buf.len()
            ))
            })?;
        Ok(&buf[off as usize..end as usize])
    }

    /// Decode an accessor of one of the `allowed` types, checking every range.
    fn read_accessor(
        &self,
        index: usize,
        ctx: &str,
        allowed: &[json::accessor::Type],
    ) -> Result<Elements, SceneError> {
        let ctx = format!("{ctx}: accessor {index}");
        let acc = self.root.accessors.get(index).ok_or_else(|| {
            self.invalid(format!(
                "{ctx} does not exist ({} defined)",
                self.root.accessors.len()
            ))
        })?;
        let Checked::Valid(json::accessor::GenericComponentType(ct)) = acc.component_type else {
            return Err(self.invalid(format!("{ctx} has an invalid componentType")));
        };
        let Checked::Valid(ty) = acc.type_ else {
            return Err(self.invalid(format!("{ctx} has an invalid type")));
        };
        if !allowed.contains(&ty) {
            let names: Vec<_> = allowed.iter().map(|t| type_name(*t)).collect();
            return Err(self.invalid(format!(
                "{ctx} is {}, expected {}",
                type_name(ty),
                names.join(" or ")
            )));
        }
        let comps = ty.multiplicity();
        let size = component_size(ct);
        let elem = (size * comps) as u64;
        let count = acc.count.0;
        let mut values = match acc.buffer_view {
            Some(view) => {
                let vi = view.value();
                let bytes = self.view_bytes(vi, &ctx)?;
                let stride = match self.root.buffer_views.get(vi).and_then(|v| v.byte_stride) {
                    Some(s) if (s.0 as u64) < elem => {
                        return Err(self.invalid(format!(
                            "{ctx}: byteStride {} is smaller than an element ({elem} bytes)",
                            s.0
                        )))
                    }
                    Some(s) => s.0 as u64,
                    None => elem,
                };
                let off = acc.byte_offset.map_or(0, |o| o.0);
                if count > 0 {
                    let need = (count - 1)
                        .checked_mul(stride)
                        .and_then(|x| x.checked_add(elem))
                        .and_then(|x| x.checked_add(off));
                    if need.is_none_or(|n| n > bytes.len() as u64) {
                        return Err(self.invalid(format!(
                            "{ctx}: {count} elements at offset {off} (stride {stride}) do not fit in bufferView {vi} ({} bytes)",
                            bytes.len()
                        )));
                    }
                }
                let mut values = Vec::with_capacity(count as usize * comps);
                for i in 0..count as usize {
                    let start = off as usize + i * stride as usize;
                    for c in 0..comps {
                        let at = start + c * size;
                        values.push(component(&bytes[at..at + size], ct));
                    }
                }
                values
            }
            None => {
                if count > MAX_ZERO_ELEMENTS {
                    return Err(self.invalid(format!(
                        "{ctx} has {count} elements but no data (at most {MAX_ZERO_ELEMENTS} allowed)"
                    )));
                }
                vec![0.0; count as usize * comps]
            }
        };
        if let Some(sp) = &acc.sparse {
            self.apply_sparse(sp, &ctx, ct, comps, count, &mut values)?;
        }
        if acc.normalized {
            for v in &mut values {
                *v = normalize(*v, ct);
            }
        }
        Ok(Elements { values, comps })
    }

    fn apply_sparse(
        &self,
        sp: &json::accessor::sparse::Sparse,
        ctx: &str,
        ct: json::accessor::ComponentType,
        comps: usize,
        count: u64,
        values: &mut [f64],
    ) -> Result<(), SceneError> {
        let n = sp.count.0;
        if n > count {
            return Err(self.invalid(format!(
                "{ctx}: sparse count {n} exceeds the accessor's count {count}"
            )));
        }
        let Checked::Valid(json::accessor::IndexComponentType(ict)) = sp.indices.component_type
        else {
            return Err(self.invalid(format!(
                "{ctx}: sparse indices have an invalid componentType"
            )));
        };
        let isize_ = component_size(ict) as u64;
        let ibytes = self.view_bytes(sp.indices.buffer_view.value(), ctx)?;
        let ioff = sp.indices.byte_offset.0;
        let vsize = (component_size(ct) * comps) as u64;
        let vbytes = self.view_bytes(sp.values.buffer_view.value(), ctx)?;
        let voff = sp.values.byte_offset.0;
        let fits = |off: u64, each: u64, len: usize| {
            n.checked_mul(each)
                .and_then(|x| x.checked_add(off))
                .is_some_and(|e| e <= len as u64)
        };
        if !fits(ioff, isize_, ibytes.len()) || !fits(voff, vsize, vbytes.len()) {
            return Err(self.invalid(format!(
                "{ctx}: sparse indices or values do not fit in their buffer views"
            )));
        }
        let csize = component_size(ct);
        for k in 0..n as usize {
            let at = ioff as usize + k * isize_ as usize;
            let target = component(&ibytes[at..at + isize_ as usize], ict);
            if target >= count as f64 {
                return Err(self.invalid(format!(
                    "{ctx}: sparse index {target} is out of range (count {count})"
                )));
            }
            let target = target as usize;
            for c in 0..comps {
                let at = voff as usize + k * vsize as usize + c * csize;
                values[target * comps + c] = component(&vbytes[at..at + csize], ct);
            }
        }
        Ok(())
    }

    /// An accessor read as finite `f32` values.
    fn floats(
        &self,
        index: usize,
        ctx: &str,
        allowed: &[json::accessor::Type],
    ) -> Result<(Vec<f32>, usize), SceneError> {
        let e = self.read_accessor(index, ctx, allowed)?;
        let mut out = Vec::with_capacity(e.values.len());
        for (i, &v) in e.values.iter().enumerate() {
            let f = v as f32;
            if !f.is_finite() {
                return Err(self.invalid(format!(
                    "{ctx}: accessor {index} element {} is not finite",
                    i / e.comps.max(1)
                )));
            }
            out.push(f);
        }
        Ok((out, e.comps))
    }

    fn vec3s(&self, index: usize, ctx: &str) -> Result<Vec<Vec3>, SceneError> {
        let (f, _) = self.floats(index, ctx, &[json::accessor::Type::Vec3])?;
        Ok(f.chunks_exact(3).map(Vec3::from_slice).collect())
    }

    /// Texture coordinates, flipped to this renderer's `v` (up).
    fn texcoords(&self, index: usize, ctx: &str) -> Result<Vec<Vec2>, SceneError> {
        let (f, _) = self.floats(index, ctx, &[json::accessor::Type::Vec2])?;
        Ok(f.chunks_exact(2)
            .map(|c| Vec2::new(c[0], 1.0 - c[1]))
            .collect())
    }

    /// Vertex indices, each checked against the vertex count.
    fn indices(&self, index: usize, ctx: &str, vertices: usize) -> Result<Vec<u32>, SceneError> {
        use json::accessor::ComponentType::*;
        let acc_ct = self.root.accessors.get(index).map(|a| a.component_type);
        if let Some(Checked::Valid(json::accessor::GenericComponentType(ct))) = acc_ct {
            if !matches!(ct, U8 | U16 | U32) || self.root.accessors[index].normalized {
                return Err(self.invalid(format!(
                    "{ctx}: index accessor {index} must hold unsigned, unnormalised integers"
                )));
            }
        }
        let e = self.read_accessor(index, ctx, &[json::accessor::Type::Scalar])?;
        let mut out = Vec::with_capacity(e.values.len());
        for (i, &v) in e.values.iter().enumerate() {
            if v >= vertices as f64 {
                return Err(self.invalid(format!(
                    "{ctx}: index {i} of accessor {index} is {v}, out of range for {vertices} vertices"
                )));
            }
            out.push(v as u32);
        }
        Ok(out)
    }

    /// Decode image `index` into a texture.
    fn image(&self, index: usize, ctx: &str) -> Result<Texture, SceneError> {
        let img = self.root.images.get(index).ok_or_else(|| {
            self.invalid(format!(
                "{ctx}: image {index} does not exist ({} defined)",
                self.root.images.len()
            ))
        })?;
        let what = format!("image {index}");
        let (bytes, name, path) = match (&img.uri, img.buffer_view) {
            (Some(uri), _) => {
                let bytes = self.read_uri(uri, &what)?;
                if uri.starts_with("data:") {
                    (bytes, what.clone(), PathBuf::from(&self.file))
                } else {
                    let name = uri.rsplit('/').next().unwrap_or(uri).to_string();
                    let path = self.dir.join(percent_decode(uri).unwrap_or_default());
                    (bytes, name, path)
                }
            }
            (None, Some(view)) => (
                self.view_bytes(view.value(), &format!("{ctx}: {what}"))?
                    .to_vec(),
                img.name.clone().unwrap_or_else(|| what.clone()),
                PathBuf::from(&self.file),
            ),
            (None, None) => {
                return Err(self.invalid(format!("{ctx}: {what} has neither uri nor bufferView")))
            }
        };
        decode_image(&name, &bytes).map_err(|m| SceneError::Texture {
            path,
            message: format!("{m} ({what} of {})", self.file),
        })
    }

    fn node_name(&self, index: usize) -> String {
        self.root
            .nodes
            .get(index)
            .and_then(|n| n.name.clone())
            .unwrap_or_else(|| format!("node {index}"))
    }
}

/// A node's local transform as written (matrix, or TRS with defaults).
fn node_trs(n: &json::Node) -> (Vec3, Quat, Vec3) {
    match n.matrix {
        Some(m) => {
            let (s, r, t) = Mat4::from_cols_array(&m).to_scale_rotation_translation();
            // A singular matrix has no decomposition: keep what is finite.
            let r = if r.is_finite() { r } else { Quat::IDENTITY };
            let s = if s.is_finite() { s } else { Vec3::ONE };
            (t, r, s)
        }
        None => (
            n.translation.map_or(Vec3::ZERO, Vec3::from),
            n.rotation.map_or(Quat::IDENTITY, |q| {
                Quat::from_vec4(Vec4::from(q.0).try_normalize().unwrap_or(Vec4::W))
            }),
            n.scale.map_or(Vec3::ONE, Vec3::from),
        ),
    }
}

fn node_matrix(n: &json::Node) -> Mat4 {
    match n.matrix {
        Some(m) => Mat4::from_cols_array(&m),
        None => {
            let (t, r, s) = node_trs(n);
            Mat4::from_scale_rotation_translation(s, r, t)
        }
    }
}

/// Samplers collected for one node from all animations.
#[derive(Default)]
struct Channels {
    translation: Option<Sampler>,
    rotation: Option<Sampler>,
    scale: Option<Sampler>,
}

/// Scene construction from a parsed document.
struct Build<'a> {
    doc: &'a Doc,
    scene: Scene,
    materials: HashMap<Option<usize>, MaterialId>,
    textures: HashMap<usize, TextureId>,
    warnings: Vec<String>,
    triangles: usize,
}

impl<'a> Build<'a> {
    fn new(doc: &'a Doc, path: &Path) -> Self {
        Self {
            doc,
            scene: Scene {
                name: path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                source: Some(path.to_path_buf()),
                background: BACKGROUND,
                ambient: Vec3::ONE,
                ..Default::default()
            },
            materials: HashMap::new(),
            textures: HashMap::new(),
            warnings: Vec::new(),
            triangles: 0,
        }
    }

    fn warn(&mut self, message: String) {
        if !self.warnings.contains(&message) {
            eprintln!("warning: {}: {message}", self.doc.file);
            self.warnings.push(message);
        }
    }

    fn run(&mut self, camera_name: Option<&str>) -> Result<(), SceneError> {
        let doc = self.doc;
        let root = &doc.root;
        let mut channels = self.collect_channels()?;
        let roots = self.scene_roots()?;

        // Depth-first, parents before children; glTF node index → scene node id.
        let mut ids: Vec<Option<NodeId>> = vec![None; root.nodes.len()];
        let mut cameras: Vec<(NodeId, usize, usize)> = Vec::new();
        let mut lights: Vec<(NodeId, usize)> = Vec::new();
        let mut range: Option<(f32, f32)> = None;
        let mut stack: Vec<(usize, Option<NodeId>)> =
            roots.into_iter().rev().map(|i| (i, None)).collect();
        while let Some((gi, parent)) = stack.pop() {
            let node = root.nodes.get(gi).ok_or_else(|| {
                doc.invalid(format!(
                    "node {gi} does not exist ({} defined)",
                    root.nodes.len()
                ))
            })?;
            if ids[gi].is_some() {
                return Err(doc.invalid(format!(
                    "node {gi} ({}) is reached twice: a node may have only one parent, and no cycles",
                    doc.node_name(gi)
                )));
            }
            let check = |what: &str, m: &[f32]| {
                if m.iter().all(|v| v.is_finite()) {
                    Ok(())
                } else {
                    Err(doc.invalid(format!("node {gi}: {what} is not finite")))
                }
            };
            check("matrix", &node.matrix.unwrap_or([0.0; 16]))?;
            check("translation", &node.translation.unwrap_or([0.0; 3]))?;
            check("rotation", &node.rotation.map_or([0.0; 4], |q| q.0))?;
            check("scale", &node.scale.unwrap_or([0.0; 3]))?;
            let kind = match channels.remove(&gi) {
                Some(ch) => {
                    let (translation, rotation, scale) = node_trs(node);
                    for s in [&ch.translation, &ch.rotation, &ch.scale]
                        .into_iter()
                        .flatten()
                    {
                        let (a, b) = (s.times[0], s.times[s.times.len() - 1]);
                        range = Some(range.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
                    }
                    NodeKind::Sampled(Box::new(NodeAnimation {
                        name: doc.node_name(gi),
                        translation,
                        rotation,
                        scale,
                        translation_sampler: ch.translation,
                        rotation_sampler: ch.rotation,
                        scale_sampler: ch.scale,
                    }))
                }
                None => NodeKind::Static(node_matrix(node)),
            };
            let id = self.scene.nodes.len() as NodeId;
            self.scene.nodes.push(Node { parent, kind });
            ids[gi] = Some(id);
            if let Some(mesh) = node.mesh {
                let tris = self.mesh(mesh.value(), gi)?;
                if !tris.is_empty() {
                    self.scene.groups.push(Group {
                        node: Some(id),
                        triangles: tris,
                        ..Default::default()
                    });
                }
            }
            if let Some(c) = node.camera {
                cameras.push((id, gi, c.value()));
            }
            if let Some(l) = node
                .extensions
                .as_ref()
                .and_then(|e| e.khr_lights_punctual.as_ref())
            {
                lights.push((id, l.light.value()));
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), Some(id)));
            }
        }
        if let Some((a, b)) = range {
            let start = a.min(0.0);
            if b > start {
                self.scene.animation = Some(AnimationRange {
                    start,
                    end: b,
                    frames: ((b - start) * 30.0).round().clamp(1.0, u32::MAX as f32) as u32,
                });
            }
        }
        let bounds = world_bounds(&self.scene, 0.0);
        self.camera(&cameras, camera_name, bounds)?;
        self.lights(&lights, bounds)?;
        if self.scene.lights.is_empty() {
            self.scene
                .lights
                .push(default_light(&self.scene.camera.base));
        }
        Ok(())
    }

    /// Roots of the scene to show.
    fn scene_roots(&self) -> Result<Vec<usize>, SceneError> {
        let root = &self.doc.root;
        let chosen = match root.scene {
            Some(s) => Some(root.scenes.get(s.value()).ok_or_else(|| {
                self.doc.invalid(format!(
                    "default scene {} does not exist ({} defined)",
                    s.value(),
                    root.scenes.len()
                ))
            })?),
            None => root.scenes.first(),
        };
        Ok(match chosen {
            Some(s) => s.nodes.iter().map(|n| n.value()).collect(),
            None => {
                let mut is_child = vec![false; root.nodes.len()];
                for n in &root.nodes {
                    for c in n.children.iter().flatten() {
                        if let Some(f) = is_child.get_mut(c.value()) {
                            *f = true;
                        }
                    }
                }
                (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
            }
        })
    }

    /// Samplers of every animation, by target node.
    fn collect_channels(&mut self) -> Result<HashMap<usize, Channels>, SceneError> {
        use json::animation::{Interpolation as I, Property};
        let doc = self.doc;
        let mut out: HashMap<usize, Channels> = HashMap::new();
        for (ai, anim) in doc.root.animations.iter().enumerate() {
            for (ci, ch) in anim.channels.iter().enumerate() {
                let ctx = format!("animation {ai} channel {ci}");
                let target = match ch.target.path {
                    Checked::Valid(Property::Translation) => SamplerTarget::Translation,
                    Checked::Valid(Property::Rotation) => SamplerTarget::Rotation,
                    Checked::Valid(Property::Scale) => SamplerTarget::Scale,
                    Checked::Valid(Property::MorphTargetWeights) => {
                        self.warn("morph target weight animation is ignored".into());
                        continue;
                    }
                    Checked::Invalid => {
                        return Err(doc.invalid(format!("{ctx}: invalid target path")));
                    }
                };
                let node = ch.target.node.value();
                if node >= doc.root.nodes.len() {
                    return Err(doc.invalid(format!(
                        "{ctx}: target node {node} does not exist ({} defined)",
                        doc.root.nodes.len()
                    )));
                }
                let si = ch.sampler.value();
                let s = anim.samplers.get(si).ok_or_else(|| {
                    doc.invalid(format!(
                        "{ctx}: sampler {si} does not exist ({} defined)",
                        anim.samplers.len()
                    ))
                })?;
                let interpolation = match s.interpolation {
                    Checked::Valid(I::Step) => Interpolation::Step,
                    Checked::Valid(I::Linear) => Interpolation::Linear,
                    Checked::Valid(I::CubicSpline) => Interpolation::CubicSpline,
                    Checked::Invalid => {
                        return Err(doc.invalid(format!("{ctx}: invalid interpolation")));
                    }
                };
                let (times, _) = doc.floats(
                    s.input.value(),
                    &format!("{ctx} input"),
                    &[json::accessor::Type::Scalar],
                )?;
                let ty = if target == SamplerTarget::Rotation {
                    json::accessor::Type::Vec4
                } else {
                    json::accessor::Type::Vec3
                };
                let (vals, comps) =
                    doc.floats(s.output.value(), &format!("{ctx} output"), &[ty])?;
                let values = vals
                    .chunks_exact(comps)
                    .map(|c| {
                        if comps == 4 {
                            Vec4::from_slice(c)
                        } else {
                            Vec3::from_slice(c).extend(0.0)
                        }
                    })
                    .collect();
                let sampler = Sampler::new(target, interpolation, times, values)
                    .map_err(|m| doc.invalid(format!("{ctx}: {m}")))?;
                let slot = out.entry(node).or_default();
                match target {
                    SamplerTarget::Translation => slot.translation = Some(sampler),
                    SamplerTarget::Rotation => slot.rotation = Some(sampler),
                    SamplerTarget::Scale => slot.scale = Some(sampler),
                }
            }
        }
        Ok(out)
    }

    /// Triangles of a mesh, in the space of its node.
    fn mesh(&mut self, index: usize, node: usize) -> Result<Vec<Triangle>, SceneError> {
        use json::mesh::{Mode, Semantic};
        let doc = self.doc;
        let mesh = doc.root.meshes.get(index).ok_or_else(|| {
            doc.invalid(format!(
                "node {node}: mesh {index} does not exist ({} defined)",
                doc.root.meshes.len()
            ))
        })?;
        let mut out = Vec::new();
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let ctx = format!("mesh {index} primitive {pi}");
            let mode = match prim.mode {
                Checked::Valid(m) => m,
                Checked::Invalid => return Err(doc.invalid(format!("{ctx}: invalid mode"))),
            };
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                self.warn(format!(
                    "{ctx}: {mode:?} primitives have no surface and are skipped"
                ));
                continue;
            }
            let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|i| i.value());
            let pos_index = attr(Semantic::Positions)
                .ok_or_else(|| doc.invalid(format!("{ctx}: no POSITION attribute")))?;
            let positions = doc.vec3s(pos_index, &format!("{ctx} POSITION"))?;
            let nv = positions.len();
            let normals = match attr(Semantic::Normals) {
                Some(i) => {
                    let n = doc.vec3s(i, &format!("{ctx} NORMAL"))?;
                    if n.len() != nv {
                        return Err(
                            doc.invalid(format!("{ctx}: {} normals for {nv} positions", n.len()))
                        );
                    }
                    Some(n)
                }
                None => None,
            };
            let material_index = prim.material.map(|m| m.value());
            let material = self.material(material_index, &ctx)?;
            let set = material_index
                .and_then(|m| doc.root.materials.get(m))
                .and_then(|m| m.pbr_metallic_roughness.base_color_texture.as_ref())
                .map_or(0, |t| t.tex_coord);
            let uvs = match attr(Semantic::TexCoords(set)) {
                Some(i) => {
                    let ctx = format!("{ctx} TEXCOORD_{set}");
                    let uv = doc.texcoords(i, &ctx)?;
                    if uv.len() != nv {
                        return Err(doc.invalid(format!(
                            "{ctx}: {} texture coordinates for {nv} positions",
                            uv.len()
                        )));
                    }
                    Some(uv)
                }
                None => None,
            };
            let indices = match prim.indices {
                Some(i) => Some(doc.indices(i.value(), &format!("{ctx} indices"), nv)?),
                None => None,
            };
            let n = indices.as_ref().map_or(nv, Vec::len);
            let at = |k: usize| indices.as_ref().map_or(k, |ix| ix[k] as usize);
            let tri_count = match mode {
                Mode::Triangles => n / 3,
                _ => n.saturating_sub(2),
            };
            if self.triangles + tri_count > MAX_TRIANGLES {
                return Err(doc.invalid(format!(
                    "{ctx}: the scene expands to more than {MAX_TRIANGLES} triangles"
                )));
            }
            for k in 0..tri_count {
                let v = match mode {
                    Mode::Triangles => [at(3 * k), at(3 * k + 1), at(3 * k + 2)],
                    // glTF 2.0 §3.7.2.1: strip p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2−i%2)}},
                    // fan p_i = {v_{i+1}, v_{i+2}, v_0}.
                    Mode::TriangleStrip => [at(k), at(k + 1 + k % 2), at(k + 2 - k % 2)],
                    _ => [at(k + 1), at(k + 2), at(0)],
                };
                if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
                    continue;
                }
                out.push(Triangle {
                    p: v.map(|i| positions[i]),
                    n: normals.as_ref().map(|ns| v.map(|i| ns[i])),
                    uv: uvs.as_ref().map(|uv| v.map(|i| uv[i])),
                    material,
                });
            }
            self.triangles += tri_count;
        }
        Ok(out)
    }

    /// The scene material for a glTF material index (`None`: the default material).
    fn material(&mut self, index: Option<usize>, ctx: &str) -> Result<MaterialId, SceneError> {
        if let Some(&id) = self.materials.get(&index) {
            return Ok(id);
        }
        let doc = self.doc;
        let m = match index {
            None => Material::default(),
            Some(i) => {
                let gm = doc.root.materials.get(i).ok_or_else(|| {
                    doc.invalid(format!(
                        "{ctx}: material {i} does not exist ({} defined)",
                        doc.root.materials.len()
                    ))
                })?;
                let texture = match &gm.pbr_metallic_roughness.base_color_texture {
                    Some(info) => Some(self.texture(info.index.value(), &format!("material {i}"))?),
                    None => None,
                };
                let mut m = convert_material(gm);
                if m.diffuse.is_nan()
                    || m.specular.is_nan()
                    || m.ambient.is_nan()
                    || m.shininess.is_nan()
                {
                    return Err(doc.invalid(format!("material {i} has non-finite factors")));
                }
                m.texture = texture;
                m
            }
        };
        self.scene.materials.push(m);
        let id = (self.scene.materials.len() - 1) as MaterialId;
        self.materials.insert(index, id);
        Ok(id)
    }

    fn texture(&mut self, index: usize, ctx: &str) -> Result<TextureId, SceneError> {
        let doc = self.doc;
        let tex = doc.root.textures.get(index).ok_or_else(|| {
            doc.invalid(format!(
                "{ctx}: texture {index} does not exist ({} defined)",
                doc.root.textures.len()
            ))
        })?;
        let image = tex.source.value();
        if let Some(&id) = self.textures.get(&image) {
            return Ok(id);
        }
        let t = doc.image(image, &format!("{ctx} texture {index}"))?;
        self.scene.textures.push(t);
        let id = (self.scene.textures.len() - 1) as TextureId;
        self.textures.insert(image, id);
        Ok(id)
    }

    fn camera(
        &mut self,
        cameras: &[(NodeId, usize, usize)],
        wanted: Option<&str>,
        bounds: Option<(Vec3, Vec3)>,
    ) -> Result<(), SceneError> {
        let doc = self.doc;
        let mut chosen = None;
        for &(id, gi, ci) in cameras {
            let cam = doc.root.cameras.get(ci).ok_or_else(|| {
                doc.invalid(format!(
                    "node {gi}: camera {ci} does not exist ({} defined)",
                    doc.root.cameras.len()
                ))
            })?;
            let label = cam.name.clone().unwrap_or_else(|| format!("camera {ci}"));
            if let Some(w) = wanted {
                if doc.root.nodes[gi].name.as_deref() != Some(w) && cam.name.as_deref() != Some(w) {
                    continue;
                }
            }
            match (&cam.perspective, cam.type_) {
                (Some(p), Checked::Valid(json::camera::Type::Perspective) | Checked::Invalid) => {
                    chosen = Some((id, gi, p.clone()));
                    break;
                }
                _ if wanted.is_some() => {
                    return Err(doc.invalid(format!(
                        "camera `{label}` is not a perspective camera (only pinhole cameras are supported)"
                    )));
                }
                _ => self.warn(format!(
                    "{label} is not a perspective camera and is ignored"
                )),
            }
        }
        let Some((id, gi, p)) = chosen else {
            if let Some(w) = wanted {
                let names: Vec<String> = cameras
                    .iter()
                    .map(|&(_, gi, ci)| {
                        let node = doc.node_name(gi);
                        match doc.root.cameras.get(ci).and_then(|c| c.name.clone()) {
                            Some(c) => format!("{node} ({c})"),
                            None => node,
                        }
                    })
                    .collect();
                return Err(doc.invalid(format!(
                    "no camera named `{w}` in the scene (cameras: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                )));
            }
            self.scene.camera = CameraTrack {
                base: default_camera(bounds),
                track: None,
                resolution: None,
            };
            return Ok(());
        };
        if !(p.yfov.is_finite() && p.yfov > 0.0) {
            return Err(doc.invalid(format!(
                "node {gi}: camera yfov {} is not a positive angle",
                p.yfov
            )));
        }
        let m = self.scene.node_world(id, 0.0);
        let (eye, at, up) = view_of(m);
        let hither = if p.znear.is_finite() && p.znear > 0.0 {
            p.znear
        } else {
            1e-3
        };
        let base = Camera {
            eye,
            at,
            up,
            fov_y_deg: p.yfov.to_degrees(),
            hither,
        };
        let track = if self.scene.node_is_animated(id) {
            self.bake(id, "camera", true)
        } else {
            None
        };
        self.scene.camera = CameraTrack {
            base,
            track,
            resolution: None,
        };
        Ok(())
    }

    fn lights(
        &mut self,
        lights: &[(NodeId, usize)],
        bounds: Option<(Vec3, Vec3)>,
    ) -> Result<(), SceneError> {
        use json::extensions::scene::khr_lights_punctual::Type as L;
        let doc = self.doc;
        let defined = doc
            .root
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map_or(&[][..], |l| &l.lights[..]);
        let (center, radius) = bounds.map_or((Vec3::ZERO, 1.0), |(lo, hi)| {
            ((lo + hi) * 0.5, ((hi - lo).length() * 0.5).max(1e-3))
        });
        for &(id, li) in lights {
            let l = defined.get(li).ok_or_else(|| {
                doc.invalid(format!(
                    "light {li} does not exist ({} defined)",
                    defined.len()
                ))
            })?;
            let color = Vec3::from(l.color) * l.intensity;
            if !color.is_finite() {
                return Err(doc.invalid(format!("light {li}: color or intensity is not finite")));
            }
            let m = self.scene.node_world(id, 0.0);
            let (color, position) = match l.type_ {
                Checked::Valid(L::Directional) => {
                    let dir = m.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
                    (color, center - dir * (1000.0 * radius))
                }
                Checked::Valid(L::Point | L::Spot) => {
                    let p = m.transform_point3(Vec3::ZERO);
                    let d = (p - center).length().max(0.25 * radius);
                    (color / (d * d), p)
                }
                Checked::Invalid => return Err(doc.invalid(format!("light {li}: invalid type"))),
            };
            let directional = matches!(l.type_, Checked::Valid(L::Directional));
            let name = l.name.clone().unwrap_or_else(|| format!("light {li}"));
            let track = if self.scene.node_is_animated(id) && !directional {
                self.bake(id, &name, false)
            } else {
                None
            };
            self.scene.lights.push(Light {
                position,
                color,
                track,
                name: Some(name),
            });
        }
        Ok(())
    }

    /// Sample a node's world transform over the animation range into a keyframe track
    /// (translation, and rotation when asked), for the camera and lights, which follow
    /// tracks rather than nodes.
    fn bake(&mut self, node: NodeId, name: &str, rotation: bool) -> Option<u32> {
        let range = self.scene.animation?;
        let (start, end) = (range.start, range.end);
        let samples = ((end - start) * BAKE_RATE)
            .ceil()
            .clamp(1.0, MAX_BAKE_SAMPLES as f32) as usize;
        let step = (end - start) / samples as f32;
        let mut tkeys = Vec::with_capacity(samples + 3);
        let mut rkeys = Vec::with_capacity(samples + 3);
        // One extra key before and after: the spline uses its end keys only for tangents.
        for i in -1..=samples as i64 + 1 {
            let t = start + step * i as f32;
            let (_, r, p) = self
                .scene
                .node_world(node, t)
                .to_scale_rotation_translation();
            let (axis, angle) = r.to_axis_angle();
            tkeys.push(tcb_key(t, p));
            rkeys.push(tcb_key(t, (axis, angle.to_degrees())));
        }
        let track = KeyframeTrack {
            name: name.to_string(),
            translation: VectorSpline::new(tkeys),
            rotation: if rotation {
                RotationSpline::new(rkeys)
            } else {
                None
            },
            ..Default::default()
        };
        self.scene.tracks.push(track);
        Some((self.scene.tracks.len() - 1) as u32)
    }
}

/// A Catmull–Rom key (tension, continuity and bias zero).
fn tcb_key<T>(time: f32, value: T) -> TcbKey<T> {
    TcbKey {
        time,
        value,
        tension: 0.0,
        continuity: 0.0,
        bias: 0.0,
    }
}

/// Eye, look-at point and up of a camera node's world matrix (looking down −Z, up +Y).
fn view_of(m: Mat4) -> (Vec3, Vec3, Vec3) {
    let eye = m.transform_point3(Vec3::ZERO);
    let dir = m.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
    let up = m.transform_vector3(Vec3::Y).normalize_or(Vec3::Y);
    (eye, eye + dir, up)
}

/// Map a metallic–roughness material to Phong (see the module documentation).
fn convert_material(gm: &json::Material) -> Material {
    let pbr = &gm.pbr_metallic_roughness;
    let [r, g, b, alpha] = pbr.base_color_factor.0;
    let base = Vec3::new(r, g, b);
    let metallic = pbr.metallic_factor.0.clamp(0.0, 1.0);
    let rough = pbr.roughness_factor.0.clamp(0.0, 1.0);
    let ext = gm.extensions.as_ref();
    let mut transmission = ext
        .and_then(|e| e.transmission.as_ref())
        .map_or(0.0, |t| t.transmission_factor.0.clamp(0.0, 1.0))
        * (1.0 - metallic);
    let mut ior = ext.and_then(|e| e.ior.as_ref()).map_or(1.5, |i| i.ior.0);
    if gm.alpha_mode == Checked::Valid(json::material::AlphaMode::Blend) {
        let see_through = (1.0 - alpha).clamp(0.0, 1.0);
        if see_through > transmission {
            transmission = see_through;
            ior = 1.0;
        }
    }
    let gloss = (1.0 - rough) * (1.0 - rough);
    let f0 = Vec3::splat(0.04).lerp(base, metallic);
    let diffuse = base * (1.0 - metallic) * (1.0 - transmission) + base * metallic * (1.0 - gloss);
    let r4 = rough.powi(4);
    let shininess = if r4 > 0.0 {
        (2.0 / r4 - 2.0).clamp(1.0, 10000.0)
    } else {
        10000.0
    };
    Material {
        ambient: diffuse * 0.1 + Vec3::from(gm.emissive_factor.0),
        diffuse,
        specular: f0 * gloss,
        shininess,
        transmission,
        ior,
        texture: None,
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn sampler(target: SamplerTarget, i: Interpolation, t: &[f32], v: &[Vec4]) -> Sampler {
        Sampler::new(target, i, t.to_vec(), v.to_vec()).unwrap()
    }

    #[test]
    fn base64_round_trip() {
        assert_eq!(base64_decode("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(base64_decode("aGVsbG8").unwrap(), b"hello");
        assert_eq!(base64_decode("AAEC/w==").unwrap(), [0, 1, 2, 255]);
        assert!(base64_decode("a$b").is_err());
    }

    #[test]
    fn percent_escapes() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert!(percent_decode("%FF").is_err());
        assert!(percent_decode("%G0").is_err());
        assert!(percent_decode("%2").is_err());
    }

    #[test]
    fn step_linear_and_clamping() {
        let t = [1.0, 2.0, 4.0];
        let v = [Vec4::ZERO, Vec4::X, Vec4::X * 3.0];
        let lin = sampler(SamplerTarget::Translation, Interpolation::Linear, &t, &v);
        assert_eq!(lin.eval(0.0), Vec4::ZERO);
        assert_eq!(lin.eval(f32::NAN), Vec4::ZERO);
        assert!((lin.eval(1.5).x - 0.5).abs() < 1e-6);
        assert!((lin.eval(3.0).x - 2.0).abs() < 1e-6);
        assert_eq!(lin.eval(9.0), Vec4::X * 3.0);
        let step = sampler(SamplerTarget::Translation, Interpolation::Step, &t, &v);
        assert_eq!(step.eval(1.99), Vec4::ZERO);
        assert_eq!(step.eval(2.0), Vec4::X);
        assert_eq!(step.eval(3.99), Vec4::X);
    }

    #[test]
    fn repeated_key_times_do_not_divide_by_zero() {
        let s = sampler(
            SamplerTarget::Translation,
            Interpolation::Linear,
            &[0.0, 1.0, 1.0, 2.0],
            &[Vec4::ZERO, Vec4::X, Vec4::Y, Vec4::Z],
        );
        for t in [0.5, 1.0, 1.5] {
            assert!(s.eval(t).is_finite());
        }
        assert_eq!(s.eval(1.0), Vec4::Y);
    }

    #[test]
    fn slerp_takes_the_short_way() {
        let a = Quat::IDENTITY;
        let b = -Quat::from_rotation_y(1.0); // same rotation as +1 rad, opposite sign
        let s = sampler(
            SamplerTarget::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[Vec4::from(a), Vec4::from(b)],
        );
        let q = Quat::from_vec4(s.eval(0.5));
        assert!(q.dot(Quat::from_rotation_y(0.5)).abs() > 1.0 - 1e-6);
    }

    #[test]
    fn rejects_bad_samplers() {
        let v = [Vec4::ZERO; 2];
        assert!(Sampler::new(SamplerTarget::Scale, Interpolation::Linear, vec![], vec![]).is_err());
        assert!(Sampler::new(
            SamplerTarget::Scale,
            Interpolation::Linear,
            vec![1.0, 0.0],
            v.to_vec()
        )
        .is_err());
        assert!(Sampler::new(
            SamplerTarget::Scale,
            Interpolation::CubicSpline,
            vec![0.0, 1.0],
            v.to_vec()
        )
        .is_err());
        assert!(Sampler::new(
            SamplerTarget::Scale,
            Interpolation::Linear,
            vec![0.0, f32::NAN],
            v.to_vec()
        )
        .is_err());
    }

    #[test]
    fn glb_container_errors() {
        assert!(parse_glb(b"glTF").is_err());
        let mut v = b"glTF".to_vec();
        v.extend_from_slice(&2u32.to_le_bytes());
        v.extend_from_slice(&100u32.to_le_bytes());
        assert!(parse_glb(&v).unwrap_err().contains("truncated"));
    }

    #[test]
    fn material_mapping() {
        let gm: json::Material = serde_json::from_str(
            r#"{"pbrMetallicRoughness":{"baseColorFactor":[1,0.5,0.25,1],"metallicFactor":0,"roughnessFactor":1}}"#,
        )
        .unwrap();
        let m = convert_material(&gm);
        assert!((m.diffuse - Vec3::new(1.0, 0.5, 0.25)).length() < 1e-6);
        assert_eq!(m.specular, Vec3::ZERO);
        assert_eq!(m.shininess, 1.0);
        let gm: json::Material = serde_json::from_str(
            r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.9,0.8,0.7,1],"metallicFactor":1,"roughnessFactor":0}}"#,
        )
        .unwrap();
        let m = convert_material(&gm);
        assert!((m.specular - Vec3::new(0.9, 0.8, 0.7)).length() < 1e-6);
        assert_eq!(m.diffuse, Vec3::ZERO);
        assert_eq!(m.shininess, 10000.0);
    }
}
