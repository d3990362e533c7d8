//! The command line: raw arguments become validated settings, then built objects.

mod args;
mod sweep;

mod progress;

use std::{path::Path, sync::Arc, time::Instant};

use anyhow::{bail, Context, Result};
use clap::Parser;

pub use args::{Cli, Command};
use frameless::settings::Size;
use progress::Meter;

use frameless::{
    bench,
    evaluation::{self, report, EvalConfig, EvalError},
    gpu::Devices,
    image::ImageFormat,
    reconstruction::device::{self, GpuContext, ReconDevice},
    render::still,
    scene::{self, builtin, CameraPath, Scene},
    settings,
    trace::{TraceOptions, Tracer},
};

/// Entry point of the `frameless` binary, and of the Python package's `frameless`
/// command, which compiles this module into its extension: parse `args` (the program's
/// name first) and run the command; returns the process exit code. A usage error
/// exits the process here, as clap does.
pub fn main<I, T>(args: I) -> std::process::ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    std::process::ExitCode::from(status(args))
}

/// [`main`]'s exit status as a number: 0 on success, 1 after printing the error.
pub fn status<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = Cli::parse_from(args);
    match run(cli) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {}", message(&e));
            1
        }
    }
}

/// An error and its causes joined by ": ", leaving out a cause whose text the message
/// already ends with (typed errors that print their source, such as an I/O error after
/// its path, would otherwise show it twice).
fn message(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = match cause.downcast_ref::<EvalError>() {
            Some(EvalError::Config { setting, why }) => format!("{} {why}", setting.option()),
            _ => cause.to_string(),
        };
        if msg.ends_with(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    msg
}

/// Run one parsed command.
pub fn run(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build_global()
            .context("setting the thread count")?;
    }
    if let Some((out, inputs)) = folder_and_inputs(&cli.command) {
        frameless::output::check_apart(out, &inputs)?;
    }
    match cli.command {
        Command::Scenes => {
            for (name, desc) in builtin::NAMES.iter().zip(builtin::DESCRIPTIONS) {
                println!("{name}\t{desc}");
            }
            Ok(())
        }
        Command::Still(a) => still(a),
        Command::Eval(a) => eval(a),
        Command::Sampler(a) => sampler(a),
        Command::Table1(a) => table1(a),
        Command::Render(a) => render(a),
        Command::View(a) => view(a, cli.threads),
        Command::Live(a) => live(a, cli.threads),
        Command::Sweep(a) => sweep::sweep(a),
        Command::Merge(a) => sweep::merge(a),
        Command::Report(a) => rewrite_report(&a.dir),
        Command::Bench(a) => bench(a),
    }
}

/// The output folder a command replaces whole and the paths it reads (scene file,
/// camera path, ideal-image cache, BART folder, result folders): replacing the folder
/// would delete an input inside it, after the input was read and with the command
/// succeeding, so every such command is checked here, before any work.
fn folder_and_inputs(cmd: &Command) -> Option<(&Path, Vec<std::path::PathBuf>)> {
    let scene = |s: &str| -> Option<std::path::PathBuf> {
        (!builtin::NAMES.contains(&s)).then(|| s.into())
    };
    let input = |s: &frameless::settings::SceneGroup| vec![s.camera_path.clone(), scene(&s.scene)];
    let (out, inputs) = match cmd {
        Command::Eval(a) => (
            &a.out,
            [input(&a.scene), vec![a.reference.cache()]].concat(),
        ),
        Command::Render(a) => (&a.out, input(&a.scene)),
        Command::Sampler(a) => (&a.out, input(&a.scene)),
        Command::View(a) if a.headless => (&a.out, input(&a.scene)),
        Command::Live(a) => (
            &a.out,
            [input(&a.scene), vec![a.reference.cache()]].concat(),
        ),
        Command::Table1(a) => {
            let bart = a
                .bart
                .clone()
                .or_else(|| std::env::var_os("FRAMELESS_BART_DIR").map(Into::into));
            (
                &a.out,
                vec![bart, a.reference.cache(), a.camera_path.clone()],
            )
        }
        Command::Merge(a) => (&a.out, a.results.iter().cloned().map(Some).collect()),
        _ => return None,
    };
    Some((out.as_path(), inputs.into_iter().flatten().collect()))
}

