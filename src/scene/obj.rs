//! Wavefront OBJ loader (with MTL materials), parsed by `tobj`.
//!
//! Before `tobj` sees the file, a scan checks what `tobj` would trust or get wrong: every
//! line is UTF-8, `v`/`vt`/`vn` carry enough finite numbers, and every face (`f`) and line
//! (`l`) index is a non-zero integer that resolves to an existing element (negative
//! indices count back from the elements defined so far; positive ones may refer ahead,
//! as `tobj` allows). Problems found there are errors with line and column; errors `tobj`
//! reports itself get the line it stopped on (column 1). Nothing in a malformed file
//! panics.
//!
//! # Mapping
//!
//! - **Geometry.** Faces are triangulated as fans; points and lines (`p`, `l`, and `f`
//!   with fewer than three vertices) are skipped. All geometry is static, in world space.
//!   A face gets shading normals, and texture coordinates, only when every one of its
//!   vertices names one (`tobj` would substitute another index for a missing one); faces
//!   without normals are shaded with the geometric normal (flat). Texture coordinates are
//!   used as written: OBJ, like this renderer, puts `v = 0` at the bottom of the image.
//! - **Materials.** `mtllib` files are read relative to the OBJ file. A library that cannot
//!   be read is a warning on stderr and its materials fall back to [`Material::default`],
//!   as do faces with no (or an unknown) `usemtl`. With `opacity = d` (or `1 − Tr` when
//!   only `Tr` is given; 1 when neither is):
//!   - diffuse `Kd·opacity` (`Kd` defaults to 0.7), transmission `1 − opacity`;
//!   - specular `Ks` (default 0), which in this renderer is also the mirror reflectance,
//!     so a large `Ks` looks metallic; zero for `illum` 0 and 1, which have no specular
//!     term;
//!   - shininess `Ns` clamped to `[1, 10000]` (default 10);
//!   - ior `Ni` (default 1, so plain dissolve is see-through without refraction);
//!   - ambient `0.1·diffuse + Ke`. `Ka` is ignored: exporters commonly write `Ka 1 1 1`,
//!     which against this renderer's global ambient would wash every surface out.
//!   - `map_Kd` (options such as `-s u v w` are skipped; backslashes read as `/`) is
//!     resolved relative to the MTL file and may be binary PPM, PNG or JPEG; a missing or
//!     undecodable texture is an error naming the file. Other maps are ignored.
//! - **Camera and lights.** OBJ has neither: the camera looks at the bounds from +Z and
//!   one white light sits above and to the right of it, as for glTF files without them
//!   (see [`super::gltf`]).

use std::cell::RefCell;
use std::collections::HashMap;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::{
    limits::MAX_COORDINATE,
    loader::{
        decode_image, default_camera, default_light, empty_scene, world_bounds, MAX_TRIANGLES,
    },
    CameraTrack, Group, Material, MaterialId, Scene, SceneError, TextureId, Triangle,
};

/// A byte reader that counts the lines `tobj` has consumed, so its errors get a line.
struct LineReader<'a> {
    data: &'a [u8],
    pos: usize,
    newlines: usize,
}

impl<'a> LineReader<'a> {
    fn new(data: &'a [u8]) -> Self {
        Self {
            data,
            pos: 0,
            newlines: 0,
        }
    }

    /// The 1-based line being (or just) read.
    fn line(&self) -> usize {
        if self.pos > 0 && self.data[self.pos - 1] == b'\n' {
            self.newlines.max(1)
        } else {
            self.newlines + 1
        }
    }
}

