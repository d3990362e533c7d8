//! Texture filtering by ray cones (Akenine-Möller et al., "Texture Level of Detail
//! Strategies for Real-Time Ray Tracing", Ray Tracing Gems, ch. 20).
//!
//! A ray stands for the bundle of directions through its pixel; a cone of half-width
//! angle `spread` around it tells how large a patch of surface the pixel covers where the
//! ray lands. That patch, measured in texels, picks the mip level, so a far or grazing
//! textured surface reads its texture's local average instead of one point of it (which
//! aliases: moiré on a checkered floor).
//!
//! Choices, after the chapter's simplest variant:
//! - A primary cone starts with width 0 at the eye and spread equal to one pixel's
//!   angular size at the image center (`atan` of the pixel's size on the plane at
//!   distance 1); off-center pixels are treated alike.
//! - Width grows linearly, `width + spread · distance`, the small-angle form.
//! - Reflected and refracted rays carry the cone on: the width continues from the hit and
//!   the spread is unchanged, exact for planar mirrors and flat interfaces. Curved
//!   mirrors would widen (convex) or narrow (concave) the cone; that curvature term is
//!   left out, so reflections in curved mirrors are filtered as if the mirror were flat.
//! - The level is `Δ + log2(width / |cos θ|)` with `Δ = 0.5 · log2(t_a / p_a)`: `t_a`
//!   the triangle's area in texels (`w · h ·` its UV area), `p_a` its world area, and `θ`
//!   the angle between the ray and the geometric normal. `1/|cos θ|` is clamped to
//!   `1 / MIN_COS` so a ray exactly along a surface still gives a finite level.
//! - Analytic primitives (spheres, cones) and animated triangles carry no texture
//!   coordinates here (their UV is constant 0), so their texel density is taken as 0:
//!   level 0, the same lookup as without filtering, which for a constant UV is exact.

use crate::scene::CameraFrame;

pub use crate::settings::TextureFilter;

/// Smallest `|cos θ|` the level computation uses: at most `log2(1/MIN_COS)` ≈ 6.6
/// levels are added for grazing incidence.
pub const MIN_COS: f32 = 0.01;

/// A ray cone at some point along its ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayCone {
    /// Width (diameter) of the cone there, world units.
    pub width: f32,
    /// Spread angle, radians (the growth of width per unit distance).
    pub spread: f32,
}

impl RayCone {
    /// The cone of a primary ray at the eye.
    pub fn primary(camera: &CameraFrame) -> Self {
        let pixel = 0.5 * (camera.du.length() + camera.dv.length());
        Self {
            width: 0.0,
            spread: pixel.atan(),
        }
    }

    /// The cone `distance` further along its ray.
    #[inline]
    pub fn advance(self, distance: f32) -> Self {
        Self {
            width: self.width + self.spread * distance,
            ..self
        }
    }
}

/// What the shader needs to filter a texture at a hit: the cone there and the hit
/// triangle's texture-space over world-space area ratio (`|uv area| / world area`, 0
/// where the surface has no texture parametrisation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// The cone at the hit.
    pub cone: RayCone,
    /// UV area per unit world area of the hit triangle.
    pub uv_density: f32,
}

/// The mip level for a texture of `texels` texels (`w · h`) seen through a cone of
/// `width` at a hit where `cos_incidence` is the cosine between the ray and the surface
/// normal, on a triangle with `uv_density` UV area per unit world area. Negative levels
/// (magnification) are returned as is; lookups clamp them to 0. Returns 0 when the
/// footprint or density is 0 or not finite.
pub fn texture_lod(width: f32, cos_incidence: f32, texels: u32, uv_density: f32) -> f32 {
    let cos = cos_incidence.abs().clamp(MIN_COS, 1.0);
    // Δ + log2(width / cos) in one log: 0.5 · log2(t_a/p_a · width² / cos²).
    let x = texels as f32 * uv_density * (width * width) / (cos * cos);
    if x > 0.0 && x.is_finite() {
        0.5 * x.log2()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lod_grows_with_distance_and_grazing_angle() {
        let spread = 0.002;
        // A 1×1 m quad mapped once onto a 256×256 texture.
        let lod = |dist: f32, cos: f32| {
            let cone = RayCone { width: 0.0, spread }.advance(dist);
            texture_lod(cone.width, cos, 256 * 256, 1.0)
        };
        let mut prev = f32::NEG_INFINITY;
        for dist in [1.0, 2.0, 4.0, 8.0, 16.0] {
            let l = lod(dist, 1.0);
            assert!(l > prev, "{dist}: {l} after {prev}");
            prev = l;
        }
        // Doubling the distance adds one level.
        assert!((lod(8.0, 1.0) - lod(4.0, 1.0) - 1.0).abs() < 1e-5);
        let mut prev = f32::NEG_INFINITY;
        for cos in [1.0, 0.7, 0.3, 0.1, 0.03] {
            let l = lod(4.0, cos);
            assert!(l > prev, "cos {cos}: {l} after {prev}");
            prev = l;
        }
        // Clamped, finite, and either sign of the cosine.
        assert_eq!(lod(4.0, 0.0), lod(4.0, MIN_COS));
        assert_eq!(lod(4.0, -0.3), lod(4.0, 0.3));
        // Denser texturing (4× the UV area on the same triangle) is one level up.
        assert!(
            (texture_lod(0.1, 1.0, 1024, 4.0) - texture_lod(0.1, 1.0, 1024, 1.0) - 1.0).abs()
                < 1e-5
        );
        // No parametrisation or no footprint: level 0.
        assert_eq!(texture_lod(0.1, 1.0, 1024, 0.0), 0.0);
        assert_eq!(texture_lod(0.0, 1.0, 1024, 1.0), 0.0);
        assert_eq!(texture_lod(f32::NAN, 1.0, 1024, 1.0), 0.0);
    }

    #[test]
    fn cones_continue_and_start_at_the_pixel_size() {
        let c = RayCone {
            width: 0.5,
            spread: 0.01,
        };
        assert_eq!(
            c.advance(10.0),
            RayCone {
                width: 0.6,
                spread: 0.01
            }
        );
        let cam = crate::scene::Camera::default().frame(100, 100);
        let p = RayCone::primary(&cam);
        assert_eq!(p.width, 0.0);
        assert!((p.spread - cam.dv.length().atan()).abs() < 1e-6);
    }
}
