//! BART AFF scene loader.
//!
//! Implements the format of BART's reference parser (`parse.c`) as summarised in
//! `AFF_FORMAT.md`. Where the reference is silent, or where following it would be
//! unhelpful, this loader decides as follows:
//!
//! - **Lexing.** Files are read as bytes (some BART comments are Latin-1). A token is a
//!   run of bytes up to whitespace, `#`, `%`, `{` or `}`; `{` and `}` are tokens of their
//!   own, and `#`/`%` start a comment to the end of the line wherever they appear (so names
//!   cannot contain them). Numbers follow C's `%f` grammar (sign, digits, optional
//!   fraction, optional exponent); NaN, infinities and values overflowing `f32` are errors.
//!   Counts and indices are decimal integers.
//! - **Paths.** Included files and textures are resolved relative to the directory of the
//!   file that names them, not the process working directory as in the reference; BART
//!   scene directories are flat, so both agree for the published scenes.
//! - **Includes.** A file that includes itself, directly or along the current include
//!   stack, is an error naming the chain; the same file may be included any number of
//!   times otherwise. `i level file` is skipped when `level` exceeds the detail level set
//!   by `d` (default 0).
//! - **Blocks.** As in the reference, the `x`/`xs` block stack is shared across include
//!   boundaries (a block may be closed in another file); a `}` with no open block, or a
//!   block still open at the end of the main file, is an error.
//! - **`v`.** The six fields (`from at up angle hither resolution`) are all required, in
//!   any order. A `hither` below 0.0001 becomes 1.0 (reference behaviour).
//! - **Materials.** One current material, kept across `}` and include boundaries (no
//!   save/restore, as in the reference); geometry before any material uses
//!   [`Material::default`]. `fm` maps directly, with the Phong exponent used as written
//!   (the reference's `4·phong_pow` is only a suggestion in a comment). NFF `f R G B Kd Ks
//!   Shine T ior` becomes diffuse `Kd·color`, ambient `0.1·Kd·color` (the convention of
//!   [`Material::matte`]; NFF has no ambient term), specular `Ks` as white. Textured
//!   primitives (`tt`, `ttp`, `m` with `texturecoords`) get a variant of the current
//!   material with its texture set; identical materials are shared.
//! - **Textures** are loaded once per resolved file; a missing or malformed texture is a
//!   parse error at the token naming it.
//! - **Transforms.** Every `xs`/`x` becomes a [`Node`]. Geometry with no animated ancestor
//!   is baked to world space and grouped under `node: None`; geometry below an animated
//!   node goes to the group of its innermost animated ancestor, with only the static
//!   matrices below that node baked in. Baked normals use the inverse transpose and are
//!   renormalised; a mirroring matrix (negative determinant) swaps the winding so the
//!   geometric normal keeps agreeing with the shading normals; spheres and cones scale
//!   their radii by the largest axis scale. A normal that degenerates to zero drops the
//!   triangle's shading normals. A zero rotation axis means no rotation.
//! - **Animated triangles** (`tpa`) are not baked: their `node` is the innermost enclosing
//!   node, static or animated. Key normals are kept as written (the BART museum data has
//!   non-unit normals), except that zero ones are replaced by the key's face normal.
//! - **Lights.** `l` positions are transformed by the static matrices of the enclosing
//!   blocks (animated nodes count as the identity, since a [`Light`] cannot follow a
//!   node); `la` lights are taken as written and follow the translation of the `k` block
//!   of their name.
//! - **Keyframes.** Tracks are resolved by name after the whole scene is read: a node,
//!   light or the camera (`k camera`) uses the *last* `k` block of its name. A `k` block
//!   naming nothing is kept and ignored. Visibility flags are true when non-zero.
//! - **Degenerate data.** Zero-area triangles are kept; polygons with fewer than three
//!   vertices produce no triangle. Counts above [`MAX_COUNT`] are errors, and storage is
//!   never reserved from a count beyond a small cap, so a lying count fails at the end of
//!   the file rather than in the allocator.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Quat, Vec2, Vec3};

use super::animation::{KeyframeTrack, RotationSpline, TcbKey, VectorSpline, MIN_SPLINE_KEYS};
use super::camera::{Camera, CameraTrack};
use super::{
    limits, AnimatedTriangle, AnimationRange, Cone, Group, Light, Material, MaterialId, Node,
    NodeId, NodeKind, Scene, SceneError, Sphere, Texture, TextureId, TrackId, Triangle,
};

/// Largest element count (vertices, triangles, polygon vertices, keys) accepted in a file.
pub const MAX_COUNT: usize = 50_000_000;
/// Deepest include nesting accepted; keeps recursion well inside a thread's stack.
const MAX_INCLUDE_DEPTH: usize = 200;
/// Most files parsed for one scene (with repeats); stops include fan-out explosions.
const MAX_FILES: usize = 100_000;
/// Most elements reserved up front from a count read in the file.
const PREALLOC_CAP: usize = 1 << 16;
/// Largest image side accepted from `resolution`.
const MAX_RESOLUTION: i64 = 1 << 16;

/// Load an AFF scene from its main file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let bytes = crate::scene::limits::read_bounded(path).map_err(|e| SceneError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let display = path.display().to_string();
    let mut scene = parse_root(&display, &bytes, dir, identity_of(path))?;
    scene.name = stem(path);
    scene.source = Some(path.to_path_buf());
    limits::check(&scene)?;
    Ok(scene)
}

