//! A shard's run: each of its jobs evaluated and written as one result file.
//!
//! A result file is JSON and says everything the merge needs without the sweep's other
//! files: the job's identity, the sweep file's text and hash, the renderer version, the
//! scene's fingerprint, the job's per-frame rows and aggregates, its image strips (PNG,
//! base64) and its timing. Files are written atomically ([`crate::output`]), so a
//! folder of results holds only whole ones, and shards may share one folder.

use std::{
    collections::HashMap,
    path::{Path, PathBuf},
    sync::Arc,
    time::Instant,
};

use base64::Engine as _;
use serde::{Deserialize, Serialize};

use super::{Instance, JobKey, Shard, SweepError, SweepFile};
use crate::{
    evaluation::{self, FrameRow, Progress, ResultRow, Timing},
    output,
    render::cache::scene_fingerprint,
    scene::{self, Scene},
    trace::RENDERER_VERSION,
};

/// `format` of every result file.
pub const RESULT_FORMAT: &str = "frameless sweep job result";
/// Bump when a result file's content changes meaning; the merge reads only its own.
pub const RESULT_VERSION: u32 = 2;

/// One refresh's image strip of one job: the ideal image and the method's, as PNG in
/// base64.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StripImages {
    /// The rate column.
    pub rate: f64,
    /// Frame index in the window.
    pub frame: usize,
    /// The ideal image.
    pub ideal_png: String,
    /// The method's displayed image.
    pub shown_png: String,
}

/// A strip of a job, decoded: `w × h` 8-bit RGB images.
pub struct DecodedStrip {
    /// The rate column.
    pub rate: f64,
    /// Frame index in the window.
    pub frame: usize,
    /// The ideal image.
    pub ideal: Vec<u8>,
    /// The method's displayed image.
    pub shown: Vec<u8>,
}

/// One job's result file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobResult {
    /// [`RESULT_FORMAT`].
    pub format: String,
    /// [`RESULT_VERSION`].
    pub format_version: u32,
    /// The job's name ([`JobKey::id`]).
    pub job: String,
    /// The job's identity.
    pub key: JobKey,
    /// The sweep's name.
    pub sweep_name: String,
    /// [`SweepFile::hash`], hexadecimal.
    pub sweep_hash: String,
    /// The sweep file's text, from which the merge learns every job there must be.
    pub sweep_text: String,
    /// [`SweepFile::cameras_hash`], hexadecimal: with `sweep_text` it gives
    /// `sweep_hash` again ([`super::sweep_hash`]).
    pub cameras_hash: String,
    /// The tracer's [`RENDERER_VERSION`] that rendered it.
    pub renderer_version: u32,
    /// The `frameless` package version that ran it.
    pub frameless_version: String,
    /// The shard that ran it.
    pub shard: Shard,
    /// The scene's content fingerprint (the ideal-image cache's), hexadecimal.
    pub scene_fingerprint: String,
    /// Aggregates, one per rate column the job fills.
    pub results: Vec<ResultRow>,
    /// Every frame's measurements, column by column.
    pub frames: Vec<FrameRow>,
    /// Image strips.
    pub strips: Vec<StripImages>,
    /// Where the job's time went.
    pub timing: Timing,
}

impl JobResult {
    /// Read a result file; errors name the file and the place in it.
    pub fn read(path: &Path) -> Result<JobResult, SweepError> {
        let text = crate::limits::read_text(path, crate::limits::MAX_DATA_FILE_BYTES).map_err(
            |source| SweepError::Io {
                path: path.to_path_buf(),
                source,
            },
        )?;
        let not = |why: String| SweepError::NotAResult {
            path: path.to_path_buf(),
            why,
        };
        // The format is checked first so that another JSON file, or a result of another
        // version, is named as such rather than by its first unexpected field.
        let head: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| not(e.to_string()))?;
        match (head.get("format"), head.get("format_version")) {
            (Some(f), Some(v)) if f == RESULT_FORMAT => {
                if v != RESULT_VERSION {
                    return Err(not(format!(
                        "result format version {v}; this frameless reads version {RESULT_VERSION}"
                    )));
                }
            }
            _ => return Err(not(format!("it has no \"format\": \"{RESULT_FORMAT}\""))),
        }
        let r: JobResult = serde_json::from_str(&text).map_err(|e| not(e.to_string()))?;
        let cameras = u64::from_str_radix(&r.cameras_hash, 16).map_err(|_| {
            not(format!(
                "cameras_hash \"{}\" is not hexadecimal",
                r.cameras_hash
            ))
        })?;
        if format!("{:016x}", super::sweep_hash(&r.sweep_text, cameras)) != r.sweep_hash {
            return Err(not(
                "its sweep_text does not give its sweep file hash: the file was edited".into(),
            ));
        }
        if r.job != r.key.id() {
            return Err(not(format!(
                "its job \"{}\" does not match its key ({})",
                r.job,
                r.key.id()
            )));
        }
        Ok(r)
    }

    /// The strip images, decoded (`path` names the file in errors).
    pub fn decoded_strips(&self, path: &Path) -> Result<Vec<DecodedStrip>, SweepError> {
        let (w, h) = (self.key.width, self.key.height);
        self.strips
            .iter()
            .map(|s| {
                let img = |b64: &str| {
                    decode_png(b64, w, h).map_err(|why| SweepError::NotAResult {
                        path: path.to_path_buf(),
                        why: format!("strip at frame {}: {why}", s.frame),
                    })
                };
                Ok(DecodedStrip {
                    rate: s.rate,
                    frame: s.frame,
                    ideal: img(&s.ideal_png)?,
                    shown: img(&s.shown_png)?,
                })
            })
            .collect()
    }
}

