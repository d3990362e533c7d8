//! The adaptive method's overlays: its tiling drawn over the image, its per-tile
//! gradients and its sample density (paper Figs. 3, 4, 7), which the viewer cycles.

use std::sync::Arc;

use crate::{
    image::Image,
    methods::adaptive::vis,
    realtime::shared::{Overlay, Overlays},
    tiles::TilingSnapshot,
};

/// What the adaptive method offers besides the image.
pub(super) const OVERLAYS: &[Overlay] = &[
    Overlay {
        name: "tiling",
        key: "tiling: tile borders in yellow",
    },
    Overlay {
        name: "gradients",
        key: "gradients per tile: red Gx, green Gy, blue Gt (each scaled to its 95th percentile)",
    },
    Overlay {
        name: "density",
        key: "density: local sample rate (∝ 1/tile area), log scale, dark sparse to bright dense",
    },
];

/// The tiling an image was reconstructed with, which draws the overlays of it.
pub(super) struct TilingOverlays(pub Arc<TilingSnapshot>);

impl Overlays for TilingOverlays {
    fn draw(&self, name: &str, image: &Image) -> Option<Image> {
        let size = (image.width, image.height);
        match name {
            "tiling" => Some(vis::tiling_overlay_of(&self.0, image)),
            "gradients" => Some(vis::gradient_map_of(&self.0, size)),
            "density" => Some(vis::density_map_of(&self.0, size)),
            _ => None,
        }
    }
}
