//! Evaluation sweeps that outgrow one machine.
//!
//! A sweep file (TOML) names evaluations (a scene, an optional camera path, a time
//! window) and the sizes, seeds, methods and rates to run each at. It expands into
//! jobs, one per evaluation × size × seed × method × rate; a method that ignores the
//! rate is one job that fills every rate column, as in [`super::run`].
//!
//! A job's shard is a hash of its identity modulo the shard count ([`JobKey::shard`]),
//! so the shards of any count partition the same jobs and no shard needs to hear from
//! the others. Each job writes one self-describing result file ([`run_shard`]);
//! [`merge()`] checks that every job is there exactly once, from the same sweep and
//! renderer, and [`write_merged`] writes the outputs a single run writes.

pub mod merge;
pub mod run;

use std::{
    fmt::{self, Write as _},
    path::{Path, PathBuf},
};

use serde::{de, Deserialize, Deserializer, Serialize};

use super::{EvalConfig, EvalError};
use crate::{
    clock::{parse_rate, rate_label},
    gpu::Devices,
    methods::MethodKind,
    sampling::rng::mix64,
    scene::{builtin, CameraPath, SceneError},
    settings::{self, DisplayGroup, QualityGroup, ReferenceGroup},
    trace::TextureFilter,
};

pub use merge::{merge, write_merged, Merged, SweepSummary};
pub use run::{run_shard, JobEvent, JobResult, ShardOptions, ShardRun};

/// Why a sweep could not be read, run or merged.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A file or folder could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The sweep file is not valid TOML or has a key of the wrong type or an unknown
    /// key (the message names line, column and key).
    #[error("{file}: {message}")]
    Toml {
        /// The sweep file.
        file: String,
        /// The parser's message.
        message: String,
    },
    /// A value in the sweep file is out of range or inconsistent.
    #[error("{file}:{line}: {key}: {why}")]
    Invalid {
        /// The sweep file.
        file: String,
        /// Its line (1-based).
        line: usize,
        /// The key, as written in the file (`evaluation.toycar.start`).
        key: String,
        /// What is wrong and what would do.
        why: String,
    },
    /// A camera path named by the sweep could not be loaded.
    #[error("{file}: evaluation '{evaluation}': {source}")]
    CameraPath {
        /// The sweep file.
        file: String,
        /// The evaluation naming it.
        evaluation: String,
        /// Why (boxed: scene errors are large and rare).
        source: Box<SceneError>,
    },
    /// A scene named by the sweep cannot be found or loaded.
    #[error("evaluation '{evaluation}': scene '{scene}': {why}")]
    Scene {
        /// The evaluation.
        evaluation: String,
        /// The scene as the sweep names it.
        scene: String,
        /// Why.
        why: String,
    },
    /// A scene named `bart:<path>`, and no BART folder to find it in (the binary says
    /// how to give one).
    #[error("evaluation '{evaluation}': scene '{scene}' names a BART scene, and no BART folder was given")]
    NoBartFolder {
        /// The evaluation.
        evaluation: String,
        /// The scene as the sweep names it.
        scene: String,
    },
    /// A shard is not `i/N` with `i < N`.
    #[error("`{0}` is not a shard: expected i/N with 0 <= i < N <= 100000, e.g. 0/4")]
    Shard(String),
    /// A job's evaluation failed.
    #[error("job {job}: {source}")]
    Job {
        /// The job's identity.
        job: String,
        /// Why (boxed: evaluation errors are large and rare).
        source: Box<EvalError>,
    },
    /// A file among the results is not a job result this version can read.
    #[error("{}: not a job result: {why}", path.display())]
    NotAResult {
        /// The file.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// Results disagree on something that must be the same for all.
    #[error("{}: {what} is {found}, but {} has {expected}; results whose {what} differs cannot be merged", path.display(), reference.display())]
    Mismatch {
        /// What differs (`sweep file hash`, `renderer version`).
        what: &'static str,
        /// The file that differs.
        path: PathBuf,
        /// Its value.
        found: String,
        /// The file the others are compared with.
        reference: PathBuf,
        /// Its value.
        expected: String,
    },
    /// Jobs are missing, duplicated or not in the sweep.
    #[error("{}", incomplete_message(.missing, .duplicated, .unknown, *.total))]
    Incomplete {
        /// Missing jobs, each with the shard that runs it in every shard count seen.
        missing: Vec<String>,
        /// Jobs found more than once, with their files.
        duplicated: Vec<String>,
        /// Results of jobs the sweep does not have.
        unknown: Vec<String>,
        /// Jobs in the sweep.
        total: usize,
    },
    /// Jobs of one evaluation disagree on what they evaluated (a different scene or
    /// ideal images): they were run on different inputs.
    #[error("{first} and {second} {why}")]
    Inconsistent {
        /// A job.
        first: String,
        /// Another job of the same evaluation.
        second: String,
        /// What differs.
        why: String,
    },
    /// No job result in the folders given.
    #[error("no job results (*.json) in {0}")]
    NoResults(String),
    /// An output folder cannot be written.
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// Writing the merged outputs failed.
    #[error(transparent)]
    Eval(Box<EvalError>),
}

