//! One figure of `frameless bench --live-recon`, for profiling:
//! `cargo run --release --example live_recon -- WIDTH HEIGHT RATE HZ RING_SPP [resplat|carried] [still] [gpu]`
//! (`gpu`: the refreshes on the best GPU adapter there is, a software one included).
//! The hash it prints, `IMAGE/AGES`, tells whether two builds make the same images: the
//! first part covers the last image, its splat scales and history counts, the second
//! its pixel ages (figures beside the image, which a change may alter alone).

use frameless::{
    bench,
    reconstruction::{device, ReconParams},
};

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() < 5 {
        eprintln!(
            "usage: live_recon WIDTH HEIGHT RATE HZ RING_SPP [resplat|carried] [still] [gpu]"
        );
        std::process::exit(2);
    }
    if let Some(bad) = a[5..]
        .iter()
        .find(|x| !["resplat", "carried", "still", "gpu"].contains(&x.as_str()))
    {
        eprintln!("live_recon: unknown option {bad:?} (resplat, carried, still or gpu)");
        std::process::exit(2);
    }
    let num = |i: usize| -> f64 { a[i].parse().expect("a number") };
    let flag = |f: &str| a[5..].iter().any(|x| x == f);
    let case = bench::LiveCase {
        width: num(0) as u32,
        height: num(1) as u32,
        rate: num(2),
        refresh_hz: num(3),
    };
    let params = ReconParams {
        carry: !flag("resplat"),
        resplat_moving_view: !flag("carried"),
        ..ReconParams::realtime()
    };
    let gpu = if flag("gpu") {
        match device::acquire(device::ReconDevice::Gpu) {
            Ok(Some(c)) => {
                eprintln!("reconstructing on {}", c.describe());
                Some(c)
            }
            Ok(None) => None,
            Err(e) => {
                eprintln!("live_recon: {e}");
                std::process::exit(1);
            }
        }
    } else {
        None
    };
    let f = match bench::live_image_ms(case, num(4), params, 30, !flag("still"), gpu) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("live_recon: {e}");
            std::process::exit(1);
        }
    };
    println!(
        "{:.2} ms per image, {:.0} placed, image {}",
        f.ms_median, f.placed_per_image, f.image_hash
    );
    println!("  taking the new samples in: {:.2} ms", f.take_in_ms_median);
    if let Some(cpu) = f.cpu_ms_mean {
        println!("  CPU time of the whole process per image (mean): {cpu:.1} ms");
    }
    let passes: Vec<String> = f
        .pass_ms
        .iter()
        .map(|(n, ms)| format!("{n} {ms:.1}"))
        .collect();
    println!("  per pass (ms, mean): {}", passes.join(", "));
}
