//! The merge: job results from any number of folders (and shard counts) become the
//! outputs of one run of the whole sweep.
//!
//! Results are put back in the order a single run produces them (evaluations, then
//! methods, then rates), so every output that is a result (`frames.csv`, the results in
//! `summary.json`, `summary.md`, plots, strips) is the same, byte for byte, however the
//! jobs were spread. Timings are not results: each evaluation's `timing` is the sum of
//! its jobs' (each job renders or loads the ideal images itself, so ideal time and
//! cache hits add up over jobs).

use std::{
    collections::{BTreeSet, HashMap, HashSet},
    fmt::Write as _,
    path::{Path, PathBuf},
};

use serde::{Deserialize, Serialize};

use super::{run::JobResult, Instance, JobKey, Sweep, SweepError, SweepReport};
use crate::{
    evaluation::{
        report::{self, rate_label},
        table1::{AnimationResult, Table1Output, TableSummary},
        EvalConfig, EvalOutput, FrameRow, ResultRow, Strip, Summary, Timing,
    },
    methods::MethodKind,
    output::OutputDir,
};

/// A whole sweep's results, checked and in single-run order.
pub struct Merged {
    /// The sweep, as the results' copy of its file says.
    pub sweep: Sweep,
    /// Its hash, hexadecimal.
    pub sweep_hash: String,
    /// The renderer version of every result.
    pub renderer_version: u32,
    /// Result files merged.
    pub jobs: usize,
    /// The shard counts the results were run under.
    pub shard_counts: Vec<u32>,
    /// Each instance and its evaluation's outputs, as `frameless eval` makes them.
    pub instances: Vec<(Instance, EvalOutput)>,
}

/// One evaluation in the merged `summary.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SweepEvaluation {
    /// The evaluation's name.
    pub name: String,
    /// Its output folder.
    pub folder: String,
    /// What it shows.
    pub description: String,
    /// Its camera-path file, as the sweep names it.
    pub camera_path: Option<String>,
    /// Its summary, as `frameless eval` writes it.
    pub summary: Summary,
}

/// The merged `summary.json` of a sweep whose report is `evaluations`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SweepSummary {
    /// The sweep's name.
    pub sweep: String,
    /// Hash of the sweep file and its camera paths.
    pub sweep_hash: String,
    /// The renderer version of every result.
    pub renderer_version: u32,
    /// Jobs merged.
    pub jobs: usize,
    /// Every evaluation at every size and seed.
    pub evaluations: Vec<SweepEvaluation>,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> SweepError + '_ {
    move |source| SweepError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The `*.json` files of `dirs`, each folder's in name order.
fn result_files(dirs: &[PathBuf]) -> Result<Vec<PathBuf>, SweepError> {
    let mut files = Vec::new();
    for d in dirs {
        let mut here: Vec<PathBuf> = std::fs::read_dir(d)
            .map_err(io(d))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            // Temporary files of writes under way end in `.partial-…`, not `.json`.
            .filter(|p| p.extension().is_some_and(|x| x == "json") && p.is_file())
            .collect();
        here.sort();
        files.extend(here);
    }
    Ok(files)
}

/// Read every job result in `dirs` and check that together they are the whole sweep,
/// each job once, all from the same sweep file and renderer version.
pub fn merge(dirs: &[PathBuf]) -> Result<Merged, SweepError> {
    let files = result_files(dirs)?;
    if files.is_empty() {
        let names: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
        return Err(SweepError::NoResults(names.join(", ")));
    }
    let results = files
        .into_iter()
        .map(|p| JobResult::read(&p).map(|r| (p, r)))
        .collect::<Result<Vec<_>, _>>()?;
    check_same_sweep(&results)?;
    let (p0, r0) = &results[0];
    let sweep = Sweep::parse(
        &r0.sweep_text,
        &format!("the sweep file inside {}", p0.display()),
    )?;
    let (found, shard_counts) = each_job_once(&sweep, &results)?;
    let mut instances = Vec::new();
    for inst in sweep.instances() {
        let output = assemble(&sweep, &inst, &results, &found)?;
        instances.push((inst, output));
    }
    Ok(Merged {
        sweep_hash: r0.sweep_hash.clone(),
        renderer_version: r0.renderer_version,
        jobs: results.len(),
        shard_counts,
        sweep,
        instances,
    })
}

