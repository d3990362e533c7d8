//! The real-time parallel pipeline (as the OptiX adaptive frameless renderer runs it),
//! the interactive viewer and its headless mode.
//!
//! Scene time follows the wall clock ([`clock`]). Several sampling threads trace samples
//! concurrently, each at the current time; per-pixel exclusion ([`pixel_locks`])
//! guarantees two threads never sample the same pixel at once. An image thread
//! ([`pipeline`]) builds images at the display rate, concurrently with sampling; the
//! display (the [`viewer`] window or the [`headless`] loop) presents the newest image at
//! every refresh and never waits for one.
//!
//! Each real-time method is one file: [`adaptive`] (the adaptive sampler, whose tiling
//! and deep buffer live on one controller thread owning the ordinary
//! [`Sampler`](crate::methods::adaptive::Sampler), and the adaptive reconstructor),
//! [`frameless`] (traditional frameless), [`framed`] (double-buffered frames, and
//! their late warp) and [`taa`] (the temporal upsampler, and its late warp). Each
//! describes itself in one constant (name, default threads, how it starts) that the
//! registry below maps its [`RtMethod`] variant to; the pipeline only calls that
//! description. Adding a method is a new file, a variant and a line in `REGISTRY`.
//!
//! Files depend downwards only: `config` (settings, errors), `clock`, `machine` (CPU
//! time and load of the machine) and `pixel_locks` ← `shared` (what all threads of a
//! pipeline share; the interface of a method) ← the method files ← this registry ←
//! `pipeline` ← `headless`, `viewer`, `record` (every refresh of a window kept with its
//! scan-out time, for the live evaluation).
//!
//! Unlike the evaluation, nothing here is deterministic: the sample count depends on
//! the machine and on scheduling.

pub mod adaptive;
pub mod camera;
pub mod clock;
pub mod config;
mod error;
pub mod framed;
pub mod frameless;
pub mod headless;
pub mod machine;
pub mod pacing;
pub mod pipeline;
pub mod pixel_locks;
#[cfg(test)]
mod probe;
pub mod record;
mod shared;
pub mod taa;
pub mod viewer;

pub use adaptive::{AdaptiveArgs, AdaptiveSettings};
pub use camera::{CameraRecorder, FlyCamera};
pub use clock::WallClock;
pub use config::{RealtimeError, RtConfig};
pub use headless::{run_headless, HeadlessOptions, HeadlessStats};
pub use pipeline::{Frame, Pipeline, PipelineStats};
pub use pixel_locks::{PixelGuard, PixelLocks};
pub use viewer::{run_viewer, ViewerOptions};

use clap::builder::PossibleValue;

use shared::MethodInfo;

/// Declares [`RtMethod`], a variant per registered method, and the registry that maps
/// each variant to the description in the method's own file.
macro_rules! registry {
    ($($(#[doc = $doc:literal])* $(#[cfg($cfg:meta)])? $variant:ident => $info:path,)*) => {
        /// What the pipeline renders: one variant per method of the registry, in the
        /// viewer's key order ([`RtMethod::ALL`]). Each is described (name, threads,
        /// how it starts) in its own file.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
        #[serde(rename_all = "kebab-case")]
        pub enum RtMethod {
            $($(#[doc = $doc])* $(#[cfg($cfg)])? $variant,)*
        }

        /// The registry: every real-time method and its description.
        const REGISTRY: &[(RtMethod, &MethodInfo)] = &[
            $($(#[cfg($cfg)])? (RtMethod::$variant, &$info),)*
        ];
    };
}

// Adding a method: its file (a `MethodInfo`, its threads and its image builder) and a
// line here.
registry! {
    /// Adaptive sampler + adaptive space-time reconstructor.
    Adaptive => adaptive::METHOD,
    /// Traditional frameless: random pixels, newest sample shown per pixel.
    TraditionalFrameless => frameless::METHOD,
    /// Double-buffered framed rendering at full resolution, as fast as it goes.
    Framed => framed::METHOD,
    /// Framed, with the newest frame reprojected to the camera at every refresh.
    LateWarp => framed::LATE_WARP,
    /// Temporal upsampler: jittered low-resolution frames accumulated into a
    /// full-resolution history.
    Taa => taa::METHOD,
    /// The temporal upsampler, its image reprojected to the camera at every refresh.
    TaaWarp => taa::TAA_WARP,
    /// A flat grey from threads that trace nothing: the pipeline's own tests.
    #[cfg(test)]
    Probe => probe::METHOD,
}

impl RtMethod {
    /// All methods, in the viewer's key order (1, 2, 3, …).
    pub const ALL: [RtMethod; REGISTRY.len()] = {
        let mut all = [RtMethod::Adaptive; REGISTRY.len()];
        let mut i = 0;
        while i < all.len() {
            all[i] = REGISTRY[i].0;
            i += 1;
        }
        all
    };

    /// Its description.
    pub(crate) fn info(self) -> &'static MethodInfo {
        REGISTRY
            .iter()
            .find(|(m, _)| *m == self)
            .map(|(_, info)| *info)
            .expect("every method is in the registry")
    }

    /// Command-line name.
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// One line for help texts.
    pub fn about(self) -> &'static str {
        self.info().about
    }

    /// Parse a command-line name.
    pub fn parse(s: &str) -> Result<Self, RealtimeError> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|m| m.name()).collect();
                RealtimeError::Config(format!(
                    "unknown method `{s}` (expected {})",
                    one_of(&names)
                ))
            })
    }
}

impl clap::ValueEnum for RtMethod {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.name()).help(self.about()))
    }
}

