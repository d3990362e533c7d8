//! Regression tests for the hardening issue's reproducers: each input that once
//! panicked, hung, aborted or wrongly succeeded now loads and renders or fails with a
//! clear error and a non-zero exit. Classes are covered by `parser_fuzz.rs`; these are
//! the exact cases reported.

use std::{path::PathBuf, process::Command, sync::Arc};

use frameless::{
    render::still,
    scene::{self, CameraPath, Scene},
    trace::{TraceOptions, Tracer},
};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-hardening-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run the binary; returns (exit code, stderr).
fn run(args: &[&str]) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The command fails (exit 1, not a panic's 101 or a signal) with all of `needles` in
/// its message.
fn fails_with(args: &[&str], needles: &[&str]) {
    let (code, err) = run(args);
    assert_eq!(code, 1, "{args:?} should fail cleanly; stderr: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` not in: {err}");
    }
}

/// Build the tracer and render a small image: nothing may panic, pixels are finite.
fn traces(scene: Scene) -> Tracer {
    let tracer = Tracer::new(Arc::new(scene), 8, 6, TraceOptions::default());
    let img = still::render(&tracer, 0.0, 1, 1, &|_| {});
    assert!(img.pixels.iter().all(|p| p.is_finite()));
    tracer
}

const AFF_HEAD: &str = "v\nfrom 0 0 -5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.01\nresolution 8 8\nb 0 0 0\nl 1 1 -3\nf 1 1 1 1 0 0 0 0\n";

// --- Panic: tiny displays -------------------------------------------------------------

#[test]
fn displays_under_1024_pixels_run_every_adaptive_path() {
    let d = dir("tiny");
    let out = |n: &str| d.join(n).display().to_string();
    for size in ["16x16", "1x1", "31x3"] {
        let (code, err) = run(&[
            "sampler",
            "--size",
            size,
            "--duration",
            "0.2",
            "--out",
            &out(&format!("s{size}")),
        ]);
        assert_eq!(code, 0, "sampler {size}: {err}");
    }
    let (code, err) = run(&[
        "eval",
        "--size",
        "16x16",
        "--methods",
        "adaptive,adaptive-paper",
        "--rates",
        "100k",
        "--duration",
        "0.1",
        "--warmup",
        "0.2",
        "--no-cache",
        "--out",
        &out("eval"),
    ]);
    assert_eq!(code, 0, "eval: {err}");
    let (code, err) = run(&[
        "render",
        "--size",
        "16x16",
        "--method",
        "adaptive",
        "--duration",
        "0.1",
        "--out",
        &out("render"),
    ]);
    assert_eq!(code, 0, "render: {err}");
    let (code, err) = run(&[
        "view",
        "--headless",
        "--seconds",
        "1",
        "--size",
        "16x16",
        "--method",
        "adaptive",
        "--out",
        &out("view"),
    ]);
    assert_eq!(code, 0, "view: {err}");
    // The controller thread used to die here: samples must have been traced and shown.
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("view/stats.json")).unwrap()).unwrap();
    assert!(
        stats["pipeline"]["samples"].as_f64().unwrap() > 1000.0,
        "{stats}"
    );
    assert!(stats["display_fps"].as_f64().unwrap() > 0.0, "{stats}");
}

// --- Panic: huge finite coordinates ---------------------------------------------------

