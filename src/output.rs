//! Outputs that are never seen half-written.
//!
//! A file is written beside its final name, under a temporary name unique to this
//! process and write, and renamed over the final name when complete: a reader sees the
//! old file or the new one, never a truncated one, and two writers never share a
//! temporary file. A folder of outputs is built the same way in a temporary sibling
//! folder and swapped in when every file is written, so a folder never holds files of
//! two runs. Temporary names say what they are (`<name>.partial-<pid>-<n>`), and the
//! next run beside them removes those whose process has died.
//!
//! This guards against a process that stops (killed, out of disk, a failed write), not
//! against a power cut: nothing is flushed to the device before the rename.

use std::{
    fs::{self, File},
    io::{self, BufWriter, Write},
    path::{Path, PathBuf},
    sync::atomic::{AtomicU64, Ordering},
};

/// Marks a temporary file or folder still being written.
const PARTIAL: &str = ".partial-";
/// Marks a previous output folder moved aside while the new one takes its name.
const OLD: &str = ".old-";
/// Marks the entry a writability check creates and removes.
const PROBE: &str = ".probe-";
/// A file in every committed output folder: replacing a folder deletes what was in it,
/// so only folders that say they are outputs are replaced.
pub const MARKER: &str = ".frameless-output";
/// Files that mark output folders written before [`MARKER`] existed.
const EARLIER_MARKERS: [&str; 2] = ["summary.json", "stats.json"];
/// Why a folder is not replaced.
const NOT_AN_OUTPUT: &str = "exists and is not an output folder (it is not empty and has no \
                             .frameless-output, summary.json or stats.json); outputs replace \
                             their folder whole, so name a new or empty folder";

/// Why an output cannot be written where it was asked for.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The place cannot be written (its folder cannot be created, or nothing can be
    /// created in it).
    #[error("cannot write {}: {reason}", path.display())]
    Unwritable {
        /// The output asked for.
        path: PathBuf,
        /// What the operating system said (part of the message, so not also a source,
        /// which would print it twice in an error chain).
        reason: io::Error,
    },
    /// The output would replace something of the wrong kind.
    #[error("{}: {why}", path.display())]
    WrongKind {
        /// The output asked for.
        path: PathBuf,
        /// What is there and what was expected.
        why: &'static str,
    },
    /// The output folder is, holds or lies inside a file or folder the command reads.
    #[error("{}: the output folder {how} the input {}; writing it would replace what is read", path.display(), input.display())]
    Overlaps {
        /// The output asked for.
        path: PathBuf,
        /// The input it overlaps.
        input: PathBuf,
        /// `is`, `holds` or `lies inside`.
        how: &'static str,
    },
    /// A file's name does not end in the extension of the format written.
    #[error("{}: {found}; the file is written as {expected}, so its name must end in .{extension}", path.display())]
    Extension {
        /// The output asked for.
        path: PathBuf,
        /// The extension found, described (`extension .jpg`, `no extension`).
        found: String,
        /// The format written (`PNG`).
        expected: &'static str,
        /// The extension required, lowercase, without the dot.
        extension: &'static str,
    },
    /// A file's name ends in none of the extensions of the formats it can be written as.
    #[error("{}: {found}; the format is chosen by the name, which must end in {choices}", path.display())]
    Extensions {
        /// The output asked for.
        path: PathBuf,
        /// The extension found, described (`extension .jpg`, `no extension`).
        found: String,
        /// The extensions accepted and their formats, in words.
        choices: String,
    },
}

/// `<path><marker><pid>-<n>`: the process id and a process-wide counter keep the name
/// unique among concurrent writers (other processes, other threads).
fn sibling(path: &Path, marker: &str) -> io::Result<PathBuf> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let Some(name) = path.file_name() else {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "names no file or folder of its own (such as `.` or `..`)",
        ));
    };
    let mut name = name.to_os_string();
    name.push(format!(
        "{marker}{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    Ok(path.with_file_name(name))
}

/// The folder holding `path` (`.` for a bare relative name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Write a file through `write`, atomically: into a unique temporary sibling that is
/// renamed over `path` once `write` succeeds, and removed if anything fails.
pub fn write_with(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    write_seekable(path, |w| write(w))
}

/// As [`write_with`], for writers that also seek (formats whose offset tables are
/// filled in after the data, such as OpenEXR).
pub fn write_seekable(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    if path.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a folder, not a file",
        ));
    }
    write_through(&sibling(path, PARTIAL)?, path, write)
}