/// Parse AFF text held in memory, as if it were the file `name` in `base_dir` (includes and
/// textures are resolved relative to `base_dir`; errors name the file `name`).
pub fn parse_str(name: &str, text: &[u8], base_dir: &Path) -> Result<Scene, SceneError> {
    let path = base_dir.join(name);
    let mut scene = parse_root(name, text, base_dir, identity_of(&path))?;
    scene.name = stem(Path::new(name));
    limits::check(&scene)?;
    Ok(scene)
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// A path's identity for include-cycle detection: symlinks and `..` must not hide a cycle.
fn identity_of(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

fn parse_root(
    display: &str,
    bytes: &[u8],
    dir: &Path,
    identity: PathBuf,
) -> Result<Scene, SceneError> {
    let mut p = Parser::new();
    p.includes.push((identity, display.to_string()));
    let mut lx = Lexer::new(bytes, display, dir);
    p.parse_file(&mut lx)?;
    p.finish()
}

// ---------------------------------------------------------------------------------------
// Lexer

#[derive(Clone, Copy, Debug)]
struct Tok {
    start: usize,
    end: usize,
    line: usize,
    col: usize,
}

struct Lexer<'a> {
    src: &'a [u8],
    pos: usize,
    line: usize,
    col: usize,
    peeked: Option<Option<Tok>>,
    file: &'a str,
    dir: &'a Path,
}

fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c)
}

fn is_delim(b: u8) -> bool {
    is_space(b) || matches!(b, b'#' | b'%' | b'{' | b'}')
}

/// A token's text for messages: lossy, and short enough to read.
fn show(b: &[u8]) -> String {
    let s = String::from_utf8_lossy(b);
    if s.chars().count() > 40 {
        let cut: String = s.chars().take(40).collect();
        format!("{cut}…")
    } else {
        s.into_owned()
    }
}

#[derive(Debug, PartialEq)]
enum NumErr {
    NotNumber,
    OutOfRange,
}

/// Parse a number with C `%f` syntax; the whole token must be the number.
fn parse_f32(b: &[u8]) -> Result<f32, NumErr> {
    let digits = |i: &mut usize| {
        let s = *i;
        while b.get(*i).is_some_and(u8::is_ascii_digit) {
            *i += 1;
        }
        *i - s
    };
    let mut i = 0;
    if matches!(b.first(), Some(b'+' | b'-')) {
        i = 1;
    }
    let mut mantissa = digits(&mut i);
    if b.get(i) == Some(&b'.') {
        i += 1;
        mantissa += digits(&mut i);
    }
    if mantissa == 0 {
        return Err(NumErr::NotNumber);
    }
    if matches!(b.get(i), Some(b'e' | b'E')) {
        i += 1;
        if matches!(b.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        if digits(&mut i) == 0 {
            return Err(NumErr::NotNumber);
        }
    }
    if i != b.len() {
        return Err(NumErr::NotNumber);
    }
    let s = std::str::from_utf8(b).map_err(|_| NumErr::NotNumber)?;
    let v: f32 = s.parse().map_err(|_| NumErr::NotNumber)?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(NumErr::OutOfRange)
    }
}

/// Parse a decimal integer (optional sign); `None` when malformed or beyond ±10¹⁸.
fn parse_int(b: &[u8]) -> Option<i64> {
    let (neg, digits) = match b.first() {
        Some(b'-') => (true, &b[1..]),
        Some(b'+') => (false, &b[1..]),
        _ => (false, b),
    };
    if digits.is_empty() || digits.len() > 18 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let v = digits
        .iter()
        .fold(0i64, |acc, d| acc * 10 + i64::from(d - b'0'));
    Some(if neg { -v } else { v })
}

type Res<T> = Result<T, SceneError>;

impl<'a> Lexer<'a> {
    fn new(src: &'a [u8], file: &'a str, dir: &'a Path) -> Self {
        Self {
            src,
            pos: 0,
            line: 1,
            col: 1,
            peeked: None,
            file,
            dir,
        }
    }

    fn bump(&mut self) {
        if self.src.get(self.pos) == Some(&b'\n') {
            self.line += 1;
            self.col = 1;
        } else {
            self.col += 1;
        }
        self.pos += 1;
    }

    fn scan(&mut self) -> Option<Tok> {
        loop {
            let b = *self.src.get(self.pos)?;
            if is_space(b) {
                self.bump();
            } else if b == b'#' || b == b'%' {
                while self.src.get(self.pos).is_some_and(|&c| c != b'\n') {
                    self.bump();
                }
            } else {
                break;
            }
        }
        let (start, line, col) = (self.pos, self.line, self.col);
        if matches!(self.src.get(self.pos), Some(b'{' | b'}')) {
            self.bump();
        } else {
            while self.src.get(self.pos).is_some_and(|&c| !is_delim(c)) {
                self.bump();
            }
        }
        Some(Tok {
            start,
            end: self.pos,
            line,
            col,
        })
    }

    fn next(&mut self) -> Option<Tok> {
        match self.peeked.take() {
            Some(t) => t,
            None => self.scan(),
        }
    }

    fn peek(&mut self) -> Option<Tok> {
        if let Some(t) = self.peeked {
            return t;
        }
        let t = self.scan();
        self.peeked = Some(t);
        t
    }

