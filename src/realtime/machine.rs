//! What the operating system says about the machine a run shares: this process's CPU
//! time, every core's busy time and the load average (Linux; `None` elsewhere).

/// Clock ticks per second of `/proc` times (`USER_HZ`, 100 on every Linux port).
const TICKS_PER_S: f64 = 100.0;

/// User + system CPU seconds of this process, from `/proc/self/stat`.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are the 14th and
    // 15th fields of the line.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / TICKS_PER_S)
}

/// CPU seconds every core together spent busy (not idle, not waiting for I/O) since
/// boot, from the first line of `/proc/stat`.
pub fn machine_busy_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let line = stat.lines().next()?.strip_prefix("cpu ")?;
    let f: Vec<f64> = line
        .split_whitespace()
        .map(|v| v.parse().ok())
        .collect::<Option<_>>()?;
    // user nice system idle iowait irq softirq steal: guest time is inside user.
    let busy = [0, 1, 2, 5, 6, 7]
        .iter()
        .filter_map(|&i| f.get(i))
        .sum::<f64>();
    Some(busy / TICKS_PER_S)
}

/// The 1-minute load average.
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// Cores the OS offers this process.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// CPU time read at one instant, to take shares of the machine over an interval.
#[derive(Clone, Copy, Debug)]
pub struct CpuMark {
    at: std::time::Instant,
    process: Option<f64>,
    machine: Option<f64>,
}

/// Shares of the machine's cores over an interval (0–1 each).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct CpuShares {
    /// This process: its CPU seconds / (wall seconds × cores).
    pub process: Option<f64>,
    /// Every other process together, the same way: what contended with the run.
    pub others: Option<f64>,
}

impl CpuMark {
    /// Now.
    pub fn now() -> Self {
        Self {
            at: std::time::Instant::now(),
            process: process_cpu_seconds(),
            machine: machine_busy_seconds(),
        }
    }

    /// The shares of the machine from this mark to `later`.
    pub fn shares_until(&self, later: &CpuMark) -> CpuShares {
        let wall = (later.at - self.at).as_secs_f64().max(1e-9) * cores() as f64;
        let process = self.process.zip(later.process).map(|(a, b)| b - a);
        let machine = self.machine.zip(later.machine).map(|(a, b)| b - a);
        CpuShares {
            process: process.map(|p| p / wall),
            others: machine.zip(process).map(|(m, p)| ((m - p) / wall).max(0.0)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A busy loop on this thread shows as this process's share, not as others'.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_busy_thread_counts_as_this_process() {
        let a = CpuMark::now();
        let t0 = std::time::Instant::now();
        let mut x = 0u64;
        while t0.elapsed().as_secs_f64() < 0.3 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        let s = a.shares_until(&CpuMark::now());
        let own = s.process.unwrap() * cores() as f64;
        assert!(own > 0.5, "one busy thread for 0.3 s used {own} cores");
        assert!(s.others.unwrap() >= 0.0);
    }
}
