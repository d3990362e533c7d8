//! Command-line arguments (clap derive) and their validation.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};
use frameless::{
    clock::parse_rate,
    methods::MethodKind,
    realtime::{RtMethod, Visualisation},
    settings::{self, finite_f64, Size},
};

/// `frameless`: adaptive frameless rendering.
#[derive(Parser, Debug)]
#[command(name = "frameless", version, about, long_about = None)]
pub struct Cli {
    /// Worker threads (default: all cores); for `view` and `live`, the real-time
    /// pipeline's threads sized for this many cores.
    #[arg(long, global = true, value_parser = clap::value_parser!(u16).range(1..=1024), allow_negative_numbers = true)]
    pub threads: Option<u16>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// List the built-in scenes, one per line.
    Scenes,
    /// Render a still reference image by stratified supersampling.
    Still(StillArgs),
    /// Measure ray throughput; `--json` prints one JSON object.
    Bench(BenchArgs),
    /// Gold-standard evaluation: methods vs. the ideal image at every refresh.
    Eval(EvalArgs),
    /// Run the adaptive sampler and write its visualisations (tiling, gradients,
    /// density, occlusion) and statistics.
    Sampler(SamplerArgs),
    /// Paper Table 1 and Fig. 8 on the BART kitchen: every method on the Interactive,
    /// Bart, Toycar and Still animations at each rate, with the paper's numbers beside
    /// ours.
    Table1(Table1Args),
    /// Render a sequence of displayed images of one method under the simulated clock
    /// (one PNG or OpenEXR file per refresh).
    Render(RenderArgs),
    /// The real-time pipeline: an interactive window, or `--headless` for a number of
    /// seconds writing images and statistics.
    View(ViewArgs),
    /// Live evaluation: real-time methods one after another on this machine, every
    /// displayed refresh scored against the ideal image at its scan-out time.
    Live(LiveArgs),
    /// Run one shard (`--shard i/N`) of a sweep file's evaluation jobs, writing one
    /// result file per job; `frameless merge` combines them.
    Sweep(super::sweep::SweepArgs),
    /// Merge the job results of a sweep's shards into the outputs of one run
    /// (summary.json, summary.md, plots, strips, report.html).
    Merge(super::sweep::MergeArgs),
    /// Make the plots, FLIP maps and report.html of an `eval`, `table1` or `live` output
    /// folder again with this version, from its summary.json, frames.csv and image
    /// strips.
    Report(ReportArgs),
}

/// Arguments of `frameless report`.
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// The output folder of `frameless eval` or `frameless live` (or of `frameless
    /// table1`: each animation's folder is redone).
    pub dir: PathBuf,
}

/// Arguments of `frameless render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: settings::SceneGroup,
    #[command(flatten)]
    pub display: settings::DisplayGroup,
    #[command(flatten)]
    pub quality: settings::QualityGroup,
    #[command(flatten)]
    pub devices: settings::DevicesGroup,
    /// The method (any of `frameless eval --help`'s).
    #[arg(long, default_value = "adaptive", value_parser = method_parser())]
    pub method: MethodKind,
    /// Sample budget, samples per second of scene time; suffixes k and M.
    #[arg(long, default_value = "400k", value_parser = parse_rate, allow_negative_numbers = true)]
    pub rate: f64,
    /// First displayed refresh (seconds).
    #[arg(long, default_value = "0", value_parser = finite_f64, allow_negative_numbers = true)]
    pub start: f64,
    /// Length of the sequence (seconds).
    #[arg(long, alias = "seconds", default_value = "1", value_parser = finite_f64, allow_negative_numbers = true)]
    pub duration: f64,
    /// Sampling before the first refresh (seconds).
    #[arg(long, default_value_t = settings::WARMUP_S, value_parser = finite_f64, allow_negative_numbers = true)]
    pub warmup: f64,
    /// File format of the frames: png (display values, 8-bit sRGB-encoded) or exr
    /// (OpenEXR, the linear values, 32-bit float); docs/colour.md.
    #[arg(long, value_enum, default_value = "png")]
    pub format: FrameFormat,
    /// Output folder for `frame_NNNNN.png` (or `.exr`) and `stats.json`.
    #[arg(short, long, default_value = "render-out")]
    pub out: PathBuf,
}

