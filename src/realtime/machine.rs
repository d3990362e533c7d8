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
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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

/// Tasks of other processes running or waiting for a core now: the kernel's count of
/// runnable tasks (`/proc/loadavg`) less this process's.
pub fn others_running() -> Option<f64> {
    let loadavg = std::fs::read_to_string("/proc/loadavg").ok()?;
    others_from(&loadavg, own_running_threads()?)
}

/// `/proc/loadavg`'s runnable tasks (its fourth field, `running/total`) less `own`.
fn others_from(loadavg: &str, own: usize) -> Option<f64> {
    let running: f64 = loadavg
        .split_whitespace()
        .nth(3)?
        .split('/')
        .next()?
        .parse()
        .ok()?;
    Some((running - own as f64).max(0.0))
}

/// This process's threads running or waiting for a core (state `R`), the caller included.
fn own_running_threads() -> Option<usize> {
    let tasks = std::fs::read_dir("/proc/self/task").ok()?;
    Some(
        tasks
            .filter_map(|e| std::fs::read_to_string(e.ok()?.path().join("stat")).ok())
            .filter(|stat| {
                // The state is the first field after the parenthesised command name.
                stat.rfind(')')
                    .and_then(|i| stat[i + 1..].split_whitespace().next())
                    .is_some_and(|state| state == "R")
            })
            .count(),
    )
}

/// The load of other processes just before a run: [`others_running`] averaged over
/// `samples` readings `gap` apart, while this process waits. Unlike the 1-minute load
/// average it does not carry this process's own work of the last minute.
pub fn others_load(samples: usize, gap: std::time::Duration) -> Option<f64> {
    let mut sum = 0.0;
    for i in 0..samples.max(1) {
        if i > 0 {
            std::thread::sleep(gap);
        }
        sum += others_running()?;
    }
    Some(sum / samples.max(1) as f64)
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

    /// Spinning threads of this process are its own running tasks, and are taken
    /// off the kernel's count.
    #[cfg(target_os = "linux")]
    #[test]
    fn own_threads_are_not_others_load() {
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let spinners: Vec<_> = (0..2)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let mut x = 1u64;
                    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                        x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
                    }
                    x
                })
            })
            .collect();
        std::thread::sleep(std::time::Duration::from_millis(20));
        // Running or waiting for a core, a spinning thread is always in state R, and so
        // is the reading thread.
        let own = own_running_threads().unwrap();
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for s in spinners {
            std::hint::black_box(s.join().unwrap());
        }
        assert!(own >= 3, "{own} running threads");
        assert_eq!(others_from("0.52 0.58 0.59 5/301 4182", 3), Some(2.0));
        assert_eq!(others_from("0.52 0.58 0.59 2/301 4182", 3), Some(0.0));
        assert_eq!(others_from("0.52 0.58", 3), None);
        assert!(others_load(3, std::time::Duration::from_millis(1)).unwrap() >= 0.0);
    }
}