impl Read for LineReader<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let rest = &self.data[self.pos..];
        let n = rest.len().min(buf.len());
        buf[..n].copy_from_slice(&rest[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for LineReader<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(&self.data[self.pos..])
    }

    fn consume(&mut self, amt: usize) {
        let end = (self.pos + amt).min(self.data.len());
        self.newlines += self.data[self.pos..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        self.pos = end;
    }
}

/// Whitespace-separated words of a line with their 1-based byte columns.
fn words(line: &str) -> impl Iterator<Item = (usize, &str)> {
    let base = line.as_ptr() as usize;
    line.split_whitespace()
        .map(move |w| (w.as_ptr() as usize - base + 1, w))
}

/// Lines of a file as text, with their 1-based numbers; a line that is not UTF-8 is an
/// error.
fn text_lines<'a>(
    file: &'a str,
    bytes: &'a [u8],
) -> impl Iterator<Item = Result<(usize, &'a str), SceneError>> + 'a {
    bytes.split(|&b| b == b'\n').enumerate().map(move |(i, l)| {
        std::str::from_utf8(l)
            .map(|s| (i + 1, s))
            .map_err(|e| SceneError::Parse {
                file: file.to_string(),
                line: i + 1,
                column: e.valid_up_to() + 1,
                message: "line is not valid UTF-8".into(),
            })
    })
}

/// What the scan learned about one `f` or `l` statement, which `tobj` turns into
/// `vertices − 2` triangles in file order (both keywords alike).
#[derive(Clone, Copy, Debug, PartialEq)]
struct FaceInfo {
    /// Triangles `tobj` makes of it.
    triangles: usize,
    /// False for `l`: a polyline is not a surface.
    keep: bool,
    /// Every vertex names a texture coordinate.
    uv: bool,
    /// Every vertex names a normal.
    normal: bool,
}

/// Check what `tobj` would trust: numbers of vertex lines and indices of faces. Returns
/// what each face statement contributes.
fn prescan(file: &str, bytes: &[u8]) -> Result<Vec<FaceInfo>, SceneError> {
    let err = |line: usize, column: usize, message: String| SceneError::Parse {
        file: file.to_string(),
        line,
        column,
        message,
    };
    // Totals, for forward references.
    let mut total = [0i64; 3];
    for l in text_lines(file, bytes) {
        let (_, l) = l?;
        match l.split_whitespace().next() {
            Some("v") => total[0] += 1,
            Some("vt") => total[1] += 1,
            Some("vn") => total[2] += 1,
            _ => {}
        }
    }
    let mut seen = [0i64; 3];
    let mut faces = Vec::new();
    for l in text_lines(file, bytes) {
        let (ln, l) = l?;
        let at = |column: usize, message: String| err(ln, column, message);
        let mut w = words(l);
        let Some((_, key)) = w.next() else { continue };
        let (slot, needed) = match key {
            "v" => (0, 3),
            "vt" => (1, 2),
            "vn" => (2, 3),
            "f" | "l" => {
                faces.push(scan_face(key, w, (&total, &seen), &at)?);
                continue;
            }
            _ => continue,
        };
        seen[slot] += 1;
        let count = scan_numbers(w, &at)?;
        if count < needed {
            return Err(at(
                l.len().max(1),
                format!("`{key}` needs {needed} numbers, found {count}"),
            ));
        }
    }
    Ok(faces)
}

/// The indices of an `f` or `l` statement (`key`), given the vertex lines of each kind
/// in the file (`total`) and before this line (`seen`); `at` makes an error at a column
/// of the line.
fn scan_face<'a>(
    key: &str,
    words: impl Iterator<Item = (usize, &'a str)>,
    (total, seen): (&[i64; 3], &[i64; 3]),
    at: &dyn Fn(usize, String) -> SceneError,
) -> Result<FaceInfo, SceneError> {
    const KIND: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let mut info = FaceInfo {
        triangles: 0,
        keep: key == "f",
        uv: true,
        normal: true,
    };
    let mut vertices = 0usize;
    for (col, tok) in words {
        vertices += 1;
        let parts: Vec<&str> = tok.split('/').collect();
        if parts.len() > 3 {
            return Err(at(col, format!("`{tok}` has more than three indices")));
        }
        info.uv &= parts.get(1).is_some_and(|p| !p.is_empty());
        info.normal &= parts.get(2).is_some_and(|p| !p.is_empty());
        for (k, part) in parts.iter().enumerate() {
            if part.is_empty() {
                if k == 0 {
                    return Err(at(col, format!("`{tok}` has no vertex index")));
                }
                continue;
            }
            let x: i64 = part
                .parse()
                .map_err(|_| at(col, format!("`{part}` is not an index")))?;
            let ok = match x {
                0 => {
                    return Err(at(
                        col,
                        "index 0 is invalid (OBJ indices start at 1)".into(),
                    ))
                }
                x if x > 0 => x <= total[k],
                x => x.checked_add(seen[k]).is_some_and(|i| i >= 0),
            };
            if !ok {
                let (have, when) = if x > 0 {
                    (total[k], "in the file")
                } else {
                    (seen[k], "so far")
                };
                return Err(at(
                    col,
                    format!(
                        "{} index {x} is out of range ({have} defined {when})",
                        KIND[k]
                    ),
                ));
            }
        }
    }
    if vertices == 0 {
        return Err(at(1, format!("`{key}` without vertices")));
    }
    info.triangles = vertices.saturating_sub(2);
    Ok(info)
}

/// How many numbers a `v`, `vt` or `vn` statement gives, each checked against the
/// coordinate limit.
fn scan_numbers<'a>(
    words: impl Iterator<Item = (usize, &'a str)>,
    at: &dyn Fn(usize, String) -> SceneError,
) -> Result<usize, SceneError> {
    let mut count = 0;
    for (col, tok) in words {
        match tok.parse::<f32>() {
            Ok(v) if v.abs() <= MAX_COORDINATE => count += 1,
            Ok(v) if v.is_finite() => {
                return Err(at(
                    col,
                    format!("`{tok}` exceeds the coordinate limit of ±{MAX_COORDINATE:e}"),
                ))
            }
            Ok(_) => return Err(at(col, format!("`{tok}` is not a finite number"))),
            Err(_) => return Err(at(col, format!("`{tok}` is not a number"))),
        }
    }
    Ok(count)
}

/// Expand MTL colors given as one value (`Kd 0.8`, which the MTL format defines as grey)
/// to three, and reject colors with two values or none, on which `tobj` would panic.
fn normalize_mtl(file: &str, bytes: &[u8]) -> Result<Vec<u8>, SceneError> {
    let mut out = Vec::with_capacity(bytes.len() + 64);
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        if i > 0 {
            out.push(b'\n');
        }
        let Ok(line) = std::str::from_utf8(raw) else {
            out.extend_from_slice(raw);
            continue;
        };
        let mut w = words(line);
        let key = w.next().map(|(_, k)| k);
        if !matches!(key, Some("Ka" | "Kd" | "Ks" | "Ke")) {
            out.extend_from_slice(raw);
            continue;
        }
        let key = key.unwrap_or_default();
        let values: Vec<(usize, &str)> = w.take(3).collect();
        // A word that is not a number is an error tobj reports by itself.
        if values.iter().any(|(_, v)| v.parse::<f32>().is_err()) || values.len() == 3 {
            out.extend_from_slice(raw);
            continue;
        }
        match values.as_slice() {
            [(_, v)] => out.extend_from_slice(format!("{key} {v} {v} {v}").as_bytes()),
            _ => {
                return Err(SceneError::Parse {
                    file: file.to_string(),
                    line: i + 1,
                    column: values.last().map_or(line.len().max(1), |(c, _)| *c),
                    message: format!("`{key}` needs one or three numbers, found {}", values.len()),
                })
            }
        }
    }
    Ok(out)
}

