//! On-disk cache of ideal images.
//!
//! Ideal images dominate an evaluation's cost, so they are kept across runs and methods.
//! An entry is found by a hash of its key, but a file name proves nothing (files get
//! copied, swapped, re-encoded), so every entry carries its proof and is checked on
//! every read:
//!
//! - its full key, as explicit text ([`IdealCache::entry_key`]): [`CACHE_VERSION`], the
//!   tracer's [`RENDERER_VERSION`], a fingerprint of the scene's whole content
//!   ([`scene_fingerprint`]), the camera path as CSV, the image size, every tracer
//!   option, the time's exact bits, samples per pixel and seed;
//! - a checksum of its pixels;
//! - the exact format it was written in: 8-bit RGB PNG of the cache's size.
//!
//! Key and checksum live in tEXt chunks of the PNG itself, so an entry is one file,
//! written atomically (see [`crate::output`]). An entry that fails any check is
//! re-rendered and overwritten, and [`get_or_render`](IdealCache::get_or_render) says
//! so, for the caller to count.
//!
//! One cache folder may be shared by any number of runs at once: threads, processes,
//! and the shards of a sweep on several machines over a shared file system. Nothing is
//! locked. Two writers of one entry render the same pixels (rendering is
//! deterministic) and each renames its own temporary file into place, so either rename
//! leaves a whole, valid entry; a writer whose temporary name is taken (process ids
//! repeat across machines) does not store the entry, which the other does. A file
//! system that breaks these guarantees (a rename that is not atomic, a torn read) can
//! at worst show an entry that fails its checks: it is re-rendered, never served. The
//! cost of sharing is only work done twice while two writers race for a new entry.

use std::{
    fmt::{Debug, Write as _},
    path::{Path, PathBuf},
};

use glam::{Mat4, Quat, Vec2, Vec3};

use crate::{
    gpu::DeviceUsed,
    image::{read_png, write_png_rgb8_tagged, Image},
    render::still,
    sampling::rng::mix64,
    scene::{
        gltf::NodeAnimation, Camera, CameraPath, CameraTrack, KeyframeTrack, Material, NodeKind,
        Scene, Texture,
    },
    trace::{batch::GpuRays, TextureFilter, TraceOptions, Tracer, RENDERER_VERSION},
};

/// Bump when the still renderer's sampling or the stored format changes what an entry
/// holds. Changes to the tracer itself bump [`RENDERER_VERSION`] instead.
pub const CACHE_VERSION: u64 = 2;

/// tEXt keyword of an entry's key.
const KEY_CHUNK: &str = "frameless-cache-key";
/// tEXt keyword of an entry's pixel checksum.
const CHECKSUM_CHUNK: &str = "frameless-cache-checksum";

/// What a lookup found on disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookup {
    /// A valid entry was served.
    Hit,
    /// There was no entry; the image was rendered and stored.
    Miss,
    /// An entry was there but failed a check; the image was rendered and the entry
    /// overwritten.
    Rejected(Mismatch),
}

/// Why an entry on disk was not served.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mismatch {
    /// It does not decode as PNG.
    Unreadable,
    /// It is not 8-bit RGB (e.g. RGBA, grey, 16-bit).
    Format,
    /// Its size is not the cache's.
    Size,
    /// It carries no key, or another entry's key.
    Key,
    /// Its pixels do not match its checksum.
    Checksum,
}

/// A 64-bit streaming hash (SplitMix64 finaliser per word), for fingerprints, file
/// names and checksums. Fixed here, not `std`'s hasher, whose output may change between
/// Rust releases and would silently empty every cache.
struct Words(u64);

