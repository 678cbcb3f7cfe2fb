//! Per-body damping through the scene file (`[[body]] damping = { ... }`):
//! each body keeps its own behaviour, a scene whose bodies all name the same
//! damping runs as the `[damping]` scene, and mistakes name
//! `body[i].damping.KEY`.
//!
//! The ratio is measured as in `damping_ratio.rs`: implicit midpoint is, for
//! a linear system, the Cayley map of the continuous equation, so one
//! decoupled mode's coordinate obeys `q_{n+1} = a q_n + b q_{n-1}`, whose
//! roots `mu` map back to the continuous `lambda = (2/h)(mu - 1)/(mu + 1)`,
//! and `zeta = -Re(lambda) / |lambda|`.

use std::ops::Range;
use std::path::Path;

use nalgebra::{Complex, Matrix2, Vector2};
use pd_io::scene::{Scene, Syntax};
use pd_mesh::Point;
use pd_solver::{Simulation, State};

fn scene(text: &str) -> Scene {
    Scene::parse(text, Syntax::Toml, Path::new("per_body.toml")).unwrap()
}

/// The clamped beam of `damping_ratio.rs` (1 m x 0.1 m x 0.1 m, 10 x 1 x 1
/// cells, E = 1 MPa, rho = 1000 kg/m^3), shifted by `z` m, with `extra`
/// lines (its `damping`).
fn beam_body(z: f64, extra: &str) -> String {
    format!(
        "[[body]]\nmesh = {{ generator = \"box\", size = [1.0, 0.1, 0.1], cells = [10, 1, 1] }}\n\
         density = 1000.0\nconstraints = [ {{ kind = \"tet-strain\", stiffness = 1.0e6 }} ]\n\
         fixed = {{ box = {{ min = [-1.0, -1.0, -1.0], max = [1e-9, 1.0, 1.0] }} }}\n\
         translate = [0.0, 0.0, {z}]\n{extra}\n"
    )
}

/// Implicit midpoint at `dt`, no gravity, solved to 1e-10, with `rest`
/// (the `[damping]` table and the bodies).
fn scene_text(dt: f64, rest: &str) -> String {
    format!(
        "[simulation]\ndt = {dt}\nsteps = 1\ngravity = [0.0, 0.0, 0.0]\n\
         integrator = \"implicit-midpoint\"\niterations = 5000\ntolerance = 1e-10\n\n{rest}"
    )
}

/// The continuous damping ratio behind implicit midpoint's roots of `q`.
fn midpoint_ratio(q: &[f64], dt: f64) -> f64 {
    let (mut normal, mut rhs) = (Matrix2::zeros(), Vector2::zeros());
    for n in 1..q.len() - 1 {
        let row = Vector2::new(q[n], q[n - 1]);
        normal += row * row.transpose();
        rhs += row * q[n + 1];
    }
    let ab = normal.lu().solve(&rhs).unwrap();
    let (a, b) = (Complex::new(ab[0], 0.0), Complex::new(ab[1], 0.0));
    let mu = (a + (a * a + 4.0 * b).sqrt()) / 2.0;
    let one = Complex::new(1.0, 0.0);
    let lambda = (mu - one) / (mu + one) * (2.0 / dt);
    -lambda.re / lambda.norm()
}

/// Releases every body of `ranges` from rest, bent along `shape` (one
/// body's mode, scaled so that its largest displacement is `1e-3` m), and
/// records each body's modal coordinate for `steps` steps.
fn release(
    sim: &mut Simulation,
    shape: &[Point],
    ranges: &[Range<usize>],
    steps: usize,
) -> Vec<Vec<f64>> {
    let rest = sim.model().rest_positions().to_vec();
    let masses = sim.model().masses().to_vec();
    let largest = shape.iter().map(|p| p.norm()).fold(0.0, f64::max);
    let mut positions = rest.clone();
    for range in ranges {
        for (v, p) in range.clone().zip(shape) {
            positions[v] += p * (1e-3 / largest);
        }
    }
    sim.set_state(State {
        positions,
        velocities: vec![Point::zeros(); rest.len()],
    })
    .unwrap();
    let q = |sim: &Simulation, range: &Range<usize>| -> f64 {
        let x = &sim.state().positions;
        range
            .clone()
            .zip(shape)
            .map(|(v, p)| masses[v] * p.dot(&(x[v] - rest[v])))
            .sum()
    };
    let mut out: Vec<Vec<f64>> = ranges.iter().map(|r| vec![q(sim, r)]).collect();
    for _ in 0..steps {
        sim.step().unwrap();
        for (history, range) in out.iter_mut().zip(ranges) {
            history.push(q(sim, range));
        }
    }
    out
}