/// [`write_with`] through the temporary file `tmp`, which must not exist.
fn write_through(
    tmp: &Path,
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    // A name that exists is another writer's: process ids repeat across machines that
    // share a folder (every container's first process may be pid 1), so it is left
    // alone, and only this write fails.
    let file = File::create_new(tmp)?;
    let result = (|| {
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        // Flushing here, not on drop, is what surfaces a full disk as an error.
        w.into_inner().map_err(io::IntoInnerError::into_error)?;
        fs::rename(tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(tmp);
    }
    result
}

/// Write `bytes` to `path` atomically (see [`write_with`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_with(path, |w| w.write_all(bytes))
}

/// Check that `path` ends in `.extension` (any case), the format a writer produces.
pub fn require_extension(
    path: &Path,
    extension: &'static str,
    format: &'static str,
) -> Result<(), OutputError> {
    match path.extension() {
        Some(e) if e.eq_ignore_ascii_case(extension) => Ok(()),
        _ => Err(OutputError::Extension {
            path: path.to_path_buf(),
            found: describe_extension(path),
            expected: format,
            extension,
        }),
    }
}

/// Check, before any work, that the file `path` can be written in one of `formats`
/// (`(extension, format)` pairs), chosen by its extension (any case); returns the
/// extension chosen.
pub fn check_file_target_of(
    path: &Path,
    formats: &[(&'static str, &'static str)],
) -> Result<&'static str, OutputError> {
    let chosen = path.extension().and_then(|e| {
        formats
            .iter()
            .find(|(x, _)| e.eq_ignore_ascii_case(x))
            .map(|(x, f)| (*x, *f))
    });
    match chosen {
        Some((extension, format)) => check_file_target(path, extension, format).map(|()| extension),
        None => Err(OutputError::Extensions {
            path: path.to_path_buf(),
            found: describe_extension(path),
            choices: formats
                .iter()
                .map(|(x, f)| format!(".{x} ({f})"))
                .collect::<Vec<_>>()
                .join(" or "),
        }),
    }
}

fn describe_extension(path: &Path) -> String {
    match path.extension() {
        Some(e) => format!("extension .{}", e.to_string_lossy()),
        None => "no extension".into(),
    }
}

/// Check, before any work, that an output folder can be written at `path` and may be
/// replaced whole (see [`OutputDir`]): what is there is absent, an empty folder or an
/// earlier output; creates the parent folder if needed, then creates and removes a
/// probe beside `path`. Nothing is left at `path` itself.
pub fn check_folder_target(path: &Path) -> Result<(), OutputError> {
    check_writable_folder(path)?;
    if !replaceable(path) {
        return Err(OutputError::WrongKind {
            path: path.to_path_buf(),
            why: NOT_AN_OUTPUT,
        });
    }
    Ok(())
}

/// Check that the output folder `out` is not one of `inputs` (files or folders), does
/// not hold one and does not lie inside one (compared as absolute paths with links resolved, as far as
/// they exist): an output folder is replaced whole.
pub fn check_apart(out: &Path, inputs: &[PathBuf]) -> Result<(), OutputError> {
    let o = resolved(out);
    for input in inputs {
        let i = resolved(input);
        let how = if o == i {
            "is"
        } else if i.starts_with(&o) {
            "holds"
        } else if o.starts_with(&i) {
            "lies inside"
        } else {
            continue;
        };
        return Err(OutputError::Overlaps {
            path: out.to_path_buf(),
            input: input.clone(),
            how,
        });
    }
    Ok(())
}

/// `path` made absolute, with the links of its longest existing ancestor resolved and
/// the rest appended (`..` in the rest taken lexically).
fn resolved(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut existing = abs.as_path();
    let mut rest = Vec::new();
    while fs::canonicalize(existing).is_err() {
        match (existing.parent(), existing.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                existing = parent;
            }
            _ => break,
        }
    }
    let mut p = fs::canonicalize(existing).unwrap_or_else(|_| existing.to_path_buf());
    for name in rest.into_iter().rev() {
        if name == ".." {
            p.pop();
        } else if name != "." {
            p.push(name);
        }
    }
    p
}