/// Check that every result comes from the first one's sweep file and renderer version.
fn check_same_sweep(results: &[(PathBuf, JobResult)]) -> Result<(), SweepError> {
    let (p0, r0) = &results[0];
    for (p, r) in &results[1..] {
        let mismatch = |what, found: String, expected: String| SweepError::Mismatch {
            what,
            path: p.clone(),
            found,
            reference: p0.clone(),
            expected,
        };
        if r.sweep_hash != r0.sweep_hash {
            return Err(mismatch(
                "sweep file hash",
                r.sweep_hash.clone(),
                r0.sweep_hash.clone(),
            ));
        }
        if r.renderer_version != r0.renderer_version {
            return Err(mismatch(
                "renderer version",
                r.renderer_version.to_string(),
                r0.renderer_version.to_string(),
            ));
        }
    }
    Ok(())
}

/// Check that `results` hold each of the sweep's jobs exactly once and nothing else;
/// each job's index in `results`, and the shard counts the results were run with.
fn each_job_once(
    sweep: &Sweep,
    results: &[(PathBuf, JobResult)],
) -> Result<(HashMap<String, usize>, Vec<u32>), SweepError> {
    let expected = sweep.jobs();
    let expected_ids: HashSet<String> = expected.iter().map(|j| j.id()).collect();
    let mut found: HashMap<String, usize> = HashMap::new();
    let (mut duplicated, mut unknown) = (Vec::new(), Vec::new());
    for (i, (p, r)) in results.iter().enumerate() {
        if !expected_ids.contains(&r.job) {
            unknown.push(format!("{} ({})", r.job, p.display()));
        } else if let Some(&j) = found.get(&r.job) {
            duplicated.push(format!(
                "{} in {} and {}",
                r.job,
                results[j].0.display(),
                p.display()
            ));
        } else {
            found.insert(r.job.clone(), i);
        }
    }
    let shard_counts: Vec<u32> = results
        .iter()
        .map(|(_, r)| r.shard.count)
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let missing: Vec<String> = expected
        .iter()
        .filter(|j| !found.contains_key(&j.id()))
        .map(|j| {
            let shards: Vec<String> = shard_counts
                .iter()
                .map(|&n| format!("{}/{n}", j.shard(n)))
                .collect();
            format!("{} (shard {})", j.id(), shards.join(", "))
        })
        .collect();
    if !(missing.is_empty() && duplicated.is_empty() && unknown.is_empty()) {
        return Err(SweepError::Incomplete {
            missing,
            duplicated,
            unknown,
            total: expected.len(),
        });
    }
    Ok((found, shard_counts))
}