#[test]
fn an_undamped_and_a_damped_beam_keep_their_own_behaviour() {
    let zeta = 0.05;
    // h omega_1 = 0.1, as in damping_ratio.rs (omega_1 = 5.799 rad/s).
    let dt = 0.1 / 5.798936;
    let one = scene(&scene_text(dt, &beam_body(0.0, "")));
    let mode = pd_modes::elastic_modes(one.build().unwrap().model(), 1)
        .unwrap()
        .modes
        .remove(0);
    let text = scene_text(
        dt,
        &format!(
            "{}{}",
            beam_body(0.0, "damping = { model = \"none\" }"),
            beam_body(
                0.5,
                &format!("damping = {{ model = \"laplacian\", ratio = {zeta} }}")
            ),
        ),
    );
    let mut sim = scene(&text).build().unwrap();
    assert_eq!(sim.damping_name(), "per-body");
    let ranges: Vec<_> = sim.model().bodies().iter().map(|b| b.vertices()).collect();
    let steps = (2.0 * std::f64::consts::TAU / (mode.omega * dt)).round() as usize;
    let q = release(&mut sim, &mode.shape, &ranges, steps);
    let (undamped, damped) = (midpoint_ratio(&q[0], dt), midpoint_ratio(&q[1], dt));
    println!("undamped body: zeta {undamped:e}; damped body: zeta {damped} (asked {zeta})");
    // The damped beam is the beam of damping_ratio.rs with its ratio fitted
    // to its own first mode (the same mode: it is that beam, alone): the
    // same 2% (mode coupling through L_d, estimated there at 5e-3).
    assert!((damped - zeta).abs() <= 0.02 * zeta, "{damped}");
    // The undamped beam gets no damping term at all: implicit midpoint
    // keeps its energy up to the solve (relative change 1e-10 per step, so
    // ~1e-10 relative energy per step and ~1e-8 over the 126 steps) and the
    // geometric nonlinearity at 1e-3 L (frequency shift ~1e-6, which
    // changes no decay), so its fitted ratio is of order 1e-8 (measured
    // 2.9e-8). 1e-5 is the smallest ratio whose decay over the two periods
    // (exp(-4 pi 1e-5) = 1 - 1.3e-4) stands clear of that; a leak of the
    // other body's damping would show as a ratio of order 0.05.
    assert!(undamped.abs() <= 1e-5, "{undamped}");
}

#[test]
fn every_body_with_the_same_damping_runs_as_the_global_table() {
    let dt = 0.01;
    let damping = "model = \"laplacian\", stiffness = 0.01, mass = 0.5";
    let global = scene_text(
        dt,
        &format!(
            "[damping]\n{}\n\n{}{}",
            damping.replace(", ", "\n"),
            beam_body(0.0, ""),
            beam_body(0.5, "")
        ),
    );
    let own = format!("damping = {{ {damping} }}");
    let per_body = scene_text(
        dt,
        &format!("{}{}", beam_body(0.0, &own), beam_body(0.5, &own)),
    );
    let run = |text: &str| {
        let mut sim = scene(text).build().unwrap();
        let n = sim.model().num_vertices();
        let kick: Vec<Point> = (0..n)
            .map(|v| Point::new(0.0, 0.01 * v as f64, 0.0))
            .collect();
        let mut state = sim.state().clone();
        state.velocities = kick;
        sim.set_state(state).unwrap();
        sim.run(20).unwrap();
        sim.state().clone()
    };
    assert_eq!(run(&global), run(&per_body));
}

#[test]
fn per_body_mistakes_name_the_body_and_key() {
    let parse = |extra: &str| {
        Scene::parse(
            &scene_text(
                0.01,
                &format!("{}{}", beam_body(0.0, ""), beam_body(0.5, extra)),
            ),
            Syntax::Toml,
            Path::new("p.toml"),
        )
    };
    let unknown = parse("damping = { model = \"viscous\" }")
        .unwrap_err()
        .to_string();
    assert!(unknown.contains("body[1].damping.model"), "{unknown}");
    let field = parse("damping = { model = \"pbd\", stiffness = 0.1 }")
        .unwrap_err()
        .to_string();
    assert!(field.contains("body[1].damping.stiffness"), "{field}");
    let both = parse("damping = { model = \"laplacian\", stiffness = 0.01, ratio = 0.1 }")
        .unwrap_err()
        .to_string();
    assert!(
        both.contains("body[1].damping.stiffness") && both.contains("not both"),
        "{both}"
    );
    let bad = parse("damping = { model = \"laplacian\", stiffness = -1.0 }")
        .unwrap_err()
        .to_string();
    assert!(
        bad.contains("body[1].damping") && bad.contains("stiffness"),
        "{bad}"
    );
    let typo = parse("damping = { model = \"laplacian\", stifness = 0.01 }")
        .unwrap_err()
        .to_string();
    assert!(typo.contains("stifness"), "{typo}");
    // A lagged model cannot share a step with another body's model.
    let lagged = scene(&scene_text(
        0.01,
        &format!(
            "{}{}",
            beam_body(0.0, "damping = { model = \"laplacian\", stiffness = 0.01 }"),
            beam_body(
                0.5,
                "damping = { model = \"rayleigh-lagged\", stiffness = 0.01 }"
            )
        ),
    ))
    .build()
    .unwrap_err()
    .to_string();
    assert!(
        lagged.contains("body[1].damping") && lagged.contains("rayleigh-lagged"),
        "{lagged}"
    );
}
