//! The run budgets: how large, long and fast a run may be. Each is checked when the
//! settings are validated, before anything is allocated or traced, and the error names
//! the limit. Scene budgets (coordinates, triangles, textures, file sizes) are in
//! [`crate::scene::limits`]. The "Input limits" table of
//! `docs/usage.md` lists them all.

/// Largest sample rate, samples per second of scene time: two orders of magnitude
/// beyond what a CPU traces, so only a typing slip reaches it.
pub const MAX_RATE: f64 = 1e8;

/// Most samples one method may trace in one run (rate × (warm-up + duration)): about
/// two hours of tracing on a small machine.
pub const MAX_SAMPLES_PER_RUN: f64 = 2e9;

/// Longest warm-up, seconds of scene time.
pub const MAX_WARMUP_S: f64 = 600.0;

/// Longest evaluated or rendered window, seconds of scene time.
pub const MAX_DURATION_S: f64 = 3600.0;

/// Largest scene time a run may start at or reach, seconds. Scene time is evaluated in
/// f32; at 1e4 s its resolution is about 1 ms, already a sixteenth of a 60 Hz refresh.
pub const MAX_SCENE_TIME_S: f64 = 1e4;

/// Most display pixels (4096 × 4096) for the methods that keep per-pixel state.
pub const MAX_DISPLAY_PIXELS: u64 = 1 << 24;

/// Longest side of an image size (`WxH`) any command or file accepts; the display
/// budget ([`MAX_DISPLAY_PIXELS`]) bounds the product further where per-pixel state is
/// kept.
pub const MAX_SIDE: u32 = 16384;

/// A setting past its budget, or a size that does not parse. The message names the
/// value and the limit; the caller names the setting.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LimitError {
    /// Not of the form `WxH`.
    #[error("`{0}` is not a size: expected WxH (e.g. 640x480) or N for NxN (e.g. 256)")]
    NotASize(String),
    /// A side of a size is not a whole number.
    #[error("`{side}` in `{size}` is not a whole number")]
    NotASide {
        /// The side as written.
        side: String,
        /// The size as written.
        size: String,
    },
    /// A side of a size is 0 or over [`MAX_SIDE`].
    #[error("size side {0} out of range 1..={MAX_SIDE}")]
    Side(u32),
    /// A buffer over [`MAX_BUFFER_BYTES`].
    #[error(
        "the {what} would take {:.1} GiB ({because}), over the {} GiB limit per buffer",
        *bytes as f64 / (1u64 << 30) as f64,
        MAX_BUFFER_BYTES >> 30
    )]
    Buffer {
        /// The buffer.
        what: String,
        /// Its size.
        bytes: u64,
        /// What makes it that large.
        because: String,
    },
    /// A display over [`MAX_DISPLAY_PIXELS`].
    #[error(
        "display {width}x{height} has {} pixels, over the limit of {MAX_DISPLAY_PIXELS} (4096x4096)",
        *width as u64 * *height as u64
    )]
    Display {
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
    },
    /// A sample rate that is not a positive number.
    #[error("{} must be a positive number of samples per second", num(*.0))]
    RateNotPositive(f64),
    /// A sample rate over [`MAX_RATE`].
    #[error("{} samples/s is over the limit of {}", num(*.0), num(MAX_RATE))]
    Rate(f64),
    /// A run tracing more than [`MAX_SAMPLES_PER_RUN`].
    #[error(
        "{} samples/s for {} s (warm-up included) is {} samples, over the limit of {} per run",
        num(*rate),
        num(*seconds),
        num(rate * seconds),
        num(MAX_SAMPLES_PER_RUN)
    )]
    Samples {
        /// Samples per second.
        rate: f64,
        /// Seconds traced.
        seconds: f64,
    },
    /// A value outside its range, both as people read them (`0 Hz`, `[1, 1000]`).
    #[error("{value} must be in {range}")]
    Range {
        /// The value with its unit.
        value: String,
        /// The range allowed.
        range: String,
    },
    /// More rates than [`MAX_RATES`].
    #[error("lists {0} rates, over the limit of {MAX_RATES}")]
    RateCount(usize),
    /// A run reaching past ±[`MAX_SCENE_TIME_S`].
    #[error(
        "{} s: the run would span scene times {} to {} s, outside ±{} s",
        num(*start),
        num(*first),
        num(*last),
        num(MAX_SCENE_TIME_S)
    )]
    SceneTime {
        /// The window's start.
        start: f64,
        /// The first scene time the run touches (start − warm-up).
        first: f64,
        /// The last (start + duration).
        last: f64,
    },
}

