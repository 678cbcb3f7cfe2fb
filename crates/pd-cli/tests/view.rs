//! `pd view`: the page in a real browser (headless Chromium, started by
//! the test; skipped with a message where it is absent), and the page's
//! input errors without one.
//!
//! In the browser, for the default scene, a contact scene with a mesh
//! collider and a cloth scene: the page runs without errors, the bodies
//! and the colliders are on screen (pixels of their colours against the
//! neutral background), frames 0 and last differ, and `#frame=N` and the
//! slider agree.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{arg, pd, pd_ok, read_png, stderr, temp_dir};

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Chromium: `PD_CHROMIUM`, else `chromium` or `chromium-browser` on the
/// path.
fn chromium() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("PD_CHROMIUM") {
        return Some(PathBuf::from(path));
    }
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .flat_map(|dir| ["chromium", "chromium-browser"].map(|name| dir.join(name)))
        .find(|candidate| candidate.is_file())
}

/// Headless Chromium on `page#frame=N`, with WebGL through SwiftShader
/// and no network; `mode` is `--dump-dom` or `--screenshot=PATH`. Returns
/// stdout.
fn browse(browser: &Path, page: &Path, frame: usize, mode: &str, profile: &Path) -> String {
    let url = format!(
        "file://{}#frame={frame}",
        page.canonicalize().unwrap().display()
    );
    let output = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--disable-quic",
            "--window-size=800,600",
            // Scripts run to completion (the page is static once drawn).
            "--virtual-time-budget=10000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(mode)
        .arg(url)
        .output()
        .expect("chromium starts");
    assert!(
        output.status.success(),
        "chromium {mode} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// The value of `name="..."` in the first element of `dom` whose tag
/// starts with `start`.
fn attribute(dom: &str, start: &str, name: &str) -> String {
    let element = &dom[dom
        .find(start)
        .unwrap_or_else(|| panic!("{start} in the page"))..];
    let element = &element[..element.find('>').unwrap()];
    let key = format!("{name}=\"");
    let value = &element[element
        .find(&key)
        .unwrap_or_else(|| panic!("{name} in {element}"))
        + key.len()..];
    value[..value.find('"').unwrap()].to_string()
}

/// Pixel counts in the 3D area (the top half of the window, above the
/// controls and plots): the body's warm colour, the colliders' cool one.
struct Pixels {
    rgb: Vec<[u8; 3]>,
}

impl Pixels {
    fn of(path: &Path) -> Self {
        let (width, height, bytes, samples) = read_png(path);
        let rows = height as usize / 2;
        let rgb = bytes
            .chunks(samples)
            .take(rows * width as usize)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        Pixels { rgb }
    }

    /// The body's orange, lit or seen through a collider: red well above
    /// blue. The background is grey (red and blue within 3).
    fn warm(&self) -> usize {
        (self.rgb.iter())
            .filter(|p| i32::from(p[0]) > i32::from(p[2]) + 40)
            .count()
    }

    /// The colliders' blue: blue well above red.
    fn cool(&self) -> usize {
        (self.rgb.iter())
            .filter(|p| i32::from(p[2]) > i32::from(p[0]) + 15)
            .count()
    }

    /// Pixels that differ from `other`'s by more than 30 in a channel.
    fn differing(&self, other: &Pixels) -> usize {
        (self.rgb.iter().zip(&other.rgb))
            .filter(|(a, b)| (0..3).any(|k| a[k].abs_diff(b[k]) > 30))
            .count()
    }
}

/// Least pixels that count as "on screen": 0.1% of the 800 x 300 area; a
/// body or collider framed by the camera covers 5% or more of it.
const VISIBLE: usize = 240;

/// Runs `scene` for `steps` into `dir/name`, writes its page, and checks it
/// in the browser. `colliders`: whether the scene has colliders to see.
fn check_scene(
    browser: &Path,
    dir: &Path,
    name: &str,
    scene: Option<&Path>,
    steps: &str,
    colliders: bool,
) {
    let out = dir.join(name);
    let mut args = vec!["run"];
    if let Some(scene) = scene {
        args.push(arg(scene));
    }
    args.extend(["--steps", steps, "--out", arg(&out), "--view"]);
    pd_ok(&args);
    let page = out.join("view.html");
    let text = std::fs::read_to_string(&page).unwrap();
    // Self-contained: nothing fetched from anywhere.
    assert!(
        !text.contains("http://") && !text.contains("https://"),
        "{name}: the page names a URL"
    );
    assert!(!text.contains(" src="), "{name}: the page loads a file");
    let profile = dir.join(format!("{name}-profile"));

    // Where `#frame=N` points, the slider and the page's state agree.
    let dom = browse(browser, &page, 0, "--dump-dom", &profile);
    assert_eq!(
        attribute(&dom, "<div id=\"status\"", "data-ready"),
        "1",
        "{name}: the page did not finish"
    );
    assert_eq!(
        attribute(&dom, "<div id=\"status\"", "data-errors"),
        "",
        "{name}: errors on the page"
    );
    let frames: usize = attribute(&dom, "<div id=\"status\"", "data-frames")
        .parse()
        .unwrap();
    assert!(frames >= 3, "{name}: {frames} frames");
    let middle = frames / 2;
    let dom = browse(browser, &page, middle, "--dump-dom", &profile);
    assert_eq!(
        attribute(&dom, "<div id=\"status\"", "data-frame"),
        middle.to_string()
    );
    assert_eq!(
        attribute(&dom, "<input id=\"slider\"", "value"),
        middle.to_string()
    );
    assert_eq!(attribute(&dom, "<div id=\"status\"", "data-errors"), "");

    let first = dir.join(format!("{name}-first.png"));
    let last = dir.join(format!("{name}-last.png"));
    browse(
        browser,
        &page,
        0,
        &format!("--screenshot={}", first.display()),
        &profile,
    );
    browse(
        browser,
        &page,
        frames - 1,
        &format!("--screenshot={}", last.display()),
        &profile,
    );
    let (a, b) = (Pixels::of(&first), Pixels::of(&last));
    for (which, p) in [("first", &a), ("last", &b)] {
        assert!(
            p.warm() >= VISIBLE,
            "{name}, {which} frame: {} body pixels",
            p.warm()
        );
        if colliders {
            assert!(
                p.cool() >= VISIBLE,
                "{name}, {which} frame: {} collider pixels",
                p.cool()
            );
        }
    }
    assert!(
        a.differing(&b) >= VISIBLE,
        "{name}: frames 0 and last look the same"
    );
    if let (Some(target), None) = (std::env::var_os("PD_VIEW_SCREENSHOT"), scene) {
        std::fs::copy(&last, target).unwrap();
    }
}

#[test]
fn pages_render_in_headless_chromium() {
    let Some(browser) = chromium() else {
        eprintln!(
            "skipped: Chromium not found (install Debian's `chromium` package, or set \
             PD_CHROMIUM to a Chromium binary); .ci/run installs it"
        );
        return;
    };
    let dir = temp_dir("view-browser");
    let scenes = root().join("scenes");
    // The default cantilever (frames every 5 steps), a ball dropped into a
    // mesh bowl, and a flag.
    check_scene(&browser, &dir, "default", None, "60", false);
    let bowl = scenes.join("contact_bowl.toml");
    check_scene(&browser, &dir, "bowl", Some(&bowl), "100", true);
    let flag = scenes.join("cloth_flag.toml");
    check_scene(&browser, &dir, "flag", Some(&flag), "60", false);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A short default run with frames, for the error cases.
fn short_run(dir: &Path) -> PathBuf {
    let out = dir.join("run");
    pd_ok(&["run", "--steps", "10", "--out", arg(&out)]);
    out
}

#[test]
fn a_folder_without_frames_is_bad_input() {
    let dir = temp_dir("view-no-frames");
    let output = pd(&["view", arg(&dir)]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("frames"), "{}", stderr(&output));
}

#[test]
fn frames_of_different_vertex_counts_are_bad_input() {
    let dir = temp_dir("view-mixed");
    let run = short_run(&dir);
    // The second frame loses its last vertex line.
    let frame = run.join("frames/frame_00001.obj");
    let text = std::fs::read_to_string(&frame).unwrap();
    let last_v = text.rfind("\nv ").unwrap();
    let end = last_v + 1 + text[last_v + 1..].find('\n').unwrap();
    std::fs::write(&frame, format!("{}{}", &text[..last_v], &text[end..])).unwrap();
    let output = pd(&["view", arg(&run)]);
    let message = stderr(&output);
    // Either the face that now points past the end, or the count.
    assert_eq!(output.status.code(), Some(2), "{message}");
    assert!(message.contains("frame_00001.obj"), "{message}");
    assert!(!run.join("view.html").exists());
}

#[test]
fn without_metrics_the_page_has_no_energy_curves() {
    let dir = temp_dir("view-no-metrics");
    let run = short_run(&dir);
    std::fs::remove_file(run.join("metrics.csv")).unwrap();
    pd_ok(&["view", arg(&run), "-o", arg(&dir.join("page.html"))]);
    let page = std::fs::read_to_string(dir.join("page.html")).unwrap();
    assert!(page.contains("\"metrics\":null"));
}

#[test]
fn a_page_above_max_mb_is_refused_with_the_way_out() {
    let dir = temp_dir("view-too-big");
    let run = short_run(&dir);
    let output = pd(&["view", arg(&run), "--max-mb", "0.001"]);
    assert_eq!(output.status.code(), Some(2));
    let message = stderr(&output);
    assert!(message.contains("--every"), "{message}");
    assert!(!run.join("view.html").exists());
    // And the way out works: every 1000th frame (the first and last kept).
    pd_ok(&["view", arg(&run), "--every", "1000", "--max-mb", "0.5"]);
    assert!(run.join("view.html").exists());
}

#[test]
fn two_runs_share_one_page() {
    let dir = temp_dir("view-two");
    let run = short_run(&dir);
    let page = dir.join("compare.html");
    pd_ok(&["view", arg(&run), arg(&run), "-o", arg(&page)]);
    let text = std::fs::read_to_string(&page).unwrap();
    assert_eq!(text.matches("\"label\":\"run\"").count(), 2);
}