/// The file name in a `map_*` statement, after any options.
fn map_file_name(value: &str) -> &str {
    // Option name → number of arguments (at most; `-o`, `-s`, `-t` take 1 to 3 numbers).
    const OPTIONS: &[(&str, usize)] = &[
        ("-blendu", 1),
        ("-blendv", 1),
        ("-bm", 1),
        ("-boost", 1),
        ("-cc", 1),
        ("-clamp", 1),
        ("-imfchan", 1),
        ("-mm", 2),
        ("-o", 3),
        ("-s", 3),
        ("-t", 3),
        ("-texres", 1),
        ("-type", 1),
    ];
    let mut rest = value.trim();
    while let Some(&(opt, args)) = OPTIONS.iter().find(|(o, _)| {
        rest.strip_prefix(o)
            .is_some_and(|r| r.starts_with(char::is_whitespace))
    }) {
        rest = rest[opt.len()..].trim_start();
        for i in 0..args {
            let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            // Optional numeric arguments stop at the first non-number.
            if i > 0 && rest[..end].parse::<f32>().is_err() {
                break;
            }
            if end == rest.len() {
                // Nothing follows: the last token is the file name after all.
                return rest;
            }
            rest = rest[end..].trim_start();
        }
    }
    rest
}

/// Load an OBJ scene (and its MTL libraries).
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let bytes = crate::scene::limits::read_bounded(path).map_err(|e| SceneError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let faces = prescan(&file, &bytes)?;
    let dir = path
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let Parsed {
        models,
        materials,
        libraries,
    } = parse(&file, &bytes, &dir)?;

    let mut scene = empty_scene(path);
    let mut b = Build {
        file: &file,
        materials: &materials,
        libraries: &libraries,
        ids: HashMap::new(),
        textures: HashMap::new(),
        scene: &mut scene,
    };
    // One entry per output triangle of tobj. tobj substitutes some other index for a
    // missing `vt`/`vn`, so its attributes are only used where the face named them.
    // Should the counts ever disagree, tobj's data are used as given.
    let flags: Vec<FaceInfo> = faces
        .iter()
        .flat_map(|f| std::iter::repeat_n(*f, f.triangles))
        .collect();
    let produced: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    let flags = (flags.len() == produced).then_some(flags);
    let mut triangles = Vec::new();
    // tobj's triangles before this model's, kept or not.
    let mut first = 0;
    for model in &models {
        let faces = flags.as_ref().map(|f| &f[first..]);
        model_triangles(&mut b, model, faces, &mut triangles)?;
        first += model.mesh.indices.len() / 3;
    }
    scene.groups.push(Group {
        node: None,
        triangles,
        ..Default::default()
    });
    let base = default_camera(world_bounds(&scene, 0.0));
    scene.lights.push(default_light(&base));
    scene.camera = CameraTrack {
        base,
        track: None,
        resolution: None,
    };
    crate::scene::limits::check(&scene)?;
    Ok(scene)
}