impl From<EvalError> for SweepError {
    fn from(e: EvalError) -> Self {
        SweepError::Eval(Box::new(e))
    }
}

/// At most this many jobs are named per kind of problem; the count says the rest.
const NAMED: usize = 100;

fn incomplete_message(
    missing: &[String],
    duplicated: &[String],
    unknown: &[String],
    total: usize,
) -> String {
    let mut s = String::from("the results are not one whole sweep");
    let mut list = |title: String, items: &[String]| {
        if items.is_empty() {
            return;
        }
        let _ = write!(s, "\n{title}:");
        for item in items.iter().take(NAMED) {
            let _ = write!(s, "\n  {item}");
        }
        if items.len() > NAMED {
            let _ = write!(s, "\n  ... and {} more", items.len() - NAMED);
        }
    };
    list(
        format!(
            "missing {} of {total} jobs (run the shards named, or the whole sweep again; \
             finished jobs are kept)",
            missing.len()
        ),
        missing,
    );
    list(
        format!(
            "{} jobs found more than once (give each result folder once, and each job \
             in one folder)",
            duplicated.len()
        ),
        duplicated,
    );
    list(
        format!("{} results of jobs this sweep does not have", unknown.len()),
        unknown,
    );
    s
}

/// What `frameless merge` writes beside the evaluations' folders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SweepReport {
    /// An index: `summary.json` with every evaluation's summary, `summary.md`,
    /// `report.html`.
    #[default]
    Evaluations,
    /// What `frameless table1` writes: `table.md` beside the paper's numbers,
    /// `report.html`, `summary.json` (one evaluation per animation).
    Table1,
}

/// Which refreshes of a window get image strips.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StripFrames {
    /// The frames at ¼, ½ and ¾ of the window.
    #[default]
    Quartiles,
    /// The middle frame.
    Middle,
    /// None.
    None,
}

impl StripFrames {
    /// The strip frames of a window of `n` refreshes.
    pub fn frames(self, n: usize) -> Vec<usize> {
        match self {
            StripFrames::Quartiles => {
                // ⌊3n/4⌋ without forming 3n, which overflows for a window of
                // unbounded length (caught by the checks that follow).
                let mut f = vec![n / 4, n / 2, n / 4 * 3 + n % 4 * 3 / 4];
                f.dedup();
                f
            }
            StripFrames::Middle => vec![n / 2],
            StripFrames::None => Vec::new(),
        }
    }
}

/// A rate as a sweep file writes it: `"400k"`, `"1.5M"` or a number.
struct Rate(f64);

impl<'de> Deserialize<'de> for Rate {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl de::Visitor<'_> for V {
            type Value = Rate;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a rate such as \"400k\", \"1.5M\" or 100000")
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<Rate, E> {
                parse_rate(s).map(Rate).map_err(E::custom)
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Rate, E> {
                self.visit_str(&v.to_string())
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Rate, E> {
                self.visit_str(&v.to_string())
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Rate, E> {
                self.visit_str(&v.to_string())
            }
        }
        d.deserialize_any(V)
    }
}

/// A display size as a sweep file writes it: `"256x256"`.
struct Size(u32, u32);

impl<'de> Deserialize<'de> for Size {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        let (w, h) = crate::limits::parse_size(&s).map_err(de::Error::custom)?;
        Ok(Size(w, h))
    }
}

