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
}

/// The folder's `vdp.json`: `None` when there is none, else the scores or why they
/// could not be read.
pub fn read(dir: &Path) -> Option<Result<VideoScores, String>> {
    let path = dir.join(FILE);
    if !path.is_file() {
        return None;
    }
    let text = match limits::read_text(&path, limits::MAX_DATA_FILE_BYTES) {
        Ok(t) => t,
        Err(e) => return Some(Err(e.to_string())),
    };
    Some(
        serde_json::from_str::<VideoScores>(&text)
            .map_err(|e| e.to_string())
            // 10 is no visible difference, the most a JOD can be; a video far worse than
            // its reference scores below 0.
            .and_then(|v| {
                match v
                    .results
                    .iter()
                    .find(|r| !(r.jod.is_finite() && r.jod <= 10.0 + 1e-3))
                {
                    Some(r) => Err(format!(
                        "{} at {}: JOD {} is not a finite value of at most 10",
                        r.method, r.rate, r.jod
                    )),
                    None => Ok(v),
                }
            }),
    )
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
        assert!(read(&d).unwrap().is_err());
        std::fs::write(
            d.join(FILE),
            r#"{"metric":"ColorVideoVDP","version":"0.5.7","display":"standard_fhd",
               "results":[{"method":"adaptive","rate":400000.0,"jod":11.5}]}"#,
        )
        .unwrap();
        let why = read(&d).unwrap().unwrap_err();
        assert!(why.contains("at most 10"), "{why}");
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