/// What `tobj` made of an OBJ file.
struct Parsed {
    models: Vec<tobj::Model>,
    materials: Vec<tobj::Material>,
    /// Material libraries in load order, each with the number of materials it added,
    /// so a material index tells which library (and directory) it came from.
    libraries: Vec<(PathBuf, usize)>,
}

/// Parse the OBJ text `bytes` of `file` with `tobj`, reading its material libraries
/// from `dir`.
fn parse(file: &str, bytes: &[u8], dir: &Path) -> Result<Parsed, SceneError> {
    let libraries: RefCell<Vec<(PathBuf, usize)>> = RefCell::new(Vec::new());
    let mtl_error: RefCell<Option<SceneError>> = RefCell::new(None);
    // tobj's optional features (merging, reordering) add fields; the update keeps this
    // compiling should another crate in the build enable them.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut reader = LineReader::new(bytes);
    let result = tobj::load_obj_buf(&mut reader, &options, |name| {
        let mtl = dir.join(name);
        let loaded = load_library(file, &mtl, &mtl_error);
        if let Ok(m) = &loaded {
            libraries.borrow_mut().push((mtl, m.0.len()));
        }
        loaded
    });
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let (models, materials) = result.map_err(|e| SceneError::Parse {
        file: file.to_string(),
        line: reader.line(),
        column: 1,
        message: e.to_string(),
    })?;
    Ok(Parsed {
        models,
        // Errors of missing libraries were reported as warnings.
        materials: materials.unwrap_or_default(),
        libraries: libraries.into_inner(),
    })
}

