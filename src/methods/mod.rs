//! Rendering methods compared by the evaluation.
//!
//! Each method lives in one file that defines its [`MethodInfo`]: name, description,
//! budget rules and constructor. The `registry!` below lists every method once; it
//! declares the files and derives [`MethodKind`], the typed name that the evaluation,
//! Table 1, the CLI (clap) and the reports (serde) use. None of them matches on a
//! variant: they read the description. Adding a method is one file defining a
//! `MethodInfo` and one line in the registry (see `docs/ARCHITECTURE.md`).
//!
//! A method is driven by the simulated [`Clock`]: it may trace the samples the budget
//! allows up to a display time and must then say what the display shows at that time.

use std::sync::Arc;

use crate::{
    clock::{rate_label, Clock},
    image::Image,
    reconstruction::device::GpuContext,
    render::cache::IdealCache,
    trace::{batch::GpuRays, Tracer},
};

/// Declares the method files and derives [`MethodKind`] from
/// `file { Variant => INFO, ... }` lines, where `file::INFO` is the variant's
/// [`MethodInfo`]. A line's variants are in report order; attributes on a variant
/// (e.g. `#[cfg(test)]`) apply to it everywhere.
macro_rules! registry {
    ($( $file:ident { $( $(#[$attr:meta])* $variant:ident => $info:ident ),+ $(,)? } )*) => {
        $( pub mod $file; )*

        /// The methods `frameless eval --methods` accepts, in report order. Each
        /// variant's name, description and rules are its [`MethodInfo`].
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[allow(missing_docs)] // documented by their descriptions
        pub enum MethodKind {
            $( $( $(#[$attr])* $variant, )+ )*
        }

        impl MethodKind {
            /// Every method, in report order.
            pub const ALL: &'static [MethodKind] = &[ $( $( $(#[$attr])* MethodKind::$variant, )+ )* ];

            /// The method's description.
            pub fn info(self) -> &'static MethodInfo {
                match self {
                    $( $( $(#[$attr])* MethodKind::$variant => &$file::$info, )+ )*
                }
            }
        }
    };
}

registry! {
    ideal { Ideal => IDEAL }
    framed { Framed60Hz => FRAMED_60HZ, FramedFull => FRAMED_FULL, FullRes60Hz => FULL_RES_60HZ }
    frameless { TraditionalFrameless => TRADITIONAL_FRAMELESS }
    adaptive {
        Adaptive => ADAPTIVE,
        AdaptivePaper => ADAPTIVE_PAPER,
        AdaptiveNoReprojection => ADAPTIVE_NO_REPROJECTION,
        AdaptiveNoHistory => ADAPTIVE_NO_HISTORY,
        AdaptiveNoReprojRecon => ADAPTIVE_NO_REPROJ_RECON,
        AdaptiveFixedFilter => ADAPTIVE_FIXED_FILTER,
    }
    point_tracking { PointTracking => POINT_TRACKING, PointTrackingNoBlend => POINT_TRACKING_NO_BLEND }
    taa { Taa => TAA }
    late_warp { LateWarp => LATE_WARP }
    taa_warp { TaaWarp => TAA_WARP }
    test_method { #[cfg(test)] TestFrameless => TEST_FRAMELESS }
}

/// A method: everything the evaluation, Table 1, the CLI and the reports know of it.
pub struct MethodInfo {
    /// Command-line and report name.
    pub name: &'static str,
    /// One line, shown by `frameless eval --help`.
    pub description: &'static str,
    /// How it spends the sample budget.
    pub budget: Budget,
    /// Whether it can run at a rate in a run of a given shape (checked before any work
    /// starts, so that a bad combination fails at once).
    pub check_rate: fn(&RunShape, f64) -> Result<(), MethodError>,
    /// Build it for one run.
    pub build: fn(&MethodContext) -> Result<Box<dyn Method>, MethodError>,
}

/// How a method spends the sample budget.
#[derive(Clone, Copy, Debug)]
pub enum Budget {
    /// It traces at the evaluated rate.
    Rate,
    /// It has its own budget whatever the rate (samples per second for a run of this
    /// shape), so one run serves every rate column.
    Own(fn(&RunShape) -> f64),
    /// The reference: held to no budget; what it spends, in samples per second.
    Unbounded(fn(&RunShape) -> f64),
}

impl Budget {
    /// The rate the method actually uses when `rate` is asked.
    pub fn effective_rate(&self, shape: &RunShape, rate: f64) -> f64 {
        match self {
            Budget::Rate => rate,
            Budget::Own(f) | Budget::Unbounded(f) => f(shape),
        }
    }

    /// Whether the method ignores the asked rate (one run serves every rate).
    pub fn rate_independent(&self) -> bool {
        !matches!(self, Budget::Rate)
    }

    /// Whether the evaluation holds the method to its budget.
    pub fn enforced(&self) -> bool {
        !matches!(self, Budget::Unbounded(_))
    }
}

/// What a method's budget rules need to know of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunShape {
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// Display refresh rate, Hz.
    pub refresh_hz: f64,
    /// Samples per pixel of ideal images.
    pub ideal_spp: u32,
    /// Warm-up plus the evaluated window, seconds.
    pub seconds: f64,
}

impl RunShape {
    /// Display pixels.
    pub fn pixels(&self) -> f64 {
        self.width as f64 * self.height as f64
    }
}

/// Why a method cannot run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MethodError {
    /// The sample rate cannot feed the method.
    #[error("rate {rate} is too low for {method}: {why}")]
    RateTooLow {
        /// The method, as users name it.
        method: &'static str,
        /// The rate, as users write it.
        rate: String,
        /// What the method would need.
        why: String,
    },
    /// A parameter is out of range.
    #[error("{group} parameter {name}: {why}")]
    Parameter {
        /// Whose parameter (e.g. `sampler`).
        group: &'static str,
        /// Which.
        name: &'static str,
        /// The valid range.
        why: &'static str,
    },
    /// A buffer or size over its budget ([`crate::limits`]).
    #[error(transparent)]
    Budget(#[from] crate::limits::LimitError),
    /// A consistency check of a method's data failed (a bug).
    #[error("inconsistent {what}: {why}")]
    Inconsistent {
        /// Which structure.
        what: &'static str,
        /// What does not hold.
        why: String,
    },
    /// The method cannot reconstruct on the GPU it was given (`--recon gpu|auto`).
    #[error("{method}: {why}")]
    Gpu {
        /// The method, as users name it.
        method: &'static str,
        /// Why (the GPU reconstructor's error).
        why: String,
    },
}

/// [`MethodInfo::check_rate`] of a method that runs at any positive rate.
pub fn any_rate(_: &RunShape, _: f64) -> Result<(), MethodError> {
    Ok(())
}

/// The check of a method that must finish at least one full-resolution frame within the
/// run to show anything.
pub fn one_frame_in_run(
    method: &'static str,
    shape: &RunShape,
    rate: f64,
) -> Result<(), MethodError> {
    let frame_s = shape.pixels() / rate;
    if frame_s > shape.seconds {
        return Err(MethodError::RateTooLow {
            method,
            rate: rate_label(rate),
            why: format!(
                "one {}x{} frame takes {frame_s:.2} s, longer than warm-up + duration ({:.2} s)",
                shape.width, shape.height, shape.seconds
            ),
        });
    }
    Ok(())
}

/// The frame rate of the framed methods that render at a fixed rate (`framed-60hz`,
/// `full-res-60hz`, `taa`), Hz: their names say it, so it is not a setting.
pub const FRAME_HZ: f64 = 60.0;

/// The check of a method that renders a frame every 1/[`FRAME_HZ`] s and needs a sample
/// in each.
pub fn sixty_per_second(method: &'static str, rate: f64) -> Result<(), MethodError> {
    if rate < FRAME_HZ {
        return Err(MethodError::RateTooLow {
            method,
            rate: rate_label(rate),
            why: format!("it needs at least {FRAME_HZ} samples/s (one per frame)"),
        });
    }
    Ok(())
}

impl MethodKind {
    /// Command-line and report name.
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// One-line description.
    pub fn description(self) -> &'static str {
        self.info().description
    }

    /// Parse a command-line name, or an old name [`OLD_NAMES`] lists.
    pub fn parse(s: &str) -> Result<Self, UnknownMethod> {
        let s = current_name(s);
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| UnknownMethod(s.to_string()))
    }

    /// Whether the method ignores the sample rate (so one run serves every rate).
    pub fn rate_independent(self) -> bool {
        self.info().budget.rate_independent()
    }

    /// Build the method for one run. A GPU error names this method.
    pub fn build(self, ctx: &MethodContext) -> Result<Box<dyn Method>, MethodError> {
        (self.info().build)(ctx).map_err(|e| match e {
            MethodError::Gpu { why, .. } => MethodError::Gpu {
                method: self.name(),
                why,
            },
            e => e,
        })
    }
}

/// Names methods had before the command line, the real-time pipeline and Python
/// spoke one vocabulary, each with the name it has now. They are still accepted, so
/// that scripts and result files written before keep working; the binary and the
/// Python module say the new name when one is used.
pub const OLD_NAMES: &[(&str, &str)] = &[
    // The real-time pipeline's name for what the simulated clock called `framed-full`:
    // full-resolution frames, each shown when complete, as fast as the budget allows.
    ("framed", "framed-full"),
];

/// The current name of a method named `name`: the new name if `name` is an old one
/// ([`OLD_NAMES`]), else `name` itself.
pub fn current_name(name: &str) -> &str {
    OLD_NAMES
        .iter()
        .find(|(old, _)| *old == name)
        .map_or(name, |(_, new)| new)
}

/// A method name that no method has.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown method `{0}`; methods are: {list}", list = method_names())]
pub struct UnknownMethod(pub String);

fn method_names() -> String {
    let names: Vec<&str> = MethodKind::ALL.iter().map(|m| m.name()).collect();
    names.join(", ")
}

impl std::fmt::Display for MethodKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for MethodKind {
    type Err = UnknownMethod;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}

impl serde::Serialize for MethodKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for MethodKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        Self::parse(&s).map_err(serde::de::Error::custom)
    }
}

impl clap::ValueEnum for MethodKind {
    fn value_variants<'a>() -> &'a [Self] {
        Self::ALL
    }
    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.name()).help(self.description()))
    }
}

/// Everything a method needs to run.
#[derive(Clone)]
pub struct MethodContext {
    /// The tracer (scene, image size, camera).
    pub tracer: Arc<Tracer>,
    /// The simulated clock with this run's sample rate.
    pub clock: Clock,
    /// Seed of every random choice.
    pub seed: u64,
    /// Samples per pixel of ideal images.
    pub ideal_spp: u32,
    /// Where ideal images are cached, if anywhere.
    pub ideal_cache: Option<Arc<IdealCache>>,
    /// The GPU the adaptive reconstructor runs on (`None`: the CPU, the reference).
    pub gpu: Option<Arc<GpuContext>>,
    /// The GPU tracer the methods that trace in batches and the ideal images use
    /// (`--trace gpu`; `None`: the CPU tracer, the reference).
    pub rays: Option<Arc<GpuRays>>,
}

/// What the display shows at one refresh.
pub struct Displayed<'a> {
    /// The displayed image (linear; the evaluation clamps and quantizes it).
    pub image: &'a Image,
    /// Mean over pixels of (display time − time the pixel's information was sampled).
    pub mean_age: f64,
}

/// A rendering method under the simulated clock.
pub trait Method: Send {
    /// Trace whatever the budget allows up to display time `t` (non-decreasing across
    /// calls) and return what the display shows then.
    fn display(&mut self, t: f64) -> Displayed<'_>;
    /// Samples traced so far.
    fn samples_used(&self) -> u64;
    /// Wall-clock seconds spent tracing rays so far (the rest of a method's time is
    /// its own overhead).
    fn trace_seconds(&self) -> f64;
    /// Method-specific statistics for the summary (e.g. point tracking's histogram).
    fn extra_stats(&self) -> Option<serde_json::Value> {
        None
    }
}
