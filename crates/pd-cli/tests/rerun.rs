//! Running again into a folder that holds an earlier run: nothing of the
//! earlier run passes for the new one's, and a scene refused at set-up
//! leaves the earlier run as it was. `pd compare`'s damping variants damp
//! every body, whatever a body's own damping says.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use common::{arg, file_names, json, pd, pd_ok, stderr, temp_dir, tiny_scene};

/// Every file below `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(folder) = pending.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                pending.push(path);
            } else {
                files.insert(path.clone(), std::fs::read(&path).unwrap());
            }
        }
    }
    files
}

#[test]
fn a_shorter_rerun_leaves_no_frame_of_the_earlier_run() {
    let dir = temp_dir("rerun-frames");
    let scene = tiny_scene(&dir, "beam", "backward-euler", "model = \"none\"");
    let out = dir.join("out");
    // 10 steps, a frame every 2: frames 0 to 5, and their pictures.
    pd_ok(&["run", arg(&scene), "--out", arg(&out)]);
    pd_ok(&["render", arg(&out), "--width", "64", "--height", "48"]);
    assert_eq!(file_names(&out.join("frames")).len(), 12);
    assert_eq!(file_names(&out.join("render")).len(), 7);

    // 4 steps into the same folder: frames 0 to 2 only.
    pd_ok(&["run", arg(&scene), "--out", arg(&out), "--steps", "4"]);
    let expected: Vec<String> = (0..3)
        .flat_map(|i| [format!("frame_{i:05}.obj"), format!("frame_{i:05}.vtk")])
        .collect();
    assert_eq!(file_names(&out.join("frames")), expected);
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("\"frames\": 3"), "{summary}");
    pd_ok(&["render", arg(&out), "--width", "64", "--height", "48"]);
    assert_eq!(
        file_names(&out.join("render")),
        [
            "animation.gif",
            "frame_00000.png",
            "frame_00001.png",
            "frame_00002.png"
        ]
    );

    // A scene without probes leaves no probes.csv of the earlier run.
    let text = std::fs::read_to_string(&scene).unwrap();
    let unprobed = dir.join("unprobed.toml");
    std::fs::write(&unprobed, text.replace("probes = [4, 19]\n", "")).unwrap();
    assert!(out.join("probes.csv").exists());
    pd_ok(&["run", arg(&unprobed), "--out", arg(&out)]);
    assert!(!out.join("probes.csv").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_solver_refused_at_set_up_leaves_the_earlier_run_as_it_was() {
    let dir = temp_dir("rerun-refused");
    let lagged = "model = \"rayleigh-lagged\"\nstiffness = 0.001";
    let scene = tiny_scene(&dir, "beam", "backward-euler", lagged);
    let out = dir.join("out");
    pd_ok(&["run", arg(&scene), "--out", arg(&out)]);
    let before = snapshot(&out);

    // Newton and L-BFGS cannot run a lagged damping model.
    let text = std::fs::read_to_string(&scene).unwrap();
    for method in ["lbfgs", "newton"] {
        let refused = dir.join(format!("{method}.toml"));
        std::fs::write(
            &refused,
            format!("{text}\n[solver]\nmethod = \"{method}\"\n"),
        )
        .unwrap();
        let output = pd(&["run", arg(&refused), "--out", arg(&out)]);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(2), "{method}: {message}");
        assert!(
            message.contains(&format!("{}: solver.method:", refused.display()))
                && message.contains("lagged"),
            "{method}: {message}"
        );
        assert!(
            snapshot(&out) == before,
            "{method}: the earlier run changed"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn compare_variants_damp_every_body() {
    let dir = temp_dir("compare-own-damping");
    let scene = tiny_scene(&dir, "beam", "backward-euler", "model = \"none\"");
    let text = std::fs::read_to_string(&scene).unwrap();
    // The body's own damping would keep it damped in every variant.
    let own = text.replace(
        "initial_velocity",
        "damping = { model = \"laplacian\", ratio = 0.3 }\ninitial_velocity",
    );
    let scene = dir.join("own.toml");
    std::fs::write(&scene, own).unwrap();
    let out = dir.join("out");
    pd_ok(&[
        "compare",
        arg(&scene),
        "--damping",
        "none,laplacian",
        "--out",
        arg(&out),
    ]);
    let table = json(&out.join("comparison.json"));
    let rows = table["variants"].as_array().unwrap();
    let final_energy = |i: usize| rows[i]["final_energy"].as_f64().unwrap();
    // Undamped, the swinging beam keeps more energy than under Laplacian
    // damping; with the body's own damping left in place both variants
    // would end with the same energy, bit for bit.
    assert!(final_energy(1) < final_energy(0), "{rows:?}");
    let summary = std::fs::read_to_string(out.join("none/summary.json")).unwrap();
    assert!(summary.contains("\"damping\": \"none\""), "{summary}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_empty_format_list_writes_and_counts_no_frame() {
    let dir = temp_dir("no-formats");
    let scene = tiny_scene(&dir, "beam", "backward-euler", "model = \"none\"");
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(
        &scene,
        text.replace("formats = [\"vtk\", \"obj\"]", "formats = []"),
    )
    .unwrap();
    let out = dir.join("out");
    pd_ok(&["run", arg(&scene), "--out", arg(&out)]);
    assert!(!out.join("frames").exists());
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("\"frames\": 0"), "{summary}");
    std::fs::remove_dir_all(&dir).unwrap();
}
