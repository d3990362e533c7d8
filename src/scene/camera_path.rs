//! Camera path files: CSV with header
//! `t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg`, rows sorted by `t` in
//! seconds, linear interpolation between rows, clamped outside; one row is a fixed camera.
//! A path overrides the scene's camera.

use std::path::Path;

use glam::Vec3;

use super::{Camera, SceneError};

/// The exact header line of a camera path file.
pub const HEADER: &str = "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg";

/// A camera path: keyed views interpolated linearly in time.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    /// `(time, view)` pairs, strictly increasing in time.
    pub keys: Vec<(f32, Camera)>,
}

fn err(path: &str, line: usize, column: usize, message: impl Into<String>) -> SceneError {
    SceneError::Parse {
        file: path.into(),
        line,
        column,
        message: message.into(),
    }
}

/// One row of a camera path, `fields` as written on line `ln` of `name`: its time and
/// camera, checked (finite numbers, a field of view in (0, 180), eye and at apart and in
/// range, an up vector that defines the image's horizontal axis).
fn parse_row(name: &str, ln: usize, fields: &[&str]) -> Result<(f32, Camera), SceneError> {
    if fields.len() != 11 {
        return Err(err(
            name,
            ln,
            1,
            format!("expected 11 comma-separated values, found {}", fields.len()),
        ));
    }
    // 1-based column where field `i` starts.
    let column = |i: usize| fields[..i].iter().map(|f| f.len() + 1).sum::<usize>() + 1;
    let not_a_number = |i: usize| {
        err(
            name,
            ln,
            column(i),
            format!("`{}` is not a finite number", fields[i].trim()),
        )
    };
    let trimmed: csv::StringRecord = fields.iter().map(|f| f.trim()).collect();
    let row: PathRow = trimmed.deserialize(None).map_err(|e| {
        let i = match e.kind() {
            csv::ErrorKind::Deserialize { err, .. } => err.field().unwrap_or(0) as usize,
            _ => 0,
        };
        not_a_number(i.min(10))
    })?;
    let vals = row.values();
    if let Some(i) = vals.iter().position(|v| !v.is_finite()) {
        return Err(not_a_number(i));
    }
    let v = |i: usize| Vec3::new(vals[i], vals[i + 1], vals[i + 2]);
    let cam = Camera {
        eye: v(1),
        at: v(4),
        up: v(7),
        fov_y_deg: vals[10],
        hither: 1e-3,
    };
    if !(vals[10] > 0.0 && vals[10] < 180.0) {
        return Err(err(name, ln, column(10), "fov_y_deg must be in (0, 180)"));
    }
    if (cam.at - cam.eye).length_squared() == 0.0 {
        return Err(err(name, ln, 1, "eye and at coincide"));
    }
    if let Some(&p) = [cam.eye, cam.at]
        .iter()
        .find(|&&p| !super::limits::coordinate_ok(p))
    {
        return Err(err(
            name,
            ln,
            1,
            super::limits::coordinate_message("eye or at", p),
        ));
    }
    // The view's frame is built from the up vector: a zero one, or one along the
    // view direction, leaves the image's horizontal axis undefined.
    let up_col = column(7);
    let dir = (cam.at - cam.eye).normalize();
    if cam.up.length_squared() == 0.0 || !cam.up.is_finite() {
        return Err(err(name, ln, up_col, "the up vector is zero"));
    }
    if dir.cross(cam.up.normalize()).length() < 1e-4 {
        return Err(err(
            name,
            ln,
            up_col,
            "the up vector is parallel to the view direction (at − eye)",
        ));
    }
    Ok((vals[0], cam))
}

/// Why a row's time `written` is refused after the previous row's `previous`, both
/// quoted as the file has them: times are kept as 32-bit floats, so two that differ in
/// the file (`1e-300` and `0`) may be one time, and the rounded values would name
/// numbers the file never says.
fn not_increasing(written: &str, previous: &str) -> String {
    let differ = match (written.parse::<f64>(), previous.parse::<f64>()) {
        (Ok(a), Ok(b)) => a > b,
        _ => false,
    };
    let why = if differ {
        " (times are kept to 32-bit float precision, where the two are equal)"
    } else {
        ""
    };
    format!("time {written} does not increase (previous {previous}){why}")
}

