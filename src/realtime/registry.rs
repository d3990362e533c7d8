//! The registry of real-time methods: the one place that names them all. The
//! `registry!` line of a method maps its [`RtMethod`] variant to the description in its
//! own file and, where it has settings of its own, to their type, which becomes the
//! payload of its [`RtSettings`] variant. Nothing below this file names a method.

use std::sync::{Arc, OnceLock};

use clap::builder::PossibleValue;

#[cfg(test)]
use super::probe::{self, ProbeSettings};
use super::{
    adaptive::{self, AdaptiveSettings},
    config::{RealtimeError, RtConfig},
    framed, frameless, machine,
    shared::{ImageBuilder, MethodSettings, NoSettings, Overlay, Spawner},
    taa,
};
use crate::reconstruction::device::GpuContext;

/// A method's settings type: the one named in its registry line, or [`NoSettings`].
macro_rules! settings_type {
    () => {
        NoSettings
    };
    ($t:ty) => {
        $t
    };
}

/// Declares [`RtMethod`] (a variant per registered method), [`RtSettings`] (the same
/// variants, each holding its method's own settings) and what dispatches from them to
/// the description in the method's own file.
macro_rules! registry {
    ($($(#[doc = $doc:literal])* $(#[cfg($cfg:meta)])? $variant:ident $(($settings:ty))? => $info:path,)*) => {
        /// What the pipeline renders: one variant per method of the registry, in the
        /// viewer's key order ([`RtMethod::ALL`]). Each is described (name, threads,
        /// how it starts) in its own file.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum RtMethod {
            $($(#[doc = $doc])* $(#[cfg($cfg)])? $variant,)*
        }

        /// A method with its own settings: what a real-time run renders and how.
        // A run holds one, made once: the adaptive method's few hundred bytes beside
        // the others' none are not worth a box.
        #[allow(clippy::large_enum_variant)]
        #[derive(Clone, Debug)]
        pub enum RtSettings {
            $($(#[doc = $doc])* $(#[cfg($cfg)])? $variant(settings_type!($($settings)?)),)*
        }

        /// Every method, in the viewer's key order.
        const ALL_METHODS: &[RtMethod] = &[$($(#[cfg($cfg)])? RtMethod::$variant,)*];

        impl RtMethod {
            /// Its description's facts that do not depend on its settings.
            fn facts(self) -> Facts {
                match self {
                    $($(#[cfg($cfg)])? RtMethod::$variant => {
                        let i = &$info;
                        Facts {
                            name: i.name,
                            about: i.about,
                            default_sampling_threads: i.default_sampling_threads,
                            extra_threads: i.extra_threads,
                            overlays: i.overlays,
                            traces_on_gpu: i.traces_on_gpu,
                        }
                    })*
                }
            }

            /// Its settings, each at its default.
            pub fn settings(self) -> RtSettings {
                match self {
                    $($(#[cfg($cfg)])? RtMethod::$variant => RtSettings::$variant(Default::default()),)*
                }
            }
        }

        impl RtSettings {
            /// The method these are the settings of.
            pub fn method(&self) -> RtMethod {
                match self {
                    $($(#[cfg($cfg)])? RtSettings::$variant(_) => RtMethod::$variant,)*
                }
            }

            /// Check the method's own settings' ranges.
            pub fn validate(&self) -> Result<(), RealtimeError> {
                match self {
                    $($(#[cfg($cfg)])? RtSettings::$variant(s) => s.validate(),)*
                }
            }

            /// Hand the method the GPU its reconstruction may run on (`None`: the CPU);
            /// a method that reconstructs nothing ignores it.
            pub fn use_gpu(&mut self, gpu: Option<Arc<GpuContext>>) {
                match self {
                    $($(#[cfg($cfg)])? RtSettings::$variant(s) => s.use_gpu(gpu),)*
                }
            }

            /// Check that a `width × height` display fits the run budgets
            /// ([`crate::limits`]) with this method's buffers, before any thread
            /// allocates them.
            pub fn check_size(
                &self,
                config: &RtConfig,
                width: u32,
                height: u32,
            ) -> Result<(), RealtimeError> {
                match self {
                    $($(#[cfg($cfg)])? RtSettings::$variant(s) => ($info.check_size)(config, s, width, height),)*
                }
                .map_err(|e| RealtimeError::Config(e.to_string()))
            }

            /// Start the method's threads; the image thread then calls the builder.
            /// A method that cannot trace on the GPU refuses a run that has a GPU
            /// tracer rather than trace on the CPU.
            pub(crate) fn start(
                &self,
                sp: &mut Spawner<'_>,
            ) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
                let method = self.method();
                if sp.shared().config.rays.is_some() && !method.traces_on_gpu() {
                    return Err(RealtimeError::Config(cannot_trace_on_gpu(method)));
                }
                match self {
                    $($(#[cfg($cfg)])? RtSettings::$variant(s) => ($info.start)(sp, s),)*
                }
            }
        }
    };
}

// Adding a method: its file (a `MethodInfo`, its threads and its image builder, and the
// type of its own settings if it has any), a line here, and the file's `mod` line in
// `realtime/mod.rs`.
registry! {
    /// Adaptive sampler + adaptive space-time reconstructor.
    Adaptive(AdaptiveSettings) => adaptive::METHOD,
    /// Traditional frameless: random pixels, newest sample shown per pixel.
    TraditionalFrameless => frameless::METHOD,
    /// Double-buffered framed rendering at full resolution, as fast as it goes.
    FramedFull => framed::METHOD,
    /// Framed, with the newest frame reprojected to the camera at every refresh.
    LateWarp => framed::LATE_WARP,
    /// Temporal upsampler: jittered low-resolution frames accumulated into a
    /// full-resolution history.
    Taa => taa::METHOD,
    /// The temporal upsampler, its image reprojected to the camera at every refresh.
    TaaWarp => taa::TAA_WARP,
    /// A flat grey from threads that trace nothing: the pipeline's own tests.
    #[cfg(test)]
    Probe(ProbeSettings) => probe::METHOD,
}

/// What [`RtMethod`] reads of a method's description.
struct Facts {
    name: &'static str,
    about: &'static str,
    default_sampling_threads: fn(usize) -> usize,
    extra_threads: fn(&RtConfig) -> usize,
    overlays: &'static [Overlay],
    traces_on_gpu: bool,
}

impl RtMethod {
    /// All methods, in the viewer's key order (1, 2, 3, …).
    pub const ALL: [RtMethod; ALL_METHODS.len()] = {
        let mut all = [RtMethod::Adaptive; ALL_METHODS.len()];
        let mut i = 0;
        while i < all.len() {
            all[i] = ALL_METHODS[i];
            i += 1;
        }
        all
    };

    /// Command-line name.
    pub fn name(self) -> &'static str {
        self.facts().name
    }

    /// Whether its sampling traces on the GPU tracer (`--trace gpu`).
    pub fn traces_on_gpu(self) -> bool {
        self.facts().traces_on_gpu
    }

    /// One line for help texts.
    pub fn about(self) -> &'static str {
        self.facts().about
    }

    /// Threads it runs, in a run of `config`, besides its sampling threads and the
    /// pipeline's image thread.
    pub fn extra_threads(self, config: &RtConfig) -> usize {
        (self.facts().extra_threads)(config)
    }

    /// The images it offers besides the displayed one, which the viewer cycles.
    pub fn overlays(self) -> &'static [Overlay] {
        self.facts().overlays
    }

    /// Parse a command-line name, or an old name the evaluation's methods list
    /// ([`crate::methods::OLD_NAMES`]).
    pub fn parse(s: &str) -> Result<Self, RealtimeError> {
        let s = crate::methods::current_name(s);
        Self::ALL
            .iter()
            .copied()
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

// By name, as the command line spells it: result files written before a method was
// renamed ([`crate::methods::OLD_NAMES`]) still read.
impl serde::Serialize for RtMethod {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for RtMethod {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = <String as serde::Deserialize>::deserialize(d)?;
        Self::parse(&s).map_err(serde::de::Error::custom)
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

/// What the viewer shows: the image, or one of the method's overlays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Visualisation(Option<&'static Overlay>);

impl Visualisation {
    /// The displayed image.
    pub const IMAGE: Visualisation = Visualisation(None);

    /// The image and every registered method's overlays, each name once.
    pub fn all() -> &'static [Visualisation] {
        static ALL_VIS: OnceLock<Vec<Visualisation>> = OnceLock::new();
        ALL_VIS.get_or_init(|| {
            let mut all = vec![Visualisation::IMAGE];
            for o in RtMethod::ALL.into_iter().flat_map(|m| m.overlays()) {
                if all.iter().all(|v| v.name() != o.name) {
                    all.push(Visualisation(Some(o)));
                }
            }
            all
        })
    }

    /// The next one in the cycle key V steps through for `method`: the image, then
    /// the method's overlays.
    pub fn next(self, method: RtMethod) -> Self {
        let overlays = method.overlays();
        let at = self
            .0
            .and_then(|o| overlays.iter().position(|x| x.name == o.name));
        match at {
            None => overlays
                .first()
                .map_or(Self::IMAGE, |o| Visualisation(Some(o))),
            Some(i) => overlays
                .get(i + 1)
                .map_or(Self::IMAGE, |o| Visualisation(Some(o))),
        }
    }

    /// Parse a name.
    pub fn parse(s: &str) -> Result<Self, RealtimeError> {
        Self::all()
            .iter()
            .copied()
            .find(|v| v.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::all().iter().map(|v| v.name()).collect();
                RealtimeError::Config(format!(
                    "unknown visualisation `{s}` (expected {})",
                    one_of(&names)
                ))
            })
    }

    /// The overlay shown, if any.
    pub fn overlay(self) -> Option<&'static Overlay> {
        self.0
    }

    /// The name with its colour key, for the title bar (the window has no room for a
    /// drawn legend that would not hide the image).
    pub fn key(self) -> &'static str {
        self.0.map_or("image", |o| o.key)
    }

    /// Name for the title bar and `--vis`.
    pub fn name(self) -> &'static str {
        self.0.map_or("image", |o| o.name)
    }
}

impl clap::ValueEnum for Visualisation {
    fn value_variants<'a>() -> &'a [Self] {
        Self::all()
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.name()))
    }
}

/// Why `method` cannot run with a GPU tracer.
pub fn cannot_trace_on_gpu(method: RtMethod) -> String {
    let on_gpu: Vec<&str> = RtMethod::ALL
        .iter()
        .filter(|m| m.traces_on_gpu())
        .map(|m| m.name())
        .collect();
    format!(
        "{} traces on the CPU only; the real-time methods that trace on the GPU: {}",
        method.name(),
        on_gpu.join(", ")
    )
}

impl RtConfig {
    /// Defaults for `method`: the sampling threads its description asks for on this
    /// machine, and reconstruction on half the cores.
    pub fn new(method: RtMethod) -> Self {
        Self::for_cores(method, machine::cores())
    }

    /// [`RtConfig::new`] with threads sized for `cores` cores instead of the machine's.
    pub fn for_cores(method: RtMethod, cores: usize) -> Self {
        let cores = cores.max(1);
        Self {
            sampling_threads: (method.facts().default_sampling_threads)(cores),
            recon_threads: (cores / 2).max(1),
            refresh_hz: crate::settings::REFRESH_HZ,
            start: 0.0,
            seed: crate::settings::SEED,
            rays: None,
            view_ahead: true,
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::ValueEnum;

    use super::*;

    #[test]
    fn every_shipped_method_traces_on_the_gpu_and_one_that_cannot_is_named() {
        for m in RtMethod::ALL.iter().filter(|m| **m != RtMethod::Probe) {
            assert!(m.traces_on_gpu(), "{}", m.name());
        }
        // The tests' probe traces nothing: it stands for a method that cannot.
        assert!(!RtMethod::Probe.traces_on_gpu());
        let e = cannot_trace_on_gpu(RtMethod::Probe);
        assert!(e.starts_with("probe traces on the CPU only"), "{e}");
        assert!(e.contains("adaptive, traditional-frameless"), "{e}");
    }

    #[test]
    fn method_names_parse_back_and_are_clap_values() {
        let names: Vec<&str> = RtMethod::ALL.iter().map(|m| m.name()).collect();
        // The shipped methods first (the tests' own methods follow them).
        assert_eq!(
            names[..6],
            [
                "adaptive",
                "traditional-frameless",
                "framed-full",
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
            assert_eq!(m.settings().method(), m);
        }
        // The old name still parses and reads from result files.
        assert_eq!(RtMethod::parse("framed").unwrap(), RtMethod::FramedFull);
        let old: RtMethod = serde_json::from_value(serde_json::json!("framed")).unwrap();
        assert_eq!(old, RtMethod::FramedFull);
        let err = RtMethod::parse("bogus").unwrap_err().to_string();
        assert!(
            err.contains(
                "unknown method `bogus` (expected adaptive, traditional-frameless, framed-full, late-warp, taa, taa-warp"
            ),
            "{err}"
        );
    }

    #[test]
    fn visualisations_are_the_overlays_methods_offer() {
        let names: Vec<&str> = Visualisation::all().iter().map(|v| v.name()).collect();
        assert_eq!(names, ["image", "tiling", "gradients", "density"]);
        for &v in Visualisation::all() {
            assert_eq!(Visualisation::parse(v.name()).unwrap(), v);
            assert_eq!(Visualisation::from_str(v.name(), false).unwrap(), v);
        }
        assert!(Visualisation::parse("bogus").is_err());
        // Key V cycles through the image and the method's own overlays.
        let mut v = Visualisation::IMAGE;
        let mut seen = Vec::new();
        for _ in 0..4 {
            v = v.next(RtMethod::Adaptive);
            seen.push(v.name());
        }
        assert_eq!(seen, ["tiling", "gradients", "density", "image"]);
        assert_eq!(
            Visualisation::IMAGE.next(RtMethod::FramedFull),
            Visualisation::IMAGE
        );
        assert_eq!(
            Visualisation::all()[1].next(RtMethod::Taa),
            Visualisation::IMAGE
        );
    }

    #[test]
    fn threads_come_from_the_description() {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let threads = |m| RtConfig::new(m).sampling_threads;
        assert_eq!(threads(RtMethod::Adaptive), cores);
        assert_eq!(threads(RtMethod::TraditionalFrameless), cores);
        assert_eq!(threads(RtMethod::FramedFull), cores);
        assert_eq!(threads(RtMethod::LateWarp), cores);
        assert_eq!(threads(RtMethod::Taa), cores);
        assert_eq!(threads(RtMethod::TaaWarp), cores);
        // Adaptive's controllers: one per four sampling threads.
        let extra = |m, n| RtMethod::extra_threads(m, &RtConfig::for_cores(m, n));
        let adaptive = |n| extra(RtMethod::Adaptive, n);
        assert_eq!(
            (adaptive(1), adaptive(4), adaptive(5), adaptive(15)),
            (1, 1, 2, 4)
        );
        assert_eq!(extra(RtMethod::TraditionalFrameless, 15), 0);
    }
}
