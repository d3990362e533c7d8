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

//!
//! # Code layout
//!
//! [`load_with_camera`] reads the file (`container.rs`: `.glb` chunks, JSON, buffers and
//! URIs), then walks the node hierarchy (`build.rs`), which asks for meshes (`mesh.rs`,
//! reading vertex data through `accessor.rs`), materials and their images
//! (`material.rs`) and animation samplers (`animation.rs`), and finally places the
//! camera (`camera.rs`) and lights (`light.rs`). What the OBJ loader shares with this
//! one (defaults, limits, image decoding) lives in `scene/loader.rs`.
//!
//! [`Node`]: super::Node
//! [`NodeKind::Static`]: super::NodeKind::Static
//! [`NodeKind::Sampled`]: super::NodeKind::Sampled
//! [`Triangle`]: super::Triangle
//! [`Group`]: super::Group
//! [`Material::default`]: super::Material::default

mod accessor;
mod animation;
mod build;
mod camera;
mod container;
mod light;
mod material;
mod mesh;

use std::path::{Path, PathBuf};

pub use animation::{Interpolation, NodeAnimation, Sampler, SamplerTarget};

use super::{Scene, SceneError};
use build::Build;
use container::{parse_container, Doc};

/// Extensions whose requirement this loader can honour.
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_mesh_quantization",
];

/// Load a glTF scene, viewed through its first perspective camera.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with_camera(path, None)
}

/// Load a glTF scene, viewed through the camera whose node or camera object is named
/// `camera_name` (the first perspective camera when `None`). Naming a camera that does
/// not exist, or an orthographic one, is an error.
pub fn load_with_camera(path: &Path, camera_name: Option<&str>) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let bytes = crate::scene::limits::read_bounded(path).map_err(|e| SceneError::Io {
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
    crate::scene::limits::check(&b.scene)?;
    Ok(b.scene)
}
