//! Whitted shading: ambient, hard shadows and Phong highlights from every point light,
//! mirror reflection and refraction up to a depth limit.
//!
//! Surfaces are shaded two-sided: normals are flipped to face the incoming ray, because
//! scene meshes do not reliably agree on winding. Transmissive surfaces refract with
//! Snell's law (total internal reflection goes to the mirror term) and let a fraction
//! `transmission` of light through in shadow tests.

use glam::{Vec3, Vec3A};
use obvhs::ray::Ray;

use super::{
    cones::{texture_lod, Footprint, RayCone},
    SceneState, Surface, Tracer,
};

fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Refract unit `d` through unit `n` (facing against `d`) with ratio `eta = n1/n2`.
fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    (k >= 0.0).then(|| (eta * d + (eta * cos_i - k.sqrt()) * n).normalize())
}

/// A shaded point as its lights see it.
#[derive(Clone, Copy)]
struct Lit {
    /// The hit pushed off the surface, where shadow rays start.
    p_out: Vec3,
    /// The self-intersection offset there.
    eps: f32,
    /// Shading and geometric normals, facing the viewer.
    n: Vec3,
    ng: Vec3,
    /// The incoming ray's direction.
    d: Vec3,
    /// Diffuse colour, texture applied.
    diffuse: Vec3,
}

impl Tracer {
    /// Shade a hit; `fp` is the ray cone's footprint there when filtering textures by
    /// ray cones (`None`: unfiltered lookups). Also says whether anything moving took
    /// part (see [`super::Sample::dynamic`]).
    pub(crate) fn shade(
        &self,
        state: &SceneState,
        ray: &Ray,
        s: &Surface,
        fp: Option<Footprint>,
        depth: u32,
    ) -> (Vec3, bool) {
        let scene = &self.scene;
        let mut dynamic = s.velocity != Vec3::ZERO;
        let Some(m) = scene.materials.get(s.material as usize) else {
            // Unreachable for loaded scenes: loud magenta.
            return (Vec3::new(1.0, 0.0, 1.0), dynamic);
        };
        let d = Vec3::from(ray.direction).normalize();
        let entering = s.ng.dot(d) < 0.0;
        let (ng, mut n) = if entering { (s.ng, s.n) } else { (-s.ng, -s.n) };
        if n.dot(d) > 0.0 {
            // Interpolated normal points away from the viewer: fall back to geometry.
            n = ng;
        }
        let tex = m
            .texture
            .and_then(|t| scene.textures.get(t as usize))
            .map_or(Vec3::ONE, |t| match fp {
                None => t.sample(s.uv),
                Some(f) => {
                    let lod =
                        texture_lod(f.cone.width, d.dot(ng), t.width * t.height, f.uv_density);
                    t.sample_lod(s.uv, lod)
                }
            });
        let mut color = scene.ambient * m.ambient * tex;
        let eps = self.epsilon(s.p);
        let p_out = s.p + ng * eps;
        let lit = Lit {
            p_out,
            eps,
            n,
            ng,
            d,
            diffuse: m.diffuse * tex,
        };
        dynamic |= self.add_direct_light(state, m, &lit, &mut color);
        if depth >= self.options.max_depth {
            return (color, dynamic);
        }
        // Secondary rays carry the cone on from this hit, spread unchanged (flat-mirror
        // approximation; see `cones`).
        let cone: Option<RayCone> = fp.map(|f| f.cone);
        let refl_dir = reflect(d, n);
        let mut mirror_weight = if m.is_reflective() {
            m.specular
        } else {
            Vec3::ZERO
        };
        if m.transmission > 0.0 {
            let ior = m.effective_ior();
            let eta = if entering { 1.0 / ior } else { ior };
            match refract(d, n, eta) {
                Some(t_dir) => {
                    let origin = s.p - ng * eps;
                    let (c, d) = self.radiance(state, origin, t_dir, cone, depth + 1);
                    color += m.transmission * c;
                    dynamic |= d;
                }
                None => mirror_weight += Vec3::splat(m.transmission),
            }
        }
        if mirror_weight.max_element() > 0.0 {
            let (c, d) = self.radiance(state, p_out, refl_dir, cone, depth + 1);
            color += mirror_weight * c;
            dynamic |= d;
        }
        (color, dynamic)
    }

    /// Add each light's diffuse and specular contribution at `lit` to `color`, in the
    /// lights' order; whether a moving object shadowed any.
    fn add_direct_light(
        &self,
        state: &SceneState,
        m: &crate::scene::Material,
        lit: &Lit,
        color: &mut Vec3,
    ) -> bool {
        let Lit {
            p_out,
            eps,
            n,
            ng,
            d,
            diffuse,
        } = *lit;
        let mut dynamic = false;
        for &(lp, lc) in &state.lights {
            let l = lp - p_out;
            let dist = l.length();
            if dist <= eps {
                continue;
            }
            let l = l / dist;
            let ndl = n.dot(l);
            if ndl <= 0.0 || ng.dot(l) <= 0.0 {
                continue;
            }
            let sray = Ray::new(Vec3A::from(p_out), Vec3A::from(l), 0.0, dist * (1.0 - 1e-5));
            let (vis, moving_blocker) = self.shadow(state, &sray);
            dynamic |= moving_blocker;
            if vis <= 0.0 {
                continue;
            }
            let mut c = diffuse * ndl;
            if m.specular.max_element() > 0.0 {
                let rv = reflect(-l, n).dot(-d);
                if rv > 0.0 {
                    c += m.specular * rv.powf(m.shininess.max(0.0));
                }
            }
            *color += lc * vis * c;
        }
        dynamic
    }

    fn radiance(
        &self,
        state: &SceneState,
        origin: Vec3,
        dir: Vec3,
        cone: Option<RayCone>,
        depth: u32,
    ) -> (Vec3, bool) {
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), 0.0, f32::INFINITY);
        match self.closest(state, &ray) {
            None => (self.scene.background, false),
            Some(h) => {
                let s = self.surface(state, &ray, &h);
                let fp = self.footprint(state, &h, cone);
                self.shade(state, &ray, &s, fp, depth)
            }
        }
    }
}