/// Read the material library `mtl` of `file`. Where the input is broken rather than
/// incomplete, the first such error goes to `error` besides `tobj`'s.
fn load_library(
    file: &str,
    mtl: &Path,
    error: &RefCell<Option<SceneError>>,
) -> tobj::MTLLoadResult {
    let data = match crate::scene::limits::read_bounded(mtl) {
        Ok(d) => d,
        // A library that is missing is common in downloaded models and only costs
        // materials; one that exists but is no regular file or is too large is a
        // broken input.
        Err(e) if mtl.exists() => {
            error.borrow_mut().get_or_insert(SceneError::Io {
                path: mtl.to_path_buf(),
                message: format!("{e} (material library of {file})"),
            });
            return Err(tobj::LoadError::OpenFileFailed);
        }
        Err(e) => {
            eprintln!(
                "warning: {file}: material library {} cannot be read ({e}); its materials fall back to the default",
                mtl.display()
            );
            return Err(tobj::LoadError::OpenFileFailed);
        }
    };
    let data = match normalize_mtl(&mtl.display().to_string(), &data) {
        Ok(d) => d,
        Err(e) => {
            error.borrow_mut().get_or_insert(e);
            return Err(tobj::LoadError::MaterialParseError);
        }
    };
    let mut r = LineReader::new(&data);
    tobj::load_mtl_buf(&mut r).inspect_err(|e| {
        error.borrow_mut().get_or_insert(SceneError::Parse {
            file: mtl.display().to_string(),
            line: r.line(),
            column: 1,
            message: e.to_string(),
        });
    })
}

/// Append the triangles of `model` to `triangles`. `faces`, when the scan's count
/// matched `tobj`'s, says per triangle from this model's first on whether to keep it
/// and which of its attributes the file named.
fn model_triangles(
    b: &mut Build<'_>,
    model: &tobj::Model,
    faces: Option<&[FaceInfo]>,
    triangles: &mut Vec<Triangle>,
) -> Result<(), SceneError> {
    let m = &model.mesh;
    let invalid = |message: String| SceneError::Invalid {
        name: b.file.to_string(),
        message,
    };
    let material = b.material(m.material_id)?;
    let has_uv = !m.texcoords.is_empty() && m.texcoord_indices.len() == m.indices.len();
    let has_n = !m.normals.is_empty() && m.normal_indices.len() == m.indices.len();
    if triangles.len() + m.indices.len() / 3 > MAX_TRIANGLES {
        return Err(invalid(format!("more than {MAX_TRIANGLES} triangles")));
    }
    let get3 = |data: &[f32], i: u32, what: &str| -> Result<Vec3, SceneError> {
        let i = i as usize;
        data.get(3 * i..3 * i + 3)
            .map(Vec3::from_slice)
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                invalid(format!(
                    "object `{}`: {what} {i} is missing or not finite",
                    model.name
                ))
            })
    };
    for k in 0..m.indices.len() / 3 {
        let (keep, face_uv, face_n) =
            faces.map_or((true, true, true), |f| (f[k].keep, f[k].uv, f[k].normal));
        if !keep {
            continue;
        }
        let idx = |list: &[u32], j: usize| list[3 * k + j];
        let mut p = [Vec3::ZERO; 3];
        for (j, pj) in p.iter_mut().enumerate() {
            *pj = get3(&m.positions, idx(&m.indices, j), "vertex")?;
        }
        let n = if has_n && face_n {
            let mut n = [Vec3::ZERO; 3];
            for (j, nj) in n.iter_mut().enumerate() {
                *nj = get3(&m.normals, idx(&m.normal_indices, j), "normal")?;
            }
            Some(n)
        } else {
            None
        };
        let uv = if has_uv && face_uv {
            let mut uv = [Vec2::ZERO; 3];
            for (j, t) in uv.iter_mut().enumerate() {
                let i = idx(&m.texcoord_indices, j) as usize;
                let c = m.texcoords.get(2 * i..2 * i + 2).ok_or_else(|| {
                    invalid(format!(
                        "object `{}`: texture coordinate {i} is missing",
                        model.name
                    ))
                })?;
                *t = Vec2::new(c[0], c[1]);
            }
            Some(uv)
        } else {
            None
        };
        triangles.push(Triangle { p, n, uv, material });
    }
    Ok(())
}

