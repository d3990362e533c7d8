//! The settings every command, the evaluation, sweeps and the real-time pipeline share:
//! their defaults, in one place, and the names errors give them ([`Setting`]). Their
//! ranges are checked by [`crate::limits`].

/// Display refresh rate, Hz, unless one is asked for.
pub const REFRESH_HZ: f64 = 60.0;

/// Reflection/refraction depth the tracer recurses to, unless one is asked for.
pub const MAX_DEPTH: u32 = 5;

/// Samples per pixel of an ideal image, unless another count is asked for.
pub const IDEAL_SPP: u32 = 16;

/// Seed of every random choice, unless another is asked for.
pub const SEED: u64 = 1;

/// Display size, unless one is asked for.
pub const SIZE: (u32, u32) = (256, 256);

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
        }
    }

    /// The command-line option that sets it, which the binary and the Python module put
    /// before a configuration error's reason. The lists take their plural spellings,
    /// which every command accepts.
    pub fn option(self) -> &'static str {
        match self {
            Setting::Warmup => "--warmup",
            Setting::Duration => "--duration",
            Setting::Seconds => "--seconds",
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
        }
    }
}

impl std::fmt::Display for Setting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.words())
    }
}