fn encode_png(rgb: &[u8], w: u32, h: u32) -> String {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // Writing into memory fails only on a buffer of the wrong size, which
        // `to_rgb8` never makes.
        let mut writer = enc.write_header().expect("PNG header into memory");
        writer
            .write_image_data(rgb)
            .expect("PNG data of the image's own size");
    }
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// An 8-bit RGB PNG of exactly `w × h`, from base64; the size is checked before any
/// pixel buffer is allocated.
fn decode_png(b64: &str, w: u32, h: u32) -> Result<Vec<u8>, StripError> {
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(b64)
        .map_err(StripError::Base64)?;
    let dec = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = dec.read_info().map_err(StripError::NotPng)?;
    let info = reader.info();
    if (info.width, info.height) != (w, h)
        || info.color_type != png::ColorType::Rgb
        || info.bit_depth != png::BitDepth::Eight
    {
        return Err(StripError::Shape {
            found: format!(
                "{}x{} {:?} {:?}",
                info.width, info.height, info.bit_depth, info.color_type
            ),
            width: w,
            height: h,
        });
    }
    let mut buf = vec![0; w as usize * h as usize * 3];
    reader.next_frame(&mut buf).map_err(StripError::Data)?;
    Ok(buf)
}

/// Why a result file's strip image is not one the merge can use.
#[derive(Debug, thiserror::Error)]
enum StripError {
    #[error("not base64: {0}")]
    Base64(base64::DecodeError),
    #[error("not a PNG: {0}")]
    NotPng(png::DecodingError),
    #[error("a {found} PNG, not {width}x{height} 8-bit RGB")]
    Shape {
        found: String,
        width: u32,
        height: u32,
    },
    #[error("PNG data: {0}")]
    Data(png::DecodingError),
}

/// What a shard run needs besides the sweep.
#[derive(Clone, Debug, Default)]
pub struct ShardOptions {
    /// The BART folder, for scenes named `bart:<path>`.
    pub bart_dir: Option<PathBuf>,
    /// The ideal-image cache (`None`: no cache). Shards may share one, on one machine
    /// or on a shared file system: see [`crate::render::cache`].
    pub cache_dir: Option<PathBuf>,
}

/// What happened to a job, as it happens.
pub enum JobEvent<'a> {
    /// The job starts; `index` of `total` in this shard.
    Start {
        /// The job.
        job: &'a JobKey,
        /// Its place in the shard, from 0.
        index: usize,
        /// Jobs in the shard.
        total: usize,
    },
    /// The job is written.
    Done {
        /// The job.
        job: &'a JobKey,
        /// Wall-clock seconds it took.
        seconds: f64,
    },
    /// A valid result of the job was already there; it is not run again.
    Kept {
        /// The job.
        job: &'a JobKey,
    },
}

/// What a shard run did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ShardRun {
    /// Jobs in the shard.
    pub jobs: usize,
    /// Jobs run and written.
    pub ran: usize,
    /// Jobs whose valid results were already there.
    pub kept: usize,
}

/// The result file of `job` in `out`.
pub fn result_path(out: &Path, job: &JobKey) -> PathBuf {
    out.join(format!("{}.json", job.id()))
}

/// The jobs of `shard`, in the sweep's order.
pub fn shard_jobs(file: &SweepFile, shard: Shard) -> Vec<JobKey> {
    shard_instance_jobs(file, shard)
        .into_iter()
        .map(|(_, j)| j)
        .collect()
}

/// [`shard_jobs`] with the instance each job belongs to.
fn shard_instance_jobs(file: &SweepFile, shard: Shard) -> Vec<(Instance, JobKey)> {
    let sweep = &file.sweep;
    sweep
        .instances()
        .into_iter()
        .flat_map(|inst| {
            let jobs = sweep.instance_jobs(&inst);
            jobs.into_iter()
                .filter(|j| shard.owns(j))
                .map(move |j| (inst, j))
        })
        .collect()
}

