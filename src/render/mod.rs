//! Image renderers built on the tracer.

pub mod still;
