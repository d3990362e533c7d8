//! `frameless`: adaptive frameless rendering.
//!
//! A ray tracer for animated scenes whose image is never rendered as a frame. See
//! `docs/ARCHITECTURE.md` for how data flows from a scene to the displayed image.
//!
//! Evaluating two methods against the ideal image, as `frameless eval` does (here
//! small and short, so that it runs in a second):
//!
//! ```
//! use std::sync::Arc;
//! use frameless::{evaluation::{self, EvalConfig, Silent}, methods::MethodKind, scene::builtin};
//!
//! let scene = Arc::new(builtin::load("toycar").expect("a built-in scene"));
//! let mut cfg = EvalConfig::new("toycar");
//! cfg.display.size = frameless::settings::Size(64, 48);
//! cfg.duration = 0.25;
//! cfg.warmup = 0.25;
//! cfg.rates = vec![400_000.0];
//! cfg.methods = vec![MethodKind::TraditionalFrameless, MethodKind::Adaptive];
//! cfg.strip_frames = cfg.quartile_frames();
//! let out = evaluation::run(scene, &cfg, &Silent)?;
//! for row in &out.summary.results {
//!     println!("{} at {}: RMS {:.2}, FLIP {:.3}", row.method, row.rate, row.rms_mean, row.flip_mean);
//! }
//! assert_eq!(out.summary.results.len(), 2);
//! // `evaluation::report::write_all(&mut out, dir)` writes the report folder.
//! # Ok::<(), frameless::evaluation::EvalError>(())
//! ```
//!
//! `examples/evaluate.rs` does the same at full size and writes the report.
#![deny(missing_docs)]

pub mod bench;
pub mod clock;
pub mod evaluation;
pub mod gpu;
pub mod image;
pub mod limits;
pub mod methods;
pub mod output;
pub mod realtime;
pub mod reconstruction;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod settings;
pub mod tiles;
pub mod trace;
