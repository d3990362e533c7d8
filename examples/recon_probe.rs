//! Development probe of the reconstructor (not part of the product): statistics of the
//! footprints and temporal weights on the synthetic bench fixture or after a real
//! sampler run, and timings of repeated refreshes.
//!
//! `cargo run --release --example recon_probe -- fixture[SIZE]|SCENE [refreshes]`

use std::{sync::Arc, time::Instant};

use frameless::{
    bench::{adaptive_after_one_second, reconstruct_fixture},
    methods::Method,
    reconstruction::Reconstructor,
    scene::CameraFrame,
    trace::{TraceOptions, Tracer},
};

/// Classes of the kernel's smaller sigma, pixels.
const SIG_EDGES: [f32; 4] = [1.0, 2.0, 3.0, 4.0];
/// Sigmas beyond which a footprint's pixels are counted.
const BEYOND: [f32; 4] = [3.0, 4.0, 6.0, 13.2];

fn stats(r: &mut Reconstructor, cam: &CameraFrame, t: f64) {
    let sc = r.splat_scale().to_vec();
    let (w, h) = (r.image().width as usize, r.image().height as usize);
    let p = *r.params();
    let f = r.filter_map();
    let (mut kept, mut area, mut wide, mut tall) = (0usize, 0f64, 0f64, 0f64);
    let mut hist_w = [0usize; 8];
    let mut old = 0usize;
    let (mut rowgroups, mut bandsplats) = (0f64, 0f64);
    let mut by_sigma = [(0f64, 0f64, 0f64); SIG_EDGES.len() + 1];
    let mut beyond = [0f64; BEYOND.len()];
    let mut by_max = [0f64; SIG_EDGES.len() + 1];
    let mut max_et = 0f32;
    for e in f {
        max_et = max_et.max(e[2]);
    }
    for s in r.ring().iter() {
        let age = (t - s.t).max(0.0) as f32;
        if age > p.temporal_cutoff * max_et {
            old += 1;
        }
        let (x, y) = if p.reproject {
            match cam.project(s.hit_point + s.velocity * age) {
                Some((x, y, _)) => (x, y),
                None => continue,
            }
        } else {
            (s.x, s.y)
        };
        let px = (x.floor() as i64).clamp(0, w as i64 - 1) as usize;
        let py = (y.floor() as i64).clamp(0, h as i64 - 1) as usize;
        let i = py * w + px;
        let [ex, ey, et] = f[i];
        if age / et > p.temporal_cutoff {
            continue;
        }
        kept += 1;
        let rx = (p.spatial_cutoff * ex * sc[i]).min(p.max_radius);
        let ry = (p.spatial_cutoff * ey * sc[i]).min(p.max_radius);
        let x0 = ((x - 0.5 - rx).ceil() as i32).max(0);
        let x1 = ((x - 0.5 + rx).floor() as i32).min(w as i32 - 1);
        let y0 = ((y - 0.5 - ry).ceil() as i32).max(0);
        let y1 = ((y - 0.5 + ry).floor() as i32).min(h as i32 - 1);
        if x0 > x1 || y0 > y1 {
            continue;
        }
        let (nw, nh) = ((x1 - x0 + 1) as f64, (y1 - y0 + 1) as f64);
        rowgroups += nh * (x1 / 8 - x0 / 8 + 1) as f64;
        bandsplats += (y1 / 32 - y0 / 32 + 1) as f64;
        area += nw * nh;
        wide += nw;
        tall += nh;
        hist_w[((nw as usize - 1) / 8).min(7)] += 1;
        // Pixel updates and cell-row updates by the kernel's smaller sigma, and the
        // part of the footprint beyond k sigmas along either axis.
        let sig = ex.min(ey);
        let class = SIG_EDGES.iter().filter(|&&e| sig >= e).count();
        let cells = nh * (x1 / 8 - x0 / 8 + 1) as f64;
        by_sigma[class].0 += 1.0;
        by_sigma[class].1 += nw * nh;
        by_sigma[class].2 += cells;
        let cmax = SIG_EDGES.iter().filter(|&&e| ex.max(ey) >= e).count();
        by_max[cmax] += nw * nh;
        for (k, &m) in BEYOND.iter().enumerate() {
            let within = |c: f32, e: f32, lo: i32, hi: i32| {
                let a = ((c - 0.5 - m * e).ceil() as i32).max(lo);
                let b = ((c - 0.5 + m * e).floor() as i32).min(hi);
                (b - a + 1).max(0) as f64
            };
            let inner = within(x, ex, x0, x1) * within(y, ey, y0, y1);
            beyond[k] += nw * nh - inner;
        }
    }
    let tot: f64 = by_sigma.iter().map(|b| b.1).sum();
    let totc: f64 = by_sigma.iter().map(|b| b.2).sum();
    for (k, b) in by_sigma.iter().enumerate() {
        let lo = if k == 0 { 0.0 } else { SIG_EDGES[k - 1] };
        println!(
            "min sigma >= {lo:.1}: {:.0} splats, {:.0} px updates ({:.1}%), {:.0} cell-rows ({:.1}%)",
            b.0,
            b.1,
            100.0 * b.1 / tot,
            b.2,
            100.0 * b.2 / totc
        );
    }
    println!(
        "px updates by larger sigma class (edges {SIG_EDGES:?}): {:?} %",
        by_max.map(|v| (1000.0 * v / tot).round() / 10.0)
    );
    for (k, &m) in BEYOND.iter().enumerate() {
        println!(
            "px updates beyond {m} sigma on an axis: {:.1}%",
            100.0 * beyond[k] / tot
        );
    }
    let n = r.ring().len();
    let mut ets: Vec<f32> = f.iter().map(|e| e[2]).collect();
    ets.sort_by(f32::total_cmp);
    let mut exs: Vec<f32> = f.iter().map(|e| e[0]).collect();
    exs.sort_by(f32::total_cmp);
    let mut scs: Vec<f32> = sc.to_vec();
    scs.sort_by(f32::total_cmp);
    let q = |v: &[f32]| {
        format!(
            "{:.3}/{:.3}/{:.3}/{:.3}",
            v[v.len() / 10],
            v[v.len() / 2],
            v[v.len() * 9 / 10],
            v[v.len() - 1]
        )
    };
    println!(
        "ring {n}, kept {kept} ({:.1}%), older than cutoff·max e_t: {old}",
        100.0 * kept as f64 / n as f64
    );
    println!(
        "mean footprint {:.1} px ({:.1} × {:.1}), width histogram by 8: {hist_w:?}",
        area / kept as f64,
        wide / kept as f64,
        tall / kept as f64
    );
    println!("row-groups of 8 {rowgroups}, splats in 32-row bands {bandsplats}");
    println!(
        "pixel quantiles p10/p50/p90/max: e_x {}  e_t {}  scale {}",
        q(&exs),
        q(&ets),
        q(&scs)
    );
    println!("holes {}, mean age {:.4}", r.holes(), r.mean_age());
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let what = args.get(1).map(String::as_str).unwrap_or("fixture");
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    if let Some(size) = what.strip_prefix("fixture") {
        let s: usize = size.parse().unwrap_or(256);
        let n = if s == 256 { 400_000 } else { 6 * s * s };
        let (mut r, cam, tiling) = reconstruct_fixture(s as u32, s as u32, n, 1);
        let mut areas: Vec<u32> = tiling.tiles.iter().map(|t| t.rect.area()).collect();
        areas.sort();
        println!(
            "tiles {}, area p10/p50/p90/max {} {} {} {}",
            areas.len(),
            areas[areas.len() / 10],
            areas[areas.len() / 2],
            areas[areas.len() * 9 / 10],
            areas[areas.len() - 1]
        );
        for _ in 0..2 {
            r.reconstruct(1.0, &cam, &tiling);
        }
        stats(&mut r, &cam, 1.0);
        for _ in 0..reps {
            let t0 = Instant::now();
            r.reconstruct(1.0, &cam, &tiling);
            println!("refresh {:.2} ms", t0.elapsed().as_secs_f64() * 1e3);
        }
        return;
    }
    let scene = frameless::scene::load(what).expect("scene");
    let time = scene.time_range().0 as f64;
    let tracer = Arc::new(Tracer::new(
        Arc::new(scene),
        256,
        256,
        TraceOptions::default(),
    ));
    let (mut m, end) = adaptive_after_one_second(&tracer, time).expect("adaptive");
    m.display(end);
    let cam = tracer.state_at(end).camera;
    let tiling = m.sampler().tiling();
    let mut areas: Vec<f32> = tiling
        .leaves()
        .iter()
        .map(|&l| tiling.node(l).rect.area() as f32)
        .collect();
    let mut gs: [Vec<f32>; 3] = Default::default();
    for &l in tiling.leaves() {
        let g = tiling.node(l).stats.gradients();
        gs[0].push(g.0.abs() as f32);
        gs[1].push(g.1.abs() as f32);
        gs[2].push(g.2.abs() as f32);
    }
    areas.sort_by(f32::total_cmp);
    for v in &mut gs {
        v.sort_by(f32::total_cmp);
    }
    let q = |v: &[f32]| {
        format!(
            "{:.4}/{:.4}/{:.4}/{:.4}/{:.4}",
            v[v.len() / 10],
            v[v.len() / 4],
            v[v.len() / 2],
            v[v.len() * 3 / 4],
            v[v.len() * 9 / 10]
        )
    };
    println!(
        "tiles {}, area p10/25/50/75/90 {}; |gx| {} |gy| {} |gt| {}",
        areas.len(),
        q(&areas),
        q(&gs[0]),
        q(&gs[1]),
        q(&gs[2])
    );
    stats(m.reconstructor_mut(), &cam, end);
    for _ in 0..reps {
        let t0 = Instant::now();
        m.display(end);
        println!("refresh {:.2} ms", t0.elapsed().as_secs_f64() * 1e3);
    }
}