fn default_ideal_spp() -> u32 {
    crate::settings::IDEAL_SPP
}
fn default_max_depth() -> u32 {
    crate::settings::MAX_DEPTH
}
fn default_flip_every() -> u32 {
    1
}
fn default_refresh_hz() -> f64 {
    crate::settings::REFRESH_HZ
}

/// The file as written; checked and turned into a [`Sweep`] by [`Sweep::parse`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSweep {
    name: toml::Spanned<String>,
    #[serde(default)]
    report: SweepReport,
    sizes: toml::Spanned<Vec<Size>>,
    seeds: toml::Spanned<Vec<u64>>,
    methods: toml::Spanned<Vec<MethodKind>>,
    rates: toml::Spanned<Vec<Rate>>,
    #[serde(default = "default_ideal_spp")]
    ideal_spp: u32,
    #[serde(default = "default_max_depth")]
    max_depth: u32,
    #[serde(default)]
    texture_filter: TextureFilter,
    #[serde(default = "default_flip_every")]
    flip_every: u32,
    #[serde(default)]
    strips: StripFrames,
    #[serde(default = "default_refresh_hz")]
    refresh_hz: f64,
    #[serde(rename = "evaluation", default)]
    evaluations: Vec<RawEvaluation>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEvaluation {
    name: toml::Spanned<String>,
    scene: String,
    #[serde(default)]
    title: Option<String>,
    #[serde(default)]
    description: String,
    #[serde(default)]
    camera_path: Option<String>,
    start: f64,
    duration: f64,
    warmup: f64,
}

/// One evaluation of a sweep: a scene, a camera, a window.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// Name: part of every job's identity and of output folder names.
    pub name: String,
    /// The scene: a built-in name, `bart:<path>` (inside the BART folder given to
    /// `frameless sweep`) or a file path relative to the sweep file.
    pub scene: String,
    /// The scene as reports name it (default: `scene`).
    pub title: String,
    /// What the evaluation shows.
    pub description: String,
    /// Camera-path CSV overriding the scene camera, relative to the sweep file.
    pub camera_path: Option<String>,
    /// First evaluated refresh, seconds.
    pub start: f64,
    /// Window length, seconds.
    pub duration: f64,
    /// Seconds every method runs before the window.
    pub warmup: f64,
    /// Line of its `name` in the sweep file, for messages.
    pub line: usize,
}

/// A sweep, as its file says: no file other than the sweep file itself is read.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// Name, for reports.
    pub name: String,
    /// What the merge writes beside the evaluations.
    pub report: SweepReport,
    /// Display sizes, each evaluation runs at every one.
    pub sizes: Vec<(u32, u32)>,
    /// Seeds, each evaluation runs with every one.
    pub seeds: Vec<u64>,
    /// Methods, in report order.
    pub methods: Vec<MethodKind>,
    /// Rates, in report order.
    pub rates: Vec<f64>,
    /// Samples per pixel of the ideal images.
    pub ideal_spp: u32,
    /// Reflection/refraction depth limit.
    pub max_depth: u32,
    /// Texture filtering of every image traced.
    pub texture_filter: TextureFilter,
    /// FLIP on every n-th refresh.
    pub flip_every: u32,
    /// Which refreshes get image strips.
    pub strips: StripFrames,
    /// Display refresh rate, Hz.
    pub refresh_hz: f64,
    /// The evaluations.
    pub evaluations: Vec<Evaluation>,
}

/// One evaluation at one size and seed: one `frameless eval` run, one output folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Instance {
    /// Index into [`Sweep::evaluations`].
    pub evaluation: usize,
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// Seed.
    pub seed: u64,
}

/// What identifies a job: the merge finds results by it and the shard is its hash.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobKey {
    /// The evaluation's name.
    pub evaluation: String,
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// Seed.
    pub seed: u64,
    /// The method.
    pub method: MethodKind,
    /// The rate (`None`: a method that ignores the rate, run once for every column).
    pub rate: Option<f64>,
}

impl JobKey {
    /// The job's name, also its result file's stem:
    /// `<evaluation>.<W>x<H>.seed<S>.<method>.<rate label or any-rate>`.
    pub fn id(&self) -> String {
        format!(
            "{}.{}x{}.seed{}.{}.{}",
            self.evaluation,
            self.width,
            self.height,
            self.seed,
            self.method,
            self.rate.map_or_else(|| "any-rate".to_string(), rate_label)
        )
    }