    fn text(&self, t: Tok) -> &'a [u8] {
        self.src.get(t.start..t.end).unwrap_or(&[])
    }

    fn err_at(&self, line: usize, column: usize, message: String) -> SceneError {
        SceneError::Parse {
            file: self.file.to_string(),
            line,
            column,
            message,
        }
    }

    fn err(&self, t: Tok, message: String) -> SceneError {
        self.err_at(t.line, t.col, message)
    }

    /// The next token, or an error at the end of the file saying what was expected.
    fn need(&mut self, expected: &str) -> Res<Tok> {
        match self.next() {
            Some(t) => Ok(t),
            None => Err(self.err_at(
                self.line,
                self.col,
                format!("unexpected end of file, expected {expected}"),
            )),
        }
    }

    fn number(&mut self, what: &str) -> Res<f32> {
        let t = self.need(what)?;
        parse_f32(self.text(t)).map_err(|e| {
            let text = show(self.text(t));
            match e {
                NumErr::NotNumber => self.err(t, format!("expected {what}, found '{text}'")),
                NumErr::OutOfRange => {
                    self.err(t, format!("{what} '{text}' is not a finite f32 number"))
                }
            }
        })
    }

    /// Three numbers that form a colour within [`limits::MAX_COLOR`] (`name` in the
    /// error), the error at the first of them.
    fn color(&mut self, what: &str, name: &str) -> Res<Vec3> {
        let first = self.peek();
        let c = self.vec3(what)?;
        match first {
            Some(t) if !limits::color_ok(c) => Err(self.err(t, limits::color_message(name, c))),
            _ => Ok(c),
        }
    }

    fn vec3(&mut self, what: &str) -> Res<Vec3> {
        Ok(Vec3::new(
            self.number(what)?,
            self.number(what)?,
            self.number(what)?,
        ))
    }

    fn int(&mut self, what: &str) -> Res<(Tok, i64)> {
        let t = self.need(what)?;
        match parse_int(self.text(t)) {
            Some(v) => Ok((t, v)),
            None => Err(self.err(
                t,
                format!(
                    "expected {what} (an integer), found '{}'",
                    show(self.text(t))
                ),
            )),
        }
    }

    /// A count in `0..=MAX_COUNT`.
    fn count(&mut self, what: &str) -> Res<(Tok, usize)> {
        let (t, v) = self.int(what)?;
        if v < 0 {
            return Err(self.err(t, format!("{what} must not be negative, found {v}")));
        }
        match usize::try_from(v) {
            Ok(n) if n <= MAX_COUNT => Ok((t, n)),
            _ => Err(self.err(t, format!("{what} {v} exceeds the limit of {MAX_COUNT}"))),
        }
    }

    /// An index into a list of `len` elements.
    fn index(&mut self, what: &str, len: usize) -> Res<usize> {
        let (t, v) = self.int(what)?;
        match usize::try_from(v) {
            Ok(i) if i < len => Ok(i),
            _ => Err(self.err(t, format!("{what} {v} out of range (the mesh has {len})"))),
        }
    }

    /// A name or file name: any token but a brace.
    fn word(&mut self, what: &str) -> Res<(Tok, String)> {
        let t = self.need(what)?;
        let b = self.text(t);
        if b == b"{" || b == b"}" {
            return Err(self.err(t, format!("expected {what}, found '{}'", show(b))));
        }
        Ok((t, String::from_utf8_lossy(b).into_owned()))
    }

    fn keyword(&mut self, kw: &str, context: &str) -> Res<Tok> {
        let t = self.need(&format!("'{kw}' {context}"))?;
        if self.text(t) != kw.as_bytes() {
            return Err(self.err(
                t,
                format!("expected '{kw}' {context}, found '{}'", show(self.text(t))),
            ));
        }
        Ok(t)
    }

    fn peek_is_number(&mut self) -> bool {
        match self.peek() {
            Some(t) => parse_f32(self.text(t)).is_ok(),
            None => false,
        }
    }
}

// ---------------------------------------------------------------------------------------
// Transforms

/// A baking transform with what is needed to move every kind of primitive through it.
#[derive(Clone, Copy, Debug)]
struct Xf {
    m: Mat4,
    /// Inverse transpose up to a positive factor (normals are renormalised anyway).
    normal: Mat3,
    /// Negative determinant: the winding must be swapped.
    flip: bool,
    /// Largest axis scale, applied to radii.
    radius_scale: f32,
}

impl Xf {
    fn new(m: Mat4) -> Self {
        let a = Mat3::from_mat4(m);
        let (x, y, z) = (a.x_axis, a.y_axis, a.z_axis);
        // Cofactor matrix = det · inverse transpose, defined even for singular matrices.
        let cof = Mat3::from_cols(y.cross(z), z.cross(x), x.cross(y));
        let det = a.determinant();
        let flip = det < 0.0;
        Self {
            m,
            normal: if flip { -cof } else { cof },
            flip,
            radius_scale: x.length().max(y.length()).max(z.length()),
        }
    }

    fn point(&self, p: Vec3) -> Vec3 {
        self.m.transform_point3(p)
    }

    /// Unit normal, or zero when it degenerates.
    fn normal(&self, n: Vec3) -> Vec3 {
        (self.normal * n).normalize_or_zero()
    }
}

/// `T·R·S` of an `xs` directive.
fn xs_matrix(scale: Vec3, axis: Vec3, angle_deg: f32, transl: Vec3) -> Mat4 {
    let rot = match axis.try_normalize() {
        Some(a) => Quat::from_axis_angle(a, angle_deg.to_radians()),
        None => Quat::IDENTITY,
    };
    Mat4::from_scale_rotation_translation(scale, rot, transl)
}

/// An open `x`/`xs` block.
struct Frame {
    node: NodeId,
    /// Innermost animated node at or above this one.
    anim: Option<NodeId>,
    /// Static matrices below `anim` (or from the world when `anim` is `None`).
    bake: Xf,
    /// All static matrices of the chain, animated nodes counted as the identity.
    statics: Mat4,
    /// Where the block was opened, for the "never closed" error.
    file: String,
    line: usize,
    col: usize,
}

// ---------------------------------------------------------------------------------------
// Parser

/// Material identity for sharing: the bit patterns of every field.
type MaterialKey = ([u32; 12], Option<TextureId>);

/// A material's colours and coefficients within [`limits::MAX_COLOR`] (the whole-scene
/// check's rule, here with the material directive's place).
fn check_material(lx: &Lexer, t: Tok, m: &Material) -> Res<()> {
    match limits::material_out_of_limit(m) {
        Some((what, c)) => Err(lx.err(t, limits::color_message(&format!("material {what}"), c))),
        None => Ok(()),
    }
}

fn material_key(m: &Material) -> MaterialKey {
    let f = [
        m.ambient.x,
        m.ambient.y,
        m.ambient.z,
        m.diffuse.x,
        m.diffuse.y,
        m.diffuse.z,
        m.specular.x,
        m.specular.y,
        m.specular.z,
        m.shininess,
        m.transmission,
        m.ior,
    ];
    (f.map(f32::to_bits), m.texture)
}

struct Parser {
    scene: Scene,
    detail: i64,
    material: Material,
    material_ids: HashMap<MaterialKey, MaterialId>,
    /// Loaded textures by joined path and by canonical path.
    texture_ids: HashMap<PathBuf, TextureId>,
    group_ids: HashMap<Option<NodeId>, usize>,
    frames: Vec<Frame>,
    /// Files being parsed, outermost first: (identity, displayed name).
    includes: Vec<(PathBuf, String)>,
    files_parsed: usize,
    /// Triangles made so far (static and animated), against the budget.
    triangles: usize,
    /// Spheres and cones made so far, against the budget.
    analytic: usize,
    /// Last `k` block of each name.
    tracks_by_name: HashMap<String, TrackId>,
}