/// File format of the images `still`, `render` and `eval` write (`--format`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FrameFormat {
    /// PNG, as displayed: clamped to [0, 1], sRGB-encoded, 8 bits.
    Png,
    /// OpenEXR: the linear values, 32-bit float, unclamped.
    Exr,
}

/// Arguments of `frameless table1`.
#[derive(Args, Debug)]
pub struct Table1Args {
    /// The BART folder (holding `kitchen/kitchen.aff`); default `$FRAMELESS_BART_DIR`.
    #[arg(long)]
    pub bart: Option<PathBuf>,
    /// Animations to run, comma-separated (interactive, bart, toycar, still).
    #[arg(long, default_value = "interactive,bart,toycar,still")]
    pub animations: String,
    /// Sample budgets, samples per second, comma-separated; suffixes k and M.
    #[arg(long = "rate", alias = "rates", value_name = "RATE", default_value = "100k,400k,800k", value_delimiter = ',', value_parser = parse_rate, allow_hyphen_values = true)]
    pub rates: Vec<f64>,
    /// Methods, comma-separated (default: the paper's, ours, the adaptive-no-reprojection
    /// ablation of Fig. 8, point tracking, TAA and the two late warps).
    #[arg(long = "method", alias = "methods", value_name = "METHOD", value_delimiter = ',', value_parser = method_parser())]
    pub methods: Option<Vec<MethodKind>>,
    /// Override every animation's window length (seconds), e.g. for a quick trial.
    #[arg(long, alias = "seconds", value_parser = finite_f64, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Override every animation's warm-up before its window (seconds).
    #[arg(long, value_parser = finite_f64, allow_negative_numbers = true)]
    pub warmup: Option<f64>,
    /// Camera path CSV overriding every animation's camera.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// Display size.
    #[arg(long, default_value_t = Size::DEFAULT)]
    pub size: Size,
    #[command(flatten)]
    pub quality: settings::QualityGroup,
    #[command(flatten)]
    pub reference: settings::ReferenceGroup,
    /// Compute FLIP on every n-th refresh (1: every one).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..), allow_negative_numbers = true)]
    pub flip_every: u32,
    /// Image strips written per animation and rate: the frames at the window's
    /// quartiles, its middle frame only, or none.
    #[arg(long, value_enum, default_value = "quartiles")]
    pub strips: Strips,
    /// Rates that get image strips, comma-separated (default: every rate).
    #[arg(long = "strip-rate", alias = "strip-rates", value_name = "RATE", value_delimiter = ',', value_parser = parse_rate, allow_hyphen_values = true)]
    pub strip_rates: Option<Vec<f64>>,
    #[command(flatten)]
    pub devices: settings::DevicesGroup,
    /// Output folder: `summary.json`, `table.md`, `report.html`, one eval folder per
    /// animation.
    #[arg(short, long, default_value = "table1-out")]
    pub out: PathBuf,
}

/// A named set of sampler parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SamplerPreset {
    /// `SamplerParams::ours()`, as `adaptive` uses.
    Ours,
    /// `SamplerParams::paper()`, as `adaptive-paper` uses.
    Paper,
}

/// Which frames of a window get image strips.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Strips {
    /// The frames at ¼, ½ and ¾ of the window.
    Quartiles,
    /// The middle frame.
    Middle,
    /// None.
    None,
}