/// `frameless bench`: throughput of the tracer, the reconstructor (on `--recon`'s
/// device) and the real-time controllers.
fn bench(a: args::BenchArgs) -> Result<()> {
    if a.live_recon {
        if a.devices.trace.trace != ReconDevice::Cpu {
            bail!(
                "--live-recon measures the reconstructor alone and traces no ray: \
                 --trace {} has nothing to do there (leave it out)",
                a.devices.trace.trace
            );
        }
        let gpu = acquire_recon(a.devices.recon)?;
        return bench_live_recon(a.json, gpu);
    }
    let Devices {
        recon: gpu,
        trace: trace_gpu,
    } = acquire_devices(&a.devices)?;
    let t0 = Instant::now();
    let scene = load_scene(&a.scene)?;
    let load_s = t0.elapsed().as_secs_f64();
    let time = a.time.unwrap_or(scene.time_range().0 as f64);
    let Size(w, h) = a.size;
    let t1 = Instant::now();
    let tracer = Tracer::new(Arc::new(scene), w, h, TraceOptions::default());
    let build_s = t1.elapsed().as_secs_f64();
    let opts = bench::BenchOptions {
        rays: a.rays,
        gpu,
        ..Default::default()
    };
    let tracer = Arc::new(tracer);
    #[cfg(feature = "gpu")]
    let gpu_trace = match trace_gpu {
        Some(ctx) => {
            let used = ctx.used();
            let figures = bench::gpu_trace_figures(&tracer, time, &opts, ctx)
                .context("--trace gpu (--trace cpu traces on the CPU)")?;
            Some((used, figures))
        }
        None => None,
    };
    #[cfg(not(feature = "gpu"))]
    let gpu_trace: Option<(frameless::gpu::DeviceUsed, bench::GpuTraceFigures)> =
        trace_gpu.map(|c| match *c {});
    let mut report = bench::run(&tracer, time, opts, load_s, build_s);
    if let Some((used, figures)) = gpu_trace {
        report.trace = used;
        report.gpu_trace = Some(figures);
    }
    if a.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_bench(&report);
    }
    Ok(())
}

/// Timed images per figure of `frameless bench --live-recon`.
const LIVE_RECON_IMAGES: usize = 15;

/// `frameless bench --live-recon`: the reconstructor's cost per image at live rates,
/// on `gpu` if given.
fn bench_live_recon(json: bool, gpu: Option<Arc<GpuContext>>) -> Result<()> {
    let software = gpu.as_ref().is_some_and(|g| g.is_software());
    let used = gpu.as_ref().map(|g| g.used());
    let report = bench::live_report(LIVE_RECON_IMAGES, gpu, |what| eprintln!("measuring {what}"));
    if json {
        println!("{}", serde_json::to_string(&report)?);
        return Ok(());
    }
    if let Some(used) = &used {
        let label = if software {
            " (a software driver on the CPU, not a GPU's speed; the CPU's parts are real)"
        } else {
            ""
        };
        println!("reconstructor on {used}{label}");
    }
    let table = |title: &str, rows: &[bench::LiveFigure]| {
        println!("{title}");
        println!(
            "  size        rate/s   Hz  ring spp  new/image  placed/image  ms/image  take-in ms"
        );
        for f in rows {
            let c = &f.case;
            println!(
                "  {:>4}x{:<5} {:>6.2}M {:>4} {:>9} {:>10} {:>13.0} {:>9.2} {:>11.2}",
                c.width,
                c.height,
                c.rate / 1e6,
                c.refresh_hz,
                f.ring_spp,
                f.new_per_image,
                f.placed_per_image,
                f.ms_median,
                f.take_in_ms_median
            );
            if f.recon.device != "cpu" {
                println!("      {}", pass_split(&f.pass_ms));
                if let Some(cpu) = f.cpu_ms_mean {
                    println!(
                        "      CPU ms per image, every thread of the process (mean): {cpu:.1}"
                    );
                }
            }
        }
    };
    for (title, rows) in report.sections() {
        table(title, rows);
    }
    for (what, why) in &report.not_measured {
        println!("not measured on the GPU: {what}: {why}");
    }
    Ok(())
}

/// A figure's mean milliseconds per pass, the passes that took any time.
fn pass_split(pass_ms: &[(&str, f64)]) -> String {
    let parts: Vec<String> = pass_ms
        .iter()
        .filter(|(_, ms)| *ms > 0.0)
        .map(|(name, ms)| format!("{name} {ms:.1}"))
        .collect();
    format!("ms per pass (mean): {}", parts.join(", "))
}

/// `frameless bench`'s table.
fn print_bench(report: &bench::BenchReport) {
    println!("scene            {}", report.scene);
    println!("primitives       {}", report.primitives);
    println!(
        "load / build     {:.2} s / {:.2} s",
        report.load_s, report.build_s
    );
    println!("threads          {}", report.threads);
    println!(
        "primary 1 thread {:.2} M rays/s",
        report.primary_mrays_per_s_1t
    );
    println!(
        "primary all      {:.2} M rays/s",
        report.primary_mrays_per_s_all
    );
    println!(
        "shaded 1 thread  {:.0} samples/s",
        report.shaded_samples_per_s_1t
    );
    println!(
        "shaded all       {:.0} samples/s",
        report.shaded_samples_per_s_all
    );
    if let Some(g) = &report.gpu_trace {
        let label = if g.software {
            " (a software driver on the CPU, not a GPU's speed)"
        } else {
            ""
        };
        println!("tracer           {}{label}", report.trace);
        println!("gpu primary      {:.2} M rays/s", g.primary_mrays_per_s);
        println!(
            "gpu shaded       {:.2} M samples/s, {:.2} M secondary rays/s ({:.2} per sample)",
            g.shaded_msamples_per_s, g.secondary_mrays_per_s, g.secondary_per_sample
        );
        println!(
            "ideal {} spp     {:.2} s on the GPU tracer, {:.2} s on the CPU's, all threads",
            g.ideal_spp, g.ideal_s_gpu, g.ideal_s_cpu
        );
    }
    println!("reconstructor    {}", report.recon);
    println!(
        "reconstruct      {:.1} ms 1 thread, {:.1} ms all (400K, 256x256)",
        report.reconstruct_ms_1t, report.reconstruct_ms_all
    );
    println!(
        "reconstruct all  {:.1} ms 512x512, {:.1} ms 1024x1024 (6 x pixels)",
        report.reconstruct_ms_512_all, report.reconstruct_ms_1024_all
    );
    println!(
        "reconstruct rt   {:.1} ms 640x480, {:.1} ms 256x256, 1 thread (history and fill, 0.5 per pixel)",
        report.reconstruct_realtime_640_ms_1t, report.reconstruct_realtime_256_ms_1t
    );
    println!(
        "reconstruct scene {:.1} ms 1 thread, {:.1} ms all (sampler ran 1 s at 400K)",
        report.reconstruct_scene_ms_1t, report.reconstruct_scene_ms_all
    );
    for (figure, why) in &report.recon_notes {
        println!("  {figure} not measured: {why}");
    }
    println!(
        "controllers      {} together {:.2} M samples/s fed recorded batches, {:.2} M/s one tracing thread: keep up with {:.1} threads",
        report.controllers,
        report.controller_samples_per_s / 1e6,
        report.controller_tracing_samples_per_s_1t / 1e6,
        report.controller_margin
    );
}

