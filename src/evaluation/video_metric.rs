//! A video metric's scores beside an evaluation: `vdp.json`, which the Python extra
//! `frameless[vdp]` (`python -m frameless.vdp FOLDER`) writes into an `eval` output
//! folder with ColorVideoVDP's JOD of each method's displayed video against the ideal
//! one. The metric needs PyTorch, so it is computed outside this crate; the report
//! shows its table when the file is there.

use std::path::Path;

use serde::Deserialize;

use crate::limits;

/// The file in an output folder.
pub const FILE: &str = "vdp.json";

/// `vdp.json`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct VideoScores {
    /// The metric's name (`ColorVideoVDP`).
    pub metric: String,
    /// Its version.
    #[serde(default)]
    pub version: String,
    /// The display model the scores assume.
    pub display: String,
    /// One score per method and rate.
    pub results: Vec<VideoRow>,
}

/// One method's score at one rate.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct VideoRow {
    /// The method, as `summary.json` names it.
    pub method: String,
    /// The rate column.
    pub rate: f64,
    /// Just-objectionable differences: 10 is no visible difference; far worse videos
    /// score below 0.
    pub jod: f64,
    /// The JOD pooled from each of the metric's visual channels alone (`jod_parts`;
    /// empty in files written before they were kept), by channel name.
    #[serde(default, rename = "jod_parts")]
    pub parts: serde_json::Map<String, serde_json::Value>,
}

impl VideoRow {
    /// [`VideoRow::parts`] as numbers; `None` where one is not a number.
    pub fn part_values(&self) -> Option<Vec<(&str, f64)>> {
        self.parts
            .iter()
            .map(|(k, v)| Some((k.as_str(), v.as_f64()?)))
            .collect()
    }
}

/// Why a `vdp.json` could not be read.
#[derive(Debug, thiserror::Error)]
pub enum VideoMetricError {
    /// The file could not be read (too large, not UTF-8, I/O).
    #[error("{}: {source}", path.display())]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not the file's JSON layout.
    #[error("{}: {source}", path.display())]
    Parse {
        /// The file.
        path: std::path::PathBuf,
        /// The JSON error.
        source: serde_json::Error,
    },
    /// A score that no ColorVideoVDP run gives.
    #[error("{}: {method} at {rate}: JOD {jod} is not a finite value of at most 10", path.display())]
    BadScore {
        /// The file.
        path: std::path::PathBuf,
        /// The method of the score.
        method: String,
        /// Its rate column.
        rate: f64,
        /// The score.
        jod: f64,
    },
}

/// The folder's `vdp.json`: `None` when there is none, else the scores or why they
/// could not be read.
pub fn read(dir: &Path) -> Option<Result<VideoScores, VideoMetricError>> {
    let path = dir.join(FILE);
    if !path.is_file() {
        return None;
    }
    Some(parse(&path))
}

fn parse(path: &Path) -> Result<VideoScores, VideoMetricError> {
    let text = limits::read_text(path, limits::MAX_DATA_FILE_BYTES).map_err(|source| {
        VideoMetricError::Read {
            path: path.to_path_buf(),
            source,
        }
    })?;
    let v: VideoScores = serde_json::from_str(&text).map_err(|source| VideoMetricError::Parse {
        path: path.to_path_buf(),
        source,
    })?;
    // 10 is no visible difference, the most a JOD can be; a video far worse than its
    // reference scores below 0.
    let valid = |j: f64| j.is_finite() && j <= 10.0 + 1e-3;
    for r in &v.results {
        let parts = r.part_values().unwrap_or_else(|| vec![("", f64::NAN)]);
        let bad = std::iter::once(r.jod)
            .chain(parts.into_iter().map(|(_, j)| j))
            .find(|&j| !valid(j));
        if let Some(jod) = bad {
            return Err(VideoMetricError::BadScore {
                path: path.to_path_buf(),
                method: r.method.clone(),
                rate: r.rate,
                jod,
            });
        }
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("frameless-vdp-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_folder_without_the_file_has_no_scores_and_a_bad_file_says_why() {
        let d = dir("read");
        assert!(read(&d).is_none());
        std::fs::write(d.join(FILE), "{\"metric\": 3}").unwrap();
        assert!(matches!(
            read(&d).unwrap(),
            Err(VideoMetricError::Parse { .. })
        ));
        std::fs::write(
            d.join(FILE),
            r#"{"metric":"ColorVideoVDP","version":"0.5.7","display":"standard_fhd",
               "results":[{"method":"adaptive","rate":400000.0,"jod":11.5}]}"#,
        )
        .unwrap();
        let why = read(&d).unwrap().unwrap_err();
        assert!(
            matches!(why, VideoMetricError::BadScore { .. })
                && why.to_string().contains("at most 10"),
            "{why}"
        );
        std::fs::write(
            d.join(FILE),
            r#"{"metric":"ColorVideoVDP","version":"0.5.7","display":"standard_fhd",
               "results":[{"method":"adaptive","rate":400000.0,"jod":9.41},
                          {"method":"point-tracking","rate":400000.0,"jod":-1.21}]}"#,
        )
        .unwrap();
        let v = read(&d).unwrap().unwrap();
        assert_eq!((v.results[0].jod, v.results[1].jod), (9.41, -1.21));
        let _ = std::fs::remove_dir_all(&d);
    }
}