/// Arguments of `frameless view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    #[command(flatten)]
    pub scene: settings::SceneGroup,
    #[command(flatten)]
    pub display: settings::DisplayGroup,
    #[command(flatten)]
    pub quality: settings::QualityGroup,
    #[command(flatten)]
    pub devices: settings::DevicesGroup,
    /// The real-time method.
    #[arg(long, default_value = "adaptive", value_parser = RtMethodParser)]
    pub method: RtMethod,
    /// Sampling threads [default: one per core].
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256), allow_negative_numbers = true)]
    pub sampling_threads: Option<u16>,
    /// Threads of the reconstructor [default: half the cores, at least 1].
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256), allow_negative_numbers = true)]
    pub recon_threads: Option<u16>,
    /// Trace a moving view where it is now, not where the camera's past poses say it
    /// will be when the samples are shown (every method).
    #[arg(long)]
    pub no_view_ahead: bool,
    #[command(flatten)]
    pub adaptive: frameless::realtime::AdaptiveArgs,
    /// Scene time at start, seconds.
    #[arg(long, default_value = "0", value_parser = finite_f64, allow_negative_numbers = true)]
    pub start: f64,
    /// Run this many wall-clock seconds, then stop (required with --headless;
    /// `--seconds`, its old name, is accepted too).
    #[arg(long = "duration", alias = "seconds", value_parser = finite_f64, allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// No window: run the pipeline, write images and stats.json to --out.
    #[arg(long)]
    pub headless: bool,
    /// With --headless: turn the camera 20° this many seconds into the run and report
    /// how long the display takes to show it (`camera_step` in stats.json).
    #[arg(long, value_parser = finite_f64, requires = "headless")]
    pub camera_step: Option<f64>,
    /// Output directory of --headless.
    #[arg(short, long, default_value = "view-out")]
    pub out: PathBuf,
    /// Displayed images --headless writes, evenly spaced.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(0..=frameless::realtime::headless::MAX_IMAGES as i64), allow_negative_numbers = true)]
    pub images: u32,
    /// Record the camera path to this CSV file (replay with `eval --camera-path`).
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Write the last displayed image to this PNG on exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Visualisation shown at start (key V cycles).
    #[arg(long, default_value = "image")]
    pub vis: Visualisation,
}

/// Arguments of `frameless sampler`.
#[derive(Args, Debug)]
pub struct SamplerArgs {
    #[command(flatten)]
    pub scene: settings::SceneGroup,
    #[command(flatten)]
    pub display: settings::DisplayGroup,
    #[command(flatten)]
    pub quality: settings::QualityGroup,
    /// Time the sampler starts, seconds.
    #[arg(long, default_value = "0", value_parser = finite_f64, allow_negative_numbers = true)]
    pub start: f64,
    /// How long it runs, seconds; the images show the state at the end.
    #[arg(long, alias = "seconds", default_value = "1", value_parser = finite_f64, allow_negative_numbers = true)]
    pub duration: f64,
    /// Sample budget, samples per second of scene time; suffixes k and M.
    #[arg(long, default_value = "400k", value_parser = parse_rate, allow_negative_numbers = true)]
    pub rate: f64,
    /// Sampler parameters: ours (`adaptive`) or the paper's (`adaptive-paper`); the
    /// ablation flags below apply on top.
    #[arg(long, value_enum, default_value = "ours")]
    pub preset: SamplerPreset,
    /// Ablation: no reprojection in the sampler (`--preset paper`; ours has none).
    #[arg(long)]
    pub no_reprojection: bool,
    /// Ablation: no gain control (fixed tile count).
    #[arg(long)]
    pub no_gain_control: bool,
    /// Ablation: no occlusion term in tile error.
    #[arg(long)]
    pub no_occlusion_term: bool,
    /// Ablation: uniform tiling.
    #[arg(long)]
    pub uniform_tiling: bool,
    /// Output directory.
    #[arg(short, long, default_value = "sampler-out")]
    pub out: PathBuf,
}

