//! `frameless`: adaptive frameless rendering.
//!
//! A ray tracer for animated scenes whose image is never rendered as a frame. See
//! `docs/ARCHITECTURE.md` for how data flows from a scene to the displayed image.
#![deny(missing_docs)]

pub mod bench;
pub mod clock;
pub mod evaluation;
pub mod image;
pub mod limits;
pub mod methods;
pub mod output;
pub mod realtime;
pub mod reconstruction;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod tiles;
pub mod trace;