/// Parse an image size `WxH` (or `WXH`): two whole numbers in `1..=MAX_SIDE`; a single
/// number `N` is the square `NxN`. The one parser of sizes, for the command line and
/// sweep files alike.
pub fn parse_size(s: &str) -> Result<(u32, u32), LimitError> {
    // A single number is a square.
    let (w, h) = match s.split_once(['x', 'X']) {
        Some(wh) => wh,
        None if !s.trim().is_empty() && s.trim().bytes().all(|b| b.is_ascii_digit()) => (s, s),
        None => return Err(LimitError::NotASize(s.to_string())),
    };
    let side = |v: &str| -> Result<u32, LimitError> {
        let n: u32 = v.trim().parse().map_err(|_| LimitError::NotASide {
            side: v.to_string(),
            size: s.to_string(),
        })?;
        if n == 0 || n > MAX_SIDE {
            return Err(LimitError::Side(n));
        }
        Ok(n)
    };
    Ok((side(w)?, side(h)?))
}

/// Largest single per-run buffer (the adaptive sampler's deep buffer, a
/// reconstructor's sample ring), bytes.
pub const MAX_BUFFER_BYTES: u64 = 2 << 30;

/// Check a buffer's size against [`MAX_BUFFER_BYTES`] before it is allocated; the error
/// names the buffer, its size and what makes it that large.
pub fn check_buffer(what: &str, bytes: u64, because: &str) -> Result<(), LimitError> {
    if bytes > MAX_BUFFER_BYTES {
        return Err(LimitError::Buffer {
            what: what.to_string(),
            bytes,
            because: because.to_string(),
        });
    }
    Ok(())
}

/// Check a display size against [`MAX_DISPLAY_PIXELS`] (text, as [`check_buffer`]).
pub fn check_display(width: u32, height: u32) -> Result<(), LimitError> {
    if width as u64 * height as u64 > MAX_DISPLAY_PIXELS {
        return Err(LimitError::Display { width, height });
    }
    Ok(())
}

/// A number as people read it: plain in the usual range, in exponent form beyond
/// (`1e300`, not three hundred digits).
pub fn num(v: f64) -> String {
    if v == 0.0 || (1e-3..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Check a sample rate against [`MAX_RATE`] and, with the seconds a run traces, against
/// [`MAX_SAMPLES_PER_RUN`].
pub fn check_rate(rate: f64, seconds: f64) -> Result<(), LimitError> {
    if !(rate.is_finite() && rate > 0.0) {
        return Err(LimitError::RateNotPositive(rate));
    }
    if rate > MAX_RATE {
        return Err(LimitError::Rate(rate));
    }
    if rate * seconds > MAX_SAMPLES_PER_RUN {
        return Err(LimitError::Samples { rate, seconds });
    }
    Ok(())
}

/// Most samples per pixel of an ideal image.
pub const MAX_IDEAL_SPP: u32 = 4096;

/// Deepest reflection/refraction recursion: the tracer recurses once per bounce.
pub const MAX_DEPTH: u32 = 64;

/// Most samples per pixel `frameless still` takes: a still is one image, so it may
/// take far more than an ideal image of every refresh.
pub const MAX_STILL_SPP: u32 = 65536;

/// Most rates one run evaluates (table columns).
pub const MAX_RATES: usize = 64;

/// Most jobs (method × rate runs over all evaluations, sizes and seeds) in one sweep.
pub const MAX_SWEEP_JOBS: usize = 100_000;

/// Largest data file `report` and `merge` read (`summary.json`, `frames.csv`, a strip
/// image, a job result): a window of an hour at the fastest refresh, every method and rate, is
/// well under it.
pub const MAX_DATA_FILE_BYTES: u64 = 1 << 30;

/// Read a whole file, refusing what is not a regular file (`/dev/zero`, a FIFO, a
/// directory) or is larger than `max_bytes`, before reading it: a device would
/// otherwise be read until memory runs out.
pub fn read_file(path: &std::path::Path, max_bytes: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let not_regular =
        || std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a regular file");
    // Asked before opening too: opening a FIFO waits for a writer, which may never come.
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    let too_big = || {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("larger than the file size limit of {max_bytes} bytes"),
        )
    };
    if meta.len() > max_bytes {
        return Err(too_big());
    }
    // The length may change under us; never read past the limit either way.
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(max_bytes + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_big());
    }
    Ok(bytes)
}