    /// The shard that runs this job when the sweep is split `count` ways: a hash of
    /// the job's name alone, so every count partitions the same jobs.
    pub fn shard(&self, count: u32) -> u32 {
        (stable_hash(self.id().as_bytes()) % count.max(1) as u64) as u32
    }
}

/// A share of a sweep's jobs: `index` of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: u32,
    /// How many shards the sweep is split into.
    pub count: u32,
}

/// Most shards a sweep is split into (far more than any sweep has jobs).
const MAX_SHARDS: u32 = 100_000;

impl std::str::FromStr for Shard {
    type Err = SweepError;
    fn from_str(s: &str) -> Result<Self, SweepError> {
        let bad = || SweepError::Shard(s.to_string());
        let (i, n) = s.trim().split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// Whether this shard runs `job`.
    pub fn owns(&self, job: &JobKey) -> bool {
        job.shard(self.count) == self.index
    }
}

/// FNV-1a (64-bit) finished by SplitMix64, whose low bits (they pick the shard) are
/// well mixed. Written out, not `std`'s hasher, whose output may change between Rust
/// releases: shards built by two versions must agree on who runs what.
pub fn stable_hash(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    mix64(h)
}

/// The 1-based line of any byte offset of a text: the line starts are found once, so
/// that naming the line of each of a file's tables costs a search, not a scan from
/// the top (which made checking many tables quadratic).
struct Lines(Vec<usize>);

impl Lines {
    fn of(text: &str) -> Lines {
        Lines(text.match_indices('\n').map(|(i, _)| i).collect())
    }

    /// The line of byte offset `at`.
    fn line(&self, at: usize) -> usize {
        self.0.partition_point(|&newline| newline < at) + 1
    }
}

/// Whether the relative path `rel` names something inside the folder it is joined to:
/// no root or prefix, no `..`.
fn stays_inside(rel: &str) -> bool {
    use std::path::Component;
    !rel.is_empty()
        && Path::new(rel)
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
}

/// The first item of `items` that an earlier one equals (one pass).
fn first_repeat<T: std::hash::Hash + Eq + Copy>(items: &[T]) -> Option<T> {
    let mut seen = std::collections::HashSet::with_capacity(items.len());
    items.iter().copied().find(|x| !seen.insert(*x))
}

/// Names become file names and parts of job names.
fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// Check that `evaluations × sizes × seeds` instances of `methods` at `rates` rates
/// make at most [`crate::limits::MAX_SWEEP_JOBS`] jobs, counted before any is made.
fn check_job_count(
    (evaluations, sizes, seeds): (usize, usize, usize),
    methods: &[MethodKind],
    rates: usize,
) -> Result<(), TooManyJobs> {
    let per_instance: u128 = methods
        .iter()
        .map(|m| {
            if m.rate_independent() {
                1
            } else {
                rates as u128
            }
        })
        .sum();
    let jobs = evaluations as u128 * sizes as u128 * seeds as u128 * per_instance;
    let most = crate::limits::MAX_SWEEP_JOBS;
    if jobs > most as u128 {
        return Err(TooManyJobs {
            evaluations,
            sizes,
            seeds,
            per_instance,
            jobs,
            most,
        });
    }
    Ok(())
}

/// A sweep that would make more jobs than [`crate::limits::MAX_SWEEP_JOBS`].
#[derive(Debug, thiserror::Error)]
#[error(
    "{evaluations} evaluations × {sizes} sizes × {seeds} seeds × {per_instance} \
     method and rate runs make {jobs} jobs, over the limit of {most} per sweep"
)]
struct TooManyJobs {
    evaluations: usize,
    sizes: usize,
    seeds: usize,
    per_instance: u128,
    jobs: u128,
    most: usize,
}