/// Converts a collection length to a 32-bit id, failing instead of wrapping.
fn id32(len: usize, lx: &Lexer, t: Tok, what: &str) -> Res<u32> {
    u32::try_from(len).map_err(|_| lx.err(t, format!("too many {what}")))
}

impl Parser {
    fn new() -> Self {
        let scene = Scene {
            ambient: Vec3::ONE,
            camera: CameraTrack {
                base: Camera::default(),
                track: None,
                resolution: None,
            },
            ..Scene::default()
        };
        Self {
            scene,
            detail: 0,
            material: Material::default(),
            material_ids: HashMap::new(),
            texture_ids: HashMap::new(),
            group_ids: HashMap::new(),
            frames: Vec::new(),
            includes: Vec::new(),
            files_parsed: 1,
            triangles: 0,
            analytic: 0,
            tracks_by_name: HashMap::new(),
        }
    }

    fn parse_file(&mut self, lx: &mut Lexer) -> Res<()> {
        while let Some(t) = lx.next() {
            self.directive(lx, t)?;
        }
        Ok(())
    }

    fn directive(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        match lx.text(t) {
            b"v" => self.viewpoint(lx, t),
            b"b" => {
                self.scene.background = lx.color("a background color component", "background")?;
                Ok(())
            }
            b"am" => {
                self.scene.ambient = lx.color("an ambient light component", "ambient light")?;
                Ok(())
            }
            b"l" => self.light(lx, t, false),
            b"la" => self.light(lx, t, true),
            b"f" => self.nff_material(lx, t),
            b"fm" => self.extended_material(lx, t),
            b"c" => self.cone(lx, t),
            b"s" => self.sphere(lx, t),
            b"p" => self.polygon(lx, t, false),
            b"pp" => self.polygon(lx, t, true),
            b"tt" => self.textured_triangle(lx, t, false),
            b"ttp" => self.textured_triangle(lx, t, true),
            b"tpa" => self.animated_triangle(lx, t),
            b"m" => self.mesh(lx, t),
            b"i" => self.include(lx, t),
            b"d" => {
                self.detail = lx.int("a detail level")?.1;
                Ok(())
            }
            b"xs" => self.static_xform(lx, t),
            b"x" => self.animated_xform(lx, t),
            b"}" => match self.frames.pop() {
                Some(_) => Ok(()),
                None => Err(lx.err(t, "unbalanced '}': no open x or xs block".into())),
            },
            b"a" => self.animation(lx),
            b"k" => self.keyframes(lx),
            b"{" => Err(lx.err(t, "unexpected '{' (only x and xs open blocks)".into())),
            other => Err(lx.err(t, format!("unknown directive '{}'", show(other)))),
        }
    }

    fn finish(mut self) -> Res<Scene> {
        if let Some(f) = self.frames.last() {
            return Err(SceneError::Parse {
                file: f.file.clone(),
                line: f.line,
                column: f.col,
                message: "block opened here is never closed (missing '}')".into(),
            });
        }
        let by_name = &self.tracks_by_name;
        for node in &mut self.scene.nodes {
            if let NodeKind::Animated { name, track } = &mut node.kind {
                *track = by_name.get(name.as_str()).copied();
            }
        }
        for light in &mut self.scene.lights {
            if let Some(name) = &light.name {
                light.track = by_name.get(name.as_str()).copied();
            }
        }
        self.scene.camera.track = by_name.get("camera").copied();
        Ok(self.scene)
    }

    // --- state helpers -------------------------------------------------------------

    fn bake(&self) -> Xf {
        self.frames
            .last()
            .map_or_else(|| Xf::new(Mat4::IDENTITY), |f| f.bake)
    }

    fn group_index(&mut self) -> usize {
        let key = self.frames.last().and_then(|f| f.anim);
        let groups = &mut self.scene.groups;
        *self.group_ids.entry(key).or_insert_with(|| {
            groups.push(Group {
                node: key,
                ..Group::default()
            });
            groups.len() - 1
        })
    }

    fn material_id(&mut self, lx: &Lexer, t: Tok, texture: Option<TextureId>) -> Res<MaterialId> {
        let mut m = self.material.clone();
        m.texture = texture;
        let key = material_key(&m);
        if let Some(&id) = self.material_ids.get(&key) {
            return Ok(id);
        }
        let id = id32(self.scene.materials.len(), lx, t, "materials")?;
        self.scene.materials.push(m);
        self.material_ids.insert(key, id);
        Ok(id)
    }

    fn texture_id(&mut self, lx: &Lexer, t: Tok, name: &str) -> Res<TextureId> {
        let path = lx.dir.join(name);
        // Textured triangles name their texture one by one: skip the file system for
        // names seen before, and canonicalise only new ones.
        if let Some(&id) = self.texture_ids.get(&path) {
            return Ok(id);
        }
        let key = identity_of(&path);
        if let Some(&id) = self.texture_ids.get(&key) {
            self.texture_ids.insert(path, id);
            return Ok(id);
        }
        let tex = Texture::load_ppm(&path)
            .map_err(|e| lx.err(t, format!("cannot use texture '{name}': {e}")))?;
        let id = id32(self.scene.textures.len(), lx, t, "textures")?;
        self.scene.textures.push(tex);
        self.texture_ids.insert(key, id);
        self.texture_ids.insert(path, id);
        Ok(id)
    }

    fn push_node(&mut self, lx: &Lexer, t: Tok, kind: NodeKind) -> Res<NodeId> {
        let id = id32(self.scene.nodes.len(), lx, t, "transform nodes")?;
        let parent = self.frames.last().map(|f| f.node);
        self.scene.nodes.push(Node { parent, kind });
        Ok(id)
    }

    fn open_brace(lx: &mut Lexer, what: &str) -> Res<()> {
        lx.keyword("{", what).map(|_| ())
    }

