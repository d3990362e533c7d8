//! `frameless sweep` (one shard of a sweep file's jobs) and `frameless merge` (job
//! results back into one run's outputs).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use frameless::evaluation::{
    sweep::{
        self, run::shard_jobs, JobEvent, Shard, ShardOptions, SweepError, SweepFile, SweepReport,
    },
    table1,
};

use super::progress::Meter;

/// Arguments of `frameless sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// The sweep file (TOML), e.g. assets/sweeps/example.toml.
    pub file: PathBuf,
    /// This run's share of the jobs, i/N: the jobs whose name hashes to i modulo N
    /// (0/1: all of them). Any N splits the same jobs.
    #[arg(long, default_value = "0/1")]
    pub shard: Shard,
    /// Folder of job results, one JSON file per job, created if needed; shards may
    /// share it. A valid result already there is kept, not run again.
    #[arg(long, default_value = "sweep-results")]
    pub out: PathBuf,
    /// The BART folder, for scenes the sweep names `bart:<path>`; default
    /// `$FRAMELESS_BART_DIR`.
    #[arg(long)]
    pub bart: Option<PathBuf>,
    /// Ideal-image cache [default: $FRAMELESS_CACHE or ~/.cache/frameless/ideal];
    /// shards may share one, also on a shared file system.
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Do not read or write the ideal-image cache.
    #[arg(long)]
    pub no_cache: bool,
    /// Print this shard's jobs, one per line, and run none.
    #[arg(long)]
    pub list: bool,
}

/// Arguments of `frameless merge`.
#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Folders of job results (`frameless sweep --out`), together the whole sweep.
    #[arg(required = true)]
    pub results: Vec<PathBuf>,
    /// Output folder: one folder per evaluation as `frameless eval` writes it, and
    /// summary.json, summary.md and report.html (or Table 1's outputs) beside them.
    #[arg(long, default_value = "sweep-out")]
    pub out: PathBuf,
}

pub fn sweep(a: SweepArgs) -> Result<()> {
    let file = SweepFile::load(&a.file)?;
    if a.list {
        for job in shard_jobs(&file, a.shard) {
            println!("{}", job.id());
        }
        return Ok(());
    }
    let opts = ShardOptions {
        bart_dir: a
            .bart
            .clone()
            .or_else(|| std::env::var_os("FRAMELESS_BART_DIR").map(Into::into)),
        cache_dir: (!a.no_cache).then(|| {
            a.cache_dir
                .clone()
                .unwrap_or_else(frameless::settings::default_cache_dir)
        }),
    };
    let t0 = std::time::Instant::now();
    // One meter for the shard; each job's evaluation sets its total and counts up.
    let bar = Meter::new("sweep job", "rays");
    let mut events = |e: JobEvent| match e {
        JobEvent::Start { job, index, total } => {
            bar.set_position(0);
            eprintln!("[{}/{total}] {}", index + 1, job.id());
        }
        JobEvent::Done { job, seconds } => eprintln!("{}: {seconds:.1} s", job.id()),
        JobEvent::Kept { job } => eprintln!("{}: kept (already done)", job.id()),
    };
    let run =
        sweep::run_shard(&file, a.shard, &a.out, &opts, &mut events, &bar).map_err(
            |e| match e {
                SweepError::NoBartFolder { .. } => {
                    anyhow::anyhow!("{e}: give --bart DIR or set FRAMELESS_BART_DIR")
                }
                e => e.into(),
            },
        )?;
    bar.finish();
    println!(
        "shard {} of sweep {}: {} jobs, {} run, {} kept, {:.1} s; results in {}",
        a.shard,
        file.sweep.name,
        run.jobs,
        run.ran,
        run.kept,
        t0.elapsed().as_secs_f64(),
        a.out.display()
    );
    Ok(())
}

pub fn merge(a: MergeArgs) -> Result<()> {
    frameless::output::check_folder_target(&a.out)?;
    let mut merged = sweep::merge(&a.results)?;
    let report = sweep::write_merged(&mut merged, &a.out)
        .with_context(|| format!("writing {}", a.out.display()))?;
    if merged.sweep.report == SweepReport::Table1 {
        let table = sweep::merge::table(&merged);
        print!("{}", table1::markdown(&table));
        print!("{}", table1::targets(&table));
    } else {
        print!(
            "{}",
            sweep::merge::markdown(&sweep::merge::summary(&merged))
        );
    }
    println!("cost: {}", sweep::merge::cost_line(&merged));
    println!("report: {}", report.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use frameless::evaluation::sweep::{StripFrames, Sweep, SweepReport};

    use super::super::args::{Cli, Command, Strips};
    use frameless::settings::Size;

    /// `assets/sweeps/table1.toml` runs what `frameless table1` runs by default: the
    /// same rates, size, seed, ideal samples, FLIP frequency, texture filter and strips
    /// (its animations and methods are checked against the library's table in
    /// `evaluation::sweep`).
    #[test]
    fn the_table1_sweep_has_the_table1_command_defaults() {
        let text = include_str!("../../assets/sweeps/table1.toml");
        let s = Sweep::parse(text, "table1.toml").expect("parses");
        let Command::Table1(a) = Cli::parse_from(["frameless", "table1"]).command else {
            panic!("table1 expected")
        };
        assert_eq!(s.report, SweepReport::Table1);
        assert_eq!(s.rates, a.rates);
        let Size(w, h) = a.size;
        assert_eq!(s.sizes, vec![(w, h)]);
        assert_eq!(s.seeds, vec![a.quality.seed]);
        assert_eq!(s.ideal_spp, a.reference.ideal_spp);
        assert_eq!(s.flip_every, a.flip_every);
        assert_eq!(s.texture_filter, a.quality.texture_filter);
        assert_eq!(a.strips, Strips::Quartiles);
        assert_eq!(s.strips, StripFrames::Quartiles);
        assert!(a.methods.is_none() && a.duration.is_none() && a.strip_rates.is_none());
        assert_eq!(a.animations, "interactive,bart,toycar,still");
    }
}