impl CameraPath {
    /// Read a camera path file.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = crate::scene::limits::read_bounded(path).map_err(|e| SceneError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let text = String::from_utf8_lossy(&text);
        Self::parse(&path.display().to_string(), &text)
    }

    /// Parse camera path text; `name` is used in error messages.
    pub fn parse(name: &str, text: &str) -> Result<Self, SceneError> {
        // Fields are read raw (untrimmed, no header handling) so that every error can
        // name the column where the offending field starts.
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .from_reader(text.as_bytes());
        let mut records = reader.records().filter(|r| {
            // A line of blanks is a one-field record; it is skipped like an empty line.
            !matches!(r, Ok(rec) if rec.len() == 1 && rec[0].trim().is_empty())
        });
        let line_of = |rec: &csv::StringRecord| rec.position().map_or(1, |p| p.line() as usize);
        let csv_err = |e: csv::Error| {
            let line = e.position().map_or(1, |p| p.line() as usize);
            err(name, line, 1, format!("not CSV: {e}"))
        };
        let Some(header) = records.next() else {
            return Err(err(name, 1, 1, "empty camera path (expected header line)"));
        };
        let header = header.map_err(csv_err)?;
        let joined: String = header
            .iter()
            .collect::<Vec<_>>()
            .join(",")
            .chars()
            .filter(|c| !c.is_whitespace())
            .collect();
        let hl = line_of(&header);
        if joined != HEADER {
            return Err(err(name, hl, 1, format!("header must be `{HEADER}`")));
        }
        let mut keys: Vec<(f32, Camera)> = Vec::new();
        let mut previous = String::new();
        for rec in records {
            let rec = rec.map_err(csv_err)?;
            let ln = line_of(&rec);
            let fields: Vec<&str> = rec.iter().collect();
            let (t, cam) = parse_row(name, ln, &fields)?;
            let written = fields[0].trim();
            if let Some((pt, _)) = keys.last() {
                if t <= *pt {
                    return Err(err(name, ln, 1, not_increasing(written, &previous)));
                }
            }
            previous = written.to_string();
            keys.push((t, cam));
        }
        if keys.is_empty() {
            return Err(err(name, hl, 1, "camera path has a header but no rows"));
        }
        Ok(Self { keys })
    }

    /// The view at time `t`.
    pub fn at(&self, t: f32) -> Camera {
        let k = &self.keys;
        if t <= k[0].0 || k.len() == 1 {
            return k[0].1;
        }
        if t >= k[k.len() - 1].0 {
            return k[k.len() - 1].1;
        }
        let i = k.partition_point(|(kt, _)| *kt <= t);
        let (t0, a) = k[i - 1];
        let (t1, b) = k[i];
        a.lerp(&b, (t - t0) / (t1 - t0))
    }

    /// Serialise in the file format (what the viewer records). Numbers are written in
    /// Rust's shortest form that reads back exactly; the ideal-image cache keys on this
    /// text, so it must not change for the same path.
    pub fn to_csv(&self) -> String {
        let mut w = csv::WriterBuilder::new()
            .has_headers(true)
            .terminator(csv::Terminator::Any(b'\n'))
            .from_writer(Vec::new());
        for (t, c) in &self.keys {
            let row = PathRow {
                t: *t,
                eye_x: c.eye.x,
                eye_y: c.eye.y,
                eye_z: c.eye.z,
                at_x: c.at.x,
                at_y: c.at.y,
                at_z: c.at.z,
                up_x: c.up.x,
                up_y: c.up.y,
                up_z: c.up.z,
                fov_y_deg: c.fov_y_deg,
            };
            // Writing numbers into memory cannot fail.
            w.serialize(row.shortest()).expect("in-memory CSV");
        }
        let bytes = w.into_inner().expect("in-memory CSV");
        let mut s = String::from_utf8(bytes).expect("CSV of numbers is UTF-8");
        if self.keys.is_empty() {
            s = format!("{HEADER}\n");
        }
        s
    }
}

/// One row of a camera path file; the field names are the header's.
#[derive(Clone, Copy, Debug, serde::Deserialize, serde::Serialize)]
struct PathRow {
    t: f32,
    eye_x: f32,
    eye_y: f32,
    eye_z: f32,
    at_x: f32,
    at_y: f32,
    at_z: f32,
    up_x: f32,
    up_y: f32,
    up_z: f32,
    fov_y_deg: f32,
}

impl PathRow {
    fn values(&self) -> [f32; 11] {
        [
            self.t,
            self.eye_x,
            self.eye_y,
            self.eye_z,
            self.at_x,
            self.at_y,
            self.at_z,
            self.up_x,
            self.up_y,
            self.up_z,
            self.fov_y_deg,
        ]
    }

    /// The row with every number as Rust displays it (`1`, not `1.0`; no exponents).
    fn shortest(&self) -> ShortestRow {
        ShortestRow {
            t: Shortest(self.t),
            eye_x: Shortest(self.eye_x),
            eye_y: Shortest(self.eye_y),
            eye_z: Shortest(self.eye_z),
            at_x: Shortest(self.at_x),
            at_y: Shortest(self.at_y),
            at_z: Shortest(self.at_z),
            up_x: Shortest(self.up_x),
            up_y: Shortest(self.up_y),
            up_z: Shortest(self.up_z),
            fov_y_deg: Shortest(self.fov_y_deg),
        }
    }
}