impl Words {
    fn new(seed: u64) -> Self {
        Self(mix64(seed))
    }
    fn u64(&mut self, w: u64) {
        self.0 = mix64(self.0 ^ w.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    }
    fn u32(&mut self, w: u32) {
        self.u64(w as u64);
    }
    /// Lengths and variant tags keep neighbouring fields from running into each other.
    fn tag(&mut self, n: usize) {
        self.u64(n as u64 ^ 0xa5a5_0000_0000_0000);
    }
    fn bool(&mut self, b: bool) {
        self.u64(b as u64);
    }
    fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
    fn f32s(&mut self, v: &[f32]) {
        self.tag(v.len());
        // Two values per word: textures and meshes are most of a scene's bytes.
        for pair in v.chunks(2) {
            let hi = pair.get(1).map_or(0, |x| x.to_bits());
            self.u64(pair[0].to_bits() as u64 | (hi as u64) << 32);
        }
    }
    fn vec2(&mut self, v: Vec2) {
        self.f32s(&v.to_array());
    }
    fn vec3(&mut self, v: Vec3) {
        self.f32s(&v.to_array());
    }
    fn vec3s(&mut self, v: &[Vec3]) {
        self.tag(v.len());
        for x in v {
            self.vec3(*x);
        }
    }
    fn quat(&mut self, q: Quat) {
        self.f32s(&q.to_array());
    }
    fn mat4(&mut self, m: &Mat4) {
        self.f32s(&m.to_cols_array());
    }
    fn bytes(&mut self, b: &[u8]) {
        self.tag(b.len());
        for chunk in b.chunks(8) {
            let mut w = [0u8; 8];
            w[..chunk.len()].copy_from_slice(chunk);
            self.u64(u64::from_le_bytes(w));
        }
    }
    fn str(&mut self, s: &str) {
        self.bytes(s.as_bytes());
    }
    fn opt<T>(&mut self, v: Option<T>, f: impl FnOnce(&mut Self, T)) {
        match v {
            None => self.tag(0),
            Some(x) => {
                self.tag(1);
                f(self, x);
            }
        }
    }
    /// For the few values whose fields the scene module keeps private (keyframes of a
    /// rotation spline, values of a glTF sampler): derived `Debug` prints every field and
    /// floats exactly. Should that text ever change, entries stop matching (a re-render),
    /// never match the wrong scene.
    fn debug(&mut self, v: &impl Debug) {
        self.str(&format!("{v:?}"));
    }
}

/// A hash of everything in a scene that can change its images.
///
/// Fields are walked one by one, each float by its bits. The structs are destructured
/// without `..` where their fields are public, so a field added to the scene model does
/// not compile here until it is hashed or deliberately skipped.
pub fn scene_fingerprint(scene: &Scene) -> u64 {
    let Scene {
        name,
        // Where the scene was loaded from is not what it shows; the same content copied
        // elsewhere keeps its entries.
        source: _,
        nodes,
        tracks,
        groups,
        animated_triangles,
        materials,
        textures,
        lights,
        camera,
        background,
        ambient,
        animation,
    } = scene;
    let mut h = Words::new(0x5ce7e);
    h.str(name);
    h.tag(nodes.len());
    for n in nodes {
        node(&mut h, n);
    }
    h.tag(tracks.len());
    for t in tracks {
        keyframe_track(&mut h, t);
    }
    h.tag(groups.len());
    for g in groups {
        group(&mut h, g);
    }
    h.tag(animated_triangles.len());
    for a in animated_triangles {
        animated_triangle(&mut h, a);
    }
    h.tag(materials.len());
    for m in materials {
        material(&mut h, m);
    }
    h.tag(textures.len());
    for t in textures {
        texture(&mut h, t);
    }
    h.tag(lights.len());
    for l in lights {
        light(&mut h, l);
    }
    camera_track(&mut h, camera);
    h.vec3(*background);
    h.vec3(*ambient);
    h.opt(animation.as_ref(), |h, a| {
        let crate::scene::AnimationRange { start, end, frames } = a;
        h.f32(*start);
        h.f32(*end);
        h.u32(*frames);
    });
    h.0
}

fn node(h: &mut Words, n: &crate::scene::Node) {
    let crate::scene::Node { parent, kind } = n;
    h.opt(*parent, Words::u32);
    match kind {
        NodeKind::Static(m) => {
            h.tag(0);
            h.mat4(m);
        }
        NodeKind::Animated { name, track } => {
            h.tag(1);
            h.str(name);
            h.opt(*track, Words::u32);
        }
        NodeKind::Sampled(a) => {
            h.tag(2);
            node_animation(h, a);
        }
    }
}

fn group(h: &mut Words, g: &crate::scene::Group) {
    let crate::scene::Group {
        node,
        triangles,
        spheres,
        cones,
    } = g;
    h.opt(*node, Words::u32);
    h.tag(triangles.len());
    for t in triangles {
        let crate::scene::Triangle { p, n, uv, material } = t;
        h.vec3s(p);
        h.opt(n.as_ref(), |h, n| h.vec3s(n));
        h.opt(uv.as_ref(), |h, uv| uv.iter().for_each(|v| h.vec2(*v)));
        h.u32(*material);
    }
    h.tag(spheres.len());
    for s in spheres {
        let crate::scene::Sphere {
            center,
            radius,
            material,
        } = s;
        h.vec3(*center);
        h.f32(*radius);
        h.u32(*material);
    }
    h.tag(cones.len());
    for c in cones {
        let crate::scene::Cone {
            base,
            base_radius,
            apex,
            apex_radius,
            material,
        } = c;
        h.vec3(*base);
        h.f32(*base_radius);
        h.vec3(*apex);
        h.f32(*apex_radius);
        h.u32(*material);
    }
}

fn animated_triangle(h: &mut Words, a: &crate::scene::AnimatedTriangle) {
    let crate::scene::AnimatedTriangle {
        times,
        positions,
        normals,
        material,
        node,
    } = a;
    h.f32s(times);
    h.tag(positions.len());
    positions.iter().for_each(|p| h.vec3s(p));
    h.tag(normals.len());
    normals.iter().for_each(|n| h.vec3s(n));
    h.u32(*material);
    h.opt(*node, Words::u32);
}

fn light(h: &mut Words, l: &crate::scene::Light) {
    let crate::scene::Light {
        position,
        color,
        track,
        name,
    } = l;
    h.vec3(*position);
    h.vec3(*color);
    h.opt(*track, Words::u32);
    h.opt(name.as_deref(), Words::str);
}

fn node_animation(h: &mut Words, a: &NodeAnimation) {
    let NodeAnimation {
        name,
        translation,
        rotation,
        scale,
        translation_sampler,
        rotation_sampler,
        scale_sampler,
    } = a;
    h.str(name);
    h.vec3(*translation);
    h.quat(*rotation);
    h.vec3(*scale);
    for s in [translation_sampler, rotation_sampler, scale_sampler] {
        h.opt(s.as_ref(), |h, s| h.debug(s));
    }
}

fn keyframe_track(h: &mut Words, t: &KeyframeTrack) {
    let KeyframeTrack {
        name,
        translation,
        rotation,
        scale,
        visibility,
    } = t;
    h.str(name);
    for spline in [translation, scale] {
        h.opt(spline.as_ref(), |h, s| {
            h.tag(s.keys().len());
            for k in s.keys() {
                h.f32(k.time);
                h.vec3(k.value);
                h.f32s(&[k.tension, k.continuity, k.bias]);
            }
        });
    }
    h.opt(rotation.as_ref(), |h, r| h.debug(r));
    h.tag(visibility.len());
    for (t, v) in visibility {
        h.f32(*t);
        h.bool(*v);
    }
}

fn material(h: &mut Words, m: &Material) {
    let Material {
        ambient,
        diffuse,
        specular,
        shininess,
        transmission,
        ior,
        texture,
    } = m;
    h.vec3(*ambient);
    h.vec3(*diffuse);
    h.vec3(*specular);
    h.f32s(&[*shininess, *transmission, *ior]);
    h.opt(*texture, Words::u32);
}

fn texture(h: &mut Words, t: &Texture) {
    h.str(&t.name);
    // Every level of the pyramid, not only level 0: filtered lookups read them.
    h.tag(t.levels());
    for (w, ht, texels) in (0..t.levels()).filter_map(|i| t.level(i)) {
        h.u32(w);
        h.u32(ht);
        h.tag(texels.len());
        for x in texels {
            h.vec3(*x);
        }
    }
}

fn camera_track(h: &mut Words, c: &CameraTrack) {
    let CameraTrack {
        base,
        track,
        resolution,
    } = c;
    let Camera {
        eye,
        at,
        up,
        fov_y_deg,
        hither,
    } = base;
    h.vec3(*eye);
    h.vec3(*at);
    h.vec3(*up);
    h.f32(*fov_y_deg);
    h.f32(*hither);
    h.opt(*track, Words::u32);
    h.opt(*resolution, |h, (w, ht)| {
        h.u32(w);
        h.u32(ht);
    });
}

/// A checksum of an entry's pixels and size.
fn pixel_checksum(width: u32, height: u32, rgb: &[u8]) -> u64 {
    let mut h = Words::new(0xc4ec_c5a0);
    h.u32(width);
    h.u32(height);
    h.bytes(rgb);
    h.0
}

/// The ideal image at time `t` on the run's tracer, through `cache` when there is one
/// (`Lookup::Miss` without), as every evaluation and the `ideal` method take it.
pub fn ideal_image(
    cache: Option<&IdealCache>,
    tracer: &Tracer,
    rays: Option<&GpuRays>,
    t: f64,
    spp: u32,
    seed: u64,
) -> (Image, Lookup) {
    match cache {
        Some(c) => c.get_or_render(tracer, rays, t, spp, seed),
        None => (still::render_on(tracer, rays, t, spp, seed).0, Lookup::Miss),
    }
}

/// The cache for one scene, camera and image size.
pub struct IdealCache {
    dir: PathBuf,
    /// The key lines shared by every entry of this cache.
    base_key: String,
    size: (u32, u32),
    /// Whether its entries are the GPU tracer's ([`IdealCache::for_tracer`]).
    gpu: bool,
}

impl IdealCache {
    /// Open (creating) the cache directory for this tracer's scene, camera path and size.
    pub fn new(
        dir: &Path,
        tracer: &Tracer,
        camera_path: Option<&CameraPath>,
    ) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let (width, height) = tracer.size();
        // Every option, the texture filter included, so that entries made under one
        // setting are never served under another; destructured so that a new option
        // does not compile here until it is part of the key.
        let TraceOptions {
            max_depth,
            texture_filter,
        } = tracer.options();
        let texture_filter = match texture_filter {
            TextureFilter::None => "none",
            TextureFilter::RayCones => "ray-cones",
        };
        let mut key = String::new();
        let _ = writeln!(key, "frameless ideal image");
        let _ = writeln!(key, "cache_version {CACHE_VERSION}");
        let _ = writeln!(key, "renderer_version {RENDERER_VERSION}");
        let _ = writeln!(key, "scene {:016x}", scene_fingerprint(tracer.scene()));
        let _ = writeln!(key, "width {width}");
        let _ = writeln!(key, "height {height}");
        let _ = writeln!(key, "max_depth {max_depth}");
        let _ = writeln!(key, "texture_filter {texture_filter}");
        match camera_path {
            None => {
                let _ = writeln!(key, "camera_path none");
            }
            Some(p) => {
                let csv = p.to_csv();
                let _ = writeln!(key, "camera_path {} lines", csv.lines().count());
                for line in csv.lines() {
                    let _ = writeln!(key, "  {line}");
                }
            }
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            base_key: key,
            size: (width, height),
            gpu: false,
        })
    }

    /// The cache of the images the tracer `used` makes. The GPU tracer's images differ
    /// from the CPU's in the last bits of some samples, so its entries are apart: their
    /// key names the tracer and its adapter. The CPU's keys name none, as before there
    /// was a GPU tracer, so that caches made then still serve.
    pub fn for_tracer(mut self, used: &DeviceUsed) -> Self {
        if used.device != DeviceUsed::cpu().device {
            let _ = writeln!(self.base_key, "tracer {used}");
            self.gpu = true;
        }
        self
    }

    /// The full key of the entry at time `t`: the text an entry must carry to be served.
    pub fn entry_key(&self, t: f64, spp: u32, seed: u64) -> String {
        format!(
            "{}time_bits {:016x} ({t})\nspp {spp}\nseed {seed}\n",
            self.base_key,
            t.to_bits()
        )
    }

    /// Where the entry at time `t` is stored (whether or not it is there).
    pub fn entry_path(&self, t: f64, spp: u32, seed: u64) -> PathBuf {
        let mut h = Words::new(0x6e61_6d65);
        h.str(&self.entry_key(t, spp, seed));
        self.dir.join(format!("{:016x}.png", h.0))
    }

    /// The ideal image at time `t` as displayed (8-bit values), from disk when a valid
    /// entry is there, else rendered on the run's tracer (`rays`: the GPU's, else the
    /// CPU) and stored; and what the lookup found.
    pub fn get_or_render(
        &self,
        tracer: &Tracer,
        rays: Option<&GpuRays>,
        t: f64,
        spp: u32,
        seed: u64,
    ) -> (Image, Lookup) {
        self.get_or_render_with(t, spp, seed, || {
            still::render_on(tracer, rays, t, spp, seed)
        })
    }

    /// [`get_or_render`](Self::get_or_render) with the image made by `render`, which
    /// also says whether the GPU tracer made it. An image is stored only under the key
    /// of the tracer that made it: one that fell back to the CPU is served but not
    /// stored under a GPU key.
    pub fn get_or_render_with(
        &self,
        t: f64,
        spp: u32,
        seed: u64,
        render: impl FnOnce() -> (Image, bool),
    ) -> (Image, Lookup) {
        let key = self.entry_key(t, spp, seed);
        let path = self.entry_path(t, spp, seed);
        let (w, h) = self.size;
        let lookup = match self.read(&path, &key) {
            Ok(rgb) => return (from_rgb8(w, h, &rgb), Lookup::Hit),
            Err(lookup) => lookup,
        };
        let (img, on_gpu) = render();
        let rgb = img.to_rgb8();
        if on_gpu != self.gpu {
            return (from_rgb8(w, h, &rgb), lookup);
        }
        let checksum = format!("{:016x}", pixel_checksum(w, h, &rgb));
        // A failed write only costs a re-render next time.
        let _ = write_png_rgb8_tagged(
            &path,
            w,
            h,
            &rgb,
            &[(KEY_CHUNK, &key), (CHECKSUM_CHUNK, &checksum)],
        );
        (from_rgb8(w, h, &rgb), lookup)
    }

    /// The entry's pixels if it proves to be the entry for `key`; else why not.
    fn read(&self, path: &Path, key: &str) -> Result<Vec<u8>, Lookup> {
        if !path.exists() {
            return Err(Lookup::Miss);
        }
        let reject = |m| Err(Lookup::Rejected(m));
        let Ok(png) = read_png(path) else {
            return reject(Mismatch::Unreadable);
        };
        if png.color != png::ColorType::Rgb || png.depth != png::BitDepth::Eight {
            return reject(Mismatch::Format);
        }
        let (w, h) = self.size;
        if (png.width, png.height) != (w, h) || png.data.len() != (w * h * 3) as usize {
            return reject(Mismatch::Size);
        }
        let text = |keyword: &str| {
            png.text
                .iter()
                .find(|(k, _)| k == keyword)
                .map(|(_, v)| v.as_str())
        };
        if text(KEY_CHUNK) != Some(key) {
            return reject(Mismatch::Key);
        }
        let checksum = format!("{:016x}", pixel_checksum(w, h, &png.data));
        if text(CHECKSUM_CHUNK) != Some(checksum.as_str()) {
            return reject(Mismatch::Checksum);
        }
        Ok(png.data)
    }
}

