//! Use the library from Rust: load a scene, evaluate two methods against the ideal
//! image, read the summary and write the report, as `frameless eval` does.
//!
//! ```sh
//! cargo run --release --example evaluate            # built-in toycar
//! cargo run --release --example evaluate -- path/to/scene.gltf
//! ```

use std::{path::Path, sync::Arc};

use frameless::{
    evaluation::{self, report, EvalConfig, Silent},
    methods::MethodKind,
    scene,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let name = std::env::args().nth(1).unwrap_or_else(|| "toycar".into());
    // A built-in name or a scene file (.aff, .gltf, .glb, .obj).
    let scene = Arc::new(scene::load(&name)?);

    // `frameless eval`'s settings, narrowed to two methods at one rate.
    let mut cfg = EvalConfig::new(&name);
    cfg.rates = vec![400_000.0];
    cfg.methods = vec![MethodKind::TraditionalFrameless, MethodKind::Adaptive];
    // Ideal images are the costly part; keep them between runs as the command does.
    cfg.reference
        .set_cache(std::env::var_os("FRAMELESS_CACHE").map(Into::into));

    let mut out = evaluation::run(scene, &cfg, &Silent)?;
    for row in &out.summary.results {
        println!(
            "{:<22} {:>5}: RMS {:6.2}  PSNR {:5.2} dB  FLIP {:.4}  instability {:.2}",
            row.method.name(),
            report::rate_label(row.rate),
            row.rms_mean,
            row.psnr_mean,
            row.flip_mean,
            row.instability_mean
        );
    }
    let ours = out
        .summary
        .results
        .iter()
        .find(|r| r.method == MethodKind::Adaptive)
        .ok_or("no adaptive row")?;
    println!("adaptive's mean RMS: {:.2}", ours.rms_mean);

    let html = report::write_all(&mut out, Path::new("example-out"))?;
    println!("report: {}", html.display());
    Ok(())
}