/// One instance's outputs from its jobs, in the order [`crate::evaluation::run`]
/// makes them.
fn assemble(
    sweep: &Sweep,
    inst: &Instance,
    results: &[(PathBuf, JobResult)],
    found: &HashMap<String, usize>,
) -> Result<EvalOutput, SweepError> {
    let cfg = sweep.config(inst, None, None);
    let n = cfg.frames();
    let mut strips: Vec<Strip> = Vec::new();
    for &rate in &cfg.rates {
        for &k in cfg.strip_frames.iter().filter(|&&k| k < n) {
            strips.push(Strip::new(rate, k, Vec::new()));
        }
    }
    let mut ideal_from: Vec<Option<String>> = vec![None; strips.len()];
    let (mut rows, mut frames, mut timing) = (Vec::new(), Vec::new(), Timing::default());
    let mut scene: Option<(String, &str)> = None;
    for job in sweep.instance_jobs(inst) {
        let (path, r) = &results[found[&job.id()]];
        let not = |why: String| SweepError::NotAResult {
            path: path.clone(),
            why,
        };
        if r.key != job {
            return Err(not(format!(
                "its key differs from the sweep's job {}",
                job.id()
            )));
        }
        let rates = job.rate.map_or(cfg.rates.clone(), |r| vec![r]);
        check_rows(r, &job, &rates, &cfg).map_err(|e| not(e.to_string()))?;
        check_values(r, &cfg).map_err(|e| not(e.to_string()))?;
        match &scene {
            None => scene = Some((r.job.clone(), &r.scene_fingerprint)),
            Some((first, fp)) if *fp != r.scene_fingerprint => {
                return Err(SweepError::Inconsistent {
                    first: first.clone(),
                    second: r.job.clone(),
                    why: format!(
                        "evaluated different scenes (fingerprints {fp} and {}): the scene \
                         files differ between the machines that ran them",
                        r.scene_fingerprint
                    ),
                });
            }
            Some(_) => {}
        }
        rows.extend(r.results.iter().cloned());
        frames.extend(r.frames.iter().cloned());
        add_timing(&mut timing, &r.timing);
        add_strips(&mut strips, &mut ideal_from, (path, r), &job)?;
    }
    // Each strip holds the ideal image and one image per method.
    if let Some(s) = strips.iter().find(|s| s.shown.len() != cfg.methods.len()) {
        return Err(SweepError::NotAResult {
            path: results[found[&sweep.instance_jobs(inst)[0].id()]].0.clone(),
            why: format!(
                "the jobs of {} lack image strips at {} frame {}",
                sweep.folder(inst),
                rate_label(s.rate),
                s.frame
            ),
        });
    }
    let mut summary = cfg.summary(rows, timing, None);
    summary.camera_path = sweep.evaluations[inst.evaluation].camera_path.is_some();
    Ok(EvalOutput {
        summary,
        frames,
        strips,
        // Sweeps keep display-quantized strips only (no HDR strips in job results).
        linear: Vec::new(),
    })
}

/// Put the strip images of the job result `r` (read from `path`) into `strips`: its
/// method's image beside the others', and the ideal image, which every job of a strip
/// must agree on (`ideal_from` names the job each strip's ideal image came from).
fn add_strips(
    strips: &mut [Strip],
    ideal_from: &mut [Option<String>],
    (path, r): (&PathBuf, &JobResult),
    job: &JobKey,
) -> Result<(), SweepError> {
    let not = |why: String| SweepError::NotAResult {
        path: path.clone(),
        why,
    };
    for strip in r.decoded_strips(path)? {
        let (rate, frame, ideal, shown) = (strip.rate, strip.frame, strip.ideal, strip.shown);
        let Some(i) = strips
            .iter()
            .position(|s| s.rate == rate && s.frame == frame)
        else {
            return Err(not(format!(
                "a strip at {} frame {frame}, which the sweep does not make",
                rate_label(rate)
            )));
        };
        let slot = &mut strips[i];
        match &ideal_from[i] {
            None => {
                slot.ideal = ideal;
                ideal_from[i] = Some(r.job.clone());
            }
            Some(first) if slot.ideal != ideal => {
                return Err(SweepError::Inconsistent {
                    first: first.clone(),
                    second: r.job.clone(),
                    why: format!(
                        "have different ideal images at {} frame {frame}: they were \
                         rendered by different builds or from different inputs",
                        rate_label(rate)
                    ),
                });
            }
            Some(_) => {}
        }
        slot.shown.push((job.method, shown));
    }
    Ok(())
}

