//! What one pass over every pixel costs on this machine's one core, when the pass does
//! almost no arithmetic: the floor under the reconstructor's per-pixel passes.
//! `cargo run --release --example stream_floor` (pin it: `taskset -c 1`).
//!
//! For each live display size and 16 to 128 bytes of state per pixel, the best of
//! seven passes that read and write every float (`x·0.99 + 1`, which the compiler cannot
//! drop or hoist), and of seven that only read (a sum). If a per-pixel pass of the
//! reconstructor costs many times its bytes' floor, its cost is arithmetic and
//! branches, not memory traffic.

use std::time::Instant;

const SIZES: [(usize, usize); 4] = [(256, 256), (640, 480), (1280, 720), (1920, 1080)];
const RUNS: usize = 7;

/// Best time of `RUNS` calls of `pass`, milliseconds.
fn best_ms(mut pass: impl FnMut()) -> f64 {
    (0..RUNS)
        .map(|_| {
            let t0 = Instant::now();
            pass();
            t0.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    println!("one core, best of {RUNS}: read+write ms (GB/s moved) | read-only ms");
    for (w, h) in SIZES {
        for bytes in [16usize, 32, 64, 128] {
            let mut a = vec![0f32; w * h * bytes / 4];
            let rw = best_ms(|| a.iter_mut().for_each(|x| *x = *x * 0.99 + 1.0));
            let mut sink = 0f32;
            let ro = best_ms(|| {
                // Eight partial sums, so the adds are not one chain of latencies.
                let mut s = [0f32; 8];
                for c in a.chunks_exact(8) {
                    s.iter_mut().zip(c).for_each(|(s, x)| *s += x);
                }
                sink += s.iter().sum::<f32>();
            });
            std::hint::black_box(sink);
            let gbs = 2.0 * (a.len() * 4) as f64 / (rw * 1e-3) / 1e9;
            println!("{w:>5}x{h:<5} {bytes:>3} B/px: {rw:7.2} ms ({gbs:5.1} GB/s) | {ro:7.2} ms");
        }
    }
}
