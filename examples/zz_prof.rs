fn main() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let w: u32 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(640);
    let h: u32 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(480);
    pool.install(|| {
        for _ in 0..5 {
            println!(
                "{:.2} ms",
                frameless::bench::reconstruct_realtime_ms(w, h, 2, 20)
            );
        }
    });
}
