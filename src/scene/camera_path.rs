//! Camera path files (SPEC §8): CSV with header
//! `t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg`, rows sorted by `t` in
//! seconds, linear interpolation between rows, clamped outside; one row is a fixed camera.
//! A path overrides the scene's camera.

use std::{fmt::Write as _, path::Path};

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
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let Some((hl, header)) = lines.next() else {
            return Err(err(name, 1, 1, "empty camera path (expected header line)"));
        };
        let header: String = header.chars().filter(|c| !c.is_whitespace()).collect();
        if header != HEADER {
            return Err(err(name, hl + 1, 1, format!("header must be `{HEADER}`")));
        }
        let mut keys: Vec<(f32, Camera)> = Vec::new();
        for (ln, line) in lines {
            let mut vals = [0f32; 11];
            let fields: Vec<&str> = line.split(',').collect();
            if fields.len() != 11 {
                return Err(err(
                    name,
                    ln + 1,
                    1,
                    format!("expected 11 comma-separated values, found {}", fields.len()),
                ));
            }
            let mut col = 1;
            for (i, f) in fields.iter().enumerate() {
                vals[i] = f
                    .trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        err(
                            name,
                            ln + 1,
                            col,
                            format!("`{}` is not a finite number", f.trim()),
                        )
                    })?;
                col += f.len() + 1;
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
                return Err(err(
                    name,
                    ln + 1,
                    col - fields[10].len() - 1,
                    "fov_y_deg must be in (0, 180)",
                ));
            }
            if (cam.at - cam.eye).length_squared() == 0.0 {
                return Err(err(name, ln + 1, 1, "eye and at coincide"));
            }
            if let Some(&p) = [cam.eye, cam.at]
                .iter()
                .find(|&&p| !super::limits::coordinate_ok(p))
            {
                return Err(err(
                    name,
                    ln + 1,
                    1,
                    super::limits::coordinate_message("eye or at", p),
                ));
            }
            // The view's frame is built from the up vector: a zero one, or one along the
            // view direction, leaves the image's horizontal axis undefined.
            let up_col = fields[..7].iter().map(|f| f.len() + 1).sum::<usize>() + 1;
            let dir = (cam.at - cam.eye).normalize();
            if cam.up.length_squared() == 0.0 || !cam.up.is_finite() {
                return Err(err(name, ln + 1, up_col, "the up vector is zero"));
            }
            if dir.cross(cam.up.normalize()).length() < 1e-4 {
                return Err(err(
                    name,
                    ln + 1,
                    up_col,
                    "the up vector is parallel to the view direction (at − eye)",
                ));
            }
            if let Some((pt, _)) = keys.last() {
                if vals[0] <= *pt {
                    return Err(err(
                        name,
                        ln + 1,
                        1,
                        format!("time {} does not increase (previous {pt})", vals[0]),
                    ));
                }
            }
            keys.push((vals[0], cam));
        }
        if keys.is_empty() {
            return Err(err(name, hl + 1, 1, "camera path has a header but no rows"));
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

    /// Serialise in the file format (what the viewer records).
    pub fn to_csv(&self) -> String {
        let mut s = String::from(HEADER);
        s.push('\n');
        for (t, c) in &self.keys {
            let _ = writeln!(
                s,
                "{t},{},{},{},{},{},{},{},{},{},{}",
                c.eye.x,
                c.eye.y,
                c.eye.z,
                c.at.x,
                c.at.y,
                c.at.z,
                c.up.x,
                c.up.y,
                c.up.z,
                c.fov_y_deg
            );
        }
        s
    }
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
    }
}
