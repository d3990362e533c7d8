//! Command-line arguments (clap derive) and their validation.

use std::{path::PathBuf, str::FromStr};

use clap::{Args, Parser, Subcommand};
use frameless::{
    clock::parse_rate,
    methods::MethodKind,
    realtime::{RtMethod, Visualisation},
    trace::TextureFilter,
};

/// Largest image side accepted.
pub const MAX_SIDE: u32 = 16384;

/// An image size `WxH`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size(pub u32, pub u32);

impl FromStr for Size {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (w, h) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| format!("`{s}` is not a size: expected WxH, e.g. 256x256"))?;
        let side = |v: &str| -> Result<u32, String> {
            let n: u32 = v
                .trim()
                .parse()
                .map_err(|_| format!("`{v}` in `{s}` is not a whole number"))?;
            if n == 0 || n > MAX_SIDE {
                return Err(format!("size side {n} out of range 1..={MAX_SIDE}"));
            }
            Ok(n)
        };
        Ok(Size(side(w)?, side(h)?))
    }
}

/// `frameless`: adaptive frameless rendering.
#[derive(Parser, Debug)]
#[command(name = "frameless", version, about, long_about = None)]
pub struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true, value_parser = clap::value_parser!(u16).range(1..=1024))]
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
    /// (one PNG per refresh).
    Render(RenderArgs),
    /// The real-time pipeline: an interactive window, or `--headless` for a number of
    /// seconds writing images and statistics.
    View(ViewArgs),
    /// Run one shard (`--shard i/N`) of a sweep file's evaluation jobs, writing one
    /// result file per job; `frameless merge` combines them.
    Sweep(super::sweep::SweepArgs),
    /// Merge the job results of a sweep's shards into the outputs of one run
    /// (summary.json, summary.md, plots, strips, report.html).
    Merge(super::sweep::MergeArgs),
}

/// Arguments of `frameless render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = "toycar")]
    pub scene: String,
    /// Camera path CSV overriding the scene's camera.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// The method.
    #[arg(long, default_value = "adaptive")]
    pub method: MethodKind,
    /// Sampling rate (samples per second of scene time); suffixes k and M.
    #[arg(long, default_value = "400k", value_parser = parse_rate)]
    pub rate: f64,
    /// First displayed refresh (seconds).
    #[arg(long, default_value = "0", value_parser = finite_f64)]
    pub start: f64,
    /// Length of the sequence (seconds).
    #[arg(long, default_value = "1", value_parser = finite_f64)]
    pub duration: f64,
    /// Sampling before the first refresh (seconds).
    #[arg(long, default_value = "1", value_parser = finite_f64)]
    pub warmup: f64,
    /// Display refresh rate (Hz).
    #[arg(long, default_value = "60", value_parser = finite_f64)]
    pub fps: f64,
    /// Display size.
    #[arg(long, default_value = "256x256")]
    pub size: Size,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Texture filtering: ray-cones (mip-mapped lookups at each ray's footprint; no
    /// moiré on far and grazing textured surfaces) or none (full-resolution bilinear
    /// lookups, the paper's setting).
    #[arg(long, value_enum, default_value = "ray-cones")]
    pub texture_filter: TextureFilter,
    /// Output folder for `frame_NNNNN.png` and `stats.json`.
    #[arg(long, default_value = "render-out")]
    pub out: PathBuf,
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
    /// Sampling rates (samples/s), comma-separated; suffixes k and M.
    #[arg(long, default_value = "100k,400k,800k", value_delimiter = ',', value_parser = parse_rate)]
    pub rates: Vec<f64>,
    /// Methods, comma-separated (default: the paper's, ours, the adaptive-no-reprojection
    /// ablation of Fig. 8, point tracking, TAA and the two late warps).
    #[arg(long, value_delimiter = ',', value_parser = trimmed::<MethodKind>())]
    pub methods: Option<Vec<MethodKind>>,
    /// Override every animation's window length (seconds), e.g. for a quick trial.
    #[arg(long, value_parser = finite_f64)]
    pub duration: Option<f64>,
    /// Display size.
    #[arg(long, default_value = "256x256")]
    pub size: Size,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Texture filtering: ray-cones (mip-mapped lookups at each ray's footprint; no
    /// moiré on far and grazing textured surfaces) or none (full-resolution bilinear
    /// lookups, the paper's setting).
    #[arg(long, value_enum, default_value = "ray-cones")]
    pub texture_filter: TextureFilter,
    /// Samples per pixel of the ideal images.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub ideal_spp: u32,
    /// Compute FLIP on every n-th refresh (1: every one).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub flip_every: u32,
    /// Ideal-image cache (default `$FRAMELESS_CACHE`, else `~/.cache/frameless/ideal`).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Image strips written per animation and rate: the frames at the window's
    /// quartiles, its middle frame only, or none.
    #[arg(long, value_enum, default_value = "quartiles")]
    pub strips: Strips,
    /// Rates that get image strips, comma-separated (default: every rate).
    #[arg(long, value_delimiter = ',', value_parser = parse_rate)]
    pub strip_rates: Option<Vec<f64>>,
    /// Output folder: `summary.json`, `table.md`, `report.html`, one eval folder per
    /// animation.
    #[arg(long, default_value = "table1-out")]
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
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = "toycar")]
    pub scene: String,
    /// Camera path CSV overriding the scene's camera (the input of a headless run).
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// Image size WxH.
    #[arg(long, default_value = "256x256")]
    pub size: Size,
    /// The real-time method.
    #[arg(long, default_value = "adaptive")]
    pub method: RtMethod,
    /// Sampling threads [default: adaptive cores − 1 (at least 1), others all cores].
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub sampling_threads: Option<u16>,
    /// Threads of the reconstructor [default: half the cores, at least 1].
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub recon_threads: Option<u16>,
    /// Display refresh rate, Hz.
    #[arg(long, default_value = "60", value_parser = finite_f64)]
    pub refresh_hz: f64,
    /// Scene time at start, seconds.
    #[arg(long, default_value = "0", value_parser = finite_f64)]
    pub start: f64,
    /// Run this many wall-clock seconds, then stop (required with --headless).
    #[arg(long, value_parser = finite_f64)]
    pub seconds: Option<f64>,
    /// No window: run the pipeline, write images and stats.json to --out.
    #[arg(long)]
    pub headless: bool,
    /// With --headless: turn the camera 20° this many seconds into the run and report
    /// how long the display takes to show it (`camera_step` in stats.json).
    #[arg(long, value_parser = finite_f64, requires = "headless")]
    pub camera_step: Option<f64>,
    /// Output directory of --headless.
    #[arg(long, default_value = "view-out")]
    pub out: PathBuf,
    /// Displayed images --headless writes, evenly spaced.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(0..=100))]
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
    /// Reconstructor ring as a multiple of the pixel count [default: 2; paper: 6].
    #[arg(long, value_parser = finite_f64)]
    pub ring_factor: Option<f64>,
    /// Largest reconstruction splat radius, pixels [default: 8; paper reconstructor: 24].
    #[arg(long, value_parser = finite_f64)]
    pub max_radius: Option<f64>,
    /// No reprojection in the sampler's controller.
    #[arg(long)]
    pub no_reprojection: bool,
    /// Seed of the threads' random choices.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Texture filtering: ray-cones (mip-mapped lookups at each ray's footprint; no
    /// moiré on far and grazing textured surfaces) or none (full-resolution bilinear
    /// lookups, the paper's setting).
    #[arg(long, value_enum, default_value = "ray-cones")]
    pub texture_filter: TextureFilter,
}