/// [`read_file`] of a UTF-8 text file.
pub fn read_text(path: &std::path::Path, max_bytes: u64) -> std::io::Result<String> {
    String::from_utf8(read_file(path, max_bytes)?)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "not UTF-8 text"))
}

/// Check an ideal image's samples per pixel against [`MAX_IDEAL_SPP`].
pub fn check_ideal_spp(spp: u32) -> Result<(), LimitError> {
    if !(1..=MAX_IDEAL_SPP).contains(&spp) {
        return Err(out_of(spp.to_string(), format!("[1, {MAX_IDEAL_SPP}]")));
    }
    Ok(())
}

/// Check a reflection/refraction depth limit against [`MAX_DEPTH`].
pub fn check_max_depth(depth: u32) -> Result<(), LimitError> {
    if depth > MAX_DEPTH {
        return Err(out_of(depth.to_string(), format!("[0, {MAX_DEPTH}]")));
    }
    Ok(())
}

/// Check a run's count of rates against [`MAX_RATES`].
pub fn check_rate_count(n: usize) -> Result<(), LimitError> {
    if n > MAX_RATES {
        return Err(LimitError::RateCount(n));
    }
    Ok(())
}

/// Check a warm-up against [`MAX_WARMUP_S`].
pub fn check_warmup(warmup: f64) -> Result<(), LimitError> {
    if !(warmup.is_finite() && (0.0..=MAX_WARMUP_S).contains(&warmup)) {
        return Err(out_of(
            format!("{} s", num(warmup)),
            format!("[0, {MAX_WARMUP_S}]"),
        ));
    }
    Ok(())
}

/// Slowest display refresh rate any command accepts, Hz.
pub const MIN_REFRESH_HZ: f64 = 1.0;
/// Fastest display refresh rate, Hz.
pub const MAX_REFRESH_HZ: f64 = 1000.0;

/// Check a display refresh rate against [`MIN_REFRESH_HZ`] and [`MAX_REFRESH_HZ`].
pub fn check_refresh_hz(hz: f64) -> Result<(), LimitError> {
    if !(hz.is_finite() && (MIN_REFRESH_HZ..=MAX_REFRESH_HZ).contains(&hz)) {
        return Err(out_of(
            format!("{} Hz", num(hz)),
            format!("[{}, {}]", num(MIN_REFRESH_HZ), num(MAX_REFRESH_HZ)),
        ));
    }
    Ok(())
}

/// Longest run of the viewer or of a headless real-time run, wall seconds: a day.
pub const MAX_VIEW_SECONDS: f64 = 86_400.0;

/// Check a viewer's or headless run's length against [`MAX_VIEW_SECONDS`].
pub fn check_view_seconds(seconds: f64) -> Result<(), LimitError> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= MAX_VIEW_SECONDS) {
        return Err(out_of(
            num(seconds),
            format!("(0, {}]", num(MAX_VIEW_SECONDS)),
        ));
    }
    Ok(())
}

