//! The settings every command, the evaluation, sweeps and the real-time pipeline share:
//! their defaults, in one place, the names errors give them ([`Setting`]), and the
//! groups of options the commands share ([`SceneGroup`], [`DisplayGroup`],
//! [`QualityGroup`], [`ReferenceGroup`], [`DevicesGroup`]): each declared once, with its
//! default and range, and flattened into every command that takes it; the Python module
//! builds the same groups. Ranges beyond the command line's are checked by
//! [`crate::limits`].

use std::{fmt, path::PathBuf, str::FromStr};

use serde::{Deserialize, Serialize};

/// Display refresh rate, Hz, unless one is asked for.
pub const REFRESH_HZ: f64 = 60.0;

/// Reflection/refraction depth the tracer recurses to, unless one is asked for.
pub const MAX_DEPTH: u32 = 5;

/// Samples per pixel of an ideal image, unless another count is asked for.
pub const IDEAL_SPP: u32 = 16;

/// Samples per pixel of `frameless still`, unless another count is asked for.
pub const STILL_SPP: u32 = 16;

/// Seed of every random choice, unless another is asked for.
pub const SEED: u64 = 1;

/// Display size, unless one is asked for.
pub const SIZE: (u32, u32) = (256, 256);

/// The scene, unless another is asked for.
pub const SCENE: &str = "toycar";

/// Seconds of scene time each method runs before an evaluated window.
pub const WARMUP_S: f64 = 1.0;

/// Sample budgets, samples per second, an evaluation runs at unless told otherwise.
pub const RATES: [f64; 3] = [100_000.0, 400_000.0, 800_000.0];

/// A number that is not finite where a setting needs one ([`finite_f64`]).
#[derive(Debug, thiserror::Error)]
pub enum NotFinite {
    /// It does not parse as a number.
    #[error("`{0}` is not a number")]
    NotANumber(String),
    /// It is infinite or NaN.
    #[error("`{0}` is not finite")]
    Infinite(String),
}

/// A finite number: the parser of every command-line option that takes one.
pub fn finite_f64(s: &str) -> Result<f64, NotFinite> {
    let v: f64 = s.parse().map_err(|_| NotFinite::NotANumber(s.into()))?;
    if !v.is_finite() {
        return Err(NotFinite::Infinite(s.into()));
    }
    Ok(v)
}

/// A run setting, as an error names it. The library says which setting is wrong; the
/// command line and sweep files each spell it their own way ([`Setting::key`] for
/// sweep files, the option name in the binary).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setting {
    /// Seconds of scene time each method runs before the window.
    Warmup,
    /// The window's length, seconds of scene time.
    Duration,
    /// Wall seconds a live run records.
    Seconds,
    /// The window's first scene time.
    Start,
    /// The display's refresh rate.
    RefreshHz,
    /// The sample budgets.
    Rates,
    /// The methods.
    Methods,
    /// Every how many frames FLIP is computed.
    FlipEvery,
    /// The ideal image's samples per pixel.
    IdealSpp,
    /// The reflection/refraction depth limit.
    MaxDepth,
    /// The display size.
    Size,
    /// How many times each live method runs.
    Repeat,
    /// The cores the real-time pipeline's threads are sized for.
    Threads,
    /// The adaptive method's real-time options (image budget, ring, largest splat
    /// radius); the reason names which.
    Adaptive,
}

impl Setting {
    /// The setting's name in a sweep file.
    pub fn key(self) -> &'static str {
        match self {
            Setting::Warmup => "warmup",
            Setting::Duration => "duration",
            Setting::Seconds => "seconds",
            Setting::Start => "start",
            Setting::RefreshHz => "refresh_hz",
            Setting::Rates => "rates",
            Setting::Methods => "methods",
            Setting::FlipEvery => "flip_every",
            Setting::IdealSpp => "ideal_spp",
            Setting::MaxDepth => "max_depth",
            Setting::Size => "size",
            Setting::Repeat => "repeat",
            Setting::Threads => "threads",
            Setting::Adaptive => "adaptive",
        }
    }

    /// The command-line option that sets it, which the binary and the Python module put
    /// before a configuration error's reason. The lists take their plural spellings,
    /// which every command accepts.
    pub fn option(self) -> &'static str {
        match self {
            Setting::Warmup => "--warmup",
            Setting::Duration => "--duration",
            // `--seconds` is still taken, but `--duration` is its name in every command.
            Setting::Seconds => "--duration",
            Setting::Start => "--start",
            Setting::RefreshHz => "--refresh-hz",
            Setting::Rates => "--rates",
            Setting::Methods => "--methods",
            Setting::FlipEvery => "--flip-every",
            Setting::IdealSpp => "--ideal-spp",
            Setting::MaxDepth => "--max-depth",
            Setting::Size => "--size",
            Setting::Repeat => "--repeat",
            Setting::Threads => "--threads",
            // The reason names the option (`ring factor 100 out of range …`).
            Setting::Adaptive => "adaptive:",
        }
    }

    /// The setting in words, for messages that reach neither a command line nor a file.
    pub fn words(self) -> &'static str {
        match self {
            Setting::Warmup => "warm-up",
            Setting::Duration => "duration",
            Setting::Seconds => "recorded seconds",
            Setting::Start => "start",
            Setting::RefreshHz => "refresh rate",
            Setting::Rates => "rates",
            Setting::Methods => "methods",
            Setting::FlipEvery => "FLIP interval",
            Setting::IdealSpp => "ideal samples per pixel",
            Setting::MaxDepth => "depth limit",
            Setting::Size => "size",
            Setting::Repeat => "repeat count",
            Setting::Threads => "threads",
            Setting::Adaptive => "adaptive:",
        }
    }
}