    /// Count one more primitive made against its budget (`triangle`: a triangle, else a
    /// sphere or cone). Counted as they are made, so an include fan-out stops before it
    /// exhausts memory.
    fn count_made(&mut self, lx: &Lexer, t: Tok, triangle: bool) -> Res<()> {
        let (made, limit, what) = if triangle {
            (&mut self.triangles, limits::MAX_TRIANGLES, "triangles")
        } else {
            (
                &mut self.analytic,
                limits::MAX_ANALYTIC,
                "spheres and cones",
            )
        };
        *made += 1;
        if *made > limit {
            return Err(lx.err(t, format!("the scene expands to more than {limit} {what}")));
        }
        Ok(())
    }

    /// Bakes a triangle into the current group's space and stores it.
    fn emit_triangle(
        &mut self,
        lx: &Lexer,
        t: Tok,
        xf: &Xf,
        group: usize,
        tri: Triangle,
    ) -> Res<()> {
        let tri = bake_triangle(xf, tri);
        if let Some(&p) = tri.p.iter().find(|&&p| !limits::coordinate_ok(p)) {
            return Err(lx.err(
                t,
                limits::coordinate_message("vertex (after transformation)", p),
            ));
        }
        self.count_made(lx, t, true)?;
        if let Some(g) = self.scene.groups.get_mut(group) {
            g.triangles.push(tri);
        }
        Ok(())
    }

    // --- directives ----------------------------------------------------------------

    fn viewpoint(&mut self, lx: &mut Lexer, v: Tok) -> Res<()> {
        const FIELDS: &str = "a viewpoint field (from, at, up, angle, hither or resolution)";
        let mut cam = Camera::default();
        let mut resolution = (0u32, 0u32);
        let mut seen = [false; 6];
        for _ in 0..6 {
            let t = lx.need(FIELDS)?;
            let field = lx.text(t);
            let slot = match field {
                b"from" => 0,
                b"at" => 1,
                b"up" => 2,
                b"angle" => 3,
                b"hither" => 4,
                b"resolution" => 5,
                other => {
                    return Err(lx.err(t, format!("expected {FIELDS}, found '{}'", show(other))))
                }
            };
            if std::mem::replace(&mut seen[slot], true) {
                return Err(lx.err(t, format!("viewpoint field '{}' given twice", show(field))));
            }
            match slot {
                0 => cam.eye = lx.vec3("a 'from' coordinate")?,
                1 => cam.at = lx.vec3("an 'at' coordinate")?,
                2 => cam.up = lx.vec3("an 'up' coordinate")?,
                3 => cam.fov_y_deg = lx.number("the field of view angle")?,
                4 => {
                    let h = lx.number("the hither distance")?;
                    cam.hither = if h < 0.0001 { 1.0 } else { h };
                }
                _ => {
                    let mut side = |what: &str| -> Res<u32> {
                        let (t, v) = lx.int(what)?;
                        match u32::try_from(v) {
                            Ok(s) if (1..=MAX_RESOLUTION).contains(&v) => Ok(s),
                            _ => Err(
                                lx.err(t, format!("{what} {v} out of range 1..={MAX_RESOLUTION}"))
                            ),
                        }
                    };
                    resolution = (side("the image width")?, side("the image height")?);
                }
            }
        }
        if let Some((what, p)) = limits::camera_out_of_limit(&cam) {
            return Err(lx.err(v, limits::coordinate_message(what, p)));
        }
        self.scene.camera.base = cam;
        self.scene.camera.resolution = Some(resolution);
        Ok(())
    }

    fn light(&mut self, lx: &mut Lexer, t: Tok, animated: bool) -> Res<()> {
        let name = if animated {
            Some(lx.word("a light name")?.1)
        } else {
            None
        };
        let mut position = lx.vec3("a light position coordinate")?;
        let color = if lx.peek_is_number() {
            lx.color("a light color component", "light colour")?
        } else {
            Vec3::ONE
        };
        if !animated {
            if let Some(f) = self.frames.last() {
                position = f.statics.transform_point3(position);
            }
        }
        if !limits::coordinate_ok(position) {
            return Err(lx.err(t, limits::coordinate_message("light position", position)));
        }
        self.scene.lights.push(Light {
            position,
            color,
            track: None,
            name,
        });
        Ok(())
    }

    fn nff_material(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let color = lx.vec3("a material color component")?;
        let kd = lx.number("the diffuse coefficient Kd")?;
        let ks = lx.number("the specular coefficient Ks")?;
        let shine = lx.number("the Phong exponent")?;
        let transmission = lx.number("the transmittance")?;
        let ior = lx.number("the index of refraction")?;
        self.material = Material {
            ambient: color * kd * 0.1,
            diffuse: color * kd,
            specular: Vec3::splat(ks),
            shininess: shine,
            transmission,
            ior,
            texture: None,
        };
        check_material(lx, t, &self.material)
    }

    fn extended_material(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let ambient = lx.vec3("an ambient color component")?;
        let diffuse = lx.vec3("a diffuse color component")?;
        let specular = lx.vec3("a specular color component")?;
        let shininess = lx.number("the Phong exponent")?;
        let transmission = lx.number("the transmittance")?;
        let ior = lx.number("the index of refraction")?;
        self.material = Material {
            ambient,
            diffuse,
            specular,
            shininess,
            transmission,
            ior,
            texture: None,
        };
        check_material(lx, t, &self.material)
    }

    fn cone(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let base = lx.vec3("a cone base coordinate")?;
        let base_radius = lx.number("the cone base radius")?;
        let apex = lx.vec3("a cone apex coordinate")?;
        let apex_radius = lx.number("the cone apex radius")?;
        let xf = self.bake();
        let cone = Cone {
            base: xf.point(base),
            base_radius: base_radius * xf.radius_scale,
            apex: xf.point(apex),
            apex_radius: apex_radius * xf.radius_scale,
            material: self.material_id(lx, t, None)?,
        };
        let radii = Vec3::new(cone.base_radius, cone.apex_radius, 0.0);
        if let Some(p) = [cone.base, cone.apex, radii]
            .into_iter()
            .find(|&p| !limits::coordinate_ok(p))
        {
            return Err(lx.err(t, limits::coordinate_message("cone base, apex or radii", p)));
        }
        self.count_made(lx, t, false)?;
        let g = self.group_index();
        self.scene.groups[g].cones.push(cone);
        Ok(())
    }

