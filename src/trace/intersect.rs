//! Ray–primitive intersections for the analytic shapes (triangles use `obvhs`).

use glam::{Vec3, Vec3A};
use obvhs::{aabb::Aabb, ray::Ray};

use crate::scene::{Cone, Sphere};

/// Nearest `t` in `[tmin, tmax]` where the ray meets the sphere, or `INFINITY`.
pub fn sphere(s: &Sphere, ray: &Ray) -> f32 {
    let c = Vec3A::from(s.center);
    let r = s.radius.abs();
    let oc = ray.origin - c;
    let a = ray.direction.length_squared();
    let half_b = oc.dot(ray.direction);
    let cc = oc.length_squared() - r * r;
    let disc = half_b * half_b - a * cc;
    if disc < 0.0 || a == 0.0 {
        return f32::INFINITY;
    }
    let sq = disc.sqrt();
    for t in [(-half_b - sq) / a, (-half_b + sq) / a] {
        if t >= ray.tmin && t <= ray.tmax {
            return t;
        }
    }
    f32::INFINITY
}

/// Outward unit normal of a sphere at a surface point.
pub fn sphere_normal(s: &Sphere, p: Vec3) -> Vec3 {
    (p - s.center).normalize_or(Vec3::Y)
}

/// Nearest `t` in `[tmin, tmax]` where the ray meets the side of the truncated cone
/// (no caps), or `INFINITY`.
pub fn cone(c: &Cone, ray: &Ray) -> f32 {
    let base = Vec3A::from(c.base);
    let axis_full = Vec3A::from(c.apex) - base;
    let h = axis_full.length();
    if h == 0.0 {
        return f32::INFINITY;
    }
    let w = axis_full / h;
    let (r0, r1) = (c.base_radius.abs(), c.apex_radius.abs());
    let k = (r1 - r0) / h; // radius slope along the axis
                           // Point p(t) = o + t d; s = (p − base)·w; radial² = |p − base|² − s²; want radial = r0 + k s.
    let o = ray.origin - base;
    let d = ray.direction;
    let (od, dd, ow, dw) = (o.dot(d), d.dot(d), o.dot(w), d.dot(w));
    let oo = o.dot(o);
    let a = dd - dw * dw - k * k * dw * dw;
    let b = 2.0 * (od - ow * dw - k * dw * (r0 + k * ow));
    let cc = oo - ow * ow - (r0 + k * ow) * (r0 + k * ow);
    let roots = if a.abs() < 1e-12 {
        if b.abs() < 1e-12 {
            return f32::INFINITY;
        }
        [-cc / b, f32::INFINITY]
    } else {
        let disc = b * b - 4.0 * a * cc;
        if disc < 0.0 {
            return f32::INFINITY;
        }
        let sq = disc.sqrt();
        let (t0, t1) = ((-b - sq) / (2.0 * a), (-b + sq) / (2.0 * a));
        if t0 <= t1 {
            [t0, t1]
        } else {
            [t1, t0]
        }
    };
    for t in roots {
        if t >= ray.tmin && t <= ray.tmax {
            let s = ow + t * dw;
            // Within the height and on the nappe where the radius is non-negative.
            if (0.0..=h).contains(&s) && r0 + k * s >= 0.0 {
                return t;
            }
        }
    }
    f32::INFINITY
}

/// Outward unit normal of the cone side at a surface point.
pub fn cone_normal(c: &Cone, p: Vec3) -> Vec3 {
    let axis = c.apex - c.base;
    let h = axis.length().max(1e-20);
    let w = axis / h;
    let k = (c.apex_radius.abs() - c.base_radius.abs()) / h;
    let q = p - c.base;
    let s = q.dot(w);
    let radial = (q - w * s).normalize_or(w.any_orthonormal_vector());
    (radial - w * k).normalize_or(radial)
}

/// Bounding box of a sphere.
pub fn sphere_aabb(s: &Sphere) -> Aabb {
    let r = Vec3A::splat(s.radius.abs());
    let c = Vec3A::from(s.center);
    Aabb::new(c - r, c + r)
}

/// Bounding box of a cone (conservative: spheres around both end discs).
pub fn cone_aabb(c: &Cone) -> Aabb {
    let r = c.base_radius.abs().max(c.apex_radius.abs());
    let (a, b) = (Vec3A::from(c.base), Vec3A::from(c.apex));
    Aabb::new(a.min(b) - r, a.max(b) + r)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: Vec3, d: Vec3) -> Ray {
        Ray::new(o.into(), d.into(), 0.0, f32::INFINITY)
    }

    #[test]
    fn sphere_hits_front_then_inside() {
        let s = Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
            material: 0,
        };
        assert!((sphere(&s, &ray(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z)) - 4.0).abs() < 1e-6);
        // From inside: the far wall.
        assert!((sphere(&s, &ray(Vec3::ZERO, Vec3::X)) - 1.0).abs() < 1e-6);
        assert!(sphere(&s, &ray(Vec3::new(0.0, 2.0, 5.0), Vec3::NEG_Z)).is_infinite());
        // Unnormalised direction: t scales inversely.
        assert!((sphere(&s, &ray(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z * 2.0)) - 2.0).abs() < 1e-6);
    }

    #[test]
    fn cylinder_and_cone_sides() {
        let cyl = Cone {
            base: Vec3::ZERO,
            base_radius: 1.0,
            apex: Vec3::Y * 2.0,
            apex_radius: 1.0,
            material: 0,
        };
        let t = cone(&cyl, &ray(Vec3::new(5.0, 1.0, 0.0), Vec3::NEG_X));
        assert!((t - 4.0).abs() < 1e-5, "{t}");
        // Above the top: miss (no caps).
        assert!(cone(&cyl, &ray(Vec3::new(5.0, 2.5, 0.0), Vec3::NEG_X)).is_infinite());
        // Straight down the axis: no side hit.
        assert!(cone(&cyl, &ray(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y)).is_infinite());
        let n = cone_normal(&cyl, Vec3::new(1.0, 1.0, 0.0));
        assert!((n - Vec3::X).length() < 1e-5);
        // Cone radius 1 at y=0 to 0 at y=1: at y=0.5 the radius is 0.5.
        let cn = Cone {
            base: Vec3::ZERO,
            base_radius: 1.0,
            apex: Vec3::Y,
            apex_radius: 0.0,
            material: 0,
        };
        let t = cone(&cn, &ray(Vec3::new(5.0, 0.5, 0.0), Vec3::NEG_X));
        assert!((t - 4.5).abs() < 1e-5, "{t}");
        let n = cone_normal(&cn, Vec3::new(0.5, 0.5, 0.0));
        assert!((n - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-5);
    }
}