/// Material and texture conversion, shared across the file's objects.
struct Build<'a> {
    file: &'a str,
    materials: &'a [tobj::Material],
    libraries: &'a [(PathBuf, usize)],
    ids: HashMap<Option<usize>, MaterialId>,
    textures: HashMap<PathBuf, TextureId>,
    scene: &'a mut Scene,
}

impl Build<'_> {
    /// The MTL file a material index came from.
    fn library(&self, index: usize) -> PathBuf {
        let mut first = 0;
        for (path, n) in self.libraries {
            if index < first + n {
                return path.clone();
            }
            first += n;
        }
        PathBuf::from(self.file)
    }

    fn material(&mut self, index: Option<usize>) -> Result<MaterialId, SceneError> {
        let index = index.filter(|&i| i < self.materials.len());
        if let Some(&id) = self.ids.get(&index) {
            return Ok(id);
        }
        let m = match index {
            None => Material::default(),
            Some(i) => self.convert(i)?,
        };
        self.scene.materials.push(m);
        let id = (self.scene.materials.len() - 1) as MaterialId;
        self.ids.insert(index, id);
        Ok(id)
    }

    fn convert(&mut self, index: usize) -> Result<Material, SceneError> {
        let src = &self.materials[index];
        let lib = self.library(index);
        let invalid = |what: &str| SceneError::Invalid {
            name: lib.display().to_string(),
            message: format!("material `{}`: {what} is not finite", src.name),
        };
        let v3 = |v: Option<[f32; 3]>, default: f32, what: &str| {
            let v = v.map_or(Vec3::splat(default), Vec3::from);
            if v.is_finite() {
                Ok(v)
            } else {
                Err(invalid(what))
            }
        };
        let s1 = |v: Option<f32>, what: &str| match v {
            Some(x) if !x.is_finite() => Err(invalid(what)),
            _ => Ok(v),
        };
        let kd = v3(src.diffuse, 0.7, "Kd")?;
        let ks = v3(src.specular, 0.0, "Ks")?;
        let ke = v3(src.emissive, 0.0, "Ke")?;
        let tr = src
            .unknown_param
            .get("Tr")
            .and_then(|s| s.split_whitespace().next()?.parse::<f32>().ok());
        let opacity = match (s1(src.dissolve, "d")?, s1(tr, "Tr")?) {
            (Some(d), _) => d,
            (None, Some(t)) => 1.0 - t,
            (None, None) => 1.0,
        }
        .clamp(0.0, 1.0);
        let diffuse = kd * opacity;
        let specular = if matches!(src.illumination_model, Some(0 | 1)) {
            Vec3::ZERO
        } else {
            ks
        };
        let texture = match &src.diffuse_texture {
            Some(t) => Some(self.texture(&lib, t, &src.name)?),
            None => None,
        };
        Ok(Material {
            ambient: diffuse * 0.1 + ke,
            diffuse,
            specular,
            shininess: s1(src.shininess, "Ns")?.unwrap_or(10.0).clamp(1.0, 10000.0),
            transmission: 1.0 - opacity,
            ior: s1(src.optical_density, "Ni")?
                .filter(|&n| n > 0.0)
                .unwrap_or(1.0),
            texture,
        })
    }

    fn texture(
        &mut self,
        lib: &Path,
        value: &str,
        material: &str,
    ) -> Result<TextureId, SceneError> {
        let name = map_file_name(value).replace('\\', "/");
        let dir = lib.parent().unwrap_or(Path::new("."));
        let path = dir.join(&name);
        if let Some(&id) = self.textures.get(&path) {
            return Ok(id);
        }
        let context = format!("map_Kd of material `{material}` in {}", lib.display());
        let bytes = crate::scene::limits::read_bounded(&path).map_err(|e| SceneError::Io {
            path: path.clone(),
            message: format!("{e} ({context})"),
        })?;
        let file_name = path
            .file_name()
            .map_or(name.clone(), |s| s.to_string_lossy().into_owned());
        let tex = decode_image(&file_name, &bytes).map_err(|source| SceneError::Texture {
            path: path.clone(),
            source,
            context: Some(context),
        })?;
        self.scene.textures.push(tex);
        let id = (self.scene.textures.len() - 1) as TextureId;
        self.textures.insert(path, id);
        Ok(id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_options_are_skipped() {
        assert_eq!(map_file_name("wood.ppm"), "wood.ppm");
        assert_eq!(map_file_name("-s 2 2 1 wood.ppm"), "wood.ppm");
        assert_eq!(map_file_name("-s 2 wood.ppm"), "wood.ppm");
        assert_eq!(
            map_file_name("-bm 0.5 -clamp on my wood.ppm"),
            "my wood.ppm"
        );
        assert_eq!(map_file_name("-s"), "-s");
    }

    #[test]
    fn mtl_colors_are_normalised() {
        let out = normalize_mtl("m.mtl", b"newmtl a\nKd 0.5\nKs 1 2 3\n").unwrap();
        assert_eq!(out, b"newmtl a\nKd 0.5 0.5 0.5\nKs 1 2 3\n");
        let e = normalize_mtl("m.mtl", b"newmtl a\nKa 1 2\n").unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::Parse {
                    line: 2,
                    column: 6,
                    ..
                }
            ),
            "{e}"
        );
        assert!(normalize_mtl("m.mtl", b"Kd\n").is_err());
    }

    #[test]
    fn line_reader_counts_lines() {
        let data = b"a\nb\nc";
        let mut r = LineReader::new(data);
        assert_eq!(r.line(), 1);
        let mut s = String::new();
        r.read_line(&mut s).unwrap();
        assert_eq!(r.line(), 1);
        s.clear();
        r.read_line(&mut s).unwrap();
        assert_eq!(r.line(), 2);
        s.clear();
        r.read_line(&mut s).unwrap();
        assert_eq!(r.line(), 3);
    }

    #[test]
    fn prescan_locates_problems() {
        let e = prescan("x.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::Parse {
                    line: 4,
                    column: 7,
                    ..
                }
            ),
            "{e}"
        );
        let e = prescan("x.obj", b"v 0 0 0\nf -2 1 1\n").unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::Parse {
                    line: 2,
                    column: 3,
                    ..
                }
            ),
            "{e}"
        );
        let e = prescan("x.obj", b"v 0 nan 0\n").unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::Parse {
                    line: 1,
                    column: 5,
                    ..
                }
            ),
            "{e}"
        );
        let e = prescan("x.obj", b"v 0 0 0\nf 1/1 1 1\n").unwrap_err();
        assert!(e.to_string().contains("texture coordinate"), "{e}");
        let e = prescan("x.obj", b"v 0 0 0\nf 0 1 1\n").unwrap_err();
        assert!(e.to_string().contains("index 0"), "{e}");
        let e = prescan("x.obj", b"v 0 0 0\nf -9223372036854775808 1 1\n").unwrap_err();
        assert!(e.to_string().contains("out of range"), "{e}");
        let faces = prescan(
            "x.obj",
            b"f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\nf 1/1 2/1 3\nvt 0 0\n",
        )
        .unwrap();
        assert_eq!(faces.len(), 3);
        assert_eq!(
            faces[0],
            FaceInfo {
                triangles: 1,
                keep: true,
                uv: false,
                normal: false
            }
        );
        assert!(!faces[1].keep);
        assert!(!faces[2].uv);
    }
}
