//! Wall time of each step of a refresh, so that the first bottleneck of an image can
//! be named from a live run's statistics (and a bench's), not guessed.

use std::time::Instant;

/// The steps of a refresh, in the order they run (on the CPU the splat and the resolve
/// share one pass over bands of rows, each band resolved once splatted; that pass's time
/// goes to the two as its bands' time did): on the GPU, the filters, the carry
/// and the history's plan stay on the CPU, and the rest is the GPU's three parts:
/// `gpu_upload` (packing the carried sums, uploads, encoding, submission), `gpu_wait`
/// (until the read-back buffers are mapped: the shaders and the copies) and
/// `gpu_read` (unpacking the read-back and taking it in); on the CPU those are zero.
pub const PASSES: [&str; 10] = [
    "filters",
    "place",
    "fronts",
    "carry",
    "splat",
    "resolve",
    "history",
    "gpu_upload",
    "gpu_wait",
    "gpu_read",
];

/// Seconds spent in each of [`PASSES`] since the reconstructor was made, and the
/// refreshes they were spent over.
#[derive(Clone, Debug, Default)]
pub struct PassTimes {
    seconds: [f64; PASSES.len()],
    refreshes: u64,
}

impl PassTimes {
    /// Mean milliseconds per refresh of each pass, by name (zero before any refresh).
    pub fn mean_ms(&self) -> Vec<(&'static str, f64)> {
        let n = self.refreshes.max(1) as f64;
        PASSES
            .iter()
            .zip(&self.seconds)
            .map(|(&name, s)| (name, s * 1e3 / n))
            .collect()
    }

    /// What was spent after `earlier` (an earlier copy of these times).
    pub fn since(&self, earlier: &PassTimes) -> PassTimes {
        PassTimes {
            seconds: std::array::from_fn(|k| self.seconds[k] - earlier.seconds[k]),
            refreshes: self.refreshes - earlier.refreshes.min(self.refreshes),
        }
    }

    /// Refreshes timed so far.
    pub fn refreshes(&self) -> u64 {
        self.refreshes
    }

    pub(super) fn count_refresh(&mut self) {
        self.refreshes += 1;
    }

    /// `seconds` more of pass `k` (an index of [`PASSES`]), timed elsewhere.
    pub(super) fn add(&mut self, k: usize, seconds: f64) {
        self.seconds[k] += seconds;
    }

    /// Time from `since` to now goes to pass `k` (an index of [`PASSES`]); returns now,
    /// the start of the next pass.
    pub(super) fn lap(&mut self, k: usize, since: Instant) -> Instant {
        let now = Instant::now();
        self.seconds[k] += (now - since).as_secs_f64();
        now
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laps_add_to_their_pass_and_average_over_refreshes() {
        let mut p = PassTimes::default();
        let t0 = Instant::now();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let t1 = p.lap(4, t0);
        p.lap(6, t1);
        p.count_refresh();
        p.count_refresh();
        let ms = p.mean_ms();
        assert_eq!(ms.len(), PASSES.len());
        assert_eq!(ms[4].0, "splat");
        // Two or more milliseconds over two refreshes.
        assert!(ms[4].1 >= 1.0, "{ms:?}");
        assert!(ms[0].1 == 0.0 && ms[6].1 >= 0.0 && ms[7].1 == 0.0);
        p.add(8, 0.004);
        assert!((p.mean_ms()[8].1 - 2.0).abs() < 1e-9, "{:?}", p.mean_ms());
        assert_eq!(p.refreshes(), 2);
        let later = {
            let mut q = p.clone();
            q.lap(4, Instant::now() - std::time::Duration::from_millis(4));
            q.count_refresh();
            q
        };
        let d = later.since(&p);
        assert_eq!(d.refreshes(), 1);
        assert!(
            d.mean_ms()[4].1 >= 4.0 && d.mean_ms()[6].1 == 0.0,
            "{:?}",
            d.mean_ms()
        );
    }
}
