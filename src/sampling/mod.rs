//! Sampling: counter-based random numbers and sample patterns.
//!
//! Every random value is a pure function of `(seed, stream, index, dimension)`, so
//! results never depend on which thread asked, or in which order.

pub mod rng;
pub mod stratified;

pub use rng::Rng;
