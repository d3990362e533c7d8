//! Acceleration structures: one `obvhs` CwBvh per rigid group (the static world is one
//! big group), a small top level over the animated instances, and a refit Bvh2 for
//! animated triangles.

use glam::{Mat3, Mat4, Vec2, Vec3, Vec3A};
use obvhs::{
    aabb::Aabb,
    bvh2::Bvh2,
    cwbvh::CwBvh,
    ray::{Ray, RayHit},
    rt_triangle::RtTriangle,
    triangle::Triangle as ObTriangle,
    Boundable,
};

use super::{build, intersect};
use crate::scene::{Cone, MaterialId, Sphere, Triangle};

/// Shading attributes of one triangle, in its group's space.
#[derive(Clone, Copy, Debug)]
pub struct TriAttr {
    /// Per-vertex shading normals (the geometric normal when the scene gave none).
    pub n: [Vec3; 3],
    /// Per-vertex texture coordinates (zero when the scene gave none).
    pub uv: [Vec2; 3],
    /// Material.
    pub material: MaterialId,
}

/// An analytic primitive (sphere or cone side).
#[derive(Clone, Copy, Debug)]
pub enum Analytic {
    /// A sphere.
    Sphere(Sphere),
    /// A cone or cylinder side.
    Cone(Cone),
}

impl Analytic {
    fn intersect(&self, ray: &Ray) -> f32 {
        match self {
            Analytic::Sphere(s) => intersect::sphere(s, ray),
            Analytic::Cone(c) => intersect::cone(c, ray),
        }
    }
    fn aabb(&self) -> Aabb {
        match self {
            Analytic::Sphere(s) => intersect::sphere_aabb(s),
            Analytic::Cone(c) => intersect::cone_aabb(c),
        }
    }
    /// Material of the primitive.
    pub fn material(&self) -> MaterialId {
        match self {
            Analytic::Sphere(s) => s.material,
            Analytic::Cone(c) => c.material,
        }
    }
    /// Outward normal at a point on the surface.
    pub fn normal(&self, p: Vec3) -> Vec3 {
        match self {
            Analytic::Sphere(s) => intersect::sphere_normal(s, p),
            Analytic::Cone(c) => intersect::cone_normal(c, p),
        }
    }
}

/// Which primitive of a group a ray hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimRef {
    /// Triangle index (in the group's BVH order).
    Tri(u32),
    /// Analytic primitive index.
    Analytic(u32),
}

/// Analytic sets up to this size are intersected one by one.
const ANALYTIC_BRUTE_FORCE: usize = 4;

/// A rigid set of primitives with its own BVH, in its own space.
pub struct GroupAccel {
    bvh: Option<CwBvh>,
    /// Triangles in BVH leaf order, ready for intersection.
    pub tris: Vec<RtTriangle>,
    /// Attributes aligned with `tris`.
    pub attrs: Vec<TriAttr>,
    /// Analytic primitives, in `analytic_bvh` leaf order when there is one.
    pub analytic: Vec<Analytic>,
    /// BVH over the analytic primitives; small sets are tested one by one.
    analytic_bvh: Option<Bvh2>,
    /// Bounds of everything in the group.
    pub aabb: Aabb,
    /// Triangles left out of the build: degenerate, exact copies, or beyond the build
    /// limit.
    pub dropped: usize,
}

/// Largest coordinate magnitude the builders are given. Loaders keep scenes within
/// [`crate::scene::limits::MAX_COORDINATE`]; this is the last guard for what a transform
/// or a programmatic scene produces: the builders' surface areas overflow f32 beyond
/// about 1e19, and then obvhs indexes out of bounds.
const BUILD_COORDINATE_LIMIT: f32 = 1e18;

/// Whether a point is finite and inside the build limit.
fn within_build_limit(p: Vec3A) -> bool {
    p.is_finite() && p.abs().max_element() <= BUILD_COORDINATE_LIMIT
}

/// Whether a triangle can be built and hit: inside the build limit and with a non-zero
/// area (a degenerate triangle is never hit; it would only cost the build).
fn buildable(t: &Triangle) -> bool {
    t.p.iter().all(|&p| within_build_limit(p.into()))
        && (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]) != Vec3::ZERO
}