/// Check that a job's result rows, frame rows and strips are those of `job`: its
/// method, at its `rates`, each rate's row and each of its `n` frames once, and a strip
/// at most once per rate and frame.
fn check_rows(
    r: &JobResult,
    job: &JobKey,
    rates: &[f64],
    cfg: &EvalConfig,
) -> Result<(), NotTheJobs> {
    let (columns, n) = (rates.len(), cfg.frames());
    if r.results.len() != columns || r.frames.len() != columns * n {
        return Err(NotTheJobs::Counts {
            results: r.results.len(),
            frames: r.frames.len(),
            columns,
            job_frames: columns * n,
        });
    }
    let column = |rate: f64| rates.iter().position(|&x| x == rate);
    let mut rows = vec![false; columns];
    for row in &r.results {
        let Some(c) = column(row.rate).filter(|_| row.method == job.method) else {
            return Err(NotTheJobs::ForeignResult {
                method: row.method,
                rate: row.rate,
            });
        };
        if std::mem::replace(&mut rows[c], true) {
            return Err(NotTheJobs::TwoResults { rate: row.rate });
        }
    }
    let mut frames = vec![false; columns * n];
    for f in &r.frames {
        let Some(c) = column(f.rate).filter(|_| f.method == job.method && f.frame < n) else {
            return Err(NotTheJobs::ForeignFrame {
                method: f.method,
                rate: f.rate,
                frame: f.frame,
            });
        };
        if std::mem::replace(&mut frames[c * n + f.frame], true) {
            return Err(NotTheJobs::TwoFrames {
                rate: f.rate,
                frame: f.frame,
            });
        }
    }
    let mut strips = HashSet::new();
    for s in &r.strips {
        if column(s.rate).is_none() || !strips.insert((s.rate.to_bits(), s.frame)) {
            return Err(NotTheJobs::ForeignStrip {
                rate: s.rate,
                frame: s.frame,
            });
        }
    }
    Ok(())
}

/// Check the values of a job result whose rows [`check_rows`] found to be the job's:
/// each frame row's measurements in their ranges and its time the refresh its frame
/// index is in the job's window, and each result row the aggregate of its frame rows,
/// at the rate its method runs at for the job's key and within that rate's budget.
fn check_values(r: &JobResult, cfg: &EvalConfig) -> Result<(), NotTheJobs> {
    check_frame_values(r, cfg)?;
    for row in &r.results {
        let mut frames: Vec<FrameRow> = r
            .frames
            .iter()
            .filter(|f| f.rate == row.rate)
            .cloned()
            .collect();
        frames.sort_by_key(|f| f.frame);
        let why = row
            .disagrees_with(&frames)
            .or_else(|| over_budget(row, r.key.method, cfg));
        if let Some(why) = why {
            return Err(NotTheJobs::ResultRow {
                rate: row.rate,
                why,
            });
        }
    }
    Ok(())
}

/// Where a result row's rate or samples are not what its method may have at its rate
/// column in the run `cfg` describes.
fn over_budget(row: &ResultRow, method: MethodKind, cfg: &EvalConfig) -> Option<String> {
    let budget = method.info().budget;
    let rate = budget.effective_rate(&cfg.shape(), row.rate);
    if (row.effective_rate - rate).abs() > 1e-9 * rate.abs() {
        return Some(format!(
            "effective_rate {}, but {method} at {} runs at {rate}",
            row.effective_rate, row.rate
        ));
    }
    let last = cfg.refresh(cfg.frames() - 1);
    let most = cfg.clock(rate).samples_until(last);
    if budget.enforced() && row.samples > most {
        return Some(format!(
            "{} samples, over the {most} its rate allows by the last refresh",
            row.samples
        ));
    }
    None
}

fn check_frame_values(r: &JobResult, cfg: &EvalConfig) -> Result<(), NotTheJobs> {
    for f in &r.frames {
        let wrong = |why| NotTheJobs::FrameRow {
            rate: f.rate,
            frame: f.frame,
            why,
        };
        if let Some(why) = f.out_of_range() {
            return Err(wrong(why));
        }
        let time = cfg.refresh(f.frame);
        if (f.time - time).abs() > 1e-6 * time.abs().max(1.0) {
            return Err(wrong(format!(
                "time {} is not that frame's refresh, {time} s",
                f.time
            )));
        }
    }
    Ok(())
}