/// Arguments of `frameless eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    #[command(flatten)]
    pub scene: settings::SceneGroup,
    #[command(flatten)]
    pub display: settings::DisplayGroup,
    #[command(flatten)]
    pub quality: settings::QualityGroup,
    #[command(flatten)]
    pub reference: settings::ReferenceGroup,
    #[command(flatten)]
    pub devices: settings::DevicesGroup,
    /// First evaluated refresh, seconds of scene time.
    #[arg(long, default_value = "0", value_parser = finite_f64, allow_negative_numbers = true)]
    pub start: f64,
    /// Length of the evaluated window, seconds.
    #[arg(long, alias = "seconds", default_value = "1", value_parser = finite_f64, allow_negative_numbers = true)]
    pub duration: f64,
    /// Sample budgets, samples per second of scene time, comma-separated; suffixes k and
    /// M (e.g. 100k,400k,800k).
    #[arg(long = "rate", alias = "rates", value_name = "RATE", default_value = "100k,400k,800k", value_delimiter = ',', value_parser = parse_rate, allow_hyphen_values = true)]
    pub rates: Vec<f64>,
    /// Methods to evaluate, comma-separated.
    #[arg(
        long = "method",
        alias = "methods",
        value_name = "METHOD",
        value_delimiter = ',',
        value_parser = method_parser(),
        default_value = "framed-60hz,framed-full,full-res-60hz,traditional-frameless,point-tracking,taa,late-warp,taa-warp,adaptive"
    )]
    pub methods: Vec<MethodKind>,
    /// Seconds every method runs before the first evaluated refresh.
    #[arg(long, default_value_t = settings::WARMUP_S, value_parser = finite_f64, allow_negative_numbers = true)]
    pub warmup: f64,
    /// Compute FLIP on every n-th frame only (1: every frame; RMS, PSNR and temporal
    /// instability are always computed on every frame).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..), allow_negative_numbers = true)]
    pub flip_every: u32,
    /// Format of the image strips: png only, or exr to write them also as OpenEXR
    /// (the linear values, before the display clamps and encodes them) under `exr/`:
    /// the ideal image and every method's. The report reads the PNGs.
    #[arg(long, value_enum, default_value = "png")]
    pub format: FrameFormat,
    /// `--format exr`, by its old name.
    #[arg(long, hide = true)]
    pub exr: bool,
    /// Output folder.
    #[arg(short, long, default_value = "eval-out")]
    pub out: PathBuf,
}

/// Arguments of `frameless live`.
#[derive(Args, Debug)]
pub struct LiveArgs {
    #[command(flatten)]
    pub scene: settings::SceneGroup,
    #[command(flatten)]
    pub display: settings::DisplayGroup,
    #[command(flatten)]
    pub quality: settings::QualityGroup,
    #[command(flatten)]
    pub reference: settings::ReferenceGroup,
    #[command(flatten)]
    pub devices: settings::DevicesGroup,
    /// Scene time of the first recorded refresh, seconds (the warm-up runs before it).
    #[arg(long, default_value = "0", value_parser = finite_f64, allow_negative_numbers = true)]
    pub start: f64,
    /// Wall seconds recorded per run; scene time runs with the wall clock
    /// (`--seconds`, its old name, is accepted too).
    #[arg(long = "duration", alias = "seconds", default_value = "3", value_parser = finite_f64, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Wall seconds each run goes before its recorded window (whole refreshes).
    #[arg(long, default_value = "1", value_parser = finite_f64, allow_negative_numbers = true)]
    pub warmup: f64,
    /// Real-time methods to run, comma-separated [default: all of them].
    #[arg(long = "method", alias = "methods", value_name = "METHOD", value_delimiter = ',', value_parser = RtMethodParser)]
    pub methods: Option<Vec<RtMethod>>,
    /// Runs of each method, in alternation (A B C A B C …); tables show the median and
    /// the range.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100), allow_negative_numbers = true)]
    pub repeat: u32,
    /// Threads of the image build [default: half the cores `--threads` names, at least 1].
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256), allow_negative_numbers = true)]
    pub recon_threads: Option<u16>,
    /// Trace a moving view where it is now, not where the camera's past poses say it
    /// will be when the samples are shown (every method).
    #[arg(long)]
    pub no_view_ahead: bool,
    #[command(flatten)]
    pub adaptive: frameless::realtime::AdaptiveArgs,
    /// Output folder.
    #[arg(short, long, default_value = "live-out")]
    pub out: PathBuf,
}