/// Run `shard`'s jobs of the sweep, writing one result file per job into `out`
/// (created if needed; other files there are left alone). A job whose valid result
/// (same job, sweep hash and renderer version) is already in `out` is kept, not run
/// again, so a shard that was stopped picks up where it was.
pub fn run_shard(
    file: &SweepFile,
    shard: Shard,
    out: &Path,
    opts: &ShardOptions,
    events: &mut dyn FnMut(JobEvent),
    progress: &dyn Progress,
) -> Result<ShardRun, SweepError> {
    output::check_writable_folder(out)?;
    std::fs::create_dir_all(out).map_err(|source| SweepError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let sweep = &file.sweep;
    let hash = format!("{:016x}", file.hash);
    let jobs = shard_instance_jobs(file, shard);
    let mut run = ShardRun {
        jobs: jobs.len(),
        ..Default::default()
    };
    // Every scene this shard needs is found before the first job, which may be long.
    let mut sources: HashMap<usize, String> = HashMap::new();
    for (inst, _) in &jobs {
        if let std::collections::hash_map::Entry::Vacant(v) = sources.entry(inst.evaluation) {
            v.insert(file.scene_source(inst.evaluation, opts.bart_dir.as_deref())?);
        }
    }
    let mut scenes: HashMap<String, (Arc<Scene>, String)> = HashMap::new();
    for (index, (inst, job)) in jobs.iter().enumerate() {
        let path = result_path(out, job);
        if let Ok(r) = JobResult::read(&path) {
            if r.key == *job && r.sweep_hash == hash && r.renderer_version == RENDERER_VERSION {
                run.kept += 1;
                events(JobEvent::Kept { job });
                continue;
            }
        }
        events(JobEvent::Start {
            job,
            index,
            total: jobs.len(),
        });
        let t0 = Instant::now();
        let e = &sweep.evaluations[inst.evaluation];
        let src = &sources[&inst.evaluation];
        if !scenes.contains_key(src) {
            let scene = scene::load(src).map_err(|err| SweepError::Scene {
                evaluation: e.name.clone(),
                scene: e.scene.clone(),
                why: err.to_string(),
            })?;
            let fingerprint = format!("{:016x}", scene_fingerprint(&scene));
            scenes.insert(src.clone(), (Arc::new(scene), fingerprint));
        }
        let result = run_job(file, shard, opts, (inst, job), &scenes[src], progress)?;
        // Numbers and strings always serialise.
        let json = serde_json::to_string(&result).expect("job result serialises");
        output::write_atomic(&path, json.as_bytes())
            .map_err(|source| SweepError::Io { path, source })?;
        run.ran += 1;
        events(JobEvent::Done {
            job,
            seconds: t0.elapsed().as_secs_f64(),
        });
    }
    Ok(run)
}

/// Run one job of the shard on its loaded scene; its result, to be written.
fn run_job(
    file: &SweepFile,
    shard: Shard,
    opts: &ShardOptions,
    (inst, job): (&Instance, &JobKey),
    (scene, fingerprint): &(Arc<Scene>, String),
    progress: &dyn Progress,
) -> Result<JobResult, SweepError> {
    let sweep = &file.sweep;
    let cfg = sweep.job_config(
        inst,
        job,
        file.camera_paths[inst.evaluation].clone(),
        opts.cache_dir.clone(),
    );
    // Shards that reach this evaluation together render different refreshes'
    // ideal images first, and read the others' from a shared cache.
    let first_ideal = shard.index as usize * cfg.frames() / shard.count as usize;
    let options = evaluation::RunOptions {
        first_ideal,
        ..evaluation::RunOptions::default()
    };
    let out_job =
        evaluation::run_with(scene.clone(), &cfg, progress, options).map_err(|source| {
            SweepError::Job {
                job: job.id(),
                source: Box::new(source),
            }
        })?;
    let (w, h) = cfg.size();
    let strips = out_job
        .strips
        .iter()
        .map(|s| StripImages {
            rate: s.rate,
            frame: s.frame,
            ideal_png: encode_png(&s.ideal, w, h),
            // A job runs one method.
            shown_png: encode_png(&s.shown[0].1, w, h),
        })
        .collect();
    Ok(JobResult {
        format: RESULT_FORMAT.into(),
        format_version: RESULT_VERSION,
        job: job.id(),
        key: job.clone(),
        sweep_name: sweep.name.clone(),
        sweep_hash: format!("{:016x}", file.hash),
        cameras_hash: format!("{:016x}", file.cameras_hash),
        sweep_text: file.text.clone(),
        renderer_version: RENDERER_VERSION,
        frameless_version: env!("CARGO_PKG_VERSION").into(),
        shard,
        scene_fingerprint: fingerprint.clone(),
        results: out_job.summary.results,
        frames: out_job.frames,
        strips,
        timing: out_job.summary.timing,
    })
}
