//! Phong materials as BART's `fm` directive describes them.

use glam::Vec3;

use super::TextureId;

/// A Whitted/Phong material.
///
/// Mirror reflectance is the specular color (AFF has no separate reflection field; NFF
/// used `Ks` for both). `transmission > 0` makes the surface refract with `ior` and cast
/// attenuated shadows.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Ambient color, multiplied by the scene's global ambient.
    pub ambient: Vec3,
    /// Diffuse color (modulated by the texture when one is set).
    pub diffuse: Vec3,
    /// Specular color: Phong highlight strength and mirror reflectance.
    pub specular: Vec3,
    /// Phong exponent.
    pub shininess: f32,
    /// Fraction of light transmitted (0 = opaque).
    pub transmission: f32,
    /// Index of refraction (values ≤ 0 are read as 1).
    pub ior: f32,
    /// Texture modulating the diffuse and ambient terms.
    pub texture: Option<TextureId>,
}

impl Default for Material {
    /// A matte light grey, used when a file draws geometry before any material.
    fn default() -> Self {
        Self {
            ambient: Vec3::splat(0.1),
            diffuse: Vec3::splat(0.7),
            specular: Vec3::ZERO,
            shininess: 10.0,
            transmission: 0.0,
            ior: 1.0,
            texture: None,
        }
    }
}

impl Material {
    /// A diffuse-only material of the given color.
    pub fn matte(color: Vec3) -> Self {
        Self {
            ambient: color * 0.1,
            diffuse: color,
            ..Self::default()
        }
    }

    /// The index of refraction to use (non-positive means vacuum).
    pub fn effective_ior(&self) -> f32 {
        if self.ior > 0.0 {
            self.ior
        } else {
            1.0
        }
    }

    /// Whether the surface reflects (non-zero specular).
    pub fn is_reflective(&self) -> bool {
        self.specular.max_element() > 0.0
    }
}