/// As [`check_folder_target`], for outputs written into the folder file by file
/// rather than replacing it: only that the folder can be created and written beside.
pub fn check_writable_folder(path: &Path) -> Result<(), OutputError> {
    if path.exists() && !path.is_dir() {
        return Err(OutputError::WrongKind {
            path: path.to_path_buf(),
            why: "exists and is not a folder (an output folder goes here)",
        });
    }
    probe(path, |p| {
        fs::create_dir(p)?;
        fs::remove_dir(p)
    })
}

/// Whether the folder `path` may be replaced whole: it is absent, empty, or an output
/// (marked, or holding the summary an earlier version wrote).
fn replaceable(path: &Path) -> bool {
    let Ok(mut entries) = fs::read_dir(path) else {
        return !path.exists();
    };
    entries.next().is_none()
        || std::iter::once(MARKER)
            .chain(EARLIER_MARKERS)
            .any(|m| path.join(m).is_file())
}

/// Check, before any work, that the file `path` can be written as `format` (named
/// `.extension`): the extension, that `path` is not a folder, and a probe file beside it.
pub fn check_file_target(
    path: &Path,
    extension: &'static str,
    format: &'static str,
) -> Result<(), OutputError> {
    if path.is_dir() {
        return Err(OutputError::WrongKind {
            path: path.to_path_buf(),
            why: "is a folder (a file goes here)",
        });
    }
    require_extension(path, extension, format)?;
    probe(path, |p| {
        File::create_new(p)?;
        fs::remove_file(p)
    })
}

fn probe(
    path: &Path,
    make_and_remove: impl Fn(&Path) -> io::Result<()>,
) -> Result<(), OutputError> {
    let unwritable = |reason| OutputError::Unwritable {
        path: path.to_path_buf(),
        reason,
    };
    let parent = parent_of(path);
    fs::create_dir_all(parent).map_err(|e| {
        // The OS says only "File exists" when a file sits where a folder must go.
        match parent.ancestors().find(|a| a.is_file()) {
            Some(file) => unwritable(io::Error::new(
                io::ErrorKind::NotADirectory,
                format!("{} is a file, not a folder", file.display()),
            )),
            None => unwritable(e),
        }
    })?;
    let p = sibling(path, PROBE).map_err(unwritable)?;
    make_and_remove(&p).map_err(unwritable)
}

/// An output folder under construction: files go into [`OutputDir::path`], a
/// temporary sibling of the target, and [`OutputDir::commit`] puts the finished folder
/// in the target's place. Dropped without a commit, the temporary folder is removed and
/// the target is untouched.
#[derive(Debug)]
pub struct OutputDir {
    target: PathBuf,
    staging: PathBuf,
    committed: bool,
}

impl OutputDir {
    /// Start a folder that will replace `target`. Leftovers of dead runs beside it are
    /// cleaned first (see [`recover_stale`]).
    pub fn begin(target: &Path) -> io::Result<Self> {
        fs::create_dir_all(parent_of(target))?;
        recover_stale(target);
        if target.exists() && !target.is_dir() {
            return Err(io::Error::new(
                io::ErrorKind::AlreadyExists,
                "exists and is not a folder",
            ));
        }
        if !replaceable(target) {
            return Err(io::Error::new(io::ErrorKind::AlreadyExists, NOT_AN_OUTPUT));
        }
        let staging = sibling(target, PARTIAL)?;
        fs::create_dir(&staging)?;
        fs::write(
            staging.join(MARKER),
            "This folder is the output of one frameless run; the next run writing here \
             replaces it whole.\n",
        )?;
        Ok(Self {
            target: target.to_path_buf(),
            staging,
            committed: false,
        })
    }

    /// The folder to write into.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The folder this one will replace.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Put the finished folder in the target's place and delete the previous one.
    ///
    /// A folder cannot be renamed over a non-empty folder, so the previous one is first
    /// renamed aside: between the two renames the target is briefly absent, never
    /// mixed, and a run killed right there is repaired by the next [`OutputDir::begin`].
    pub fn commit(mut self) -> io::Result<PathBuf> {
        let old = match fs::symlink_metadata(&self.target) {
            Ok(_) => {
                let old = sibling(&self.target, OLD)?;
                fs::rename(&self.target, &old)?;
                Some(old)
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => None,
            Err(e) => return Err(e),
        };
        if let Err(e) = fs::rename(&self.staging, &self.target) {
            // A failed commit leaves the previous run where it was.
            if let Some(old) = &old {
                let _ = fs::rename(old, &self.target);
            }
            return Err(e);
        }
        self.committed = true;
        if let Some(old) = old {
            // The new run is in place; a previous run that cannot be deleted stays under
            // a name that says what it is, and the next run retries.
            let _ = fs::remove_dir_all(&old);
        }
        Ok(self.target.clone())
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.staging);
        }
    }
}