/// The evaluations as written, names checked (valid, distinct).
fn evaluations(
    raw: Vec<RawEvaluation>,
    lines: &Lines,
    invalid: &dyn Fn(usize, &str, String) -> SweepError,
) -> Result<Vec<Evaluation>, SweepError> {
    let mut evaluations: Vec<Evaluation> = Vec::with_capacity(raw.len());
    let mut names = std::collections::HashSet::new();
    for e in raw {
        let at = e.name.span().start;
        let name = e.name.into_inner();
        if !valid_name(&name) {
            let why = format!("`{name}` must be 1 to 64 letters, digits, - or _");
            return Err(invalid(at, "evaluation.name", why));
        }
        if !names.insert(name.clone()) {
            let why = format!("`{name}` names two evaluations");
            return Err(invalid(at, "evaluation.name", why));
        }
        evaluations.push(Evaluation {
            title: e.title.unwrap_or_else(|| e.scene.clone()),
            name,
            scene: e.scene,
            description: e.description,
            camera_path: e.camera_path,
            start: e.start,
            duration: e.duration,
            warmup: e.warmup,
            line: lines.line(at),
        });
    }
    Ok(evaluations)
}

impl Sweep {
    /// Parse and check a sweep file's text; `file` names it in messages. Every
    /// evaluation is checked as `frameless eval` checks its settings.
    pub fn parse(text: &str, file: &str) -> Result<Sweep, SweepError> {
        let raw: RawSweep = toml::from_str(text).map_err(|e| SweepError::Toml {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let lines = Lines::of(text);
        let invalid = |at: usize, key: &str, why: String| SweepError::Invalid {
            file: file.to_string(),
            line: lines.line(at),
            key: key.to_string(),
            why,
        };
        let name_at = raw.name.span().start;
        let name = raw.name.into_inner();
        if !valid_name(&name) {
            return Err(invalid(
                name_at,
                "name",
                format!("`{name}` must be 1 to 64 letters, digits, - or _"),
            ));
        }
        let (sizes_at, seeds_at) = (raw.sizes.span().start, raw.seeds.span().start);
        let (methods_at, rates_at) = (raw.methods.span().start, raw.rates.span().start);
        let sizes: Vec<(u32, u32)> = raw.sizes.into_inner().iter().map(|s| (s.0, s.1)).collect();
        let seeds = raw.seeds.into_inner();
        let methods = raw.methods.into_inner();
        let rates: Vec<f64> = raw.rates.into_inner().iter().map(|r| r.0).collect();
        let lists = [
            (sizes_at, "sizes", sizes.len()),
            (seeds_at, "seeds", seeds.len()),
            (methods_at, "methods", methods.len()),
            (rates_at, "rates", rates.len()),
        ];
        if let Some(&(at, key, _)) = lists.iter().find(|&&(_, _, len)| len == 0) {
            return Err(invalid(at, key, "lists nothing".into()));
        }
        // Job names are built from these; a repeat would be one job run twice.
        if let Some((w, h)) = first_repeat(&sizes) {
            return Err(invalid(sizes_at, "sizes", format!("lists {w}x{h} twice")));
        }
        if let Some(seed) = first_repeat(&seeds) {
            return Err(invalid(seeds_at, "seeds", format!("lists {seed} twice")));
        }
        if raw.evaluations.is_empty() {
            let why = "the sweep has no [[evaluation]]".into();
            return Err(invalid(text.len(), "evaluation", why));
        }
        let counts = (raw.evaluations.len(), sizes.len(), seeds.len());
        check_job_count(counts, &methods, rates.len())
            .map_err(|e| invalid(name_at, "jobs", e.to_string()))?;
        if raw.report == SweepReport::Table1 && (sizes.len() > 1 || seeds.len() > 1) {
            return Err(invalid(
                sizes_at,
                "report",
                "\"table1\" writes one folder per evaluation, so it takes one size and one seed"
                    .into(),
            ));
        }
        let evaluations = evaluations(raw.evaluations, &lines, &invalid)?;
        let sweep = Sweep {
            name,
            report: raw.report,
            sizes,
            seeds,
            methods,
            rates,
            ideal_spp: raw.ideal_spp,
            max_depth: raw.max_depth,
            texture_filter: raw.texture_filter,
            flip_every: raw.flip_every,
            strips: raw.strips,
            refresh_hz: raw.refresh_hz,
            evaluations,
        };
        sweep.check_instances(file)?;
        Ok(sweep)
    }

    /// Check every instance's settings as `frameless eval` checks its options.
    fn check_instances(&self, file: &str) -> Result<(), SweepError> {
        for inst in self.instances() {
            let e = &self.evaluations[inst.evaluation];
            if let Err(err) = self.config(&inst, None, None).validate() {
                let (key, why) = match err {
                    EvalError::Config { setting, why } => (setting.key(), why),
                    other => ("settings", other.to_string()),
                };
                return Err(SweepError::Invalid {
                    file: file.to_string(),
                    line: e.line,
                    key: format!(
                        "evaluation '{}' at {}x{}: {key}",
                        e.name, inst.width, inst.height
                    ),
                    why,
                });
            }
        }
        Ok(())
    }

    /// Every evaluation at every size and seed, in file order.
    pub fn instances(&self) -> Vec<Instance> {
        let mut v = Vec::new();
        for evaluation in 0..self.evaluations.len() {
            for &(width, height) in &self.sizes {
                for &seed in &self.seeds {
                    v.push(Instance {
                        evaluation,
                        width,
                        height,
                        seed,
                    });
                }
            }
        }
        v
    }

    /// An instance's jobs, in report order (methods, then rates).
    pub fn instance_jobs(&self, inst: &Instance) -> Vec<JobKey> {
        let key = |method, rate| JobKey {
            evaluation: self.evaluations[inst.evaluation].name.clone(),
            width: inst.width,
            height: inst.height,
            seed: inst.seed,
            method,
            rate,
        };
        let mut v = Vec::new();
        for &m in &self.methods {
            if m.rate_independent() {
                v.push(key(m, None));
            } else {
                v.extend(self.rates.iter().map(|&r| key(m, Some(r))));
            }
        }
        v
    }

    /// Every job of the sweep, instance by instance.
    pub fn jobs(&self) -> Vec<JobKey> {
        self.instances()
            .iter()
            .flat_map(|i| self.instance_jobs(i))
            .collect()
    }

    /// The output folder of an instance: the evaluation's name, with size and seed
    /// when the sweep has more than one of either.
    pub fn folder(&self, inst: &Instance) -> String {
        let name = &self.evaluations[inst.evaluation].name;
        if self.sizes.len() == 1 && self.seeds.len() == 1 {
            name.clone()
        } else {
            format!("{name}.{}x{}.seed{}", inst.width, inst.height, inst.seed)
        }
    }

    /// An instance's display: its size at the sweep's refresh rate.
    fn display(&self, inst: &Instance) -> DisplayGroup {
        DisplayGroup {
            size: settings::Size(inst.width, inst.height),
            refresh_hz: self.refresh_hz,
        }
    }

    /// How an instance's samples are traced: its seed, the sweep's depth and filter.
    /// A setting sweep files have no key for takes the command line's default.
    #[allow(clippy::needless_update)]
    fn quality(&self, inst: &Instance) -> QualityGroup {
        QualityGroup {
            seed: inst.seed,
            max_depth: self.max_depth,
            texture_filter: self.texture_filter,
            ..QualityGroup::default()
        }
    }

    /// The settings of `frameless eval` that run the whole instance.
    pub fn config(
        &self,
        inst: &Instance,
        camera_path: Option<CameraPath>,
        cache_dir: Option<PathBuf>,
    ) -> EvalConfig {
        let e = &self.evaluations[inst.evaluation];
        let mut cfg = EvalConfig {
            scene_name: e.title.clone(),
            camera_path,
            start: e.start,
            duration: e.duration,
            rates: self.rates.clone(),
            methods: self.methods.clone(),
            warmup: e.warmup,
            display: self.display(inst),
            quality: self.quality(inst),
            reference: ReferenceGroup {
                ideal_spp: self.ideal_spp,
                ..ReferenceGroup::uncached()
            },
            strip_frames: Vec::new(),
            flip_every: self.flip_every as usize,
            // Sweep jobs reconstruct and trace on the CPU, the reference.
            devices: Devices::default(),
        };
        cfg.reference.set_cache(cache_dir);
        cfg.strip_frames = self.strips.frames(cfg.frames());
        cfg
    }

    /// The settings that run one job: its instance's, narrowed to its method and rate
    /// (every rate for a method that ignores the rate, whose one run fills them all).
    pub fn job_config(
        &self,
        inst: &Instance,
        job: &JobKey,
        camera_path: Option<CameraPath>,
        cache_dir: Option<PathBuf>,
    ) -> EvalConfig {
        let mut cfg = self.config(inst, camera_path, cache_dir);
        cfg.methods = vec![job.method];
        if let Some(r) = job.rate {
            cfg.rates = vec![r];
        }
        cfg
    }
}

/// A sweep file read from disk with the camera paths it names.
pub struct SweepFile {
    /// Where it was read.
    pub path: PathBuf,
    /// Its text.
    pub text: String,
    /// The parsed sweep.
    pub sweep: Sweep,
    /// Each evaluation's camera path (parallel to `sweep.evaluations`).
    pub camera_paths: Vec<Option<CameraPath>>,
    /// Hash of the sweep file and of every camera-path file it names: results of
    /// different inputs are never merged ([`sweep_hash`]).
    pub hash: u64,
    /// Hash of the camera-path files alone, so that a merge can recompute
    /// [`SweepFile::hash`] from a result's sweep text.
    pub cameras_hash: u64,
}

/// The hash of a sweep whose file is `text` and whose camera-path files hash to
/// `cameras` ([`SweepFile::cameras_hash`]).
pub fn sweep_hash(text: &str, cameras: u64) -> u64 {
    let mut bytes = stable_hash(text.as_bytes()).to_le_bytes().to_vec();
    bytes.extend_from_slice(&cameras.to_le_bytes());
    stable_hash(&bytes)
}

impl SweepFile {
    /// Read, parse and check a sweep file and load its camera paths.
    pub fn load(path: &Path) -> Result<SweepFile, SweepError> {
        let io = |p: &Path, source| SweepError::Io {
            path: p.to_path_buf(),
            source,
        };
        let text = crate::limits::read_text(path, crate::limits::MAX_DATA_FILE_BYTES)
            .map_err(|e| io(path, e))?;
        let file = path.display().to_string();
        let sweep = Sweep::parse(&text, &file)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        // Length-prefixed, so that no two lists of files hash the same by moving bytes
        // from one file to the next.
        let mut hashed = Vec::new();
        let mut add = |bytes: &[u8]| {
            hashed.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
            hashed.extend_from_slice(bytes);
        };
        let mut camera_paths = Vec::new();
        for e in &sweep.evaluations {
            let Some(rel) = &e.camera_path else {
                camera_paths.push(None);
                continue;
            };
            let p = dir.join(rel);
            let cam = CameraPath::load(&p).map_err(|source| SweepError::CameraPath {
                file: file.clone(),
                evaluation: e.name.clone(),
                source: Box::new(source),
            })?;
            add(rel.as_bytes());
            add(&std::fs::read(&p).map_err(|err| io(&p, err))?);
            camera_paths.push(Some(cam));
        }
        let cameras_hash = stable_hash(&hashed);
        Ok(SweepFile {
            path: path.to_path_buf(),
            hash: sweep_hash(&text, cameras_hash),
            cameras_hash,
            text,
            sweep,
            camera_paths,
        })
    }

    /// What `scene::load` is given for an evaluation's scene: a built-in name, a path
    /// inside `bart` for `bart:<path>`, else a path relative to the sweep file.
    pub fn scene_source(
        &self,
        evaluation: usize,
        bart: Option<&Path>,
    ) -> Result<String, SweepError> {
        let e = &self.sweep.evaluations[evaluation];
        let err = |why: String| SweepError::Scene {
            evaluation: e.name.clone(),
            scene: e.scene.clone(),
            why,
        };
        if builtin::NAMES.contains(&e.scene.as_str()) {
            return Ok(e.scene.clone());
        }
        let path = match e.scene.strip_prefix("bart:") {
            // Only plain names below the folder: no root, no `..`.
            Some(rel) if !stays_inside(rel) => {
                return Err(err(format!(
                    "bart:{rel} must be a relative path inside the BART folder, without `..`"
                )))
            }
            Some(rel) => match bart {
                Some(dir) => dir.join(rel),
                None => {
                    return Err(SweepError::NoBartFolder {
                        evaluation: e.name.clone(),
                        scene: e.scene.clone(),
                    })
                }
            },
            None => self.path.parent().unwrap_or(Path::new("")).join(&e.scene),
        };
        if !path.is_file() {
            return Err(err(format!(
                "{} is not a file (a scene is a built-in name ({}), bart:<path in the BART \
                 folder>, or a path relative to the sweep file)",
                path.display(),
                builtin::NAMES.join(", ")
            )));
        }
        Ok(path.to_string_lossy().into_owned())
    }
}

#[cfg(test)]
mod tests;
