//! The screen tiling as every layer sees it: pixel rectangles, and the snapshot of a
//! tiling that the reconstructor reads.
//!
//! The adaptive sampler owns and adapts the tiling (`methods::adaptive::tiling`); the
//! reconstructor only needs each tile's rectangle and gradient estimates to size its
//! filters. Keeping that snapshot down here lets the reconstructor sit below the
//! methods that feed it.

use crate::sampling::Rng;

/// A rectangle of pixels `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    /// Left, inclusive.
    pub x0: u32,
    /// Top, inclusive.
    pub y0: u32,
    /// Right, exclusive.
    pub x1: u32,
    /// Bottom, exclusive.
    pub y1: u32,
}

impl Rect {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    /// Area in pixels.
    pub fn area(&self) -> u32 {
        self.width() * self.height()
    }
    /// Whether the continuous point `(x, y)` lies in the rectangle.
    pub fn contains_point(&self, x: f32, y: f32) -> bool {
        x >= self.x0 as f32 && y >= self.y0 as f32 && x < self.x1 as f32 && y < self.y1 as f32
    }

    /// Whether pixel `(x, y)` lies in the rectangle.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x0 && x < self.x1 && y >= self.y0 && y < self.y1
    }

    /// The rectangle moved by `(dx, dy)` pixels.
    pub fn offset(&self, dx: u32, dy: u32) -> Rect {
        Rect {
            x0: self.x0 + dx,
            y0: self.y0 + dy,
            x1: self.x1 + dx,
            y1: self.y1 + dy,
        }
    }

    /// A uniformly random sub-pixel position inside.
    pub fn random_point(&self, rng: &mut Rng) -> (f32, f32) {
        let x = self.x0 as f32 + rng.uniform() * self.width() as f32;
        let y = self.y0 as f32 + rng.uniform() * self.height() as f32;
        // Keep strictly inside the rectangle despite rounding.
        (x.min(self.x1 as f32 - 1e-3), y.min(self.y1 as f32 - 1e-3))
    }
}

/// One tile as the reconstructor reads it: where it is and the image's gradients there
/// (magnitudes of the spatial derivatives along x and y per pixel and of the temporal
/// derivative per second, from the sampler's statistics).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileGradients {
    /// The tile's pixels.
    pub rect: Rect,
    /// Spatial gradient along x.
    pub gx: f64,
    /// Spatial gradient along y.
    pub gy: f64,
    /// Temporal gradient.
    pub gt: f64,
}

/// A tiling at one instant: tiles covering the image without overlap.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TilingSnapshot {
    /// The tiles, in the sampler's leaf order.
    pub tiles: Vec<TileGradients>,
}

impl TilingSnapshot {
    /// One tile covering a `width × height` image, with no gradient information.
    pub fn whole(width: u32, height: u32) -> Self {
        Self {
            tiles: vec![TileGradients {
                rect: Rect {
                    x0: 0,
                    y0: 0,
                    x1: width,
                    y1: height,
                },
                gx: 0.0,
                gy: 0.0,
                gt: 0.0,
            }],
        }
    }
}