/// The triangles worth building: [`buildable`] ones, each exact copy of an earlier one
/// dropped (the same vertices in any rotation: a copy hits at the same distance, so it
/// can never show, only slow the build).
fn distinct_buildable(triangles: &[Triangle]) -> Vec<usize> {
    let mut seen = std::collections::HashSet::with_capacity(triangles.len());
    let key = |t: &Triangle| {
        let bits = |p: Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
        let mut v = t.p.map(bits);
        // Rotations keep the winding, so the front face and normal are the same.
        let first = (0..3).min_by_key(|&i| v[i]).unwrap_or(0);
        v.rotate_left(first);
        (v, t.material)
    };
    (0..triangles.len())
        .filter(|&i| buildable(&triangles[i]) && seen.insert(key(&triangles[i])))
        .collect()
}

/// A box clamped to the build limit (non-finite bounds become the whole range), for the
/// top level, whose boxes come from animated transforms no loader can bound.
pub fn finite_aabb(b: Aabb) -> Aabb {
    let lim = Vec3A::splat(BUILD_COORDINATE_LIMIT);
    let fix =
        |v: Vec3A, fallback: Vec3A| Vec3A::select(v.is_nan_mask(), fallback, v).clamp(-lim, lim);
    Aabb {
        min: fix(b.min, -lim),
        max: fix(b.max, lim),
    }
}

impl GroupAccel {
    /// Build from triangles (already in the group's space) and analytic shapes. Triangles
    /// that cannot be hit (degenerate, exact copies) or built (beyond the build limit) are
    /// left out; see [`GroupAccel::dropped`].
    pub fn build(triangles: &[Triangle], analytic: Vec<Analytic>) -> Self {
        let keep = distinct_buildable(triangles);
        let dropped = triangles.len() - keep.len();
        let obtris: Vec<ObTriangle> = keep
            .iter()
            .map(|&i| {
                let t = &triangles[i];
                ObTriangle {
                    v0: t.p[0].into(),
                    v1: t.p[1].into(),
                    v2: t.p[2].into(),
                }
            })
            .collect();
        let analytic: Vec<Analytic> = analytic
            .into_iter()
            .filter(|a| {
                let b = a.aabb();
                within_build_limit(b.min) && within_build_limit(b.max)
            })
            .collect();
        let mut aabb = Aabb::empty();
        for t in &obtris {
            aabb = aabb.union(&t.aabb());
        }
        for a in &analytic {
            aabb = aabb.union(&a.aabb());
        }
        let (bvh, tris, attrs) = if obtris.is_empty() {
            (None, Vec::new(), Vec::new())
        } else {
            let boxes: Vec<Aabb> = obtris.iter().map(|t| t.aabb()).collect();
            let bvh = build::build_cwbvh(&boxes);
            let mut tris = Vec::with_capacity(bvh.primitive_indices.len());
            let mut attrs = Vec::with_capacity(bvh.primitive_indices.len());
            for &i in &bvh.primitive_indices {
                let t = &triangles[keep[i as usize]];
                tris.push(RtTriangle::from(&obtris[i as usize]));
                let ng = (t.p[1] - t.p[0])
                    .cross(t.p[2] - t.p[0])
                    .normalize_or(Vec3::Y);
                attrs.push(TriAttr {
                    n: t.n.unwrap_or([ng; 3]),
                    uv: t.uv.unwrap_or([Vec2::ZERO; 3]),
                    material: t.material,
                });
            }
            (Some(bvh), tris, attrs)
        };
        let (analytic, analytic_bvh) = if analytic.len() > ANALYTIC_BRUTE_FORCE {
            let boxes: Vec<Aabb> = analytic.iter().map(|a| a.aabb()).collect();
            let bvh = build::build_bvh2(&boxes);
            let ordered = bvh
                .primitive_indices
                .iter()
                .map(|&i| analytic[i as usize])
                .collect();
            (ordered, Some(bvh))
        } else {
            (analytic, None)
        };
        Self {
            bvh,
            tris,
            attrs,
            analytic,
            analytic_bvh,
            aabb,
            dropped,
        }
    }