/// Arguments of `frameless sampler`.
#[derive(Args, Debug)]
pub struct SamplerArgs {
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = "toycar")]
    pub scene: String,
    /// Camera path CSV overriding the scene's camera.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// Time the sampler starts, seconds.
    #[arg(long, default_value = "0", value_parser = finite_f64)]
    pub start: f64,
    /// How long it runs, seconds; the images show the state at the end.
    #[arg(long, default_value = "1", value_parser = finite_f64)]
    pub duration: f64,
    /// Sample budget, samples per second.
    #[arg(long, default_value = "400k", value_parser = parse_rate)]
    pub rate: f64,
    /// Image size WxH.
    #[arg(long, default_value = "256x256")]
    pub size: Size,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sampler parameters: ours (`adaptive`) or the paper's (`adaptive-paper`); the
    /// ablation flags below apply on top.
    #[arg(long, value_enum, default_value = "ours")]
    pub preset: SamplerPreset,
    /// Ablation: no reprojection in the sampler.
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
    #[arg(long, default_value = "sampler-out")]
    pub out: PathBuf,
}

/// Arguments of `frameless eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = "toycar")]
    pub scene: String,
    /// Camera path CSV overriding the scene's camera.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// First evaluated refresh, seconds of scene time.
    #[arg(long, default_value = "0", value_parser = finite_f64)]
    pub start: f64,
    /// Length of the evaluated window, seconds.
    #[arg(long, default_value = "1", value_parser = finite_f64)]
    pub duration: f64,
    /// Display size WxH.
    #[arg(long, default_value = "256x256")]
    pub size: Size,
    /// Sample budgets, samples per second (e.g. 100k,400k,800k).
    #[arg(long, default_value = "100k,400k,800k", value_delimiter = ',', value_parser = parse_rate)]
    pub rates: Vec<f64>,
    /// Methods to evaluate, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = trimmed::<MethodKind>(),
        default_value = "framed-60hz,framed-full,full-res-60hz,traditional-frameless,point-tracking,taa,late-warp,taa-warp,adaptive"
    )]
    pub methods: Vec<MethodKind>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Texture filtering: ray-cones (mip-mapped lookups at each ray's footprint; no
    /// moiré on far and grazing textured surfaces) or none (full-resolution bilinear
    /// lookups, the paper's setting).
    #[arg(long, value_enum, default_value = "ray-cones")]
    pub texture_filter: TextureFilter,
    /// Samples per pixel of the ideal images.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub ideal_spp: u32,
    /// Seconds every method runs before the first evaluated refresh.
    #[arg(long, default_value = "1", value_parser = finite_f64)]
    pub warmup: f64,
    /// Reflection/refraction depth limit.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub max_depth: u32,
    /// Ideal-image cache directory [default: $FRAMELESS_CACHE or ~/.cache/frameless].
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Compute FLIP on every n-th frame only (1: every frame; RMS, PSNR and temporal
    /// instability are always computed on every frame).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub flip_every: u32,
    /// Do not read or write the ideal-image cache.
    #[arg(long)]
    pub no_cache: bool,
    /// Output directory.
    #[arg(long, default_value = "eval-out")]
    pub out: PathBuf,
}

fn finite_f64(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if !v.is_finite() {
        return Err(format!("`{s}` is not finite"));
    }
    Ok(v)
}

/// Arguments of `frameless still`.
#[derive(Args, Debug)]
pub struct StillArgs {
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = "toycar")]
    pub scene: String,
    /// Camera path CSV overriding the scene's camera.
    #[arg(long)]
    pub camera_path: Option<PathBuf>,
    /// Scene time in seconds.
    #[arg(long, default_value = "0", value_parser = finite_f64)]
    pub time: f64,
    /// Image size WxH.
    #[arg(long, default_value = "512x384")]
    pub size: Size,
    /// Samples per pixel (stratified).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub spp: u32,
    /// Seed of the sample positions.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Texture filtering: ray-cones (mip-mapped lookups at each ray's footprint; no
    /// moiré on far and grazing textured surfaces) or none (full-resolution bilinear
    /// lookups, the paper's setting).
    #[arg(long, value_enum, default_value = "ray-cones")]
    pub texture_filter: TextureFilter,
    /// Reflection/refraction depth limit.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub max_depth: u32,
    /// Output PNG file.
    #[arg(long, default_value = "still.png")]
    pub out: PathBuf,
}