/// The GPUs `--recon` and `--trace` ask for, acquired once for the whole command (the
/// tracer shares the reconstructor's where it may).
fn acquire_devices(d: &settings::DevicesGroup) -> Result<Devices> {
    let recon = acquire_recon(d.recon)?;
    let trace = acquire_trace(d.trace.trace, recon.as_ref())?;
    Ok(Devices { recon, trace })
}

/// [`acquire_devices`] for the real-time pipeline running `methods`: a GPU tracer for a
/// method whose sampling cannot trace on it is an error before any work.
fn realtime_devices(
    d: &settings::DevicesGroup,
    methods: &[frameless::realtime::RtMethod],
) -> Result<Devices> {
    let recon = acquire_recon(d.recon)?;
    let trace = realtime_trace(d.trace.trace, recon.as_ref(), methods)?;
    Ok(Devices { recon, trace })
}

/// The GPU `choice` asks for, acquired once for the whole command, with one line on
/// stderr saying where the reconstructor runs when that is not the CPU asked for.
/// `auto` stays on the CPU whenever no GPU can be had, for any reason: a machine's
/// environment (`WGPU_BACKEND`, `WGPU_ADAPTER_NAME`, a driver) must not decide whether a
/// run that accepts either device runs at all.
fn acquire_recon(choice: ReconDevice) -> Result<Option<Arc<GpuContext>>> {
    if choice == ReconDevice::Cpu {
        return Ok(None);
    }
    let got = check_wgpu_backend().and_then(|()| Ok(device::acquire(choice)?));
    match got {
        Ok(Some(g)) => {
            eprintln!("reconstructing on {}", g.describe());
            Ok(Some(g))
        }
        Ok(None) => {
            eprintln!("note: no hardware GPU adapter; reconstructing on the CPU");
            Ok(None)
        }
        Err(e) if choice == ReconDevice::Auto => {
            eprintln!(
                "note: --recon auto: {}; reconstructing on the CPU",
                message(&e)
            );
            Ok(None)
        }
        Err(e) => Err(e.context(format!(
            "--recon {choice} (--recon cpu reconstructs on the CPU)"
        ))),
    }
}

/// The GPU `--trace` asks for, as [`acquire_recon`] does for `--recon`: one line on
/// stderr saying where rays are traced when that is not the CPU asked for; `auto`
/// falls back to the CPU (and says so once) whenever no GPU can be had. The
/// reconstructor's GPU `recon`, where it is one `choice` accepts (`auto` takes no
/// software adapter), is shared rather than a second device opened on it.
fn acquire_trace(
    choice: settings::TraceDevice,
    recon: Option<&Arc<GpuContext>>,
) -> Result<Option<Arc<GpuContext>>> {
    if choice == settings::TraceDevice::Cpu {
        return Ok(None);
    }
    if let Some(g) = recon.filter(|g| choice == settings::TraceDevice::Gpu || !g.is_software()) {
        eprintln!("tracing on {}", g.describe());
        return Ok(Some(g.clone()));
    }
    let got = check_wgpu_backend().and_then(|()| Ok(frameless::gpu::acquire(choice)?));
    match got {
        Ok(Some(g)) => {
            eprintln!("tracing on {}", g.describe());
            Ok(Some(g))
        }
        Ok(None) => {
            eprintln!("note: no hardware GPU adapter; tracing on the CPU");
            Ok(None)
        }
        Err(e) if choice == settings::TraceDevice::Auto => {
            eprintln!("note: --trace auto: {}; tracing on the CPU", message(&e));
            Ok(None)
        }
        Err(e) => Err(e.context(format!("--trace {choice} (--trace cpu traces on the CPU)"))),
    }
}

