//! `pd-probe contact`: the cost of contact per step, at equal iterations:
//! a soft cube resting on a floor (collider contact) and two cubes stacked
//! on it (`contact.bodies = true`), each against the same scene with no
//! contact at all (the body then falls freely: the same matrix, the same
//! iterations, no contact work). Median total step time over the measured
//! steps, after a warm-up.

use std::path::Path;

use pd_io::scene::{Scene, Syntax};
use serde_json::{Value, json};

/// The scene: one cube of `cells` per side resting on the floor, or two
/// stacked (`stack`); `contact` adds the floor and, for the stack,
/// contact between the bodies. A scene TOML text (public for
/// `examples/contact_case.rs`).
pub fn scene(cells: usize, stack: bool, contact: bool) -> String {
    let cube = |size: f64, y: f64| {
        format!(
            "[[body]]\nmesh = {{ generator = \"box\", size = [{size:?}, {size:?}, {size:?}], \
             cells = [{cells}, {cells}, {cells}] }}\ndensity = 1000.0\n\
             constraints = [ {{ kind = \"tet-strain\", stiffness = 1.0e5 }} ]\n\
             translate = [0.0, {y:?}, 0.0]\n"
        )
    };
    let mut text = String::from(
        "[simulation]\ndt = 0.005\nsteps = 1\ngravity = [0.0, -9.81, 0.0]\n\
         integrator = \"backward-euler\"\niterations = 20\nthreads = 1\n\n",
    );
    if contact {
        text.push_str(
            "[[collider]]\nshape = \"plane\"\npoint = [0.0, 0.0, 0.0]\n\
             normal = [0.0, 1.0, 0.0]\nfriction = 0.5\n\n[contact]\nthickness = 0.001\n",
        );
        if stack {
            text.push_str("bodies = true\nfriction = 0.5\n");
        }
        text.push('\n');
    }
    text.push_str(&cube(0.2, 0.001));
    if stack {
        text.push_str(&cube(0.2, 0.2015));
    }
    text
}

/// Median total step time (ms) over `steps` steps after `warmup`, and the
/// active contacts at the end.
fn time(text: &str, warmup: usize, steps: usize) -> Result<(f64, usize, usize), String> {
    let scene = Scene::parse(text, Syntax::Toml, Path::new("contact-bench.toml"))
        .map_err(|e| e.to_string())?;
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    sim.run(warmup).map_err(|e| e.to_string())?;
    let stats = sim.run(steps).map_err(|e| e.to_string())?;
    let mut ms: Vec<f64> = stats.iter().map(|s| s.total_seconds * 1e3).collect();
    ms.sort_by(f64::total_cmp);
    let contacts = stats.last().map_or(0, |s| s.contacts);
    let iterations = stats.iter().map(|s| s.iterations).sum::<usize>() / stats.len().max(1);
    Ok((ms[ms.len() / 2], contacts, iterations))
}

/// Measures both scenes with and without contact.
///
/// # Errors
/// A scene that fails to build or run.
pub fn measure(cells: usize, warmup: usize, steps: usize) -> Result<Value, String> {
    let mut rows = Vec::new();
    for (label, stack) in [("cube on the floor", false), ("two cubes stacked", true)] {
        let (without, _, it_without) = time(&scene(cells, stack, false), warmup, steps)?;
        let (with, contacts, it_with) = time(&scene(cells, stack, true), warmup, steps)?;
        rows.push(json!({
            "scene": label,
            "cells": cells,
            "without_ms": without,
            "with_ms": with,
            "ratio": with / without,
            "contacts": contacts,
            "iterations_without": it_without,
            "iterations_with": it_with,
        }));
    }
    Ok(json!({ "rows": rows, "steps": steps, "warmup": warmup }))
}