#[test]
fn huge_finite_coordinates_are_errors_naming_the_place() {
    let aff = format!("{AFF_HEAD}p 3 2e38 -1 0 1 -1 0 0 1 0\np 3 -1 -1 0 1 -1 0 0 1 0\n");
    let e = scene::aff::parse_str("huge.aff", aff.as_bytes(), std::path::Path::new("."))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("huge.aff:11:") && e.contains("coordinate limit"),
        "{e}"
    );

    let d = dir("huge");
    std::fs::write(
        d.join("huge.obj"),
        "v 2e38 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = scene::obj::load(&d.join("huge.obj"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("huge.obj:1:3") && e.contains("coordinate limit"),
        "{e}"
    );

    let pos: Vec<u8> = [3e38f32, -1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    std::fs::write(d.join("huge.bin"), &pos).unwrap();
    std::fs::write(
        d.join("huge.gltf"),
        r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":36,"uri":"huge.bin"}],
"bufferViews":[{"buffer":0,"byteLength":36}],
"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#,
    )
    .unwrap();
    let e = scene::gltf::load(&d.join("huge.gltf"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("huge.gltf") && e.contains("POSITION") && e.contains("3e38"),
        "{e}"
    );
}

#[test]
fn a_scene_built_in_code_with_huge_coordinates_still_traces() {
    // Loaders refuse these; a scene made in code reaches the BVH builder directly.
    let mut s = scene::builtin::load("toycar").unwrap();
    s.groups[0].triangles.push(scene::Triangle {
        p: [
            glam::Vec3::new(2e38, -1.0, 0.0),
            glam::Vec3::new(1.0, -1.0, 0.0),
            glam::Vec3::new(0.0, 1.0, 0.0),
        ],
        n: None,
        uv: None,
        material: 0,
    });
    let t = traces(s);
    assert_eq!(t.dropped_triangles(), 1);
}

// --- Hang: identical triangles --------------------------------------------------------

#[test]
fn copies_of_one_triangle_build_and_are_left_out() {
    let aff = format!("{AFF_HEAD}{}", "p 3 -1 -1 0 1 -1 0 0 1 0\n".repeat(16384));
    let s = scene::aff::parse_str("copies.aff", aff.as_bytes(), std::path::Path::new(".")).unwrap();
    let t = traces(s);
    assert_eq!(
        t.dropped_triangles(),
        16383,
        "all but one copy are left out"
    );
}

#[test]
fn a_zero_filled_gltf_accessor_of_300k_vertices_builds() {
    let d = dir("zeros");
    let p = d.join("zeros.gltf");
    std::fs::write(
        &p,
        r#"{"asset":{"version":"2.0"},"accessors":[{"componentType":5126,"count":300000,"type":"VEC3"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#,
    )
    .unwrap();
    let t = traces(scene::gltf::load(&p).unwrap());
    assert_eq!(
        t.dropped_triangles(),
        100_000,
        "every triangle is degenerate"
    );
}

#[test]
fn obj_copies_and_a_100k_vertex_face_build() {
    let d = dir("objhang");
    let p = d.join("dup.obj");
    std::fs::write(
        &p,
        format!("v 0 0 0\nv 1 0 0\nv 0 1 0\n{}", "f 1 2 3\n".repeat(20_000)),
    )
    .unwrap();
    let t = traces(scene::obj::load(&p).unwrap());
    assert_eq!(t.dropped_triangles(), 19_999);

    // One polygon of 100k vertices on a circle: a fan whose every box holds the last.
    let mut obj = String::new();
    let n = 100_000;
    for k in 0..n {
        let a = k as f32 / n as f32 * std::f32::consts::TAU;
        obj.push_str(&format!("v {} {} 0\n", a.cos(), a.sin()));
    }
    obj.push('f');
    for k in 1..=n {
        obj.push_str(&format!(" {k}"));
    }
    obj.push('\n');
    let p = d.join("fan.obj");
    std::fs::write(&p, obj).unwrap();
    let s = scene::obj::load(&p).unwrap();
    assert_eq!(
        s.groups.iter().map(|g| g.triangles.len()).sum::<usize>(),
        n - 2
    );
    traces(s);
}

#[test]
fn an_aff_include_fan_out_of_identical_triangles_builds() {
    let d = dir("fanout");
    std::fs::write(
        d.join("leaf.aff"),
        format!(
            "f 1 1 1 1 0 0 0 0\n{}",
            "p 3 -1 -1 0 1 -1 0 0 1 0\n".repeat(2000)
        ),
    )
    .unwrap();
    std::fs::write(d.join("mid.aff"), "i 0 leaf.aff\n".repeat(9)).unwrap();
    std::fs::write(
        d.join("top.aff"),
        format!("{AFF_HEAD}{}", "i 0 mid.aff\n".repeat(9)),
    )
    .unwrap();
    let s = scene::aff::load(&d.join("top.aff")).unwrap();
    assert_eq!(
        s.groups.iter().map(|g| g.triangles.len()).sum::<usize>(),
        2000 * 81
    );
    let t = traces(s);
    assert_eq!(t.dropped_triangles(), 2000 * 81 - 1);
}

// --- Hang and abort: unbounded arguments and allocations ------------------------------

#[test]
fn unbounded_arguments_are_refused_naming_the_limit() {
    let d = dir("args");
    let out = d.join("o").display().to_string();
    fails_with(
        &["eval", "--warmup", "1e4", "--out", &out],
        &["--warmup", "600"],
    );
    fails_with(
        &["sampler", "--rate", "1e20", "--out", &out],
        &["--rate", "limit"],
    );
    fails_with(
        &[
            "view",
            "--headless",
            "--seconds",
            "1",
            "--size",
            "4096x4096",
            "--method",
            "adaptive",
            "--out",
            &out,
        ],
        &["deep buffer", "GiB"],
    );
    fails_with(
        &[
            "view",
            "--headless",
            "--seconds",
            "1",
            "--size",
            "1024x1024",
            "--ring-factor",
            "64",
            "--method",
            "adaptive",
            "--out",
            &out,
        ],
        &["ring", "GiB"],
    );
}

#[test]
fn a_gltf_strip_expanding_past_the_triangle_budget_is_refused_before_allocating() {
    let d = dir("strip");
    let p = d.join("strip.gltf");
    std::fs::write(
        &p,
        r#"{"asset":{"version":"2.0"},"accessors":[{"componentType":5126,"count":16777216,"type":"VEC3"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0},"mode":5}]}],"nodes":[{"mesh":0},{"mesh":0},{"mesh":0},{"mesh":0}],"scenes":[{"nodes":[0,1,2,3]}]}"#,
    )
    .unwrap();
    let e = scene::gltf::load(&p).unwrap_err().to_string();
    assert!(e.contains("strip.gltf") && e.contains("triangles"), "{e}");
}

// --- Wrong successes ------------------------------------------------------------------

#[test]
fn runs_that_would_measure_nothing_or_collide_are_refused() {
    let d = dir("wrong");
    let out = d.join("o").display().to_string();
    fails_with(
        &["eval", "--start", "1e300", "--out", &out],
        &["--start", "1e300"],
    );
    fails_with(&["sampler", "--rate", "1e30", "--out", &out], &["--rate"]);
    fails_with(
        &["eval", "--rates", "100k,100.001k", "--out", &out],
        &["--rates", "100K"],
    );
    fails_with(&["eval", "--rates", "400k,400k", "--out", &out], &["twice"]);
    fails_with(
        &["eval", "--methods", "taa,adaptive,taa", "--out", &out],
        &["taa twice"],
    );
    let (code, err) = run(&[
        "view",
        "--headless",
        "--seconds",
        "1",
        "--vis",
        "bogus",
        "--out",
        &out,
    ]);
    assert_eq!(code, 2, "clap's usage error: {err}");
    assert!(err.contains("bogus"), "{err}");
    assert!(
        !std::path::Path::new(&out).exists(),
        "nothing written by refused runs"
    );
}

#[test]
fn camera_paths_with_a_zero_or_parallel_up_vector_are_errors() {
    let head = "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n";
    let zero = format!("{head}0,0,0,-5,0,0,0,0,0,0,45\n");
    let e = CameraPath::parse("zero.csv", &zero)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("zero.csv:2:") && e.contains("up vector is zero"),
        "{e}"
    );
    let parallel = format!("{head}0,0,0,-5,0,0,0,0,0,0,45\n1,0,0,-5,0,0,0,0,0,3,45\n").replacen(
        ",0,0,0,45\n",
        ",0,1,0,45\n",
        1,
    );
    let e = CameraPath::parse("par.csv", &parallel)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("par.csv:3:") && e.contains("parallel"), "{e}");
}