/// `--trace` of the real-time pipeline (`view`, `live`) running `methods`, as
/// [`acquire_trace`]; a GPU for a method whose sampling cannot trace on it is an error
/// before any work, rather than a run that traces on the CPU.
fn realtime_trace(
    choice: settings::TraceDevice,
    recon: Option<&Arc<GpuContext>>,
    methods: &[frameless::realtime::RtMethod],
) -> Result<Option<Arc<GpuContext>>> {
    let got = acquire_trace(choice, recon)?;
    if got.is_some() {
        if let Some(m) = methods.iter().find(|m| !m.traces_on_gpu()) {
            bail!(
                "--trace {choice}: {} (--trace cpu traces on the CPU)",
                frameless::realtime::registry::cannot_trace_on_gpu(*m)
            );
        }
    }
    Ok(got)
}

/// Check `WGPU_BACKEND` as wgpu reads it (comma-separated backend names). wgpu skips a
/// name it does not know, and with no name left it lists no adapter, which the library
/// can only report as a missing driver; so the variable is named here instead.
#[cfg(feature = "gpu")]
fn check_wgpu_backend() -> Result<()> {
    let Some(value) = std::env::var_os("WGPU_BACKEND") else {
        return Ok(());
    };
    let value = value.to_string_lossy();
    let unknown: Vec<String> = value
        .split(',')
        .filter(|name| wgpu::Backends::from_comma_list(name).is_empty())
        .map(|name| format!("`{}`", name.trim()))
        .collect();
    if unknown.is_empty() {
        return Ok(());
    }
    let valid: Vec<&str> = wgpu::Backend::ALL.iter().map(|b| b.to_str()).collect();
    bail!(
        "WGPU_BACKEND={value}: {} names no wgpu backend; its valid values are {}, \
         comma-separated (or leave it unset for all of them)",
        unknown.join(", "),
        valid.join(", ")
    )
}

/// Without the `gpu` feature no GPU is ever asked for, so nothing reads `WGPU_BACKEND`.
#[cfg(not(feature = "gpu"))]
fn check_wgpu_backend() -> Result<()> {
    Ok(())
}