    fn sphere(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let center = lx.vec3("a sphere center coordinate")?;
        let radius = lx.number("the sphere radius")?;
        let xf = self.bake();
        let sphere = Sphere {
            center: xf.point(center),
            radius: radius * xf.radius_scale,
            material: self.material_id(lx, t, None)?,
        };
        let extent = sphere.center.abs() + Vec3::splat(sphere.radius.abs());
        if !limits::coordinate_ok(extent) {
            return Err(lx.err(
                t,
                limits::coordinate_message("sphere center ± radius", extent),
            ));
        }
        self.count_made(lx, t, false)?;
        let g = self.group_index();
        self.scene.groups[g].spheres.push(sphere);
        Ok(())
    }

    fn polygon(&mut self, lx: &mut Lexer, t: Tok, with_normals: bool) -> Res<()> {
        let (_, n) = lx.count("the polygon vertex count")?;
        let mut p = Vec::with_capacity(n.min(PREALLOC_CAP));
        let mut nn = Vec::with_capacity(if with_normals { n.min(PREALLOC_CAP) } else { 0 });
        for _ in 0..n {
            p.push(lx.vec3("a polygon vertex coordinate")?);
            if with_normals {
                nn.push(lx.vec3("a polygon vertex normal component")?);
            }
        }
        let material = self.material_id(lx, t, None)?;
        let xf = self.bake();
        let g = self.group_index();
        for i in 1..n.saturating_sub(1) {
            let idx = [0, i, i + 1];
            let tri = Triangle {
                p: idx.map(|k| p[k]),
                n: with_normals.then(|| idx.map(|k| nn[k])),
                uv: None,
                material,
            };
            self.emit_triangle(lx, t, &xf, g, tri)?;
        }
        Ok(())
    }

    fn textured_triangle(&mut self, lx: &mut Lexer, t: Tok, with_normals: bool) -> Res<()> {
        let (tex_tok, tex_name) = lx.word("a texture file name")?;
        let mut p = [Vec3::ZERO; 3];
        let mut n = [Vec3::ZERO; 3];
        let mut uv = [Vec2::ZERO; 3];
        for k in 0..3 {
            p[k] = lx.vec3("a vertex coordinate")?;
            if with_normals {
                n[k] = lx.vec3("a vertex normal component")?;
            }
            uv[k] = Vec2::new(
                lx.number("a texture coordinate")?,
                lx.number("a texture coordinate")?,
            );
        }
        let tex = self.texture_id(lx, tex_tok, &tex_name)?;
        let material = self.material_id(lx, t, Some(tex))?;
        let xf = self.bake();
        let g = self.group_index();
        let tri = Triangle {
            p,
            n: with_normals.then_some(n),
            uv: Some(uv),
            material,
        };
        self.emit_triangle(lx, t, &xf, g, tri)
    }

    fn animated_triangle(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let (kt, k) = lx.count("the number of keys")?;
        if k == 0 {
            return Err(lx.err(kt, "an animated triangle needs at least one key".into()));
        }
        let cap = k.min(PREALLOC_CAP);
        let (mut times, mut positions, mut normals) = (
            Vec::with_capacity(cap),
            Vec::with_capacity(cap),
            Vec::with_capacity(cap),
        );
        for _ in 0..k {
            times.push(lx.number("a key time")?);
            let mut p = [Vec3::ZERO; 3];
            let mut n = [Vec3::ZERO; 3];
            for j in 0..3 {
                p[j] = lx.vec3("a vertex coordinate")?;
                if !limits::coordinate_ok(p[j]) {
                    return Err(lx.err(t, limits::coordinate_message("vertex", p[j])));
                }
                n[j] = lx.vec3("a vertex normal component")?;
            }
            let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or(Vec3::Y);
            for v in &mut n {
                if *v == Vec3::ZERO {
                    *v = face;
                }
            }
            positions.push(p);
            normals.push(n);
        }
        let material = self.material_id(lx, t, None)?;
        self.count_made(lx, t, true)?;
        self.scene.animated_triangles.push(AnimatedTriangle {
            times,
            positions,
            normals,
            material,
            node: self.frames.last().map(|f| f.node),
        });
        Ok(())
    }

    fn mesh(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let xf = self.bake();
        lx.keyword("vertices", "after 'm'")?;
        let (_, nv) = lx.count("the vertex count")?;
        let mut verts = Vec::with_capacity(nv.min(PREALLOC_CAP));
        for _ in 0..nv {
            let v = xf.point(lx.vec3("a vertex coordinate")?);
            if !limits::coordinate_ok(v) {
                return Err(lx.err(t, limits::coordinate_message("mesh vertex", v)));
            }
            verts.push(v);
        }
        let mut next = lx.need("'normals', 'texturecoords' or 'triangles'")?;
        let mut normals = None;
        if lx.text(next) == b"normals" {
            let (_, nn) = lx.count("the normal count")?;
            let mut ns = Vec::with_capacity(nn.min(PREALLOC_CAP));
            for _ in 0..nn {
                ns.push(xf.normal(lx.vec3("a normal component")?));
            }
            normals = Some(ns);
            next = lx.need("'texturecoords' or 'triangles'")?;
        }
        let mut texcoords = None;
        let mut texture = None;
        if lx.text(next) == b"texturecoords" {
            let (_, nt) = lx.count("the texture coordinate count")?;
            let (tex_tok, tex_name) = lx.word("a texture file name")?;
            texture = Some(self.texture_id(lx, tex_tok, &tex_name)?);
            let mut ts = Vec::with_capacity(nt.min(PREALLOC_CAP));
            for _ in 0..nt {
                ts.push(Vec2::new(
                    lx.number("a texture coordinate")?,
                    lx.number("a texture coordinate")?,
                ));
            }
            texcoords = Some(ts);
            next = lx.need("'triangles'")?;
        }
        if lx.text(next) != b"triangles" {
            let expected = match (&normals, &texcoords) {
                (_, Some(_)) => "'triangles'",
                (Some(_), None) => "'texturecoords' or 'triangles'",
                (None, None) => "'normals', 'texturecoords' or 'triangles'",
            };
            return Err(lx.err(
                next,
                format!(
                    "expected {expected} in mesh (sections come in the order vertices, normals, \
                     texturecoords, triangles), found '{}'",
                    show(lx.text(next))
                ),
            ));
        }
        let (_, nf) = lx.count("the triangle count")?;
        let material = self.material_id(lx, t, texture)?;
        let g = self.group_index();
        let mesh = MeshData {
            verts,
            normals,
            texcoords,
            material,
            flip: xf.flip,
        };
        let mut out = mesh.triangles(lx, nf)?;
        if let Some(grp) = self.scene.groups.get_mut(g) {
            grp.triangles.append(&mut out);
        }
        Ok(())
    }