/// Arguments of `frameless still`.
#[derive(Args, Debug)]
pub struct StillArgs {
    #[command(flatten)]
    pub scene: settings::SceneGroup,
    /// Scene time in seconds.
    #[arg(long, default_value = "0", value_parser = finite_f64, allow_negative_numbers = true)]
    pub time: f64,
    /// Image size WxH (or N for NxN).
    #[arg(long, default_value_t = Size::DEFAULT)]
    pub size: Size,
    /// Samples per pixel (stratified).
    #[arg(long, default_value_t = settings::STILL_SPP, value_parser = clap::value_parser!(u32).range(1..=frameless::limits::MAX_STILL_SPP as i64), allow_negative_numbers = true)]
    pub spp: u32,
    #[command(flatten)]
    pub quality: settings::QualityGroup,
    // The tracing half of `DevicesGroup` alone: a still is traced and never
    // reconstructed, so `--recon` would be an option it takes and ignores.
    #[command(flatten)]
    pub trace: settings::TraceGroup,
    /// File format: png (display values, 8-bit sRGB-encoded) or exr (OpenEXR, the
    /// linear values, 32-bit float); docs/colour.md. Default: the one `--out`'s
    /// extension names, else png.
    #[arg(long, value_enum)]
    pub format: Option<FrameFormat>,
    /// Output file [default: still.png, or still.exr with `--format exr`].
    #[arg(short, long)]
    pub out: Option<PathBuf>,
}

/// Arguments of `frameless bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = "toycar")]
    pub scene: String,
    /// Scene time (default: the start of its animation).
    #[arg(long, value_parser = finite_f64, allow_negative_numbers = true)]
    pub time: Option<f64>,
    /// View size WxH.
    #[arg(long, default_value_t = Size::DEFAULT)]
    pub size: Size,
    /// Rays per timed repetition.
    #[arg(long, default_value_t = 1 << 19, value_parser = parse_rays, allow_negative_numbers = true)]
    pub rays: usize,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Measure only the reconstructor's cost per image at live sample rates, on one
    /// thread: at 256x256, 640x480, 1280x720 and 1920x1080, and at 640x480 as the ring
    /// grows from 0.5 to 4 samples per pixel (about 3 minutes; `--scene` and the ray
    /// options are not used, `--trace` must stay cpu). With `--recon gpu|auto` the
    /// refreshes run on the GPU, their CPU parts on one thread, each pass's time
    /// printed.
    #[arg(long)]
    pub live_recon: bool,
    #[command(flatten)]
    pub devices: settings::DevicesGroup,
}

fn parse_rays(s: &str) -> anyhow::Result<usize> {
    let n: usize = s
        .parse()
        .map_err(|_| anyhow::anyhow!("`{s}` is not a whole number"))?;
    if !(1024..=1 << 28).contains(&n) {
        anyhow::bail!("rays {n} out of range 1024..=268435456");
    }
    Ok(n)
}

/// The parser of `--method` in the commands that run methods under the simulated
/// clock: blanks around a name are ignored (so that a list written `adaptive, taa`
/// parses), every method is listed in `--help`, and an old name is taken with a note
/// naming the new one.
fn method_parser() -> MethodParser {
    MethodParser(clap::builder::EnumValueParser::new())
}

#[derive(Clone)]
struct MethodParser(clap::builder::EnumValueParser<MethodKind>);

impl clap::builder::TypedValueParser for MethodParser {
    type Value = MethodKind;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<MethodKind, clap::Error> {
        let text = value.to_string_lossy();
        let name = current_name_noted(text.trim());
        self.0.parse_ref(cmd, arg, std::ffi::OsStr::new(name))
    }

    fn possible_values(
        &self,
    ) -> Option<Box<dyn Iterator<Item = clap::builder::PossibleValue> + '_>> {
        self.0.possible_values()
    }
}

/// A method's current name; an old name gets a note on stderr naming the new one, so
/// that scripts move to it while they keep working.
fn current_name_noted(name: &str) -> &str {
    let new = frameless::methods::current_name(name);
    if new != name {
        eprintln!("note: method `{name}` is called `{new}` now; the old name still works");
    }
    new
}