/// `frameless still`.
fn still(a: args::StillArgs) -> Result<()> {
    let (out, format) = still_target(&a)?;
    let trace_gpu = acquire_trace(a.trace.trace, None)?;
    let scene = load_scene(&a.scene.scene)?;
    let path = load_camera_path(a.scene.camera_path.as_deref())?;
    let Size(w, h) = a.size;
    let tracer =
        Tracer::new(Arc::new(scene), w, h, TraceOptions::from(&a.quality)).with_camera_path(path);
    let t0 = Instant::now();
    let img = match trace_gpu {
        Some(ctx) => still_on_gpu(ctx, &tracer, &a)?,
        None => {
            let bar = Meter::new("rendering", "rows");
            bar.set_total(h as u64);
            let img = still::render(&tracer, a.time, a.spp, a.quality.seed, &|rows| {
                bar.set_position(rows as u64)
            });
            bar.finish();
            img
        }
    };
    img.save(&out, format)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!(
        "wrote {} ({}x{}, {} spp, t = {} s) in {:.2} s",
        out.display(),
        w,
        h,
        a.spp,
        a.time,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `still`'s image traced on the GPU of `ctx` (`--trace gpu`): the same stratified
/// samples as on the CPU, in batches of whole rows.
#[cfg(feature = "gpu")]
fn still_on_gpu(
    ctx: Arc<GpuContext>,
    tracer: &Tracer,
    a: &args::StillArgs,
) -> Result<frameless::image::Image> {
    let mut gpu = frameless::trace::gpu::GpuTracer::new(ctx, tracer)
        .context("--trace gpu (--trace cpu traces on the CPU)")?;
    still::render_gpu(&mut gpu, tracer, a.time, a.spp, a.quality.seed)
        .context("--trace gpu (--trace cpu traces on the CPU)")
}

#[cfg(not(feature = "gpu"))]
fn still_on_gpu(
    ctx: Arc<GpuContext>,
    _tracer: &Tracer,
    _a: &args::StillArgs,
) -> Result<frameless::image::Image> {
    match *ctx {}
}

/// The file `still` writes and its format: `--format` and `--out` must agree where
/// both are given; either alone decides both, and with neither it is `still.png`.
fn still_target(a: &args::StillArgs) -> Result<(std::path::PathBuf, ImageFormat)> {
    let asked = a.format.map(image_format);
    let out = match (&a.out, asked) {
        (Some(out), _) => out.clone(),
        (None, Some(ImageFormat::Exr)) => "still.exr".into(),
        (None, _) => "still.png".into(),
    };
    let named = ImageFormat::for_output(&out)?;
    match asked {
        Some(f) if f != named => bail!(
            "--format {} but --out {} names another format: give one of them, or make \
             them agree",
            f.extension(),
            out.display()
        ),
        _ => Ok((out, named)),
    }
}

/// The library's image format of a `--format` value.
fn image_format(f: args::FrameFormat) -> ImageFormat {
    match f {
        args::FrameFormat::Png => ImageFormat::Png,
        args::FrameFormat::Exr => ImageFormat::Exr,
    }
}

/// `eval`'s `--format`, or `--exr`, its old spelling, with a note naming the new one.
fn eval_format(a: &args::EvalArgs) -> ImageFormat {
    if a.exr {
        eprintln!("note: --exr is `--format exr` now; the old flag still works");
        return ImageFormat::Exr;
    }
    image_format(a.format)
}

fn eval(a: args::EvalArgs) -> Result<()> {
    frameless::output::check_folder_target(&a.out)?;
    let mut cfg = EvalConfig::new(&a.scene.scene);
    cfg.camera_path = load_camera_path(a.scene.camera_path.as_deref())?;
    cfg.start = a.start;
    cfg.duration = a.duration;
    cfg.rates = a.rates.clone();
    cfg.methods = a.methods.clone();
    cfg.warmup = a.warmup;
    cfg.flip_every = a.flip_every as usize;
    cfg.set_groups(&a.display, &a.quality, &a.reference);
    cfg.validate()?;
    cfg.devices = acquire_devices(&a.devices)?;
    let scene = Arc::new(load_scene(&a.scene.scene)?);
    let bar = Meter::new("evaluating", "rays");
    let options = evaluation::RunOptions {
        linear_strips: eval_format(&a) == ImageFormat::Exr,
        ..evaluation::RunOptions::default()
    };
    let mut out = evaluation::run_with(scene, &cfg, &bar, options)?;
    bar.finish();
    let report = report::write_all(&mut out, &a.out)?;
    print!("{}", report::markdown(&out.summary));
    let t = &out.summary.timing;
    println!(
        "cost: ideal {:.1} s ({} cached, {} rejected), methods {:.1} s (tracing {:.1} s), metrics {:.1} s, output {:.1} s; overhead {:.1}% of the methods' evaluation",
        t.ideal_s,
        t.ideal_cache_hits,
        t.ideal_cache_rejected,
        t.methods_s,
        t.trace_s,
        t.metrics_s,
        t.output_s,
        100.0 * evaluation::overhead_fraction(t)
    );
    println!("report: {}", report.display());
    Ok(())
}

fn render(a: args::RenderArgs) -> Result<()> {
    use frameless::evaluation::sequence::{render_sequence, SequenceConfig};
    frameless::output::check_folder_target(&a.out)?;
    let mut cfg = SequenceConfig {
        scene_name: a.scene.scene.clone(),
        camera_path: load_camera_path(a.scene.camera_path.as_deref())?,
        method: a.method,
        rate: a.rate,
        start: a.start,
        duration: a.duration,
        warmup: a.warmup,
        display: a.display,
        quality: a.quality,
        format: image_format(a.format),
        devices: Devices::default(),
    };
    cfg.validate()?;
    cfg.devices = acquire_devices(&a.devices)?;
    let scene = Arc::new(load_scene(&a.scene.scene)?);
    let bar = Meter::new("rendering", "rays");
    let stats = render_sequence(scene, &cfg, &a.out, &bar)?;
    bar.finish();
    println!(
        "wrote {} frames of {} to {} ({:.1} s)",
        stats.frames,
        cfg.method,
        a.out.display(),
        stats.wall_s
    );
    Ok(())
}

fn table1(a: args::Table1Args) -> Result<()> {
    use evaluation::table1::{self, TableSummary};
    frameless::output::check_folder_target(&a.out)?;
    let kitchen = bart_kitchen(a.bart.as_deref())?;
    let animations = parse_list(&a.animations, table1::animation).context("--animations")?;
    for r in a.strip_rates.iter().flatten() {
        if !a.rates.contains(r) {
            bail!(
                "--strip-rate: {} is not one of --rate",
                frameless::clock::rate_label(*r)
            );
        }
    }
    // Validate every configuration before the first (long) run starts.
    let mut cfgs = animations
        .iter()
        .map(|anim| table1_config(&a, anim))
        .collect::<Result<Vec<_>>>()?;
    // One set of GPUs for every animation's evaluation.
    let devices = acquire_devices(&a.devices)?;
    for cfg in &mut cfgs {
        cfg.devices = devices.clone();
    }
    let scene = Arc::new(load_scene(&kitchen.to_string_lossy())?);
    let outputs = table1::Table1Output::begin(&a.out)?;
    let t0 = Instant::now();
    let mut results = Vec::new();
    let mut cost = Vec::new();
    for (anim, cfg) in animations.iter().zip(&cfgs) {
        let (result, line) = table1_animation(&a, anim, cfg, &scene, &outputs)?;
        eprintln!("{line}");
        cost.push(line);
        results.push(result);
    }
    let threads = rayon::current_num_threads();
    let cost = format!(
        "wall time {:.0} s on {threads} threads; {}",
        t0.elapsed().as_secs_f64(),
        cost.join("; ")
    );
    let table = TableSummary {
        animations: results,
    };
    let report = outputs.finish(&table, &cost)?;
    print!("{}", table1::markdown(&table));
    print!("{}", table1::targets(&table));
    println!("cost: {cost}");
    println!("report: {}", report.display());
    Ok(())
}

/// The kitchen scene file of the BART folder `--bart` (else `$FRAMELESS_BART_DIR`).
fn bart_kitchen(bart: Option<&Path>) -> Result<std::path::PathBuf> {
    let bart = match bart
        .map(Path::to_path_buf)
        .or_else(|| std::env::var_os("FRAMELESS_BART_DIR").map(Into::into))
    {
        Some(b) => b,
        None => bail!("--bart is required (the BART folder holding kitchen/kitchen.aff), or set FRAMELESS_BART_DIR"),
    };
    let kitchen = bart.join("kitchen/kitchen.aff");
    if !kitchen.is_file() {
        bail!(
            "{} not found: --bart must name the BART folder holding kitchen/kitchen.aff",
            kitchen.display()
        );
    }
    Ok(kitchen)
}

/// The evaluation of one Table 1 animation, validated.
fn table1_config(a: &args::Table1Args, anim: &evaluation::table1::Animation) -> Result<EvalConfig> {
    let camera_path = match anim.camera_path {
        _ if a.camera_path.is_some() => load_camera_path(a.camera_path.as_deref())?,
        Some(text) => Some(
            CameraPath::parse(anim.camera_path_file.unwrap_or(anim.name), text)
                .map_err(anyhow::Error::from)?,
        ),
        None => None,
    };
    let mut cfg = EvalConfig {
        scene_name: format!("kitchen ({})", anim.name),
        camera_path,
        start: anim.start,
        duration: a.duration.unwrap_or(anim.duration),
        rates: a.rates.clone(),
        methods: match &a.methods {
            Some(m) => m.clone(),
            None => evaluation::table1::METHODS.to_vec(),
        },
        warmup: a.warmup.unwrap_or(anim.warmup),
        // Table 1 is the paper's, at its refresh rate (the default).
        display: settings::DisplayGroup {
            size: a.size,
            ..Default::default()
        },
        quality: a.quality,
        reference: a.reference.clone(),
        strip_frames: Vec::new(),
        flip_every: a.flip_every as usize,
        devices: Devices::default(),
    };
    cfg.strip_frames = match a.strips {
        args::Strips::Quartiles => cfg.quartile_frames(),
        args::Strips::Middle => vec![cfg.frames() / 2],
        args::Strips::None => Vec::new(),
    };
    cfg.validate()
        .with_context(|| format!("animation {}", anim.name))?;
    Ok(cfg)
}

/// Run and write one Table 1 animation; its result and a line saying what it cost.
fn table1_animation(
    a: &args::Table1Args,
    anim: &evaluation::table1::Animation,
    cfg: &EvalConfig,
    scene: &Arc<Scene>,
    outputs: &evaluation::table1::Table1Output,
) -> Result<(evaluation::table1::AnimationResult, String)> {
    let bar = Meter::new(anim.name, "rays");
    let ta = Instant::now();
    let mut out = evaluation::run(scene.clone(), cfg, &bar)
        .with_context(|| format!("animation {}", anim.name))?;
    bar.finish();
    if let Some(keep) = &a.strip_rates {
        out.strips.retain(|s| keep.contains(&s.rate));
    }
    outputs.write_animation(anim.name, &mut out)?;
    let t = &out.summary.timing;
    let line = format!(
        "{}: {:.0} s (ideal {:.0} s, {} of {} frames from cache, {} rejected; methods {:.0} s)",
        anim.name,
        ta.elapsed().as_secs_f64(),
        t.ideal_s,
        t.ideal_cache_hits,
        cfg.frames(),
        t.ideal_cache_rejected,
        t.methods_s
    );
    let result = evaluation::table1::AnimationResult {
        name: anim.name.to_string(),
        description: anim.description.to_string(),
        camera_path: anim.camera_path_file.map(str::to_string),
        summary: out.summary,
    };
    Ok((result, line))
}

fn sampler(a: args::SamplerArgs) -> Result<()> {
    use frameless::methods::{adaptive::Adaptive, Method, MethodContext};
    frameless::output::check_folder_target(&a.out)?;
    let rate = a.rate;
    use frameless::limits;
    limits::check_duration(a.duration).map_err(|e| anyhow::anyhow!("--duration {e}"))?;
    limits::check_start(a.start, 0.0, a.duration).map_err(|e| anyhow::anyhow!("--start {e}"))?;
    limits::check_rate(rate, a.duration).map_err(|e| anyhow::anyhow!("--rate {e}"))?;
    limits::check_refresh_hz(a.display.refresh_hz)
        .map_err(|e| anyhow::anyhow!("--refresh-hz {e}"))?;
    let params = sampler_params(&a);
    let Size(w, h) = a.display.size;
    let scene = Arc::new(load_scene(&a.scene.scene)?);
    let tracer = Arc::new(
        Tracer::new(scene, w, h, TraceOptions::from(&a.quality))
            .with_camera_path(load_camera_path(a.scene.camera_path.as_deref())?),
    );
    let clock = frameless::clock::Clock {
        start: a.start,
        rate,
        first_refresh: a.start,
        refresh_hz: a.display.refresh_hz,
    };
    let ctx = MethodContext {
        tracer,
        clock,
        seed: a.quality.seed,
        ideal_spp: 1,
        ideal_cache: None,
        gpu: None,
        rays: None,
    };
    let mut m = Adaptive::new(&ctx, params)?;
    let frames = (a.duration * a.display.refresh_hz).ceil() as u64;
    let bar = Meter::new("sampling", "refreshes");
    bar.set_total(frames);
    let t0 = Instant::now();
    let mut display = frameless::image::Image::new(w, h);
    for k in 1..=frames {
        display = m
            .display(a.start + k as f64 / a.display.refresh_hz)
            .image
            .clone();
        bar.inc(1);
    }
    bar.finish();
    let wall = t0.elapsed().as_secs_f64();
    let end = a.start + frames as f64 / a.display.refresh_hz;
    let run = frameless::methods::adaptive::outputs::SamplerRun {
        scene: &a.scene.scene,
        rate: a.rate,
        start: a.start,
        end,
        wall_s: wall,
    };
    let stats = frameless::methods::adaptive::outputs::write(&a.out, m.sampler(), &display, &run)?;
    println!("{}", serde_json::to_string_pretty(&stats)?);
    println!("images: {}", a.out.display());
    Ok(())
}

/// The sampler's parameters: `--preset` with the ablations asked for.
fn sampler_params(a: &args::SamplerArgs) -> frameless::methods::adaptive::SamplerParams {
    use frameless::methods::adaptive::SamplerParams;
    let mut params = match a.preset {
        args::SamplerPreset::Ours => SamplerParams::ours(),
        args::SamplerPreset::Paper => SamplerParams::paper(),
    };
    if a.no_reprojection {
        params.reprojection = false;
    }
    params.gain_control = !a.no_gain_control;
    params.occlusion_term = !a.no_occlusion_term;
    params.uniform_tiling = a.uniform_tiling;
    params
}

fn view(a: args::ViewArgs, threads: Option<u16>) -> Result<()> {
    use frameless::realtime;
    if a.headless {
        frameless::output::check_writable_folder(&a.out)?;
    }
    if let Some(p) = &a.screenshot {
        frameless::output::check_file_target(p, "png", "PNG")?;
    }
    let mut cfg = view_config(&a, threads)?;
    let mut settings = view_settings(&a, a.method)?;
    if let Some(s) = a.seconds {
        frameless::limits::check_view_seconds(s).map_err(|e| anyhow::anyhow!("--duration {e}"))?;
    }
    let Size(w, h) = a.display.size;
    settings.check_size(&cfg, w, h)?;
    let devices = realtime_devices(&a.devices, &[a.method])?;
    settings.use_gpu(devices.recon.clone());
    let scene = Arc::new(load_scene(&a.scene.scene)?);
    let tracer = Arc::new(
        Tracer::new(scene, w, h, TraceOptions::from(&a.quality))
            .with_camera_path(load_camera_path(a.scene.camera_path.as_deref())?),
    );
    cfg.rays = frameless::trace::batch::open(devices.trace, &tracer)
        .context("--trace gpu (--trace cpu traces on the CPU)")?;
    if a.headless {
        return view_headless(&a, tracer, cfg, settings);
    }
    // The other methods' settings, for the keys that switch to them.
    let mut others = Vec::new();
    for m in realtime::RtMethod::ALL {
        let mut s = view_settings(&a, m)?;
        s.use_gpu(devices.recon.clone());
        others.push(s);
    }
    let opts = realtime::ViewerOptions {
        seconds: a.seconds,
        record: a.record.clone(),
        screenshot: a.screenshot.clone(),
        visualisation: a.vis,
        others,
    };
    realtime::run_viewer(tracer, cfg, settings, opts)?;
    Ok(())
}

/// The real-time pipeline's settings from `view`'s options, checked.
fn view_config(a: &args::ViewArgs, threads: Option<u16>) -> Result<frameless::realtime::RtConfig> {
    use frameless::realtime::RtConfig;
    // `--threads N`: the pipeline's threads sized for N cores, as `live` does.
    let mut cfg = match threads {
        Some(n) => RtConfig::for_cores(a.method, n as usize),
        None => RtConfig::new(a.method),
    };
    if let Some(n) = a.sampling_threads {
        cfg.sampling_threads = n as usize;
    }
    if let Some(n) = a.recon_threads {
        cfg.recon_threads = n as usize;
    }
    cfg.view_ahead = !a.no_view_ahead;
    cfg.set_groups(&a.display, &a.quality);
    cfg.start = a.start;
    cfg.validate()?;
    Ok(cfg)
}

/// `method`'s own settings from `view`'s options (the adaptive method's from
/// `AdaptiveArgs`), checked by the library.
fn view_settings(
    a: &args::ViewArgs,
    method: frameless::realtime::RtMethod,
) -> Result<frameless::realtime::RtSettings> {
    use frameless::realtime::RtSettings;
    let mut settings = method.settings();
    if let RtSettings::Adaptive(s) = &mut settings {
        a.adaptive.apply(s);
    }
    settings.validate()?;
    Ok(settings)
}

/// `view --headless`: run the pipeline for `--duration`, write its outputs and print
/// its figures.
fn view_headless(
    a: &args::ViewArgs,
    tracer: Arc<Tracer>,
    cfg: frameless::realtime::RtConfig,
    settings: frameless::realtime::RtSettings,
) -> Result<()> {
    use frameless::realtime;
    let Some(seconds) = a.seconds else {
        bail!("--headless needs --duration N (seconds; --seconds N as before)");
    };
    if let Some(at) = a.camera_step {
        if !(at >= 0.0 && at < seconds) {
            bail!("--camera-step {at} must be within the run: [0, --duration {seconds})");
        }
    }
    let opts = realtime::HeadlessOptions {
        seconds,
        out: a.out.clone(),
        images: a.images as usize,
        scene: a.scene.scene.clone(),
        camera_step_s: a.camera_step,
    };
    let method = settings.method();
    let st = realtime::run_headless(tracer, cfg, settings, &opts)?;
    println!(
        "{}: {:.0} samples/s, {:.1} images/s displayed ({:.0} Hz refresh, {} late), reconstruction {:.1} ms, information age mean {:.0} ms (p50 {:.0}, p95 {:.0}, p99 {:.0}), {} sampling thread{}",
        method.name(),
        st.samples_per_s,
        st.display_fps,
        st.display.present_hz,
        st.display.late_refreshes,
        st.pipeline.reconstruct_ms_mean,
        st.pipeline.mean_age_s * 1e3,
        st.pipeline.age_p50_s * 1e3,
        st.pipeline.age_p95_s * 1e3,
        st.pipeline.age_p99_s * 1e3,
        st.pipeline.sampling_threads,
        if st.pipeline.sampling_threads == 1 { "" } else { "s" }
    );
    if st.pipeline.view_ahead_ms > 0.0 {
        println!(
            "a moving view traced {:.0} ms ahead, where the camera's past poses put it when shown (--no-view-ahead: where it is)",
            st.pipeline.view_ahead_ms
        );
    }
    if let Some(c) = &st.camera_step {
        let ms = |v: Option<f64>| v.map_or("not within the run".into(), |v| format!("{v:.0} ms"));
        println!(
            "camera step of {}° at {:.2} s: first image after it {}, first from the turned camera {}, half the pixels new {}{}",
            c.yaw_deg,
            c.at_s,
            ms(c.first_image_ms),
            ms(c.view_ms),
            ms(c.half_new_ms),
            c.half_new_samples
                .map_or(String::new(), |n| format!(" ({n} samples after the step)"))
        );
    }
    if let (Some(share), Some(load)) = (st.machine_share, st.load_average_before) {
        println!(
            "this run got {:.0}% of the machine's {} cores (load average before: {load:.1})",
            share * 100.0,
            st.pipeline.cores
        );
    }
    println!("wrote {}", a.out.join("stats.json").display());
    Ok(())
}

fn live(a: args::LiveArgs, threads: Option<u16>) -> Result<()> {
    use evaluation::live::{self, LiveConfig};
    frameless::output::check_folder_target(&a.out)?;
    let mut cfg = LiveConfig::new(&a.scene.scene);
    cfg.camera_path = load_camera_path(a.scene.camera_path.as_deref())?;
    cfg.start = a.start;
    cfg.seconds = a.seconds;
    cfg.warmup = a.warmup;
    cfg.set_groups(&a.display, &a.quality, &a.reference);
    if let Some(m) = a.methods {
        cfg.methods = m;
    }
    cfg.repeat = a.repeat as usize;
    if let Some(n) = threads {
        cfg.cores = n as usize;
    }
    cfg.recon_threads = a.recon_threads.map(usize::from);
    cfg.view_ahead = !a.no_view_ahead;
    cfg.adaptive = a.adaptive.clone();
    cfg.validate()?;
    cfg.devices = realtime_devices(&a.devices, &cfg.methods)?;
    // Again with the GPU: a method it cannot reconstruct for fails before any run.
    cfg.validate()?;
    let scene = Arc::new(load_scene(&a.scene.scene)?);
    let bar = Meter::new("live", "refreshes");
    let mut out = live::run(scene, &cfg, &bar)?;
    bar.finish();
    let report = live::write_all(&mut out, &a.out)?;
    print!("{}", live::markdown(&out.summary));
    println!("report: {}", report.display());
    Ok(())
}

/// Load a scene from a built-in name or a path, with a helpful error.
pub fn load_scene(arg: &str) -> Result<Scene> {
    if let Some(why) = builtin::unknown_name(arg) {
        bail!(why);
    }
    let spinner = Meter::spinner(&format!("loading {arg}"));
    let s = scene::load(arg);
    spinner.finish();
    Ok(s?)
}

/// `frameless report DIR`: an evaluation folder's report made again, or each of a
/// Table 1 folder's.
fn rewrite_report(dir: &Path) -> Result<()> {
    let summary = dir.join("summary.json");
    if summary.symlink_metadata().is_err() {
        bail!(
            "{}: not found, so {} is not an output folder of `frameless eval`, `frameless \
             table1` or `frameless live`",
            summary.display(),
            dir.display()
        );
    }
    for p in evaluation::rewrite_reports(dir)? {
        println!("report: {}", p.display());
    }
    Ok(())
}

fn load_camera_path(p: Option<&Path>) -> Result<Option<CameraPath>> {
    p.map(|p| CameraPath::load(p).map_err(anyhow::Error::from))
        .transpose()
}

/// The items of a comma-separated option, each parsed by `parse` (trimmed).
fn parse_list<T, E: std::fmt::Display>(
    list: &str,
    parse: impl Fn(&str) -> Result<T, E>,
) -> Result<Vec<T>> {
    list.split(',')
        .map(|item| parse(item.trim()).map_err(|e| anyhow::anyhow!("{e}")))
        .collect()
}