impl std::fmt::Display for Setting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.words())
    }
}

/// An image size `WxH`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size(pub u32, pub u32);

impl Size {
    /// The display size every command defaults to.
    pub const DEFAULT: Size = Size(SIZE.0, SIZE.1);
}

impl fmt::Display for Size {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.0, self.1)
    }
}

impl FromStr for Size {
    type Err = crate::limits::LimitError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (w, h) = crate::limits::parse_size(s)?;
        Ok(Size(w, h))
    }
}

/// How the tracer filters texture lookups.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    clap::ValueEnum,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum TextureFilter {
    /// Bilinear lookup in the full-resolution texture, no footprint (the paper's
    /// setting; aliases on far and grazing surfaces).
    None,
    /// Trilinear mip-mapped lookup at the level a ray cone's footprint asks for.
    #[default]
    RayCones,
}

/// Which reconstructor a run asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReconDevice {
    /// The CPU reconstructor, the reference.
    #[default]
    Cpu,
    /// The compute-shader reconstructor on any adapter, a software one included; an
    /// error where there is none.
    Gpu,
    /// A hardware GPU adapter where there is one, the CPU otherwise.
    Auto,
}

impl ReconDevice {
    /// Every choice, in the order the help lists them.
    pub const ALL: [ReconDevice; 3] = [Self::Cpu, Self::Gpu, Self::Auto];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cpu => "cpu",
            Self::Gpu => "gpu",
            Self::Auto => "auto",
        }
    }
}

impl fmt::Display for ReconDevice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is no [`ReconDevice`].
#[derive(Debug, thiserror::Error)]
#[error("unknown reconstructor '{0}': expected cpu, gpu or auto")]
pub struct UnknownDevice(pub String);

impl FromStr for ReconDevice {
    type Err = UnknownDevice;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|d| d.name() == s)
            .ok_or_else(|| UnknownDevice(s.into()))
    }
}

/// The parser of `--recon`: its values and what each means, for `--help` and for the
/// error that lists them.
fn recon_parser() -> impl clap::builder::TypedValueParser<Value = ReconDevice> {
    let values = ReconDevice::ALL.map(|d| {
        clap::builder::PossibleValue::new(d.name()).help(match d {
            ReconDevice::Cpu => "the CPU reconstructor, the reference",
            ReconDevice::Gpu => "compute shaders on any GPU adapter, a software one included",
            ReconDevice::Auto => "a hardware GPU where there is one, else the CPU",
        })
    });
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(values).try_map(|s| s.parse::<ReconDevice>())
}

/// Scene and camera: what is rendered, and from where.
#[derive(clap::Args, Clone, Debug, PartialEq)]
pub struct SceneGroup {
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = SCENE)]
    pub scene: String,
    /// Camera path CSV overriding the scene's camera.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
}

/// The display: its size and refresh rate.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq)]
pub struct DisplayGroup {
    /// Display size WxH.
    #[arg(long, default_value_t = Size::DEFAULT)]
    pub size: Size,
    /// Display refresh rate, Hz: what is shown is asked for at each refresh.
    #[arg(long, alias = "fps", default_value_t = REFRESH_HZ, value_parser = finite_f64, allow_negative_numbers = true)]
    pub refresh_hz: f64,
}

/// How samples are traced: the seed of every random choice, the recursion depth and
/// the texture filter.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq)]
pub struct QualityGroup {
    /// Seed of every random choice.
    #[arg(long, default_value_t = SEED, allow_negative_numbers = true)]
    pub seed: u64,
    /// Reflection/refraction depth limit.
    #[arg(long, default_value_t = MAX_DEPTH, value_parser = clap::value_parser!(u32).range(0..=crate::limits::MAX_DEPTH as i64), allow_negative_numbers = true)]
    pub max_depth: u32,
    /// Texture filtering: ray-cones (mip-mapped lookups at each ray's footprint; no
    /// moiré on far and grazing textured surfaces) or none (full-resolution bilinear
    /// lookups, the paper's setting).
    #[arg(long, value_enum, default_value_t = TextureFilter::default())]
    pub texture_filter: TextureFilter,
}