/// An image holding displayed 8-bit values (exactly re-quantizable).
pub fn from_rgb8(w: u32, h: u32, rgb: &[u8]) -> Image {
    Image {
        width: w,
        height: h,
        pixels: rgb
            .chunks(3)
            .map(|c| glam::Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) / 255.0)
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::{
        image::{write_png_rgb8_fast, write_png_rgb8_tagged},
        scene::builtin,
    };

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("frameless-cache-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn key_covers_the_texture_filter() {
        let dir = scratch("key");
        let scene = Arc::new(builtin::toycar());
        let key = |texture_filter| {
            let options = TraceOptions {
                texture_filter,
                ..TraceOptions::default()
            };
            let tracer = Tracer::new(scene.clone(), 8, 8, options);
            IdealCache::new(&dir, &tracer, None)
                .unwrap()
                .entry_key(0.5, 4, 1)
        };
        let none = key(TextureFilter::None);
        assert_eq!(none, key(TextureFilter::None));
        assert_ne!(none, key(TextureFilter::RayCones));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn gpu_entries_are_apart_from_the_cpus_and_a_cpu_fallback_is_not_stored() {
        let dir = scratch("tracer");
        let scene = Arc::new(builtin::toycar());
        let tracer = Tracer::new(scene, 8, 6, TraceOptions::default());
        let open = || IdealCache::new(&dir, &tracer, None).unwrap();
        let cpu = open();
        // The CPU's keys are as they were before there was a GPU tracer.
        assert_eq!(
            cpu.entry_key(0.5, 2, 1),
            open().for_tracer(&DeviceUsed::cpu()).entry_key(0.5, 2, 1)
        );
        assert!(!cpu.entry_key(0.5, 2, 1).contains("tracer"));
        let used = |adapter: &str| DeviceUsed {
            device: "gpu".into(),
            adapter: Some(adapter.into()),
        };
        let gpu = open().for_tracer(&used("lavapipe"));
        let other = open().for_tracer(&used("another adapter"));
        let key = gpu.entry_key(0.5, 2, 1);
        assert!(key.contains("tracer gpu (lavapipe)"), "{key}");
        let paths = [&cpu, &gpu, &other].map(|c| c.entry_path(0.5, 2, 1));
        assert!(paths[0] != paths[1] && paths[1] != paths[2] && paths[0] != paths[2]);
        // A CPU image under the GPU's key is served but not stored; the GPU's is.
        let img = still::render(&tracer, 0.5, 2, 1, &|_| {});
        let (_, l) = gpu.get_or_render_with(0.5, 2, 1, || (img.clone(), false));
        assert_eq!(l, Lookup::Miss);
        assert!(
            !paths[1].exists(),
            "a fallback image was stored under the GPU's key"
        );
        let (_, l) = gpu.get_or_render(&tracer, None, 0.5, 2, 1);
        assert_eq!(l, Lookup::Miss);
        assert!(
            !paths[1].exists(),
            "a CPU image was stored under the GPU's key"
        );
        gpu.get_or_render_with(0.5, 2, 1, || (img.clone(), true));
        assert_eq!(
            gpu.get_or_render_with(0.5, 2, 1, || (img.clone(), true)).1,
            Lookup::Hit
        );
        // And a GPU image never under the CPU's key; the CPU's own is stored.
        cpu.get_or_render_with(0.5, 2, 1, || (img.clone(), true));
        assert!(
            !paths[0].exists(),
            "a GPU image was stored under the CPU's key"
        );
        assert_eq!(cpu.get_or_render(&tracer, None, 0.5, 2, 1).1, Lookup::Miss);
        assert_eq!(cpu.get_or_render(&tracer, None, 0.5, 2, 1).1, Lookup::Hit);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_fingerprint_sees_every_part_of_the_scene() {
        let base = builtin::toycar();
        let fp = scene_fingerprint(&base);
        assert_eq!(fp, scene_fingerprint(&base.clone()), "deterministic");
        let mut moved = base.clone();
        moved.source = Some("/elsewhere/toycar.aff".into());
        assert_eq!(
            fp,
            scene_fingerprint(&moved),
            "where it came from is not content"
        );
        // One changed float anywhere changes the fingerprint; -0.0 is not 0.0 to it.
        type Edit = Box<dyn Fn(&mut Scene)>;
        let edits: Vec<(&str, Edit)> = vec![
            ("ambient", Box::new(|s| s.ambient.x += 1e-6)),
            (
                "background",
                Box::new(|s| s.background.z = -s.background.z - 0.5),
            ),
            ("camera", Box::new(|s| s.camera.base.fov_y_deg += 0.001)),
            ("material", Box::new(|s| s.materials[0].shininess += 1.0)),
            ("light", Box::new(|s| s.lights[0].color.y *= 0.5)),
            (
                "triangle",
                Box::new(|s| {
                    let g = s
                        .groups
                        .iter_mut()
                        .find(|g| !g.triangles.is_empty())
                        .unwrap();
                    g.triangles[0].p[1].y += 1e-3;
                }),
            ),
            ("node", Box::new(|s| s.nodes.push(s.nodes[0].clone()))),
            (
                "track",
                Box::new(|s| s.tracks[0].visibility.push((1.0, false))),
            ),
            (
                "texture",
                Box::new(|s| {
                    let t = &s.textures[0];
                    let mut texels = t.texels.clone();
                    texels[0].x += 0.25;
                    s.textures[0] = Texture::new(&t.name, t.width, t.height, texels);
                }),
            ),
        ];
        for (what, edit) in edits {
            let mut s = base.clone();
            edit(&mut s);
            assert_ne!(fp, scene_fingerprint(&s), "{what}");
        }
    }

    #[test]
    fn an_entry_is_served_only_with_its_key_checksum_and_format() {
        let dir = scratch("lookup");
        let scene = Arc::new(builtin::toycar());
        let tracer = Tracer::new(scene, 12, 8, TraceOptions::default());
        let cache = IdealCache::new(&dir, &tracer, None).unwrap();
        let (t, u) = (0.5, 0.75);
        let (a, l) = cache.get_or_render(&tracer, None, t, 2, 1);
        assert_eq!(l, Lookup::Miss);
        let (a2, l) = cache.get_or_render(&tracer, None, t, 2, 1);
        assert_eq!((l, &a2), (Lookup::Hit, &a));
        let (b, _) = cache.get_or_render(&tracer, None, u, 2, 1);
        assert_ne!(a, b, "the two instants differ, so a swap would be visible");
        let (pa, pb) = (cache.entry_path(t, 2, 1), cache.entry_path(u, 2, 1));
        let bytes_b = std::fs::read(&pb).unwrap();
        // Each case damages entry `t`, which is then rejected, re-rendered and rewritten.
        let rgb = a.to_rgb8();
        let damage: Vec<(Mismatch, Box<dyn Fn()>)> = vec![
            (
                Mismatch::Key,
                Box::new(|| std::fs::write(&pa, &bytes_b).unwrap()),
            ),
            (
                Mismatch::Key,
                Box::new(|| write_png_rgb8_fast(&pa, 12, 8, &rgb).unwrap()),
            ),
            (
                Mismatch::Checksum,
                Box::new(|| {
                    let key = cache.entry_key(t, 2, 1);
                    let mut wrong = rgb.clone();
                    wrong[5] ^= 1;
                    let sum = format!("{:016x}", pixel_checksum(12, 8, &rgb));
                    let chunks = [(KEY_CHUNK, key.as_str()), (CHECKSUM_CHUNK, sum.as_str())];
                    write_png_rgb8_tagged(&pa, 12, 8, &wrong, &chunks).unwrap();
                }),
            ),
            (
                Mismatch::Size,
                Box::new(|| write_png_rgb8_fast(&pa, 4, 4, &[0; 48]).unwrap()),
            ),
            (
                Mismatch::Unreadable,
                Box::new(|| std::fs::write(&pa, b"not a png").unwrap()),
            ),
        ];
        for (why, damage) in damage {
            damage();
            let (img, l) = cache.get_or_render(&tracer, None, t, 2, 1);
            assert_eq!(l, Lookup::Rejected(why));
            assert_eq!(img, a, "{why:?}: the right image all the same");
            assert_eq!(
                cache.get_or_render(&tracer, None, t, 2, 1).1,
                Lookup::Hit,
                "{why:?}"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