#[test]
#[cfg(unix)]
fn a_material_library_that_is_a_device_is_an_error_not_a_read_until_memory_runs_out() {
    let d = dir("devzero");
    let p = d.join("m.obj");
    std::fs::write(&p, "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let e = scene::obj::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("/dev/zero") && e.contains("not a regular file"),
        "{e}"
    );
}

/// A sweep file with `extra` keys at the top level (one evaluation of the built-in toy
/// car, short).
fn sweep_text(extra: &str, seeds: &str) -> String {
    format!(
        "name = \"s\"\nsizes = [\"16x16\"]\nseeds = [{seeds}]\nmethods = [\"adaptive\"]\n\
         rates = [\"100k\"]\n{extra}\n[[evaluation]]\nname = \"e\"\nscene = \"toycar\"\n\
         start = 1\nduration = 0.1\nwarmup = 0.1\n"
    )
}

#[test]
fn sweep_settings_are_held_to_the_command_lines_ranges() {
    use frameless::evaluation::sweep::Sweep;
    for (extra, key) in [
        ("ideal_spp = 4097", "ideal_spp: 4097 must be in [1, 4096]"),
        ("ideal_spp = 4294967295", "ideal_spp"),
        ("max_depth = 65", "max_depth: 65 must be in [0, 64]"),
        ("max_depth = 4294967295", "max_depth"),
    ] {
        let e = Sweep::parse(&sweep_text(extra, "1"), "s.toml").unwrap_err();
        assert!(e.to_string().contains(key), "{extra}: {e}");
    }
    for extra in ["ideal_spp = 4096", "max_depth = 64", "max_depth = 0"] {
        Sweep::parse(&sweep_text(extra, "1"), "s.toml").unwrap();
    }
}

#[test]
fn a_sweep_of_a_million_seeds_is_refused_and_its_repeats_found_in_one_pass() {
    use frameless::{evaluation::sweep::Sweep, limits::MAX_SWEEP_JOBS};
    let seeds = |n: usize| (0..n).map(|i| i.to_string()).collect::<Vec<_>>().join(",");
    let e = Sweep::parse(&sweep_text("", &seeds(1_000_000)), "s.toml").unwrap_err();
    assert!(
        e.to_string().contains("1000000 jobs, over the limit"),
        "{e}"
    );
    // The largest accepted, and a repeat at its very end.
    let s = Sweep::parse(&sweep_text("", &seeds(MAX_SWEEP_JOBS)), "s.toml").unwrap();
    assert_eq!(s.jobs().len(), MAX_SWEEP_JOBS);
    let repeated = format!("{},5", seeds(MAX_SWEEP_JOBS - 1));
    let e = Sweep::parse(&sweep_text("", &repeated), "s.toml").unwrap_err();
    assert!(e.to_string().contains("lists 5 twice"), "{e}");
}