/// "a, b or c".
fn one_of(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => one.to_string(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

/// Visualisations the viewer can show instead of the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Visualisation {
    /// The displayed image.
    #[default]
    Image,
    /// Tile borders over the image (paper Fig. 3).
    Tiling,
    /// Per-tile gradients: Gx red, Gy green, Gt blue (Fig. 4).
    Gradients,
    /// Local sample density (Fig. 7).
    Density,
}

impl Visualisation {
    /// All, in the order key V cycles through them.
    pub const ALL: [Visualisation; 4] = [
        Visualisation::Image,
        Visualisation::Tiling,
        Visualisation::Gradients,
        Visualisation::Density,
    ];

    /// The next one in the cycle.
    pub fn next(self) -> Self {
        match self {
            Visualisation::Image => Visualisation::Tiling,
            Visualisation::Tiling => Visualisation::Gradients,
            Visualisation::Gradients => Visualisation::Density,
            Visualisation::Density => Visualisation::Image,
        }
    }

    /// Parse a name.
    pub fn parse(s: &str) -> Result<Self, RealtimeError> {
        Self::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|v| v.name()).collect();
                RealtimeError::Config(format!(
                    "unknown visualisation `{s}` (expected {})",
                    one_of(&names)
                ))
            })
    }

    /// The name with its colour key, for the title bar (the window has no room for a
    /// drawn legend that would not hide the image).
    pub fn key(self) -> &'static str {
        match self {
            Visualisation::Image => "image",
            Visualisation::Tiling => "tiling: tile borders in yellow",
            Visualisation::Gradients => {
                "gradients per tile: red Gx, green Gy, blue Gt (each scaled to its 95th percentile)"
            }
            Visualisation::Density => {
                "density: local sample rate (∝ 1/tile area), log scale, dark sparse to bright dense"
            }
        }
    }

    /// Name for the title bar.
    pub fn name(self) -> &'static str {
        match self {
            Visualisation::Image => "image",
            Visualisation::Tiling => "tiling",
            Visualisation::Gradients => "gradients",
            Visualisation::Density => "density",
        }
    }
}

impl clap::ValueEnum for Visualisation {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.name()))
    }
}

impl RtConfig {
    /// Defaults for `method`: the sampling threads its description asks for on this
    /// machine, reconstruction on half the cores, the paper's sampler, and the
    /// real-time reconstructor ([`ReconParams::realtime`]), builds within
    /// [`adaptive::settings::IMAGE_BUDGET`] of a refresh period.
    pub fn new(method: RtMethod) -> Self {
        Self::for_cores(method, machine::cores())
    }

    /// [`RtConfig::new`] with threads sized for `cores` cores instead of the machine's.
    pub fn for_cores(method: RtMethod, cores: usize) -> Self {
        let cores = cores.max(1);
        Self {
            method,
            sampling_threads: (method.info().default_sampling_threads)(cores),
            recon_threads: (cores / 2).max(1),
            refresh_hz: crate::settings::REFRESH_HZ,
            start: 0.0,
            seed: crate::settings::SEED,
            adaptive: AdaptiveSettings::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::ValueEnum;

    use super::*;

    #[test]
    fn method_names_parse_back_and_are_clap_values() {
        let names: Vec<&str> = RtMethod::ALL.iter().map(|m| m.name()).collect();
        // The shipped methods first (the tests' own methods follow them).
        assert_eq!(
            names[..6],
            [
                "adaptive",
                "traditional-frameless",
                "framed",
                "late-warp",
                "taa",
                "taa-warp"
            ]
        );
        for m in RtMethod::ALL {
            assert_eq!(RtMethod::parse(m.name()).unwrap(), m);
            assert_eq!(RtMethod::from_str(m.name(), false).unwrap(), m);
            // The serde name is the command-line name.
            assert_eq!(serde_json::to_value(m).unwrap(), m.name());
        }
        let err = RtMethod::parse("bogus").unwrap_err().to_string();
        assert!(
            err.contains(
                "unknown method `bogus` (expected adaptive, traditional-frameless, framed, late-warp, taa, taa-warp"
            ),
            "{err}"
        );
    }

    #[test]
    fn visualisation_names_parse_back_and_are_clap_values() {
        let names: Vec<&str> = Visualisation::ALL.iter().map(|v| v.name()).collect();
        assert_eq!(names, ["image", "tiling", "gradients", "density"]);
        for v in Visualisation::ALL {
            assert_eq!(Visualisation::parse(v.name()).unwrap(), v);
            assert_eq!(Visualisation::from_str(v.name(), false).unwrap(), v);
            assert_eq!(v.next(), Visualisation::ALL[(v as usize + 1) % 4]);
        }
        assert!(Visualisation::parse("bogus").is_err());
    }

    #[test]
    fn threads_come_from_the_description() {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let threads = |m| RtConfig::new(m).sampling_threads;
        assert_eq!(threads(RtMethod::Adaptive), cores);
        assert_eq!(threads(RtMethod::TraditionalFrameless), cores);
        assert_eq!(threads(RtMethod::Framed), cores);
        assert_eq!(threads(RtMethod::LateWarp), cores);
        assert_eq!(threads(RtMethod::Taa), cores);
        assert_eq!(threads(RtMethod::TaaWarp), cores);
        // Adaptive's controllers: one per four sampling threads.
        let extra = RtMethod::Adaptive.info().extra_threads;
        assert_eq!((extra(1), extra(4), extra(5), extra(15)), (1, 1, 2, 4));
        assert_eq!((RtMethod::TraditionalFrameless.info().extra_threads)(15), 0);
    }
}