/// The ideal images a run is scored against: their samples per pixel and their cache.
#[derive(clap::Args, Clone, Debug, PartialEq)]
pub struct ReferenceGroup {
    /// Samples per pixel of the ideal images.
    #[arg(long, default_value_t = IDEAL_SPP, value_parser = clap::value_parser!(u32).range(1..=crate::limits::MAX_IDEAL_SPP as i64), allow_negative_numbers = true)]
    pub ideal_spp: u32,
    /// Ideal-image cache folder [default: $FRAMELESS_CACHE, else
    /// ~/.cache/frameless/ideal].
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Do not read or write the ideal-image cache.
    #[arg(long)]
    pub no_cache: bool,
}

impl ReferenceGroup {
    /// The ideal images at the default samples per pixel, cached nowhere (the
    /// command line's `--no-cache`): what a run the library sets up starts from, so
    /// that a test or a script writes no cache it did not ask for.
    pub fn uncached() -> Self {
        Self {
            no_cache: true,
            ..Self::default()
        }
    }

    /// Cache the ideal images in `dir`, or (`None`) nowhere.
    pub fn set_cache(&mut self, dir: Option<PathBuf>) {
        self.no_cache = dir.is_none();
        self.cache_dir = dir;
    }

    /// The cache folder a run uses: `--cache-dir`, else `$FRAMELESS_CACHE`, else
    /// `~/.cache/frameless/ideal`; `None` with `--no-cache`.
    pub fn cache(&self) -> Option<PathBuf> {
        (!self.no_cache).then(|| self.cache_dir.clone().unwrap_or_else(default_cache_dir))
    }
}

/// `$FRAMELESS_CACHE`, else `~/.cache/frameless/ideal`, else `.frameless-cache/ideal`.
pub fn default_cache_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("FRAMELESS_CACHE") {
        return d.into();
    }
    match std::env::var_os("HOME") {
        Some(h) => PathBuf::from(h).join(".cache/frameless/ideal"),
        None => ".frameless-cache/ideal".into(),
    }
}

/// Where the work runs: the reconstructor's device and the tracer's.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq)]
pub struct DevicesGroup {
    /// Where the adaptive reconstructor runs: cpu (the reference; committed results
    /// come from it), gpu (compute shaders on any adapter, a software one such as
    /// Mesa's lavapipe included; an error where there is none) or auto (a hardware GPU
    /// where there is one, else the CPU). WGPU_BACKEND and WGPU_ADAPTER_NAME narrow
    /// the choice of adapter. Parameters the GPU reconstructor cannot run yet are an
    /// error, not a silent fallback.
    #[arg(long, value_name = "DEVICE", default_value = "cpu", value_parser = recon_parser())]
    pub recon: ReconDevice,
    /// Where rays are traced (`--trace`).
    #[command(flatten)]
    pub trace: TraceGroup,
}

/// Where rays are traced: `--trace cpu|gpu|auto`, the same three choices as `--recon`.
pub type TraceDevice = ReconDevice;

/// The parser of `--trace`: `--recon`'s values, with what each means for the tracer.
fn trace_parser() -> impl clap::builder::TypedValueParser<Value = TraceDevice> {
    let values = TraceDevice::ALL.map(|d| {
        clap::builder::PossibleValue::new(d.name()).help(match d {
            ReconDevice::Cpu => "the CPU tracer, the reference",
            ReconDevice::Gpu => "compute shaders on any GPU adapter, a software one included",
            ReconDevice::Auto => "a hardware GPU where there is one, else the CPU",
        })
    });
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(values).try_map(|s| s.parse::<TraceDevice>())
}

/// Where rays are traced. Declared once: part of [`DevicesGroup`], and flattened on
/// its own into `still`, which reconstructs nothing.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq)]
pub struct TraceGroup {
    /// Where rays are traced: cpu (the reference), gpu (wgpu compute shaders with
    /// software BVH traversal, on any adapter, a software one such as Mesa's lavapipe
    /// included; an error where there is none) or auto (a hardware GPU where there is
    /// one, else the CPU). WGPU_BACKEND and WGPU_ADAPTER_NAME narrow the choice.
    #[arg(long, value_name = "DEVICE", default_value = "cpu", value_parser = trace_parser())]
    pub trace: TraceDevice,
}

/// A group's defaults are its command-line defaults.
macro_rules! defaults_from_clap {
    ($($group:ty),*) => {$(
        impl Default for $group {
            fn default() -> Self {
                use clap::{Args, FromArgMatches};
                let cmd = <$group>::augment_args(clap::Command::new("defaults"));
                let m = cmd.get_matches_from(["defaults"]);
                <$group>::from_arg_matches(&m).expect("the defaults parse")
            }
        }
    )*};
}
defaults_from_clap!(
    SceneGroup,
    DisplayGroup,
    QualityGroup,
    ReferenceGroup,
    DevicesGroup,
    TraceGroup
);
