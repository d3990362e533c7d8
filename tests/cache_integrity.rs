//! The ideal-image cache serves an entry only when the entry proves what it is: entries
//! swapped between instants, re-encoded with other pixels, or stored in another PNG
//! format are re-rendered and counted, and an evaluation's results are exactly those of
//! a run without a cache.

use std::{
    path::{Path, PathBuf},
    sync::Arc,
};

use frameless::{
    evaluation::{self, EvalConfig, EvalOutput, Silent},
    image::read_png,
    methods::MethodKind,
    scene::builtin,
    trace::TextureFilter,
};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-integrity-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn config(cache_dir: Option<PathBuf>) -> EvalConfig {
    let mut c = EvalConfig::new("toycar");
    c.start = 0.5;
    c.duration = 0.1;
    c.display.size = frameless::settings::Size(24, 16);
    c.rates = vec![100_000.0];
    c.methods = vec![MethodKind::TraditionalFrameless, MethodKind::Framed60Hz];
    c.quality.seed = 9;
    c.reference.ideal_spp = 2;
    c.warmup = 0.1;
    c.display.refresh_hz = 60.0;
    c.quality.max_depth = 3;
    c.quality.texture_filter = TextureFilter::None;
    c.reference.set_cache(cache_dir);
    c.strip_frames = vec![0, 3];
    c.flip_every = 1;
    c
}

fn run(cache_dir: Option<&Path>) -> EvalOutput {
    let scene = Arc::new(builtin::load("toycar").expect("built-in scene"));
    evaluation::run(scene, &config(cache_dir.map(Path::to_path_buf)), &Silent)
        .expect("evaluation runs")
}

/// Everything an evaluation measured (not what it cost).
fn assert_same_results(a: &EvalOutput, b: &EvalOutput, what: &str) {
    assert_eq!(a.summary.results, b.summary.results, "{what}: summary");
    assert_eq!(a.frames, b.frames, "{what}: frames");
    assert_eq!(a.strips, b.strips, "{what}: strips");
}

fn counts(o: &EvalOutput) -> (usize, usize) {
    let t = &o.summary.timing;
    (t.ideal_cache_hits, t.ideal_cache_rejected)
}

fn entries(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("cache folder")
        .map(|e| e.expect("entry").path())
        .collect();
    v.sort();
    v
}

/// Write a PNG with `png` directly, in any colour type, with tEXt chunks.
fn write_png(
    path: &Path,
    w: u32,
    h: u32,
    color: png::ColorType,
    data: &[u8],
    text: &[(String, String)],
) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("writable"));
    let mut enc = png::Encoder::new(file, w, h);
    enc.set_color(color);
    enc.set_depth(png::BitDepth::Eight);
    // Another compression level than the cache's: a re-encoding, not a copy.
    enc.set_compression(png::Compression::High);
    for (k, t) in text {
        enc.add_text_chunk(k.clone(), t.clone())
            .expect("text chunk");
    }
    let mut wr = enc.write_header().expect("header");
    wr.write_image_data(data).expect("data");
    wr.finish().expect("finish");
}

#[test]
fn corrupted_entries_are_rejected_counted_and_never_change_results() {
    let dir = scratch("corrupt");
    let reference = run(None);
    let n = config(None).frames();
    let cold = run(Some(&dir));
    assert_eq!(counts(&cold), (0, 0));
    assert_same_results(&cold, &reference, "cold cache");
    let warm = run(Some(&dir));
    assert_eq!(counts(&warm), (n, 0));
    assert_same_results(&warm, &reference, "warm cache");

    let e = entries(&dir);
    assert_eq!(e.len(), n, "one entry per refresh");
    let (w, h) = (24, 16);
    let stored = |p: &Path| read_png(p).expect("a valid entry");
    // 1. Two entries swapped: each is a valid entry, of the wrong instant.
    let (a, b) = (std::fs::read(&e[0]).unwrap(), std::fs::read(&e[1]).unwrap());
    assert_ne!(
        stored(&e[0]).data,
        stored(&e[1]).data,
        "a swap must be visible"
    );
    std::fs::write(&e[0], &b).unwrap();
    std::fs::write(&e[1], &a).unwrap();
    // 2. Re-encoded as a solid colour of the right size, keeping the entry's own text
    //    chunks (its key and checksum): only the checksum can tell.
    let original = stored(&e[2]);
    let solid: Vec<u8> = [200u8, 40, 90].repeat((w * h) as usize);
    write_png(&e[2], w, h, png::ColorType::Rgb, &solid, &original.text);
    // 3. RGBA of the right size with another entry's pixels, again with the entry's own
    //    text chunks: only the format can tell.
    let victim = stored(&e[3]);
    let other = stored(&e[4]);
    assert_ne!(victim.data, other.data);
    let rgba: Vec<u8> = other
        .data
        .chunks(3)
        .flat_map(|c| [c[0], c[1], c[2], 255])
        .collect();
    write_png(&e[3], w, h, png::ColorType::Rgba, &rgba, &victim.text);

    let after = run(Some(&dir));
    assert_same_results(&after, &reference, "after corruption");
    assert_eq!(counts(&after), (n - 4, 4), "(hits, rejected)");
    // The rejected entries were rewritten: everything is served again.
    let again = run(Some(&dir));
    assert_eq!(counts(&again), (n, 0));
    assert_same_results(&again, &reference, "after rewriting");
    assert_eq!(entries(&dir).len(), n, "no temporary files left");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn concurrent_runs_share_a_cold_cache() {
    let dir = scratch("concurrent");
    let reference = run(None);
    let outputs: Vec<EvalOutput> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..3).map(|_| s.spawn(|| run(Some(&dir)))).collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a run"))
            .collect()
    });
    for o in &outputs {
        assert_same_results(o, &reference, "concurrent");
    }
    let n = config(None).frames();
    // Exactly the entries, no temporaries, and every one valid.
    assert_eq!(entries(&dir).len(), n, "{:?}", entries(&dir));
    assert_eq!(counts(&run(Some(&dir))), (n, 0));
    let _ = std::fs::remove_dir_all(&dir);
}