    /// Closest hit along `ray` (whose `tmax` bounds the search).
    #[inline]
    pub fn closest(&self, ray: &Ray) -> Option<(f32, PrimRef)> {
        let mut best_t = ray.tmax;
        let mut best = None;
        if let Some(bvh) = &self.bvh {
            let mut hit = RayHit::none();
            if bvh.ray_traverse(*ray, &mut hit, |r, id| self.tris[id].intersect(r)) {
                best_t = hit.t;
                best = Some((hit.t, PrimRef::Tri(hit.primitive_id)));
            }
        }
        let mut r = *ray;
        r.tmax = best_t;
        if let Some(abvh) = &self.analytic_bvh {
            let mut hit = RayHit::none();
            if abvh.ray_traverse(r, &mut hit, |r, id| self.analytic[id].intersect(r)) {
                best = Some((hit.t, PrimRef::Analytic(hit.primitive_id)));
            }
        } else {
            for (i, a) in self.analytic.iter().enumerate() {
                let t = a.intersect(&r);
                if t < r.tmax {
                    r.tmax = t;
                    best = Some((t, PrimRef::Analytic(i as u32)));
                }
            }
        }
        best
    }

    /// Whether anything opaque blocks `ray`; transmissive hits multiply `transmission`
    /// by their material's transmission (looked up through `transmission_of`).
    #[inline]
    pub fn occlusion(
        &self,
        ray: &Ray,
        transmission_of: &dyn Fn(MaterialId) -> f32,
        acc: &mut f32,
    ) -> bool {
        if let Some(bvh) = &self.bvh {
            let blocked = !bvh.ray_traverse_miss(*ray, |r, id| {
                let t = self.tris[id].intersect(r);
                if t.is_finite() {
                    let tr = transmission_of(self.attrs[id].material);
                    if tr > 0.0 {
                        *acc *= tr;
                        return f32::INFINITY;
                    }
                }
                t
            });
            if blocked {
                return true;
            }
        }
        let mut test = |a: &Analytic, r: &Ray| -> bool {
            if a.intersect(r).is_finite() {
                let tr = transmission_of(a.material());
                if tr > 0.0 {
                    *acc *= tr;
                } else {
                    return true;
                }
            }
            false
        };
        match &self.analytic_bvh {
            Some(abvh) => !abvh.ray_traverse_miss(*ray, |r, id| {
                if test(&self.analytic[id], r) {
                    0.0
                } else {
                    f32::INFINITY
                }
            }),
            None => self.analytic.iter().any(|a| test(a, ray)),
        }
    }

    /// The triangles' wide BVH (`None`: no triangles), for the GPU tracer's upload.
    #[cfg(feature = "gpu")]
    pub(super) fn cw_bvh(&self) -> Option<&CwBvh> {
        self.bvh.as_ref()
    }

    /// The analytic primitives' BVH (`None`: tested one by one).
    #[cfg(feature = "gpu")]
    pub(super) fn analytic_bvh(&self) -> Option<&Bvh2> {
        self.analytic_bvh.as_ref()
    }

    /// Number of primitives.
    pub fn len(&self) -> usize {
        self.tris.len() + self.analytic.len()
    }

    /// Whether the group is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Transform a box by a matrix (bounds of the eight transformed corners).
pub fn transform_aabb(m: &Mat4, b: &Aabb) -> Aabb {
    let mut out = Aabb::empty();
    for i in 0..8 {
        let c = Vec3A::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        );
        out.extend(m.transform_point3a(c));
    }
    out
}

/// A rigid instance placed in the world at one time.
#[derive(Clone, Copy, Debug)]
pub struct InstanceState {
    /// Index into the tracer's instance groups.
    pub group: u32,
    /// Local-to-world matrix.
    pub world: Mat4,
    /// World-to-local matrix.
    pub inv: Mat4,
    /// Inverse-transpose of the world matrix's linear part, for normals.
    pub normal: Mat3,
    /// d(world)/dt, turning local points into world velocities.
    pub velocity: Mat4,
    /// World bounds at this time.
    pub aabb: Aabb,
}

impl InstanceState {
    /// A world-space ray in the instance's local space. The direction is not
    /// renormalised, so hit distances `t` stay comparable with world-space ones.
    #[inline]
    pub fn local_ray(&self, r: &Ray) -> Ray {
        Ray::new(
            self.inv.transform_point3a(r.origin),
            self.inv.transform_vector3a(r.direction),
            r.tmin,
            r.tmax,
        )
    }
}

impl Boundable for InstanceState {
    fn aabb(&self) -> Aabb {
        self.aabb
    }
}

/// A BVH over boxes, rebuilt per scene state (instances) — tiny, so build speed wins.
pub fn build_top_level<T: Boundable>(items: &[T]) -> Option<Bvh2> {
    if items.is_empty() {
        return None;
    }
    let boxes: Vec<Aabb> = items.iter().map(|i| finite_aabb(i.aabb())).collect();
    Some(build::build_bvh2(&boxes))
}
