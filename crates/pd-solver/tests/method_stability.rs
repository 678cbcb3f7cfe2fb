//! The stability corners (`tests/stability_corners.rs`, a corner of
//! `cargo xtask stability`) with a method axis: wherever plain local-global
//! PD completes a run, every other method completes it too (it may stop
//! with `SolverError::Diverged` only where plain PD does), and no method
//! fails with another error except the documented refusals (`newton` and
//! `lbfgs` with lagged Rayleigh damping, `newton` with rotation-preserving
//! Laplacian damping).

use pd_io::scene::{Scene, Syntax};
use pd_solver::{SolverError, SolverMethod, State};

const DAMPING: [&str; 7] = [
    "",
    "[damping]\nmodel = \"ether-drag\"\nrate = 1000.0\n",
    "[damping]\nmodel = \"ether-drag\"\nrate = 1000.0\nimplicit = true\n",
    "[damping]\nmodel = \"pbd\"\nfactor = 1.0\n",
    "[damping]\nmodel = \"rayleigh-lagged\"\nstiffness = 1000.0\n",
    "[damping]\nmodel = \"laplacian\"\nstiffness = 1000.0\n",
    "[damping]\nmodel = \"laplacian\"\nstiffness = 1000.0\npreserve_rotation = true\n",
];

const INTEGRATORS: [&str; 3] = ["backward-euler", "implicit-midpoint", "bdf2"];

#[derive(Clone, Copy, PartialEq)]
enum Start {
    Rest,
    Inverted,
    Compressed,
    Fast,
}

/// Stiffness (Pa), time step (s), density (kg/m^3), iterations, clamped,
/// start.
const CORNERS: [(f64, f64, f64, usize, bool, Start); 5] = [
    (1e9, 0.1, 1.0, 1, true, Start::Inverted),
    (1e9, 0.1, 1.0, 10, true, Start::Inverted),
    (1e0, 1e-5, 1e5, 30, false, Start::Compressed),
    (1e9, 0.1, 1e5, 3, false, Start::Fast),
    (1e6, 0.01, 1e3, 10, true, Start::Rest),
];

/// Runs one corner with `method`: `Ok(true)` if it completed 8 steps,
/// `Ok(false)` if it stopped with the divergence error, `Err` otherwise.
fn run(
    corner: usize,
    integrator: &str,
    damping: &str,
    method: SolverMethod,
) -> Result<bool, String> {
    let (stiffness, dt, density, iterations, clamped, start) = CORNERS[corner];
    let fixed = if clamped {
        "fixed = { box = { min = [-1.0, -1.0, -1.0], max = [0.001, 1.0, 1.0] } }\n"
    } else {
        ""
    };
    let velocity = if start == Start::Fast {
        "initial_velocity = [100.0, -60.0, 30.0]\nangular_velocity = [0.0, 0.0, 300.0]\n"
    } else {
        ""
    };
    let text = format!(
        "[simulation]\ndt = {dt:e}\nsteps = 8\nintegrator = \"{integrator}\"\n\
         iterations = {iterations}\nthreads = 1\n\n[solver]\nmethod = \"{}\"\n\n{damping}\n\
         [[body]]\nmesh = {{ generator = \"box\", size = [1.0, 0.25, 0.25], cells = [2, 1, 1] }}\n\
         density = {density:e}\nconstraints = [ {{ kind = \"tet-strain\", stiffness = {stiffness:e} }} ]\n\
         {fixed}{velocity}",
        method.name()
    );
    let scene = Scene::parse(&text, Syntax::Toml, std::path::Path::new("corner.toml"))
        .map_err(|e| e.to_string())?;
    let mut sim = scene.build().map_err(|e| e.to_string())?;
    if matches!(start, Start::Inverted | Start::Compressed) {
        let mut positions = sim.state().positions.clone();
        for p in &mut positions {
            if start == Start::Inverted {
                p.x = -p.x;
            } else {
                p.x *= 0.01;
            }
        }
        let velocities = sim.state().velocities.clone();
        sim.set_state(State {
            positions,
            velocities,
        })
        .map_err(|e| e.to_string())?;
    }
    for _ in 0..scene.steps {
        match sim.step() {
            Ok(_) => {}
            Err(SolverError::Diverged { .. }) => return Ok(false),
            Err(e) => return Err(e.to_string()),
        }
    }
    Ok(true)
}

#[test]
fn methods_complete_where_plain_pd_completes() {
    let methods = [
        SolverMethod::Anderson,
        SolverMethod::Chebyshev,
        SolverMethod::Lbfgs,
        SolverMethod::Newton,
    ];
    let (mut compared, mut plain_diverged) = (0, 0);
    for corner in 0..CORNERS.len() {
        for integrator in INTEGRATORS {
            for (d, damping) in DAMPING.iter().enumerate() {
                let plain = run(corner, integrator, damping, SolverMethod::LocalGlobal).unwrap();
                plain_diverged += usize::from(!plain);
                for method in methods {
                    let lagged = d == 4;
                    let result = run(corner, integrator, damping, method);
                    if lagged && matches!(method, SolverMethod::Newton | SolverMethod::Lbfgs) {
                        let error = result.expect_err("refused");
                        assert!(error.contains("lagged"), "{error}");
                        continue;
                    }
                    if d == 6 && method == SolverMethod::Newton {
                        let error = result.expect_err("refused");
                        assert!(error.contains("preserve_rotation"), "{error}");
                        continue;
                    }
                    let completed = result.unwrap_or_else(|e| {
                        panic!("corner {corner} {integrator} damping {d} {method:?}: {e}")
                    });
                    if plain {
                        assert!(
                            completed,
                            "corner {corner} {integrator} damping {d}: {method:?} diverged where \
                             plain PD completed"
                        );
                    }
                    compared += 1;
                }
            }
        }
    }
    eprintln!("{compared} method runs; plain PD diverged on {plain_diverged} corners");
    // The control: the matrix has corners where plain PD completes.
    assert!(plain_diverged < CORNERS.len() * INTEGRATORS.len() * DAMPING.len());
}