/// `--method` of `frameless view`: a real-time method, or a clear word on why an
/// evaluation method is not one.
#[derive(Clone)]
struct RtMethodParser;

impl clap::builder::TypedValueParser for RtMethodParser {
    type Value = RtMethod;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<RtMethod, clap::Error> {
        let text = value.to_string_lossy();
        let name = current_name_noted(text.trim());
        if let Ok(m) = RtMethod::parse(name) {
            return Ok(m);
        }
        let real_time: Vec<&str> = RtMethod::ALL.iter().map(|m| m.name()).collect();
        let why = if MethodKind::parse(name).is_ok() {
            format!(
                "`{name}` runs only under the simulated clock (`frameless eval`, `frameless \
                 render`); the real-time pipeline runs {}",
                real_time.join(", ")
            )
        } else {
            format!("real-time methods are {}", real_time.join(", "))
        };
        Err(invalid(cmd, arg, name, why))
    }

    fn possible_values(
        &self,
    ) -> Option<Box<dyn Iterator<Item = clap::builder::PossibleValue> + '_>> {
        Some(Box::new(RtMethod::ALL.into_iter().map(|m| {
            clap::builder::PossibleValue::new(m.name()).help(m.about())
        })))
    }
}

/// clap's "invalid value" error with our reason.
fn invalid(cmd: &clap::Command, arg: Option<&clap::Arg>, value: &str, why: String) -> clap::Error {
    let arg = arg
        .and_then(|a| a.get_long())
        .map_or_else(|| "--method".to_string(), |l| format!("--{l}"));
    clap::Error::raw(
        clap::error::ErrorKind::InvalidValue,
        format!("invalid value '{value}' for '{arg}': {why}\n"),
    )
    .with_cmd(cmd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use frameless::trace::TextureFilter;

    #[test]
    fn eval_help_lists_every_method() {
        use clap::CommandFactory;
        let mut cmd = Cli::command();
        let eval = cmd.find_subcommand_mut("eval").expect("eval command");
        let help = eval.render_long_help().to_string();
        for m in MethodKind::ALL {
            assert!(help.contains(m.name()), "{}", m.name());
            assert!(help.contains(m.description()), "{}", m.name());
        }
    }

    #[test]
    fn lists_parse_into_typed_values() {
        let cli = Cli::try_parse_from([
            "frameless",
            "eval",
            "--methods",
            "adaptive, taa",
            "--rates",
            "100k,1.5M",
        ])
        .expect("parses");
        let Command::Eval(a) = cli.command else {
            panic!("eval expected")
        };
        assert_eq!(a.methods, vec![MethodKind::Adaptive, MethodKind::Taa]);
        assert_eq!(a.rates, vec![100_000.0, 1_500_000.0]);
        assert!(Cli::try_parse_from(["frameless", "eval", "--methods", "adaptive-magic"]).is_err());
        assert!(Cli::try_parse_from(["frameless", "eval", "--rates", "fast"]).is_err());
    }

    #[test]
    fn one_vocabulary_across_commands() {
        let parse = |args: &[&str]| Cli::try_parse_from(args.iter().copied());
        // One rate flag (lists where a command runs several), the old spelling kept.
        for args in [
            &["frameless", "eval", "--rate", "100k,400k"][..],
            &["frameless", "eval", "--rates", "100k,400k"],
            &["frameless", "table1", "--rate", "100k,400k"],
            &["frameless", "render", "--rate", "400k"],
            &["frameless", "sampler", "--rate", "400k"],
        ] {
            assert!(parse(args).is_ok(), "{args:?}");
        }
        // One refresh flag.
        for cmd in ["eval", "render", "sampler", "view"] {
            assert!(
                parse(&["frameless", cmd, "--refresh-hz", "30"]).is_ok(),
                "{cmd}"
            );
        }
        let Command::Render(r) = parse(&["frameless", "render", "--fps", "30"])
            .unwrap()
            .command
        else {
            panic!("render expected")
        };
        assert_eq!(r.display.refresh_hz, 30.0);
    }

    #[test]
    fn negative_numbers_are_values_not_flags() {
        for args in [
            &["frameless", "eval", "--duration", "-1"][..],
            &["frameless", "eval", "--start", "-2.5"],
            &["frameless", "render", "--warmup", "-1"],
            &["frameless", "still", "--time", "-3"],
            &["frameless", "view", "--start", "-1"],
        ] {
            // Parsed (the range is checked later, with a message naming the option).
            assert!(
                Cli::try_parse_from(args.iter().copied()).is_ok(),
                "{args:?}"
            );
        }
        let e = Cli::try_parse_from(["frameless", "eval", "--rate", "-1k"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("must be positive"), "{e}");
    }

    #[test]
    fn methods_of_the_other_clock_get_a_reason() {
        let e = Cli::try_parse_from(["frameless", "view", "--method", "point-tracking"])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("simulated clock") && e.contains("adaptive"),
            "{e}"
        );
        // Every real-time method runs under the simulated clock too, by the same name.
        for m in RtMethod::ALL {
            assert!(MethodKind::parse(m.name()).is_ok(), "{}", m.name());
            let ok = Cli::try_parse_from(["frameless", "view", "--method", m.name()]);
            assert!(ok.is_ok(), "{}", m.name());
        }
        for m in MethodKind::ALL {
            let ok = Cli::try_parse_from(["frameless", "render", "--method", m.name()]);
            assert!(ok.is_ok(), "{}", m.name());
        }
    }

    #[test]
    fn table1_takes_the_options_of_eval_that_apply() {
        let Command::Table1(a) = Cli::try_parse_from([
            "frameless",
            "table1",
            "--no-cache",
            "--warmup",
            "0.5",
            "--camera-path",
            "path.csv",
            "--max-depth",
            "2",
        ])
        .expect("parses")
        .command
        else {
            panic!("table1 expected")
        };
        assert!(a.reference.no_cache && a.reference.cache().is_none());
        assert_eq!(a.warmup, Some(0.5));
        assert_eq!(
            a.camera_path.as_deref(),
            Some(std::path::Path::new("path.csv"))
        );
        assert_eq!(a.quality.max_depth, 2);
        // Unset, every animation keeps its own warm-up and camera.
        let Command::Table1(a) = Cli::try_parse_from(["frameless", "table1"])
            .unwrap()
            .command
        else {
            panic!("table1 expected")
        };
        assert!(a.warmup.is_none() && a.camera_path.is_none());
        assert_eq!(a.quality, frameless::settings::QualityGroup::default());
    }

    #[test]
    fn old_method_names_are_taken_as_the_new_ones() {
        for (old, new) in frameless::methods::OLD_NAMES {
            let Command::Render(r) = Cli::try_parse_from(["frameless", "render", "--method", old])
                .unwrap()
                .command
            else {
                panic!("render expected")
            };
            assert_eq!(r.method.name(), *new);
            let Command::Live(l) = Cli::try_parse_from(["frameless", "live", "--method", old])
                .unwrap()
                .command
            else {
                panic!("live expected")
            };
            assert_eq!(l.methods.unwrap()[0].name(), *new);
        }
    }

    #[test]
    fn the_shared_groups_are_on_every_command_that_flattens_them() {
        let shared = [
            "--scene",
            "room",
            "--size",
            "32x16",
            "--refresh-hz",
            "30",
            "--seed",
            "2",
            "--max-depth",
            "3",
            "--texture-filter",
            "none",
        ];
        let groups = |cmd: &str| {
            let args = ["frameless", cmd].into_iter().chain(shared);
            match Cli::try_parse_from(args).expect("parses").command {
                Command::Eval(a) => (a.scene, a.display, a.quality),
                Command::Live(a) => (a.scene, a.display, a.quality),
                Command::View(a) => (a.scene, a.display, a.quality),
                Command::Render(a) => (a.scene, a.display, a.quality),
                Command::Sampler(a) => (a.scene, a.display, a.quality),
                c => panic!("no groups on {c:?}"),
            }
        };
        for cmd in ["eval", "live", "view", "render", "sampler"] {
            let (scene, display, quality) = groups(cmd);
            assert_eq!(scene.scene, "room", "{cmd}");
            assert_eq!(
                (display.size, display.refresh_hz),
                (Size(32, 16), 30.0),
                "{cmd}"
            );
            assert_eq!(
                (quality.seed, quality.max_depth, quality.texture_filter),
                (2, 3, TextureFilter::None),
                "{cmd}"
            );
        }
    }

    #[test]
    fn eval_defaults_are_the_librarys() {
        let Command::Eval(a) = Cli::try_parse_from(["frameless", "eval"]).unwrap().command else {
            panic!("eval expected")
        };
        let cfg = frameless::evaluation::EvalConfig::new("toycar");
        assert_eq!(a.methods, cfg.methods);
        assert_eq!(a.rates, cfg.rates);
        assert_eq!(
            (a.display, a.quality, a.reference.ideal_spp),
            (cfg.display, cfg.quality, cfg.reference.ideal_spp)
        );
        assert_eq!(
            (a.start, a.duration, a.warmup),
            (cfg.start, cfg.duration, cfg.warmup)
        );
        // The groups' defaults are the library's too.
        use frameless::settings::{DisplayGroup, QualityGroup, ReferenceGroup};
        assert_eq!(a.display, DisplayGroup::default());
        assert_eq!(a.quality, QualityGroup::default());
        assert_eq!(a.reference, ReferenceGroup::default());
    }

    #[test]
    fn recon_is_one_option_on_every_command_that_reconstructs_cpu_by_default() {
        use frameless::settings::ReconDevice;
        let parse = |args: &[&str]| Cli::try_parse_from(args.iter().copied());
        let recon = |args: &[&str]| -> ReconDevice {
            match parse(args).expect("parses").command {
                Command::Eval(a) => a.devices.recon,
                Command::Table1(a) => a.devices.recon,
                Command::View(a) => a.devices.recon,
                Command::Live(a) => a.devices.recon,
                Command::Bench(a) => a.devices.recon,
                c => panic!("no --recon on {c:?}"),
            }
        };
        for cmd in ["eval", "table1", "view", "live", "bench"] {
            assert_eq!(recon(&["frameless", cmd]), ReconDevice::Cpu, "{cmd}");
            for d in ReconDevice::ALL {
                assert_eq!(recon(&["frameless", cmd, "--recon", d.name()]), d, "{cmd}");
            }
            let e = parse(&["frameless", cmd, "--recon", "bogus"])
                .unwrap_err()
                .to_string();
            assert!(e.contains("'bogus'") && e.contains("--recon"), "{cmd}: {e}");
            for d in ["cpu", "gpu", "auto"] {
                assert!(e.contains(d), "{cmd}: {e} does not list {d}");
            }
        }
        // Commands that run no reconstructor choice take no --recon.
        assert!(parse(&["frameless", "still", "--recon", "gpu"]).is_err());
    }

    #[test]
    fn recon_help_says_what_each_choice_does() {
        use clap::CommandFactory;
        let mut cmd = Cli::command();
        let eval = cmd.find_subcommand_mut("eval").expect("eval command");
        let help = eval.render_long_help().to_string();
        for words in [
            "the reference",
            "software",
            "hardware GPU",
            "WGPU_BACKEND",
            "WGPU_ADAPTER_NAME",
        ] {
            assert!(help.contains(words), "--recon help lacks {words}: {help}");
        }
    }

    #[test]
    fn sizes() {
        assert_eq!("256x128".parse::<Size>().unwrap(), Size(256, 128));
        assert!("0x10".parse::<Size>().is_err());
        assert!("100000x10".parse::<Size>().is_err());
        assert!("abc".parse::<Size>().is_err());
        assert!("10xq".parse::<Size>().is_err());
    }
}