    fn include(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let (_, level) = lx.int("a detail level")?;
        let (name_tok, name) = lx.word("an include file name")?;
        if level > self.detail {
            return Ok(());
        }
        let path = lx.dir.join(&name);
        let identity = identity_of(&path);
        let display = path.display().to_string();
        if let Some(pos) = self.includes.iter().position(|(id, _)| *id == identity) {
            let mut chain: Vec<&str> = self.includes[pos..]
                .iter()
                .map(|(_, d)| d.as_str())
                .collect();
            chain.push(&display);
            return Err(lx.err(name_tok, format!("include cycle: {}", chain.join(" -> "))));
        }
        if self.includes.len() >= MAX_INCLUDE_DEPTH {
            return Err(lx.err(
                name_tok,
                format!("includes nested deeper than {MAX_INCLUDE_DEPTH} files"),
            ));
        }
        self.files_parsed += 1;
        if self.files_parsed > MAX_FILES {
            return Err(lx.err(
                name_tok,
                format!("more than {MAX_FILES} files included in one scene"),
            ));
        }
        let bytes = crate::scene::limits::read_bounded(&path)
            .map_err(|e| lx.err(t, format!("cannot read included file {display}: {e}")))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        self.includes.push((identity, display.clone()));
        let mut inner = Lexer::new(&bytes, &display, dir);
        self.parse_file(&mut inner)?;
        self.includes.pop();
        Ok(())
    }

    fn static_xform(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let scale = lx.vec3("a scale factor")?;
        let axis = lx.vec3("a rotation axis component")?;
        let angle = lx.number("a rotation angle")?;
        let transl = lx.vec3("a translation component")?;
        Self::open_brace(lx, "after the xs parameters")?;
        let m = xs_matrix(scale, axis, angle, transl);
        let (anim, bake, statics) = match self.frames.last() {
            Some(f) => (f.anim, f.bake.m * m, f.statics * m),
            None => (None, m, m),
        };
        let node = self.push_node(lx, t, NodeKind::Static(m))?;
        self.frames.push(Frame {
            node,
            anim,
            bake: Xf::new(bake),
            statics,
            file: lx.file.to_string(),
            line: t.line,
            col: t.col,
        });
        Ok(())
    }

    fn animated_xform(&mut self, lx: &mut Lexer, t: Tok) -> Res<()> {
        let (_, name) = lx.word("a transform name")?;
        Self::open_brace(lx, "after the transform name")?;
        let statics = self.frames.last().map_or(Mat4::IDENTITY, |f| f.statics);
        let node = self.push_node(lx, t, NodeKind::Animated { name, track: None })?;
        self.frames.push(Frame {
            node,
            anim: Some(node),
            bake: Xf::new(Mat4::IDENTITY),
            statics,
            file: lx.file.to_string(),
            line: t.line,
            col: t.col,
        });
        Ok(())
    }

    fn animation(&mut self, lx: &mut Lexer) -> Res<()> {
        let start = lx.number("the animation start time")?;
        let end = lx.number("the animation end time")?;
        let (ft, frames) = lx.int("the number of frames")?;
        let frames = u32::try_from(frames)
            .map_err(|_| lx.err(ft, format!("frame count {frames} out of range")))?;
        self.scene.animation = Some(AnimationRange { start, end, frames });
        Ok(())
    }

    fn keyframes(&mut self, lx: &mut Lexer) -> Res<()> {
        let (_, name) = lx.word("an animation name")?;
        Self::open_brace(lx, "after the animation name")?;
        let mut track = KeyframeTrack {
            name: name.clone(),
            ..KeyframeTrack::default()
        };
        let mut seen = [false; 4];
        loop {
            let t = lx.need("'transl', 'rot', 'scale', 'visibility' or '}'")?;
            let kind = lx.text(t);
            let slot = match kind {
                b"}" => break,
                b"transl" => 0,
                b"rot" => 1,
                b"scale" => 2,
                b"visibility" => 3,
                other => {
                    return Err(lx.err(
                        t,
                        format!(
                            "expected 'transl', 'rot', 'scale', 'visibility' or '}}' in k {name}, found '{}'",
                            show(other)
                        ),
                    ))
                }
            };
            if std::mem::replace(&mut seen[slot], true) {
                return Err(lx.err(t, format!("'{}' given twice in k {name}", show(kind))));
            }
            let (ct, n) = lx.count("the key count")?;
            let min = if slot == 3 { 1 } else { MIN_SPLINE_KEYS };
            if n < min {
                return Err(lx.err(
                    ct,
                    format!("'{}' needs at least {min} keys, found {n}", show(kind)),
                ));
            }
            let cap = n.min(PREALLOC_CAP);
            match slot {
                0 | 2 => {
                    let mut keys = Vec::with_capacity(cap);
                    for _ in 0..n {
                        let time = lx.number("a key time")?;
                        let value = lx.vec3("a key value")?;
                        keys.push(tcb(lx, time, value)?);
                    }
                    let spline = VectorSpline::new(keys);
                    if slot == 0 {
                        track.translation = spline;
                    } else {
                        track.scale = spline;
                    }
                }
                1 => {
                    let mut keys = Vec::with_capacity(cap);
                    for _ in 0..n {
                        let time = lx.number("a key time")?;
                        let axis = lx.vec3("a rotation axis component")?;
                        let angle = lx.number("a rotation angle")?;
                        keys.push(tcb(lx, time, (axis, angle))?);
                    }
                    track.rotation = RotationSpline::new(keys);
                }
                _ => {
                    let mut keys = Vec::with_capacity(cap);
                    for _ in 0..n {
                        let time = lx.number("a key time")?;
                        let flag = lx.number("a visibility flag")?;
                        keys.push((time, flag != 0.0));
                    }
                    track.visibility = keys;
                }
            }
        }
        let id = u32::try_from(self.scene.tracks.len())
            .map_err(|_| lx.err_at(lx.line, lx.col, "too many animations".into()))?;
        self.scene.tracks.push(track);
        self.tracks_by_name.insert(name, id);
        Ok(())
    }
}