/// A copy of a committed evaluation folder to edit.
fn eval_folder(name: &str) -> PathBuf {
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/results/toycar");
    let d = dir(name);
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), d.join(e.file_name())).unwrap();
        }
    }
    d
}

fn edit_summary(d: &std::path::Path, f: impl Fn(&mut serde_json::Value)) {
    let p = d.join("summary.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
}

#[test]
fn report_holds_what_it_reads_to_the_budgets() {
    let report = |d: &std::path::Path| run(&["report", d.to_str().unwrap()]);
    // The unedited copy is reported.
    let d = eval_folder("report-ok");
    assert_eq!(report(&d).0, 0);
    // A width past the display budget: an error, not an overflow.
    let d = eval_folder("report-width");
    edit_summary(&d, |v| v["width"] = 2147483664u64.into());
    fails_with(
        &["report", d.to_str().unwrap()],
        &["summary.json", "size", "over the limit"],
    );
    // 100,000 distinct rates.
    let d = eval_folder("report-rates");
    edit_summary(&d, |v| {
        let r0 = v["results"][0].clone();
        v["results"] = (0..100_000)
            .map(|i| {
                let mut r = r0.clone();
                r["rate"] = (1000.0 + i as f64).into();
                r
            })
            .collect();
    });
    fails_with(
        &["report", d.to_str().unwrap()],
        &["summary.json", "result rows"],
    );
    // frames.csv as a device.
    #[cfg(unix)]
    {
        let d = eval_folder("report-device");
        std::fs::remove_file(d.join("frames.csv")).unwrap();
        std::os::unix::fs::symlink("/dev/zero", d.join("frames.csv")).unwrap();
        fails_with(
            &["report", d.to_str().unwrap()],
            &["frames.csv", "not a regular file"],
        );
    }
    // A frame row relabelled with another method: a repeat of that method's row.
    let d = eval_folder("report-relabel");
    let p = d.join("frames.csv");
    let text = std::fs::read_to_string(&p).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let first = lines[1].split(',').next().unwrap().to_string();
    let other = lines[1..]
        .iter()
        .map(|l| l.split(',').next().unwrap())
        .find(|m| *m != first)
        .unwrap()
        .to_string();
    lines[1] = lines[1].replacen(&first, &other, 1);
    std::fs::write(&p, lines.join("\n") + "\n").unwrap();
    fails_with(
        &["report", d.to_str().unwrap()],
        &["frames.csv", "there twice"],
    );
}

#[test]
fn framed_methods_fit_their_budget_at_any_aspect_ratio() {
    let d = dir("aspect");
    for size in ["4096x1", "2048x1", "4096x2", "1x4096"] {
        for m in ["framed-60hz", "late-warp", "taa", "taa-warp"] {
            let out = d.join(format!("{m}-{size}"));
            let (code, err) = run(&[
                "eval",
                "--size",
                size,
                "--rates",
                "100k",
                "--methods",
                m,
                "--duration",
                "0.05",
                "--warmup",
                "0",
                "--ideal-spp",
                "1",
                "--out",
                out.to_str().unwrap(),
            ]);
            assert_eq!(code, 0, "{m} at {size}: {err}");
        }
    }
}

#[test]
fn bart_names_stay_inside_the_bart_folder_and_errors_say_things_once() {
    use frameless::evaluation::sweep::SweepFile;
    let d = dir("bart-names");
    let bart = d.join("bart");
    std::fs::create_dir_all(&bart).unwrap();
    std::fs::write(d.join("outside.aff"), "").unwrap();
    for name in ["bart:../outside.aff", "bart:/etc/passwd", "bart:"] {
        let text =
            sweep_text("", "1").replace("scene = \"toycar\"", &format!("scene = \"{name}\""));
        let p = d.join("s.toml");
        std::fs::write(&p, text).unwrap();
        let f = SweepFile::load(&p).unwrap();
        let e = f.scene_source(0, Some(&bart)).unwrap_err().to_string();
        assert!(e.contains("inside the BART folder"), "{name}: {e}");
    }
    // An OS error is printed once, after the path it concerns.
    let missing = d.join("missing");
    let (code, err) = run(&[
        "merge",
        missing.to_str().unwrap(),
        "--out",
        d.join("o").to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
    assert!(!err.contains("hashs"));
}
