//! Image renderers built on the tracer.

pub mod cache;
pub mod still;
