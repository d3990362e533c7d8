//! The input budgets every loader enforces, in one place so that they are documented
//! once (`docs/usage.md`, "Input limits") and a scene that passes them can always be built and
//! traced: no overflow in the BVH builder's surface areas, no allocation the machine
//! cannot make.
//!
//! Loaders check what they can where they read it, so that errors name the line; [`check`]
//! runs on every loaded scene as a last net for what only shows after transformation
//! (a node that scales, a mesh copied to many nodes).

use glam::Vec3;

use super::{Scene, SceneError};

/// Largest coordinate magnitude accepted, in scene units, before and after static
/// transforms. f32 BVH builders square extents (surface areas) and sum them over many
/// nodes; at 1e12 the largest such sum stays about six orders of magnitude below
/// `f32::MAX`, while the precision f32 keeps at that distance (about 1e5 units) is already
/// far coarser than any scene that would need it.
pub const MAX_COORDINATE: f32 = 1e12;

/// Most triangles a scene may expand to, after meshes are copied per node and includes
/// are expanded: about 1.3 GB of triangles and attributes plus its BVH.
pub const MAX_TRIANGLES: usize = 1 << 23;

/// Largest colour component (material reflectances, light intensities, background,
/// ambient light, texels): far above any physical reflectance or practical light, low
/// enough that a path of products and sums over many lights stays finite in f32.
pub const MAX_COLOR: f32 = 1e6;

/// Most spheres and cones together.
pub const MAX_ANALYTIC: usize = 1 << 22;

pub use super::texture::MAX_TEXTURE_SIDE;

/// Largest file any loader reads (scene, include, buffer, material library, texture,
/// camera path).
pub const MAX_FILE_BYTES: u64 = 2 << 30;

/// Read a whole input file, refusing what is not a regular file (`/dev/zero`, a FIFO, a
/// directory) or is larger than [`MAX_FILE_BYTES`], before reading it: a device would
/// otherwise be read until memory runs out.
pub fn read_bounded(path: &std::path::Path) -> std::io::Result<Vec<u8>> {
    crate::limits::read_file(path, MAX_FILE_BYTES)
}

/// Whether a colour is finite and within [`MAX_COLOR`].
#[inline]
pub fn color_ok(c: Vec3) -> bool {
    c.is_finite() && c.abs().max_element() <= MAX_COLOR
}

/// The first of a material's colours and coefficients (named) outside [`MAX_COLOR`].
pub fn material_out_of_limit(m: &super::Material) -> Option<(&'static str, Vec3)> {
    [
        ("ambient", m.ambient),
        ("diffuse", m.diffuse),
        ("specular", m.specular),
        (
            "shininess, transmission or index of refraction",
            Vec3::new(m.shininess, m.transmission, m.ior),
        ),
    ]
    .into_iter()
    .find(|&(_, c)| !color_ok(c))
}

/// The camera's eye or target (named) if it lies outside the coordinate budget.
pub fn camera_out_of_limit(cam: &super::Camera) -> Option<(&'static str, Vec3)> {
    [("camera eye", cam.eye), ("camera target", cam.at)]
        .into_iter()
        .find(|&(_, p)| !coordinate_ok(p))
}

/// The error message for a colour `c` of `what` outside [`MAX_COLOR`].
pub fn color_message(what: &str, c: Vec3) -> String {
    format!(
        "{what} ({:?}, {:?}, {:?}) is outside the colour limit of ±{MAX_COLOR:e} (or not finite)",
        c.x, c.y, c.z
    )
}

/// Whether a point is finite and inside the coordinate budget.
#[inline]
pub fn coordinate_ok(v: Vec3) -> bool {
    v.is_finite() && v.abs().max_element() <= MAX_COORDINATE
}

/// The error text for a point outside the budget.
pub fn coordinate_message(what: &str, v: Vec3) -> String {
    // Debug keeps huge values short (`2e38`, not 39 digits).
    let v = format!("({:?}, {:?}, {:?})", v.x, v.y, v.z);
    format!("{what} {v} is outside the coordinate limit of ±{MAX_COORDINATE:e} (or not finite)")
}

/// Check a loaded scene against every budget, naming the first element that breaks one.
/// Every loader calls it; a scene built in code should too, since the tracer relies on
/// these bounds (finite colours and coordinates) rather than testing every sample.
pub fn check(scene: &Scene) -> Result<(), SceneError> {
    let bad = |message: String| SceneError::Invalid {
        name: scene
            .source
            .as_ref()
            .map_or_else(|| scene.name.clone(), |p| p.display().to_string()),
        message,
    };
    check_counts(scene, &bad)?;
    check_coordinates(scene, &bad)?;
    check_colors(scene, &bad)?;
    if let Some((what, p)) = camera_out_of_limit(&scene.camera.base) {
        return Err(bad(coordinate_message(what, p)));
    }
    Ok(())
}

