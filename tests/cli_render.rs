//! `frameless render`: one PNG (or OpenEXR) file per refresh plus statistics; bad
//! arguments fail cleanly.

use std::process::Command;

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-render-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn writes_one_png_per_refresh_and_stats() {
    let out = tmp("ok");
    // A longer earlier run: the folder must hold this run alone afterwards.
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("frame_00007.png"), "an earlier run's frame").unwrap();
    std::fs::write(out.join("stats.json"), "{}").unwrap();
    let st = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args([
            "render",
            "--scene",
            "toycar",
            "--method",
            "traditional-frameless",
            "--rate",
            "50k",
            "--size",
            "32x24",
            "--duration",
            "0.1",
            "--refresh-hz",
            "30",
            "--warmup",
            "0.2",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    for k in 0..3 {
        assert!(out.join(format!("frame_{k:05}.png")).is_file(), "frame {k}");
    }
    assert!(!out.join("frame_00003.png").exists());
    assert!(
        !out.join("frame_00007.png").exists(),
        "a frame of another run"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).unwrap()).unwrap();
    assert_eq!(v["frames"], 3);
    // 50K samples/s over 0.2 s warm-up + 2 refresh intervals of 1/30 s.
    let samples = v["samples"].as_u64().unwrap();
    assert!((10_000..=14_000).contains(&samples), "{samples}");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bad_arguments_fail_without_output() {
    let out = tmp("bad");
    for args in [
        &["--method", "nope"][..],
        &["--rate", "fast"],
        &["--duration", "0"],
        &["--refresh-hz", "-1"],
        &["--fps", "0"],
        &["--format", "jpg"],
        &["--method", "framed-full", "--rate", "1k"],
        &["--scene", "/nonexistent.aff"],
    ] {
        let st = Command::new(env!("CARGO_BIN_EXE_frameless"))
            .arg("render")
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(!st.status.success(), "{args:?}");
        assert!(
            String::from_utf8_lossy(&st.stderr).contains("error"),
            "{args:?}"
        );
        assert!(!out.exists(), "{args:?} wrote output");
    }
}

#[test]
fn exr_frames_hold_the_linear_values_the_png_frames_quantize() {
    let run = |format: &str| {
        let out = tmp(&format!("fmt-{format}"));
        let st = Command::new(env!("CARGO_BIN_EXE_frameless"))
            .args([
                "render",
                "--scene",
                "toycar",
                "--method",
                "adaptive",
                "--rate",
                "50k",
                "--size",
                "24x16",
                "--duration",
                "0.05",
                "--warmup",
                "0.2",
                "--format",
                format,
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
        out
    };
    let (png, exr) = (run("png"), run("exr"));
    let mut frames = 0;
    for k in 0.. {
        let p = exr.join(format!("frame_{k:05}.exr"));
        if !p.is_file() {
            break;
        }
        let linear = frameless::image::read_exr(&p).expect("an OpenEXR frame");
        let (_, _, rgb) =
            frameless::image::read_png_rgb8(&png.join(format!("frame_{k:05}.png"))).unwrap();
        // The same run: the PNG is the EXR as displayed, through docs/colour.md's
        // transform (to within float rounding at a rounding boundary).
        let values = linear.to_display_values().pixels;
        for (v, b) in values.iter().flat_map(|p| p.to_array()).zip(&rgb) {
            let v = v.clamp(0.0, 1.0) * 255.0;
            assert!(
                (v - f32::from(*b)).abs() <= 0.5 + 1e-3,
                "frame {k}: {v} vs {b}"
            );
        }
        frames += 1;
    }
    assert_eq!(frames, 3);
    assert!(!exr.join("frame_00000.png").exists());
    let _ = std::fs::remove_dir_all(&png);
    let _ = std::fs::remove_dir_all(&exr);
}