/// A number written as `Display` writes it: the form the file has always had.
#[derive(Clone, Copy, Debug)]
struct Shortest(f32);

impl serde::Serialize for Shortest {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(&self.0)
    }
}

#[derive(serde::Serialize)]
struct ShortestRow {
    t: Shortest,
    eye_x: Shortest,
    eye_y: Shortest,
    eye_z: Shortest,
    at_x: Shortest,
    at_y: Shortest,
    at_z: Shortest,
    up_x: Shortest,
    up_y: Shortest,
    up_z: Shortest,
    fov_y_deg: Shortest,
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n\
                        0,0,0,0,0,0,-1,0,1,0,40\n\
                        2,2,0,0,2,0,-1,0,1,0,60\n";

    #[test]
    fn parses_and_interpolates() {
        let p = CameraPath::parse("p.csv", GOOD).unwrap();
        assert_eq!(p.keys.len(), 2);
        let c = p.at(0.5);
        assert!((c.eye.x - 0.5).abs() < 1e-6 && (c.fov_y_deg - 45.0).abs() < 1e-5);
        assert_eq!(p.at(-1.0), p.keys[0].1);
        assert_eq!(p.at(5.0), p.keys[1].1);
        let again = CameraPath::parse("p.csv", &p.to_csv()).unwrap();
        assert_eq!(again, p);
        // The ideal-image cache keys on this text: same path, same bytes as always.
        assert_eq!(p.to_csv(), GOOD);
    }

    /// A camera held between two equal keys is the same view at every moment: with
    /// a blend that changed in the last bit, the reconstructor took each refresh for a
    /// moved view and re-splatted every sample (the fence example, live).
    #[test]
    fn a_held_camera_is_the_same_view_throughout() {
        let held = "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n\
                    0,2.5,1.2,3.2,2.5,1.160011,2.2008,0,1,0,45.8366\n\
                    10,2.5,1.2,3.2,2.5,1.160011,2.2008,0,1,0,45.8366\n";
        let p = CameraPath::parse("p.csv", held).unwrap();
        let first = p.at(0.0).frame(256, 256);
        for k in 0..600 {
            let t = k as f32 / 60.0 + 1e-3 * (k % 7) as f32;
            assert!(p.at(t).frame(256, 256).same_view(&first), "moved at {t}");
        }
    }

    #[test]
    fn errors_name_line_and_column() {
        let bad = GOOD.replace("2,2,0,0", "2,2,zz,0");
        let e = CameraPath::parse("p.csv", &bad).unwrap_err().to_string();
        assert!(e.contains("p.csv:3:5"), "{e}");
        let unsorted = GOOD.replace("\n2,", "\n0,");
        assert!(CameraPath::parse("p.csv", &unsorted)
            .unwrap_err()
            .to_string()
            .contains(":3:"));
        assert!(CameraPath::parse("p.csv", "t,x\n").is_err());
        assert!(CameraPath::parse("p.csv", "").is_err());
        assert!(CameraPath::parse("p.csv", &GOOD.replace(",40", ",40,1")).is_err());
        assert!(CameraPath::parse("p.csv", &GOOD.replace(",40", ",0")).is_err());
        let e = CameraPath::parse("p.csv", &GOOD.replace(",60", ",inf"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.csv:3:") && e.contains("`inf`"), "{e}");
        // Blank lines and CRLF line ends are read; lines keep their numbers.
        let spaced = GOOD.replace('\n', "\r\n\n   \n");
        assert_eq!(
            CameraPath::parse("p.csv", &spaced).unwrap(),
            CameraPath::parse("p.csv", GOOD).unwrap()
        );
        let e = CameraPath::parse("p.csv", &spaced.replace("2,2,0,0", "2,2,zz,0"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.csv:7:5"), "{e}");
    }

    /// A time that rounds to the previous one in f32 is quoted as the file writes it,
    /// not as the rounded number the file never says.
    #[test]
    fn a_time_that_does_not_increase_is_quoted_as_written() {
        let tiny = GOOD.replace("\n2,2,", "\n1e-300,2,");
        let e = CameraPath::parse("p.csv", &tiny).unwrap_err().to_string();
        assert!(e.contains("p.csv:3:1"), "{e}");
        assert!(
            e.contains("time 1e-300 does not increase (previous 0)"),
            "{e}"
        );
        assert!(e.contains("32-bit"), "{e}");
        let same = GOOD.replace("\n2,2,", "\n0.0,2,");
        let e = CameraPath::parse("p.csv", &same).unwrap_err().to_string();
        assert!(e.contains("time 0.0 does not increase (previous 0)"), "{e}");
        assert!(!e.contains("32-bit"), "{e}");
    }
}