/// Whether process `pid` is running, where the system can tell (Linux's `/proc`);
/// `None` elsewhere, and leftovers are then kept rather than risk deleting a live
/// run's work.
fn process_alive(pid: u32) -> Option<bool> {
    let proc = Path::new("/proc");
    proc.join("self")
        .exists()
        .then(|| proc.join(pid.to_string()).exists())
}

/// Clean what dead runs left beside `target`: temporary folders and files
/// (`.partial-`) are deleted; a previous output moved aside (`.old-`) by a run killed
/// mid-commit is moved back when the target is missing (it is a complete run), else
/// deleted. Entries of live processes are left alone. Best effort: a leftover that
/// cannot be removed keeps its telling name.
pub fn recover_stale(target: &Path) {
    let Some(name) = target.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return;
    };
    let Ok(entries) = fs::read_dir(parent_of(target)) else {
        return;
    };
    let me = std::process::id();
    for entry in entries.flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = file_name.strip_prefix(name.as_str()) else {
            continue;
        };
        let (is_old, tag) = if let Some(tag) = rest.strip_prefix(PARTIAL) {
            (false, tag)
        } else if let Some(tag) = rest.strip_prefix(OLD) {
            (true, tag)
        } else {
            continue;
        };
        let Some(pid) = tag
            .split_once('-')
            .and_then(|(pid, n)| n.parse::<u64>().is_ok().then_some(pid))
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if pid == me || process_alive(pid) != Some(false) {
            continue;
        }
        let path = entry.path();
        if is_old && fs::symlink_metadata(target).is_err() && fs::rename(&path, target).is_ok() {
            continue;
        }
        let _ = if path.is_dir() {
            fs::remove_dir_all(&path)
        } else {
            fs::remove_file(&path)
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("frameless-output-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).expect("scratch folder");
        d
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .expect("readable")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    /// Writers on two machines sharing a folder may draw the same temporary name: the
    /// second fails and leaves the first's temporary, and its write, alone.
    #[test]
    fn a_temporary_name_in_use_is_not_taken_over() {
        let d = scratch("taken");
        let (p, tmp) = (d.join("entry.png"), d.join("entry.png.partial-1-0"));
        fs::write(&tmp, b"another writer's half").expect("writes");
        let e = write_through(&tmp, &p, |w| w.write_all(b"mine")).expect_err("name in use");
        assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
        assert_eq!(
            fs::read(&tmp).expect("still there"),
            b"another writer's half"
        );
        assert!(!p.exists());
        fs::rename(&tmp, &p).expect("the other writer finishes");
        write_through(&tmp, &p, |w| w.write_all(b"mine")).expect("the name is free again");
        assert_eq!(fs::read(&p).expect("written"), b"mine");
        assert_eq!(names(&d), ["entry.png"]);
    }

    #[test]
    fn a_failed_write_leaves_neither_a_temporary_nor_a_changed_file() {
        let d = scratch("file");
        let p = d.join("a.txt");
        write_atomic(&p, b"old").expect("writes");
        let e = write_with(&p, |w| {
            w.write_all(b"half")?;
            Err(io::Error::other("disk full"))
        });
        assert!(e.is_err());
        assert_eq!(fs::read(&p).expect("readable"), b"old");
        assert_eq!(names(&d), ["a.txt"]);
        // A folder in the file's place is an error, and nothing is left beside it.
        fs::create_dir(d.join("b.txt")).expect("folder");
        let e = write_atomic(&d.join("b.txt"), b"x").expect_err("a folder");
        assert_eq!(e.kind(), io::ErrorKind::IsADirectory);
        assert_eq!(names(&d), ["a.txt", "b.txt"]);
        let _ = fs::remove_dir_all(&d);
    }

    #[test]
    fn temporary_names_are_unique_per_write() {
        let p = Path::new("x/out.png");
        let (a, b) = (sibling(p, PARTIAL).unwrap(), sibling(p, PARTIAL).unwrap());
        assert_ne!(a, b);
        let me = format!("out.png.partial-{}-", std::process::id());
        assert!(a.file_name().unwrap().to_string_lossy().starts_with(&me));
    }

    #[test]
    fn a_folder_is_replaced_whole_or_not_at_all() {
        let d = scratch("dir");
        let target = d.join("out");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("stale.txt"), "previous run").unwrap();
        fs::write(target.join(MARKER), "").unwrap();
        // Abandoned: the previous run stays as it was, and nothing else is left.
        {
            let o = OutputDir::begin(&target).unwrap();
            fs::write(o.path().join("new.txt"), "new").unwrap();
        }
        assert_eq!(names(&d), ["out"]);
        assert_eq!(names(&target), [MARKER, "stale.txt"]);
        fs::remove_file(target.join(MARKER)).unwrap();
        // Not an output (no marker): never replaced, since that deletes what is in it.
        assert!(OutputDir::begin(&target).is_err());
        assert!(check_folder_target(&target).is_err());
        fs::write(target.join("summary.json"), "{}").unwrap();
        // Committed: only the new run's files, marked as an output.
        let o = OutputDir::begin(&target).unwrap();
        fs::write(o.path().join("new.txt"), "new").unwrap();
        assert_eq!(o.commit().unwrap(), target);
        assert_eq!(names(&d), ["out"]);
        assert_eq!(names(&target), [MARKER, "new.txt"]);
        // Marked, it is replaced again.
        let o = OutputDir::begin(&target).unwrap();
        o.commit().unwrap();
        assert_eq!(names(&target), [MARKER]);
        let _ = fs::remove_dir_all(&d);
    }

    #[test]
    fn leftovers_of_dead_runs_are_cleaned_and_a_moved_aside_run_restored() {
        if process_alive(1) != Some(true) {
            return; // no /proc: leftovers are deliberately kept
        }
        let d = scratch("stale");
        let target = d.join("out");
        // A pid that cannot be running: beyond Linux's largest (2^22).
        let dead = 1u32 << 30;
        fs::create_dir(d.join(format!("out.partial-{dead}-0"))).unwrap();
        fs::write(d.join(format!("out.partial-{dead}-1")), "half").unwrap();
        let old = d.join(format!("out.old-{dead}-2"));
        fs::create_dir(&old).unwrap();
        fs::write(old.join("summary.json"), "complete").unwrap();
        // Another live run's temporary folder (pid 1 always runs) is not touched.
        let live = d.join("out.partial-1-0");
        fs::create_dir(&live).unwrap();
        recover_stale(&target);
        assert_eq!(names(&d), ["out", "out.partial-1-0"]);
        assert_eq!(names(&target), ["summary.json"]);
        let _ = fs::remove_dir_all(&d);
    }

    #[test]
    fn checks_name_the_path_and_the_reason() {
        let d = scratch("check");
        let file = d.join("plain");
        fs::write(&file, "x").unwrap();
        let e = check_folder_target(&file.join("out"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("plain/out") && e.contains("plain is a file"),
            "{e}"
        );
        let e = check_folder_target(&file).unwrap_err().to_string();
        assert!(e.contains("not a folder"), "{e}");
        let e = check_file_target(&d.join("x.JPG"), "png", "PNG")
            .unwrap_err()
            .to_string();
        assert!(e.contains(".JPG") && e.contains(".png"), "{e}");
        assert!(check_file_target(&d.join("x.PNG"), "png", "PNG").is_ok());
        let e = check_file_target(&d.join("x"), "png", "PNG")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no extension"), "{e}");
        let e = check_file_target(&d, "png", "PNG").unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
        fs::create_dir(d.join("dir.png")).unwrap();
        let e = check_file_target(&d.join("dir.png"), "png", "PNG")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is a folder"), "{e}");
        assert!(check_folder_target(&d.join("new/deeper/out")).is_ok());
        assert!(!d.join("new/deeper/out").exists());
        assert_eq!(names(&d.join("new/deeper")), Vec::<String>::new());
        let _ = fs::remove_dir_all(&d);
    }
}