/// The scene's triangles, spheres and cones against their budgets.
fn check_counts(scene: &Scene, bad: &dyn Fn(String) -> SceneError) -> Result<(), SceneError> {
    let triangles: usize = scene
        .groups
        .iter()
        .map(|g| g.triangles.len())
        .sum::<usize>()
        + scene.animated_triangles.len();
    if triangles > MAX_TRIANGLES {
        return Err(bad(format!(
            "{triangles} triangles exceed the limit of {MAX_TRIANGLES}"
        )));
    }
    let analytic: usize = scene
        .groups
        .iter()
        .map(|g| g.spheres.len() + g.cones.len())
        .sum();
    if analytic > MAX_ANALYTIC {
        return Err(bad(format!(
            "{analytic} spheres and cones exceed the limit of {MAX_ANALYTIC}"
        )));
    }
    Ok(())
}

/// Every vertex, centre, radius and light position against [`MAX_COORDINATE`].
fn check_coordinates(scene: &Scene, bad: &dyn Fn(String) -> SceneError) -> Result<(), SceneError> {
    for (gi, g) in scene.groups.iter().enumerate() {
        for (ti, t) in g.triangles.iter().enumerate() {
            if let Some(&p) = t.p.iter().find(|&&p| !coordinate_ok(p)) {
                return Err(bad(coordinate_message(
                    &format!("group {gi} triangle {ti}: vertex"),
                    p,
                )));
            }
        }
        for (si, s) in g.spheres.iter().enumerate() {
            let extent = Vec3::splat(s.radius.abs());
            if !coordinate_ok(s.center) || !coordinate_ok(extent) {
                return Err(bad(coordinate_message(
                    &format!("group {gi} sphere {si} (radius {}): center", s.radius),
                    s.center,
                )));
            }
        }
        for (ci, c) in g.cones.iter().enumerate() {
            let radii = Vec3::new(c.base_radius.abs(), c.apex_radius.abs(), 0.0);
            for p in [c.base, c.apex, radii] {
                if !coordinate_ok(p) {
                    return Err(bad(coordinate_message(
                        &format!("group {gi} cone {ci}: base, apex or radius"),
                        p,
                    )));
                }
            }
        }
    }
    for (ai, a) in scene.animated_triangles.iter().enumerate() {
        for ps in &a.positions {
            if let Some(&p) = ps.iter().find(|&&p| !coordinate_ok(p)) {
                return Err(bad(coordinate_message(
                    &format!("animated triangle {ai}: key vertex"),
                    p,
                )));
            }
        }
    }
    for (li, l) in scene.lights.iter().enumerate() {
        if !coordinate_ok(l.position) {
            return Err(bad(coordinate_message(
                &format!("light {li}: position"),
                l.position,
            )));
        }
    }
    Ok(())
}

/// Every material, light, background and texel colour against the colour limit.
fn check_colors(scene: &Scene, bad: &dyn Fn(String) -> SceneError) -> Result<(), SceneError> {
    for (mi, m) in scene.materials.iter().enumerate() {
        if let Some((what, c)) = material_out_of_limit(m) {
            return Err(bad(color_message(&format!("material {mi}: {what}"), c)));
        }
    }
    for (li, l) in scene.lights.iter().enumerate() {
        if !color_ok(l.color) {
            return Err(bad(color_message(&format!("light {li}: colour"), l.color)));
        }
    }
    for (what, c) in [
        ("background", scene.background),
        ("ambient light", scene.ambient),
    ] {
        if !color_ok(c) {
            return Err(bad(color_message(what, c)));
        }
    }
    for t in &scene.textures {
        if let Some(&c) = t.texels.iter().find(|&&c| !color_ok(c)) {
            return Err(bad(color_message(
                &format!("texture {}: a texel", t.name),
                c,
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{builtin, Group, Triangle};

    #[test]
    fn devices_and_directories_are_refused_before_reading() {
        for p in ["/dev/zero", "."] {
            let p = std::path::Path::new(p);
            if p.exists() {
                let e = read_bounded(p).unwrap_err();
                assert_eq!(
                    e.kind(),
                    std::io::ErrorKind::InvalidInput,
                    "{}",
                    p.display()
                );
            }
        }
    }

    #[test]
    fn builtin_scenes_are_within_budget() {
        for name in builtin::NAMES {
            let scene = builtin::load(name).expect("built-in");
            check(&scene).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }

    #[test]
    fn a_huge_finite_vertex_is_named() {
        let mut scene = builtin::load("toycar").expect("built-in");
        scene.groups.push(Group {
            node: None,
            triangles: vec![Triangle {
                p: [Vec3::new(2e38, -1.0, 0.0), Vec3::X, Vec3::Y],
                n: None,
                uv: None,
                material: 0,
            }],
            spheres: Vec::new(),
            cones: Vec::new(),
        });
        let e = check(&scene).unwrap_err().to_string();
        assert!(
            e.contains("outside the coordinate limit") && e.contains("2e38"),
            "{e}"
        );
        assert!(e.contains("triangle 0"), "{e}");
    }
}
