//! `pd render`, `pd plot` and `pd compare` on tiny runs: the files exist,
//! have the right counts and sizes, the body is visible, and bad input or
//! an unwritable output gives the documented exit codes.

mod common;

use std::path::Path;

use common::{arg, json, pd, pd_ok, read_png, stderr, temp_dir, tiny_scene};

/// Number of frames in a GIF, and their size.
fn gif_frames(path: &Path) -> (usize, (u16, u16)) {
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(path).unwrap())
        .unwrap();
    let size = (decoder.width(), decoder.height());
    let mut count = 0;
    while decoder.read_next_frame().unwrap().is_some() {
        count += 1;
    }
    (count, size)
}

#[test]
fn render_writes_a_png_per_frame_and_a_gif() {
    let dir = temp_dir("render");
    let scene = tiny_scene(&dir, "beam", "backward-euler", "model = \"none\"");
    let run = dir.join("run");
    pd_ok(&["run", arg(&scene), "--out", arg(&run)]);
    pd_ok(&[
        "render",
        arg(&run),
        "--width",
        "160",
        "--height",
        "120",
        "--gif-frames",
        "4",
    ]);

    // 10 steps, a frame every 2: frames 0..=5.
    let render = run.join("render");
    for i in 0..6 {
        let (w, h, pixels, channels) = read_png(&render.join(format!("frame_{i:05}.png")));
        assert_eq!((w, h), (160, 120));
        // The body is drawn in blue shades (blue well above red); the
        // background is white and the ground grey. A 0.4 m beam in a view
        // fitted to about 1.5x its size covers far more than 1% of the
        // 19200 pixels.
        let body = pixels
            .chunks_exact(channels)
            .filter(|p| u16::from(p[2]) > u16::from(p[0]) + 40)
            .count();
        assert!(body > 192, "frame {i}: only {body} body pixels");
    }
    assert!(!render.join("frame_00006.png").exists());
    // At most 4 of 6 frames: every 2nd, so 3; shrunk by 2.
    assert_eq!(gif_frames(&render.join("animation.gif")), (3, (80, 60)));

    // Panels side by side: twice as wide.
    let out = dir.join("panels");
    pd_ok(&[
        "render",
        arg(&run),
        "--panel",
        arg(&run),
        "--out",
        arg(&out),
        "--width",
        "100",
        "--height",
        "80",
    ]);
    assert_eq!(read_png(&out.join("frame_00000.png")).0, 200);
}

#[test]
fn render_and_plot_report_bad_input_and_output() {
    let dir = temp_dir("render-bad");
    // Not a run folder.
    let output = pd(&["render", arg(&dir)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    let output = pd(&["plot", arg(&dir)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));

    let scene = tiny_scene(&dir, "beam", "backward-euler", "model = \"none\"");
    let run = dir.join("run");
    pd_ok(&["run", arg(&scene), "--out", arg(&run)]);
    // A malformed frame names its file and line.
    std::fs::write(run.join("frames/frame_00003.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
    let output = pd(&["render", arg(&run)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("frame_00003.obj:2"),
        "{}",
        stderr(&output)
    );
    std::fs::remove_file(run.join("frames/frame_00003.obj")).unwrap();

    // Pictures too large to hold are bad input, before any is drawn
    // (100,000 x 100,000 pixels, six frames: 180 GB).
    let output = pd(&[
        "render",
        arg(&run),
        "--width",
        "100000",
        "--height",
        "100000",
    ]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("GB of memory"),
        "{}",
        stderr(&output)
    );

    // An output folder that cannot be created (below a file): exit code 4.
    let blocker = dir.join("file");
    std::fs::write(&blocker, "").unwrap();
    let output = pd(&["render", arg(&run), "--out", arg(&blocker.join("render"))]);
    assert_eq!(output.status.code(), Some(4), "{}", stderr(&output));

    // A malformed metrics.csv names its line.
    let metrics = run.join("metrics.csv");
    let text = std::fs::read_to_string(&metrics).unwrap();
    std::fs::write(&metrics, text.replacen("\n0,", "\nzero,", 1)).unwrap();
    let output = pd(&["plot", arg(&run)]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("metrics.csv:2"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn plot_writes_png_and_svg() {
    let dir = temp_dir("plot");
    let scene = tiny_scene(&dir, "beam", "bdf2", "model = \"none\"");
    let run = dir.join("run");
    pd_ok(&["run", arg(&scene), "--out", arg(&run)]);
    pd_ok(&["plot", arg(&run)]);
    for (stem, label) in [
        ("energy", "kinetic"),
        ("linear_momentum", "p_y"),
        ("angular_momentum", "L_z"),
    ] {
        let (w, h, _, _) = read_png(&run.join(format!("plots/{stem}.png")));
        assert_eq!((w, h), (800, 500));
        let svg = std::fs::read_to_string(run.join(format!("plots/{stem}.svg"))).unwrap();
        assert!(
            svg.contains(label) && svg.contains("<polyline"),
            "{stem}.svg"
        );
    }
}

#[test]
fn compare_damping_models_and_integrators() {
    let dir = temp_dir("compare");
    let scene = tiny_scene(&dir, "beam", "backward-euler", "model = \"none\"");
    let out = dir.join("damping");
    pd_ok(&[
        "compare",
        arg(&scene),
        "--damping",
        "none,laplacian,pbd",
        "--out",
        arg(&out),
    ]);
    let table = json(&out.join("comparison.json"));
    let rows = table["variants"].as_array().unwrap();
    assert_eq!(
        rows.iter()
            .map(|r| r["variant"].as_str().unwrap())
            .collect::<Vec<_>>(),
        ["none", "laplacian", "pbd"]
    );
    assert_eq!(rows[0]["overhead"].as_f64(), Some(0.0));
    // Laplacian damping removes energy that the undamped run keeps
    // (backward Euler dissipates too, but less).
    let final_energy = |i: usize| rows[i]["final_energy"].as_f64().unwrap();
    assert!(final_energy(1) < final_energy(0), "{rows:?}");
    let md = std::fs::read_to_string(out.join("comparison.md")).unwrap();
    assert_eq!(md.lines().filter(|l| l.starts_with("| ")).count(), 1 + 3);
    // Up to 3 variants get 320 x 240 panels, side by side.
    assert_eq!(gif_frames(&out.join("render/animation.gif")).1, (960, 240));
    assert!(
        std::fs::read_to_string(out.join("energy.svg"))
            .unwrap()
            .contains("laplacian")
    );

    let out = dir.join("integrators");
    pd_ok(&[
        "compare",
        arg(&scene),
        "--integrator",
        "backward-euler,bdf2",
        "--out",
        arg(&out),
    ]);
    assert!(out.join("bdf2/metrics.csv").exists());

    for bad in [
        vec!["compare", arg(&scene), "--damping", "viscous"],
        vec!["compare", arg(&scene), "--damping", "none,none"],
        vec!["compare", arg(&scene)],
    ] {
        let output = pd(&bad);
        assert_eq!(
            output.status.code(),
            Some(2),
            "{bad:?}: {}",
            stderr(&output)
        );
    }
}

#[test]
fn compare_reports_divergence_after_writing_the_table() {
    let dir = temp_dir("compare-diverge");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/diverging.toml");
    let out = dir.join("out");
    let output = pd(&[
        "compare",
        arg(&scene),
        "--damping",
        "none",
        "--out",
        arg(&out),
    ]);
    assert_eq!(output.status.code(), Some(3), "{}", stderr(&output));
    let table = std::fs::read_to_string(out.join("comparison.json")).unwrap();
    assert!(table.contains("\"diverged\""), "{table}");
}