fn tcb<T>(lx: &mut Lexer, time: f32, value: T) -> Res<TcbKey<T>> {
    Ok(TcbKey {
        time,
        value,
        tension: lx.number("a tension")?,
        continuity: lx.number("a continuity")?,
        bias: lx.number("a bias")?,
    })
}

/// A mesh's vertex data as read, in world space, before its triangles.
struct MeshData {
    verts: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    texcoords: Option<Vec<Vec2>>,
    material: MaterialId,
    /// The baking transform has a negative determinant: the winding must be swapped.
    flip: bool,
}

impl MeshData {
    /// Read the `nf` triangles of the mesh's `triangles` section, each as indices
    /// into the vertex data it has.
    fn triangles(&self, lx: &mut Lexer, nf: usize) -> Res<Vec<Triangle>> {
        let mut out = Vec::with_capacity(nf.min(PREALLOC_CAP));
        for _ in 0..nf {
            let mut tri_index = |what: &str, len: usize| -> Res<[usize; 3]> {
                Ok([
                    lx.index(what, len)?,
                    lx.index(what, len)?,
                    lx.index(what, len)?,
                ])
            };
            let vi = tri_index("vertex index", self.verts.len())?;
            let ni = match &self.normals {
                Some(ns) => Some(tri_index("normal index", ns.len())?),
                None => None,
            };
            let ti = match &self.texcoords {
                Some(ts) => Some(tri_index("texture coordinate index", ts.len())?),
                None => None,
            };
            let mut tri = Triangle {
                p: vi.map(|i| self.verts[i]),
                n: None,
                uv: None,
                material: self.material,
            };
            if let (Some(ns), Some(ni)) = (&self.normals, ni) {
                let n = ni.map(|i| ns[i]);
                tri.n = n.iter().all(|v| *v != Vec3::ZERO).then_some(n);
            }
            if let (Some(ts), Some(ti)) = (&self.texcoords, ti) {
                tri.uv = Some(ti.map(|i| ts[i]));
            }
            if self.flip {
                swap_winding(&mut tri);
            }
            out.push(tri);
        }
        Ok(out)
    }
}

fn swap_winding(tri: &mut Triangle) {
    tri.p.swap(1, 2);
    if let Some(n) = &mut tri.n {
        n.swap(1, 2);
    }
    if let Some(uv) = &mut tri.uv {
        uv.swap(1, 2);
    }
}

/// Moves a triangle through a baking transform (positions, normals, winding).
fn bake_triangle(xf: &Xf, mut tri: Triangle) -> Triangle {
    tri.p = tri.p.map(|p| xf.point(p));
    tri.n = tri.n.and_then(|n| {
        let n = n.map(|v| xf.normal(v));
        n.iter().all(|v| *v != Vec3::ZERO).then_some(n)
    });
    if xf.flip {
        swap_winding(&mut tri);
    }
    tri
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_follow_c_syntax() {
        for (s, v) in [
            ("1", 1.0),
            ("-2.5", -2.5),
            ("+.5", 0.5),
            ("7.21E-4", 7.21e-4),
            ("3.", 3.0),
            ("1e3", 1000.0),
        ] {
            assert_eq!(parse_f32(s.as_bytes()), Ok(v), "{s}");
        }
        for s in [
            "", ".", "-", "e5", "1e", "1.2.3", "nan", "inf", "0x10", "1,5",
        ] {
            assert_eq!(parse_f32(s.as_bytes()), Err(NumErr::NotNumber), "{s}");
        }
        assert_eq!(parse_f32(b"1e39"), Err(NumErr::OutOfRange));
        assert_eq!(parse_int(b"-12"), Some(-12));
        assert_eq!(parse_int(b"1234567890123456789"), None);
    }

    #[test]
    fn lexer_splits_braces_and_comments() {
        let src = b"x a{ 1.0%c\n}# \xe9\n  y";
        let mut lx = Lexer::new(src, "t", Path::new("."));
        let mut toks = Vec::new();
        while let Some(t) = lx.next() {
            toks.push((
                String::from_utf8_lossy(lx.text(t)).into_owned(),
                t.line,
                t.col,
            ));
        }
        let want = [
            ("x", 1, 1),
            ("a", 1, 3),
            ("{", 1, 4),
            ("1.0", 1, 6),
            ("}", 2, 1),
            ("y", 3, 3),
        ];
        let want: Vec<_> = want
            .iter()
            .map(|(s, l, c)| (s.to_string(), *l, *c))
            .collect();
        assert_eq!(toks, want);
    }

    #[test]
    fn mirroring_keeps_normals_consistent() {
        let xf = Xf::new(Mat4::from_scale(Vec3::new(-1.0, 2.0, 1.0)));
        let tri = Triangle {
            p: [Vec3::ZERO, Vec3::X, Vec3::Y],
            n: Some([Vec3::Z; 3]),
            uv: None,
            material: 0,
        };
        let b = bake_triangle(&xf, tri);
        let geo = (b.p[1] - b.p[0]).cross(b.p[2] - b.p[0]);
        assert!(geo.dot(b.n.unwrap()[0]) > 0.0);
        assert!((b.n.unwrap()[0] - Vec3::Z).length() < 1e-6);
    }
}