/// Arguments of `frameless bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Built-in scene name or scene file (.aff, .gltf, .glb, .obj).
    #[arg(long, default_value = "toycar")]
    pub scene: String,
    /// Scene time (default: the start of its animation).
    #[arg(long, value_parser = finite_f64)]
    pub time: Option<f64>,
    /// View size WxH.
    #[arg(long, default_value = "256x256")]
    pub size: Size,
    /// Rays per timed repetition.
    #[arg(long, default_value_t = 1 << 19, value_parser = parse_rays)]
    pub rays: usize,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn parse_rays(s: &str) -> Result<usize, String> {
    let n: usize = s
        .parse()
        .map_err(|_| format!("`{s}` is not a whole number"))?;
    if !(1024..=1 << 28).contains(&n) {
        return Err(format!("rays {n} out of range 1024..=268435456"));
    }
    Ok(n)
}

/// A clap enum parser that ignores blanks around the value, so that a list written
/// `adaptive, taa` parses; possible values are still listed in `--help`.
fn trimmed<E: clap::ValueEnum + Clone + Send + Sync + 'static>() -> Trimmed<E> {
    Trimmed(clap::builder::EnumValueParser::new())
}

#[derive(Clone)]
struct Trimmed<E: clap::ValueEnum + Clone + Send + Sync + 'static>(
    clap::builder::EnumValueParser<E>,
);

impl<E: clap::ValueEnum + Clone + Send + Sync + 'static> clap::builder::TypedValueParser
    for Trimmed<E>
{
    type Value = E;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<E, clap::Error> {
        let text = value.to_string_lossy();
        self.0
            .parse_ref(cmd, arg, std::ffi::OsStr::new(text.trim()))
    }

    fn possible_values(
        &self,
    ) -> Option<Box<dyn Iterator<Item = clap::builder::PossibleValue> + '_>> {
        self.0.possible_values()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn sizes() {
        assert_eq!("256x128".parse::<Size>().unwrap(), Size(256, 128));
        assert!("0x10".parse::<Size>().is_err());
        assert!("100000x10".parse::<Size>().is_err());
        assert!("abc".parse::<Size>().is_err());
        assert!("10xq".parse::<Size>().is_err());
    }
}