/// Check a window's length against [`MAX_DURATION_S`].
pub fn check_duration(duration: f64) -> Result<(), LimitError> {
    if !(duration.is_finite() && duration > 0.0 && duration <= MAX_DURATION_S) {
        return Err(out_of(
            format!("{} s", num(duration)),
            format!("(0, {MAX_DURATION_S}]"),
        ));
    }
    Ok(())
}

/// Check that a run from `start − warmup` to `start + duration` stays within
/// ±[`MAX_SCENE_TIME_S`].
pub fn check_start(start: f64, warmup: f64, duration: f64) -> Result<(), LimitError> {
    let (first, last) = (start - warmup, start + duration);
    if !(start.is_finite() && first.abs() <= MAX_SCENE_TIME_S && last.abs() <= MAX_SCENE_TIME_S) {
        return Err(LimitError::SceneTime { start, first, last });
    }
    Ok(())
}

fn out_of(value: String, range: String) -> LimitError {
    LimitError::Range { value, range }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_size_is_wxh_or_one_side_for_a_square() {
        assert_eq!(parse_size("640x480").unwrap(), (640, 480));
        assert_eq!(parse_size("64X32").unwrap(), (64, 32));
        assert_eq!(parse_size("256").unwrap(), (256, 256));
        for bad in ["", "x", "64x", "-64", "6 4", "64.5", "0"] {
            assert!(parse_size(bad).is_err(), "{bad:?}");
        }
        assert!(parse_size("abc")
            .unwrap_err()
            .to_string()
            .contains("N for NxN"));
    }

    #[test]
    fn each_budget_rejects_just_past_its_limit_and_accepts_at_it() {
        assert!(check_rate(MAX_RATE, 1.0).is_ok());
        assert!(check_rate(MAX_RATE * 1.01, 1.0).is_err());
        assert!(check_rate(1e30, 1.0)
            .unwrap_err()
            .to_string()
            .contains("limit"));
        assert!(check_rate(400e3, 1e4)
            .unwrap_err()
            .to_string()
            .contains("per run"));
        assert!(check_warmup(MAX_WARMUP_S).is_ok());
        assert!(check_warmup(1e4).is_err());
        assert!(check_start(0.0, 1.0, 1.0).is_ok());
        assert!(check_start(1e300, 1.0, 1.0)
            .unwrap_err()
            .to_string()
            .contains("1e300"));
        assert!(check_start(MAX_SCENE_TIME_S, 0.0, 1.0).is_err());
        assert!(
            check_refresh_hz(MAX_REFRESH_HZ).is_ok() && check_refresh_hz(MIN_REFRESH_HZ).is_ok()
        );
        assert!(check_refresh_hz(MAX_REFRESH_HZ * 1.001).is_err());
        assert!(check_refresh_hz(0.999).is_err() && check_refresh_hz(f64::NAN).is_err());
        assert_eq!(
            check_refresh_hz(0.0).unwrap_err().to_string(),
            "0 Hz must be in [1, 1000]"
        );
        assert!(check_duration(MAX_DURATION_S).is_ok());
        assert!(check_duration(0.0).is_err());
        assert!(check_display(4096, 4096).is_ok());
        assert!(check_display(4097, 4096).is_err());
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert_eq!(parse_size(" 16 X 9 "), Ok((16, 9)));
        // A single number is a square: 640 is 640x640.
        for bad in ["0x4", "4x0", "16385x1", "ax4", "4x-1", ""] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert!(check_ideal_spp(MAX_IDEAL_SPP).is_ok() && check_ideal_spp(1).is_ok());
        assert!(check_ideal_spp(MAX_IDEAL_SPP + 1).is_err() && check_ideal_spp(0).is_err());
        assert!(check_max_depth(MAX_DEPTH).is_ok() && check_max_depth(MAX_DEPTH + 1).is_err());
        assert!(check_rate_count(MAX_RATES).is_ok() && check_rate_count(MAX_RATES + 1).is_err());
        assert!(check_buffer("ring", MAX_BUFFER_BYTES, "x").is_ok());
        assert!(check_buffer("ring", MAX_BUFFER_BYTES + 1, "x")
            .unwrap_err()
            .to_string()
            .contains("ring"));
    }
}