/// Why a result file's rows are not those of the job it names ([`check_rows`],
/// [`check_values`]).
#[derive(Debug, thiserror::Error)]
enum NotTheJobs {
    #[error(
        "{results} result rows and {frames} frame rows; the job has {columns} and {job_frames}"
    )]
    Counts {
        results: usize,
        frames: usize,
        columns: usize,
        job_frames: usize,
    },
    #[error("a result row of {method} at {rate}, which is not this job's")]
    ForeignResult { method: MethodKind, rate: f64 },
    #[error("two result rows at {rate}")]
    TwoResults { rate: f64 },
    #[error("a frame row of {method} at {rate} frame {frame}, which is not this job's")]
    ForeignFrame {
        method: MethodKind,
        rate: f64,
        frame: usize,
    },
    #[error("two frame rows at {rate} frame {frame}")]
    TwoFrames { rate: f64, frame: usize },
    #[error("a strip at {rate} frame {frame} that is not this job's, or is there twice")]
    ForeignStrip { rate: f64, frame: usize },
    #[error("the result row at {rate}: {why}")]
    ResultRow { rate: f64, why: String },
    #[error("the frame row at {rate} frame {frame}: {why}")]
    FrameRow {
        rate: f64,
        frame: usize,
        why: String,
    },
}

fn add_timing(sum: &mut Timing, t: &Timing) {
    sum.ideal_s += t.ideal_s;
    sum.methods_s += t.methods_s;
    sum.trace_s += t.trace_s;
    sum.metrics_s += t.metrics_s;
    sum.ideal_cache_hits += t.ideal_cache_hits;
    sum.ideal_cache_rejected += t.ideal_cache_rejected;
}

/// One line on what the merged jobs cost (their times summed).
pub fn cost_line(m: &Merged) -> String {
    let mut t = Timing::default();
    for (_, o) in &m.instances {
        add_timing(&mut t, &o.summary.timing);
    }
    let counts: Vec<String> = m.shard_counts.iter().map(|n| n.to_string()).collect();
    format!(
        "{} jobs merged (run as {} shards); their times summed: ideal images {:.1} s ({} \
         from cache, {} rejected), methods {:.1} s (tracing {:.1} s), metrics {:.1} s",
        m.jobs,
        counts.join(" and "),
        t.ideal_s,
        t.ideal_cache_hits,
        t.ideal_cache_rejected,
        t.methods_s,
        t.trace_s,
        t.metrics_s
    )
}

/// The Table 1 summary of the merged evaluations (one animation per evaluation).
pub fn table(m: &Merged) -> TableSummary {
    let animations = m
        .instances
        .iter()
        .map(|(inst, o)| {
            let e = &m.sweep.evaluations[inst.evaluation];
            AnimationResult {
                name: e.name.clone(),
                description: e.description.clone(),
                // `frameless table1` names the file alone.
                camera_path: e.camera_path.as_ref().map(|p| {
                    Path::new(p)
                        .file_name()
                        .map_or_else(|| p.clone(), |f| f.to_string_lossy().into_owned())
                }),
                summary: o.summary.clone(),
            }
        })
        .collect();
    TableSummary { animations }
}

/// The merged `summary.json` of a sweep whose report is `evaluations`.
pub fn summary(m: &Merged) -> SweepSummary {
    let evaluations = m
        .instances
        .iter()
        .map(|(inst, o)| {
            let e = &m.sweep.evaluations[inst.evaluation];
            SweepEvaluation {
                name: e.name.clone(),
                folder: m.sweep.folder(inst),
                description: e.description.clone(),
                camera_path: e.camera_path.clone(),
                summary: o.summary.clone(),
            }
        })
        .collect();
    SweepSummary {
        sweep: m.sweep.name.clone(),
        sweep_hash: m.sweep_hash.clone(),
        renderer_version: m.renderer_version,
        jobs: m.jobs,
        evaluations,
    }
}

/// Write the merged outputs as the folder `out`, replacing what was there only once
/// all are written: one folder per evaluation as `frameless eval` writes it, and
/// beside them what the sweep's `report` asks for. Returns the top report's path.
pub fn write_merged(m: &mut Merged, out: &Path) -> Result<PathBuf, SweepError> {
    let cost = cost_line(m);
    if m.sweep.report == SweepReport::Table1 {
        let outputs = Table1Output::begin(out)?;
        for (inst, o) in &mut m.instances {
            outputs.write_animation(&m.sweep.evaluations[inst.evaluation].name, o)?;
        }
        return Ok(outputs.finish(&table(m), &cost)?);
    }
    let staging = OutputDir::begin(out).map_err(io(out))?;
    for (inst, o) in &mut m.instances {
        let dir = staging.path().join(m.sweep.folder(inst));
        std::fs::create_dir(&dir).map_err(io(&dir))?;
        report::write_into(o, &dir)?;
    }
    let summary = summary(m);
    let write = |name: &str, text: &str| -> Result<(), SweepError> {
        let p = staging.path().join(name);
        std::fs::write(&p, text).map_err(io(&p))
    };
    write("summary.md", &markdown(&summary))?;
    write("report.html", &html(&summary, &cost))?;
    write(
        "summary.json",
        // Numbers and strings always serialise.
        &serde_json::to_string_pretty(&summary).expect("sweep summary serialises"),
    )?;
    staging.commit().map_err(io(out))?;
    Ok(out.join("report.html"))
}

/// Every evaluation's tables (as `frameless eval` prints them) under one title.
pub fn markdown(s: &SweepSummary) -> String {
    let mut md = format!(
        "# Sweep {}: {} jobs (sweep file {}, renderer version {})\n\n",
        s.sweep, s.jobs, s.sweep_hash, s.renderer_version
    );
    for e in &s.evaluations {
        let _ = writeln!(md, "## {}\n", e.folder);
        if !e.description.is_empty() {
            let _ = writeln!(md, "{}\n", e.description);
        }
        for line in report::markdown(&e.summary).lines() {
            // One evaluation's headings sit under the sweep's.
            if line.starts_with('#') {
                md.push_str("##");
            }
            md.push_str(line);
            md.push('\n');
        }
    }
    md
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// An index page: each evaluation's description, plots and a link to its report.
fn html(s: &SweepSummary, cost: &str) -> String {
    let mut h = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>frameless sweep: {0}</title>\
         <style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}}\
         img{{max-width:100%}}</style></head><body><h1>Sweep {0}</h1>\
         <p>{1} jobs, sweep file {2}, renderer version {3}. Tables: \
         <a href=\"summary.md\">summary.md</a>; data: <a href=\"summary.json\">summary.json</a>.</p>",
        escape(&s.sweep),
        s.jobs,
        s.sweep_hash,
        s.renderer_version
    );
    for e in &s.evaluations {
        let f = escape(&e.folder);
        let _ = write!(
            h,
            "<h2>{f}</h2><p>{}</p><p>Report: <a href=\"{f}/report.html\">{f}/report.html</a>.</p>",
            escape(&e.description)
        );
        let mut rates: Vec<f64> = Vec::new();
        for r in &e.summary.results {
            if !rates.contains(&r.rate) {
                rates.push(r.rate);
            }
        }
        for r in rates {
            let _ = write!(
                h,
                "<img src=\"{f}/rms_{0}.svg\" alt=\"RMS over time at {0}\">",
                rate_label(r)
            );
        }
    }
    let _ = write!(h, "<h2>Cost</h2><p>{}</p></body></html>", escape(cost));
    h
}
