//! Gradients of a loss on a whole Projective Dynamics run, by the adjoint
//! method (docs/design/gradients.md).
//!
//! [`loss_and_gradient`] runs a [`Simulation`] forward, converged to a
//! stated tolerance (Anderson acceleration, Newton's method for a step it
//! does not converge), keeping every state, then walks
//! the steps backwards. A converged step solves `grad g(x_{n+1}) = 0` for
//! its step objective `g` (docs/design/formulation.md, "The step
//! objective"), so by the implicit function theorem each step's adjoint
//! solves `H lambda = xbar_{n+1}` with `H` the exact Hessian of `g`, by
//! conjugate gradients preconditioned with the step's prefactored PD matrix
//! `A` (the forward run's own Cholesky factor), with a dense LU or MINRES
//! fallback. The
//! result is the loss and its gradient with respect to each asked
//! [`Parameter`]: the damping coefficients (a Caughey series' too), a
//! constraint group's stiffness, a body's density, the initial positions
//! and velocities, and gravity.
//!
//! Contact, velocity filters (PBD, explicit ether drag), rotation-preserving,
//! per-body and lagged damping, and hyperelastic materials are refused with
//! an [`AdjointError::Unsupported`] naming them.
//!
//! ```
//! use pd_adjoint::{AdjointOptions, Parameter, ParameterGradient, ProbeLoss, loss_and_gradient};
//! use pd_damping::LaplacianDamping;
//! use pd_integrators::BackwardEuler;
//! use pd_mesh::{Point, VertexSelection, generators};
//! use pd_solver::{Model, Settings, Simulation};
//!
//! // A clamped beam sagging under gravity for 5 steps.
//! let beam = generators::box_tets([1.0, 0.2, 0.2], [4, 1, 1])?;
//! let clamp = VertexSelection::Box { min: [-1.0; 3], max: [1e-9, 1.0, 1.0] }.resolve(&beam)?;
//! let masses = beam.lumped_masses(1000.0)?;
//! let mut model = Model::new();
//! let body = model.add_body(beam, masses)?;
//! model.add_tet_strain(body, 1e5, None)?;
//! model.fix_vertices(body, &clamp)?;
//! let settings = Settings { dt: 0.01, ..Settings::default() };
//! let damping = LaplacianDamping::new(0.01, 0.0, false)?;
//! let sim = Simulation::new(model, Box::new(BackwardEuler), Box::new(damping), settings)?;
//!
//! // The tip (vertex 4, at x = 1) should stay where it is.
//! let tip = sim.state().positions[4];
//! let loss = ProbeLoss { vertices: vec![4], targets: vec![vec![tip]; 5] };
//! let asked = [Parameter::DampingStiffness, Parameter::ExternalForce];
//! let result = loss_and_gradient(sim, 5, &loss, &asked, &AdjointOptions::default())?;
//! assert!(result.loss > 0.0);
//! // More gravity downwards (a more negative g_y) moves the tip further away.
//! let ParameterGradient::Points(g) = &result.gradients[1] else { unreachable!() };
//! assert!(g[0].y < 0.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod loss;
mod operators;
mod solve;

use std::time::Instant;

use pd_constraints::assembly::{LaplacianKind, laplacian};
use pd_integrators::StepCoefficients;
use pd_mesh::Point;
use pd_solver::{Newton, Simulation, SolverError, SolverMethod, SolverSpec, State};

pub use loss::{Loss, ProbeLoss};
use operators::{Operators, dot, mask_fixed};

/// What a gradient is taken with respect to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parameter {
    /// `a1` (1/s), the mass-proportional damping coefficient of the implicit
    /// damping matrix `D = a1 M + a2 L_d` (Laplacian damping's `mass`,
    /// implicit ether drag's `rate`).
    DampingMass,
    /// `a2` (s), the coefficient of the damping Laplacian (Laplacian
    /// damping's `stiffness`).
    DampingStiffness,
    /// `a_(k+3)` (s^(2k+3)), entry `k` of the Caughey series' higher terms:
    /// the coefficient of `L_d (M^-1 L_d)^(k+1)` (the scene's
    /// `damping.series[k]`; `docs/design/damping.md`, "Caughey series"). A
    /// term the run's series does not have (zero) has a gradient too.
    DampingSeries(usize),
    /// The stiffness of body `body`'s constraint group `constraint`, in the
    /// order the body's constraints were added (the scene's
    /// `body[body].constraints[constraint].stiffness`), in the group's unit
    /// (Pa, N/m, ...): every weight of the group scales with it.
    ConstraintStiffness {
        /// The body, in scene order.
        body: usize,
        /// The group, in the order the body's constraints were added.
        constraint: usize,
    },
    /// Body `body`'s density (kg/m^3 for tetrahedra), which scales its
    /// lumped masses; the damping coefficients are held fixed.
    Density {
        /// The body, in scene order.
        body: usize,
    },
    /// The initial positions, one point per vertex (m).
    InitialPositions,
    /// The initial velocities, one point per vertex (m/s); zero at fixed
    /// vertices, whose velocity is always zero.
    InitialVelocities,
    /// Gravity, the uniform external acceleration (m/s^2): one point.
    ExternalForce,
}

impl std::fmt::Display for Parameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Parameter::DampingMass => write!(f, "damping.mass"),
            Parameter::DampingStiffness => write!(f, "damping.stiffness"),
            Parameter::DampingSeries(k) => write!(f, "damping.series[{k}]"),
            Parameter::ConstraintStiffness { body, constraint } => {
                write!(f, "body[{body}].constraints[{constraint}].stiffness")
            }
            Parameter::Density { body } => write!(f, "body[{body}].density"),
            Parameter::InitialPositions => write!(f, "initial positions"),
            Parameter::InitialVelocities => write!(f, "initial velocities"),
            Parameter::ExternalForce => write!(f, "gravity"),
        }
    }
}

impl std::str::FromStr for Parameter {
    type Err = String;

    /// A parameter by the path [`Parameter`]'s `Display` writes (the
    /// scene's field path for the scalar ones): `damping.mass`,
    /// `damping.stiffness`, `damping.series[k]`,
    /// `body[i].constraints[j].stiffness`,
    /// `body[i].density`, `initial positions`, `initial velocities`,
    /// `gravity`.
    ///
    /// ```
    /// use pd_adjoint::Parameter;
    ///
    /// let p: Parameter = "body[0].constraints[2].stiffness".parse().unwrap();
    /// assert_eq!(p, Parameter::ConstraintStiffness { body: 0, constraint: 2 });
    /// assert!("body[0].mass".parse::<Parameter>().is_err());
    /// ```
    fn from_str(text: &str) -> Result<Self, String> {
        let index = |inner: &str| inner.parse::<usize>().ok();
        let parsed = match text {
            "damping.mass" => Some(Parameter::DampingMass),
            "damping.stiffness" => Some(Parameter::DampingStiffness),
            "initial positions" => Some(Parameter::InitialPositions),
            "initial velocities" => Some(Parameter::InitialVelocities),
            "gravity" => Some(Parameter::ExternalForce),
            _ if text.starts_with("damping.series[") => text
                .strip_prefix("damping.series[")
                .and_then(|rest| rest.strip_suffix(']'))
                .and_then(index)
                .map(Parameter::DampingSeries),
            _ => text.strip_prefix("body[").and_then(|rest| {
                let (body, rest) = rest.split_once(']')?;
                let body = index(body)?;
                if rest == ".density" {
                    return Some(Parameter::Density { body });
                }
                let constraint = rest
                    .strip_prefix(".constraints[")?
                    .strip_suffix("].stiffness")?;
                Some(Parameter::ConstraintStiffness {
                    body,
                    constraint: index(constraint)?,
                })
            }),
        };
        parsed.ok_or_else(|| {
            format!(
                "unknown parameter {text:?}: expected damping.mass, damping.stiffness, \
                 damping.series[k], body[i].constraints[j].stiffness, body[i].density, initial positions, initial \
                 velocities or gravity"
            )
        })
    }
}

/// How the forward run is converged and the adjoint systems are solved.
#[derive(Debug, Clone, PartialEq)]
pub struct AdjointOptions {
    /// Relative residual `|g - H lambda| / |g|` each step's adjoint solve
    /// stops at.
    pub tolerance: f64,
    /// Preconditioned conjugate-gradient iterations per step before the
    /// dense fallback.
    pub max_iterations: usize,
    /// The forward run's relative stopping tolerance
    /// ([`pd_solver::Settings::tolerance`]): `|G(x) - x|_M <= tolerance
    /// |G(x) - x_n|_M`, `G` the local-global map.
    pub forward_tolerance: f64,
    /// Iterations per forward step at most.
    pub forward_iterations: usize,
    /// The forward run's iteration method (Anderson by default: on the
    /// bench beam it reaches 1e-10 9 times faster than Newton's method). A
    /// step it leaves short of [`AdjointOptions::forward_tolerance`] after
    /// [`AdjointOptions::forward_iterations`] is solved again from the same
    /// state by Newton's method ([`LossGradient::forward_retries`]), except
    /// with a Caughey series damping, which Newton's method does not run
    /// (the step counts in [`LossGradient::unconverged_steps`]).
    pub forward_method: SolverMethod,
    /// Newton iterations at most when Newton's method solves a step again.
    pub retry_iterations: usize,
    /// The largest number of unknowns (3 per free vertex) the dense
    /// fallback factorises; a larger system whose conjugate gradients fail
    /// goes to preconditioned MINRES.
    pub dense_limit: usize,
    /// MINRES iterations per step at most (the fallback of a system larger
    /// than [`AdjointOptions::dense_limit`]); if it does not converge
    /// either, the result is an [`AdjointError::NotConverged`].
    pub minres_iterations: usize,
}

impl Default for AdjointOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_iterations: 200,
            forward_tolerance: 1e-10,
            forward_iterations: 100,
            forward_method: SolverMethod::Anderson,
            retry_iterations: 100,
            dense_limit: 3000,
            minres_iterations: 1000,
        }
    }
}

/// The gradient with respect to one [`Parameter`].
#[derive(Debug, Clone, PartialEq)]
pub enum ParameterGradient {
    /// A scalar parameter's derivative (loss units per parameter unit).
    Scalar(f64),
    /// A vector parameter's: one point per vertex (initial positions and
    /// velocities) or one point (gravity).
    Points(Vec<Point>),
}

/// The loss and its gradients.
#[derive(Debug, Clone, PartialEq)]
pub struct LossGradient {
    /// The loss of the forward run.
    pub loss: f64,
    /// One gradient per asked parameter, in the order asked.
    pub gradients: Vec<ParameterGradient>,
    /// Wall time of the forward run, s.
    pub forward_s: f64,
    /// Wall time of the backward pass, s.
    pub backward_s: f64,
    /// Preconditioned conjugate-gradient iterations over all steps.
    pub adjoint_iterations: usize,
    /// Steps whose adjoint system a fallback (dense LU or MINRES) solved.
    pub fallback_steps: usize,
    /// The largest final relative residual of a step's adjoint solve.
    pub adjoint_residual: f64,
    /// Iterations of the forward run over all steps (a retried step's
    /// Newton iterations included).
    pub forward_iterations: usize,
    /// Forward steps that [`AdjointOptions::forward_method`] left short of
    /// [`AdjointOptions::forward_tolerance`] and Newton's method solved
    /// again.
    pub forward_retries: usize,
    /// Forward steps that stopped at [`AdjointOptions::forward_iterations`]
    /// without meeting [`AdjointOptions::forward_tolerance`] (even by
    /// Newton's method): their gradient
    /// is that of the converged step at the positions reached
    /// (docs/design/gradients.md, "When the forward run is not converged").
    pub unconverged_steps: usize,
}

/// Why a gradient could not be computed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AdjointError {
    /// The simulation uses something the adjoint does not differentiate.
    #[error("not differentiated: {what}")]
    Unsupported {
        /// What, and what to do instead.
        what: String,
    },
    /// An argument is invalid.
    #[error("invalid {argument}: {reason}")]
    InvalidArgument {
        /// The argument (`steps`, `loss`, a parameter).
        argument: String,
        /// What is wrong.
        reason: String,
    },
    /// The forward run (or a factorisation) failed.
    #[error(transparent)]
    Solver(#[from] SolverError),
    /// A step's adjoint system could not be solved.
    #[error(
        "the adjoint system of step {step} did not converge: relative residual {residual:e} after \
         {iterations} iterations (conjugate gradients, then MINRES: its {unknowns} unknowns exceed \
         AdjointOptions::dense_limit)"
    )]
    NotConverged {
        /// The step (1-based).
        step: usize,
        /// Iterations run.
        iterations: usize,
        /// The last relative residual.
        residual: f64,
        /// Unknowns of the system.
        unknowns: usize,
    },
}

/// How the targets and velocities of a step are formed
/// (docs/design/integrators.md).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Scheme {
    BackwardEuler,
    Midpoint,
    Bdf2,
}

/// Refuses what is not differentiated.
fn check_supported(sim: &Simulation) -> Result<(), AdjointError> {
    let refuse = |what: String| Err(AdjointError::Unsupported { what });
    if sim.uses_contact() {
        return refuse(
            "contact ([contact], colliders, contact between or within bodies): contact is not \
             differentiated; remove the colliders and contact from the scene"
                .into(),
        );
    }
    let damping = sim.damping_model();
    let d = damping.implicit_matrix();
    let name = damping.name();
    if d.is_lagged() {
        return refuse(format!(
            "the {name} damping model (lagged Rayleigh, a matrix that follows the state): use \
             laplacian"
        ));
    }
    if damping.body_coefficients().is_some() {
        return refuse(format!("per-body damping ({name}): use one damping model"));
    }
    if damping.preserves_rotation() {
        return refuse(format!(
            "rotation-preserving {name} damping (preserve_rotation = true): its projection of \
             the rigid rotations is not differentiated; use preserve_rotation = false"
        ));
    }
    if damping.has_explicit_force() {
        return refuse(format!("the {name} damping model's explicit force"));
    }
    match name {
        "none" | "laplacian" => {}
        "ether-drag" if d.mass > 0.0 => {}
        "ether-drag" => {
            return refuse(
                "explicit ether drag (a velocity filter after the step): use the implicit form"
                    .into(),
            );
        }
        _ => {
            return refuse(format!(
                "the {name} damping model (a velocity filter or a model the adjoint does not \
                 know): use none, laplacian or implicit ether-drag"
            ));
        }
    }
    if sim.model().has_materials() {
        return refuse(
            "hyperelastic materials: their gradient is not validated; use PD constraints".into(),
        );
    }
    match sim.integrator_name() {
        "backward-euler" | "implicit-midpoint" | "bdf2" => Ok(()),
        other => refuse(format!("the {other} integrator")),
    }
}

/// Checks that the simulation's step matrix is the one the derivation
/// assumes, `A = (1/h^2 + c1 c2 gamma a1) M + c1 c2^2 L_sys + c1 c2 gamma (a2
/// L_d + sum_j a_(j+2) L_ff (M_f^-1 L_ff)^j)` (docs/design/formulation.md,
/// "The global step"; the series on the free vertices), by one product with
/// a fixed vector: a damping term the adjoint does not know of (a new model's
/// matrix) would change it, and is refused rather than differentiated wrongly.
fn check_step_matrix(sim: &mut Simulation) -> Result<(), AdjointError> {
    let d = sim.damping_model().implicit_matrix();
    let (worst, scale) = step_matrix_misfit(sim, d)?;
    // Both sums add the same terms in different orders: round-off only.
    if worst > 1e-9 * scale {
        return Err(AdjointError::Unsupported {
            what: format!(
                "the {} damping model's step matrix holds a term the adjoint does not know of \
                 (|A w - A_assumed w| = {worst:e} against {scale:e})",
                sim.damping_name()
            ),
        });
    }
    Ok(())
}

/// The largest entry of `A w - A_assumed w` over the free vertices, and the
/// largest of `A_assumed w`, for the assumed damping coefficients `d`.
fn step_matrix_misfit(
    sim: &mut Simulation,
    d: pd_damping::DampingMatrix,
) -> Result<(f64, f64), AdjointError> {
    let c = sim.step_coefficients();
    let h = sim.settings().dt;
    let matrix = sim.global_matrix()?;
    let model = sim.model();
    let blocks = model.constraint_blocks();
    let n = model.num_vertices();
    let system = laplacian(&blocks, n, LaplacianKind::System);
    let damping_laplacian = laplacian(&blocks, n, LaplacianKind::Damping);
    let free = sim.free_vertices();
    // A vector with no symmetry to hide a term behind.
    let w: Vec<Point> = (0..n)
        .map(|v| {
            let t = v as f64;
            Point::new(
                (0.7 * t + 0.1).sin(),
                (1.3 * t + 0.2).cos(),
                (0.37 * t + 0.5).sin(),
            )
        })
        .collect();
    let mut on_free = w.clone();
    mask_fixed(&mut on_free, model.fixed());
    let damping = c.c1 * c.c2 * c.gamma;
    let mass = 1.0 / (h * h) + damping * d.mass;
    // The series' terms, sum_j a_(j+2) L_ff z_j.
    let powers = d.series_powers();
    let chain = operators::series_chain(
        &damping_laplacian,
        model.masses(),
        model.fixed(),
        &on_free,
        powers,
    );
    let mut series = vec![Point::zeros(); n];
    for (zj, &a) in chain.iter().skip(1).zip(&d.series) {
        let p = operators::laplacian_free(&damping_laplacian, model.fixed(), zj);
        for (s, p) in series.iter_mut().zip(p) {
            *s += p * a;
        }
    }
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for (f, &v) in free.iter().enumerate() {
        let expected = on_free[v] * (mass * model.masses()[v])
            + system.row_dot(v, &on_free) * (c.c1 * c.c2 * c.c2)
            + damping_laplacian.row_dot(v, &on_free) * (damping * d.damping_laplacian)
            + series[v] * damping;
        let actual: Point = matrix
            .row(f)
            .map(|(g, value)| on_free[free[g]] * value)
            .sum();
        worst = worst.max((expected - actual).norm());
        scale = scale.max(expected.norm());
    }
    Ok((worst, scale))
}

/// What each asked parameter needs, resolved against the model.
enum Resolved {
    DampingMass,
    DampingStiffness,
    /// Entry `k` of the series' higher terms (`a_(k+3)`).
    DampingSeries(usize),
    /// The model's group index and its stiffness.
    Stiffness {
        group: usize,
        stiffness: f64,
    },
    /// `dm_i / drho` for every vertex (zero outside the body).
    Density {
        unit_masses: Vec<f64>,
    },
    InitialPositions,
    InitialVelocities,
    Gravity,
}

fn resolve(sim: &Simulation, parameter: Parameter) -> Result<Resolved, AdjointError> {
    let model = sim.model();
    let invalid = |reason: String| {
        Err(AdjointError::InvalidArgument {
            argument: parameter.to_string(),
            reason,
        })
    };
    Ok(match parameter {
        Parameter::DampingMass => Resolved::DampingMass,
        Parameter::DampingStiffness => Resolved::DampingStiffness,
        Parameter::DampingSeries(k) => {
            if k >= pd_damping::HIGHER_SERIES_TERMS {
                return invalid(format!(
                    "a Caughey series has at most {} higher terms (damping.series[0] to \
                     damping.series[{}])",
                    pd_damping::HIGHER_SERIES_TERMS,
                    pd_damping::HIGHER_SERIES_TERMS - 1
                ));
            }
            if sim.damping_name() != "laplacian" {
                return invalid(format!(
                    "the {} damping model has no Caughey series: use laplacian",
                    sim.damping_name()
                ));
            }
            Resolved::DampingSeries(k)
        }
        Parameter::InitialPositions => Resolved::InitialPositions,
        Parameter::InitialVelocities => Resolved::InitialVelocities,
        Parameter::ExternalForce => Resolved::Gravity,
        Parameter::ConstraintStiffness { body, constraint } => {
            let bodies = model.bodies().len();
            if body >= bodies {
                return invalid(format!("the model has {bodies} bodies"));
            }
            let groups = model.constraint_groups();
            let of_body: Vec<usize> = (0..groups.len())
                .filter(|&g| groups[g].body == Some(body))
                .collect();
            let Some(&group) = of_body.get(constraint) else {
                return invalid(format!(
                    "body {body} has {} constraint groups",
                    of_body.len()
                ));
            };
            match groups[group].stiffness {
                Some(stiffness) if stiffness > 0.0 && stiffness.is_finite() => {
                    Resolved::Stiffness { group, stiffness }
                }
                other => {
                    return invalid(format!(
                        "the {} group's stiffness is {other:?}: a gradient needs a positive one",
                        groups[group].kind
                    ));
                }
            }
        }
        Parameter::Density { body } => {
            let Some(b) = model.bodies().get(body) else {
                return invalid(format!("the model has {} bodies", model.bodies().len()));
            };
            let unit = match b.mesh.lumped_masses(1.0) {
                Ok(unit) => unit,
                Err(e) => return invalid(format!("the body's mesh has no lumped masses: {e}")),
            };
            let masses = &model.masses()[b.vertices()];
            // The masses must be one density times the unit-density masses.
            let density = masses
                .iter()
                .zip(&unit)
                .find(|(_, u)| **u > 0.0)
                .map_or(0.0, |(m, u)| m / u);
            let consistent = masses
                .iter()
                .zip(&unit)
                .all(|(m, u)| (m - density * u).abs() <= 1e-9 * m.abs().max(density * u));
            if !consistent {
                return invalid(
                    "the body's masses are not its mesh's lumped masses at one density".into(),
                );
            }
            let mut unit_masses = vec![0.0; model.num_vertices()];
            unit_masses[b.vertices()].copy_from_slice(&unit);
            Resolved::Density { unit_masses }
        }
    })
}

/// The loss of `steps` steps of `sim` from its current state (with a fresh
/// integrator history: BDF-2's first step is a backward Euler step) and its
/// gradient with respect to each of `parameters`.
///
/// The forward run uses [`AdjointOptions::forward_method`] (Anderson
/// acceleration by default, Newton's method for a step it does not
/// converge) to [`AdjointOptions::forward_tolerance`] (the
/// simulation's own method, iteration count and tolerance are replaced); the backward pass solves one
/// adjoint system per step (docs/design/gradients.md).
///
/// # Errors
/// [`AdjointError::Unsupported`] for contact and the damping models,
/// integrators and materials the adjoint does not differentiate;
/// [`AdjointError::InvalidArgument`] for `steps == 0`, a loss that does not
/// fit the run or the model, or a parameter that does not exist;
/// [`AdjointError::Solver`] if the forward run fails;
/// [`AdjointError::NotConverged`] if an adjoint system cannot be solved.
pub fn loss_and_gradient(
    mut sim: Simulation,
    steps: usize,
    loss: &dyn Loss,
    parameters: &[Parameter],
    options: &AdjointOptions,
) -> Result<LossGradient, AdjointError> {
    check_supported(&sim)?;
    let invalid = |argument: &str, reason: String| {
        Err(AdjointError::InvalidArgument {
            argument: argument.into(),
            reason,
        })
    };
    if steps == 0 {
        return invalid("steps", "must be at least 1".into());
    }
    if let Some(expected) = loss.steps()
        && expected != steps
    {
        return invalid(
            "loss",
            format!("it has targets for {expected} steps, the run has {steps}"),
        );
    }
    let n = sim.model().num_vertices();
    if let Err(reason) = loss.check(n) {
        return invalid("loss", reason);
    }
    if !(options.tolerance > 0.0 && options.tolerance < 1.0) {
        return invalid(
            "AdjointOptions::tolerance",
            format!("must be in (0, 1), got {}", options.tolerance),
        );
    }
    let resolved = parameters
        .iter()
        .map(|&p| resolve(&sim, p))
        .collect::<Result<Vec<_>, _>>()?;

    check_step_matrix(&mut sim)?;

    // Forward.
    let forward_start = Instant::now();
    let method = SolverSpec {
        method: options.forward_method,
        ..SolverSpec::default()
    };
    sim.set_position_solver(method.create()?);
    sim.set_stopping(options.forward_iterations, options.forward_tolerance)?;
    let start = sim.state().clone();
    sim.set_state(start.clone())?;
    let scheme_of = |name: &str, c: StepCoefficients| match name {
        "implicit-midpoint" => Scheme::Midpoint,
        "bdf2" if c.c1 != 1.0 => Scheme::Bdf2,
        _ => Scheme::BackwardEuler,
    };
    let mut states: Vec<State> = Vec::with_capacity(steps + 1);
    states.push(start);
    let mut schemes = Vec::with_capacity(steps);
    let mut unconverged_steps = 0;
    let mut loss_value = 0.0;
    // Newton's method does not run a Caughey series: a step of a series
    // the forward method leaves short stays unconverged.
    let retry = options.forward_method != SolverMethod::Newton
        && !sim.damping_model().implicit_matrix().has_series();
    let mut forward_retries = 0;
    let mut forward_iterations = 0;
    for s in 1..=steps {
        let c = sim.step_coefficients();
        schemes.push((scheme_of(sim.integrator_name(), c), c));
        let saved = retry.then(|| sim.checkpoint());
        let mut stats = sim.step()?;
        forward_iterations += stats.iterations;
        if let Some(saved) = saved.filter(|_| !stats.converged) {
            // The same step again, from the same state and history, by
            // Newton's method.
            sim.restore(&saved)?;
            sim.set_position_solver(Box::new(Newton::default()));
            sim.set_stopping(options.retry_iterations, options.forward_tolerance)?;
            stats = sim.step()?;
            forward_iterations += stats.iterations;
            sim.set_position_solver(method.create()?);
            sim.set_stopping(options.forward_iterations, options.forward_tolerance)?;
            forward_retries += 1;
        }
        if !stats.converged {
            unconverged_steps += 1;
        }
        states.push(sim.state().clone());
        loss_value += loss.value(s, &sim.state().positions);
    }
    let forward_s = forward_start.elapsed().as_secs_f64();

    // Backward.
    let backward_start = Instant::now();
    let h = sim.settings().dt;
    let gravity = sim.settings().gravity;
    let d = sim.damping_model().implicit_matrix();
    let model = sim.model();
    let ops = Operators::new(
        model.constraint_blocks(),
        model.masses().to_vec(),
        model.fixed().to_vec(),
        h,
        (d.mass, d.damping_laplacian, &d.series[..d.series_powers()]),
    );
    // The series' powers the parameters' derivatives need: every term of
    // the run's series, and each asked term.
    let chain_powers = resolved
        .iter()
        .filter_map(|r| match r {
            Resolved::DampingSeries(k) => Some(k + 1),
            _ => None,
        })
        .fold(ops.series.len(), usize::max);
    // Each asked group's constraints, and its share of the damping
    // Laplacian (the weights scale it too) when the kind is in `L_d`.
    let group_blocks: Vec<_> = resolved
        .iter()
        .map(|r| match r {
            Resolved::Stiffness { group, .. } => model.constraint_group_block(*group).map(|b| {
                let laplacian = b
                    .translation_invariant()
                    .then(|| laplacian(std::slice::from_ref(&b), n, LaplacianKind::Damping));
                (b, laplacian)
            }),
            _ => None,
        })
        .collect();
    let free = sim.free_vertices().to_vec();
    let zeros = vec![Point::zeros(); n];
    // The adjoints of each state, allocated when a step first reaches them
    // and dropped once their step is done: at most three states' at a time.
    let mut xbar: Vec<Vec<Point>> = vec![Vec::new(); steps + 1];
    let mut vbar: Vec<Vec<Point>> = vec![Vec::new(); steps + 1];
    let mut scalars = vec![0.0; resolved.len()];
    let mut gravity_bar = Point::zeros();
    let mut lambda = zeros.clone();
    // The adjoint of the step solved before `lambda`'s (the next step in
    // time), once there is one: the solve extrapolates from the two.
    let mut earlier: Option<Vec<Point>> = None;
    let mut solved = false;
    let mut work = zeros.clone();
    let mut vb = zeros.clone();
    let mut adjoint_iterations = 0;
    let mut fallback_steps = 0;
    let mut adjoint_residual: f64 = 0.0;
    for k in (0..steps).rev() {
        let s = k + 1;
        let (scheme, c) = schemes[k];
        let (x, x_n) = (&states[s].positions, &states[k].positions);
        for state in k.saturating_sub(1)..=s {
            for adjoint in [&mut xbar[state], &mut vbar[state]] {
                if adjoint.is_empty() {
                    adjoint.resize(n, Point::zeros());
                }
            }
        }
        // The loss's own term.
        work.iter_mut().for_each(|w| *w = Point::zeros());
        loss.gradient(s, x, &mut work);
        for (a, w) in xbar[s].iter_mut().zip(&work) {
            *a += w;
        }
        // The velocity update v_{s}(x_s, x_k, v_k, x_{k-1}); fixed vertices
        // have zero velocity whatever the positions.
        vb.copy_from_slice(&vbar[s]);
        mask_fixed(&mut vb, &ops.fixed);
        {
            let (before, after) = xbar.split_at_mut(s);
            let xs = &mut after[0];
            match scheme {
                Scheme::BackwardEuler => {
                    for i in 0..n {
                        xs[i] += vb[i] / h;
                        before[k][i] -= vb[i] / h;
                    }
                }
                Scheme::Midpoint => {
                    for i in 0..n {
                        xs[i] += vb[i] * (2.0 / h);
                        before[k][i] -= vb[i] * (2.0 / h);
                        vbar[k][i] -= vb[i];
                    }
                }
                Scheme::Bdf2 => {
                    for i in 0..n {
                        xs[i] += vb[i] * (1.5 / h);
                        before[k][i] -= vb[i] * (2.0 / h);
                        before[k - 1][i] += vb[i] * (0.5 / h);
                    }
                }
            }
        }
        // The step objective's Hessian at the new positions.
        let q: Vec<Point> = match scheme {
            Scheme::Midpoint => x
                .iter()
                .zip(x_n)
                .map(|(x, x0)| x * c.c2 + x0 * (1.0 - c.c2))
                .collect(),
            _ => x.clone(),
        };
        let stiffness = ops.elastic_hessian(&q, c);
        let mut g = xbar[s].clone();
        mask_fixed(&mut g, &ops.fixed);
        let before = solved.then(|| lambda.clone());
        let report = {
            let mut precondition = |r: &mut [Point]| sim.solve_step_matrix(c, r);
            solve::solve(
                &ops,
                c,
                &stiffness,
                &free,
                &g,
                &mut lambda,
                earlier.as_deref(),
                (
                    options.tolerance,
                    options.max_iterations,
                    options.dense_limit,
                    options.minres_iterations,
                ),
                &mut precondition,
            )
        };
        let report = match report {
            Ok(report) => report,
            Err(solve::SolveFailure::Preconditioner(e)) => return Err(e.into()),
            Err(solve::SolveFailure::TooLarge {
                iterations,
                residual,
            }) => {
                return Err(AdjointError::NotConverged {
                    step: s,
                    iterations,
                    residual,
                    unknowns: 3 * free.len(),
                });
            }
            Err(solve::SolveFailure::Singular) => {
                return Err(AdjointError::NotConverged {
                    step: s,
                    iterations: options.max_iterations,
                    residual: f64::NAN,
                    unknowns: 3 * free.len(),
                });
            }
        };
        adjoint_iterations += report.iterations;
        earlier = before;
        solved = true;
        fallback_steps += usize::from(report.fallback);
        adjoint_residual = adjoint_residual.max(report.residual);

        // The new fixed positions enter the free rows through K and L_d;
        // they are the old ones.
        ops.hessian_product(c, &stiffness, &lambda, &mut work);
        {
            let (before, after) = xbar.split_at_mut(s);
            for (i, &fixed) in ops.fixed.iter().enumerate() {
                if fixed {
                    after[0][i] -= work[i];
                    before[k][i] += after[0][i];
                }
            }
        }
        // Through x_k (and x_{k-1}): P lambda = (M/h^2 + c1 c2 gamma D) lambda.
        work.iter_mut().for_each(|w| *w = Point::zeros());
        ops.add_inertia_damping(c, &lambda, 1.0, &mut work);
        match scheme {
            Scheme::BackwardEuler => {
                for (a, w) in xbar[k].iter_mut().zip(&work) {
                    *a += w;
                }
            }
            Scheme::Midpoint => {
                ops.add_elastic(&stiffness, &lambda, -c.c1 * c.c2 * (1.0 - c.c2), &mut work);
                for (a, w) in xbar[k].iter_mut().zip(&work) {
                    *a += w;
                }
            }
            Scheme::Bdf2 => {
                for i in 0..n {
                    xbar[k][i] += work[i] * (4.0 / 3.0);
                    xbar[k - 1][i] -= work[i] * (1.0 / 3.0);
                }
            }
        }
        // Through v_k (and v_{k-1}): the inertial target's h v terms.
        let masses = &ops.masses;
        match scheme {
            Scheme::BackwardEuler | Scheme::Midpoint => {
                for i in 0..n {
                    vbar[k][i] += lambda[i] * (masses[i] / h);
                }
            }
            Scheme::Bdf2 => {
                for i in 0..n {
                    vbar[k][i] += lambda[i] * (8.0 / 9.0 * masses[i] / h);
                    vbar[k - 1][i] -= lambda[i] * (2.0 / 9.0 * masses[i] / h);
                }
            }
        }

        // Parameters: pbar -= lambda . d(grad g)/dp.
        let energy = c.c1 * c.c2;
        let damping = energy * c.gamma;
        let (y, anchor) = targets(scheme, c, h, gravity, &states, k);
        let e: Vec<Point> = x.iter().zip(&anchor).map(|(x, a)| x - a).collect();
        // The series' chains of `e` and `lambda`: z_m = (M_f^-1 L_ff)^m e_f,
        // rl_m = (M_f^-1 L_ff)^m lambda_f.
        let (z, rl) = if chain_powers > 0 {
            (
                ops.series_chain(&e, chain_powers),
                ops.series_chain(&lambda, chain_powers),
            )
        } else {
            (Vec::new(), Vec::new())
        };
        for ((r, out), block) in resolved.iter().zip(scalars.iter_mut()).zip(&group_blocks) {
            match r {
                Resolved::DampingMass => {
                    *out -= damping
                        * (0..n)
                            .map(|i| masses[i] * lambda[i].dot(&(x[i] - anchor[i])))
                            .sum::<f64>();
                }
                Resolved::DampingStiffness => {
                    let ld = &ops.damping_laplacian;
                    *out -= damping
                        * (0..n)
                            .map(|i| lambda[i].dot(&ld.row_dot(i, &e)))
                            .sum::<f64>();
                }
                Resolved::DampingSeries(k) => {
                    // d r / d a_(k+3) = c1 c2 gamma P_(k+1) e, P_(k+1) e =
                    // L_ff z_(k+1).
                    *out -= damping * dot(&lambda, &ops.laplacian_free(&z[k + 1]));
                }
                Resolved::Stiffness { stiffness, .. } => {
                    if let Some((block, group_laplacian)) = block {
                        // c1 c2 grad E_group(q) + c1 c2 gamma a2 L_group (x - x_hat),
                        // both proportional to the stiffness.
                        work.iter_mut().for_each(|w| *w = Point::zeros());
                        block.add_gradient(&q, &mut work);
                        let mut sum = energy * dot(&lambda, &work);
                        if let Some(lg) = group_laplacian
                            && d.damping_laplacian != 0.0
                        {
                            sum += damping
                                * d.damping_laplacian
                                * (0..n)
                                    .map(|i| lambda[i].dot(&lg.row_dot(i, &e)))
                                    .sum::<f64>();
                        }
                        // The series: P_j has j + 1 factors L_ff, each with
                        // the group's share L_g, so lambda^T dP_j e =
                        // sum_(i=0..j) rl_i^T L_g z_(j-i) (per unit weight).
                        if let Some(lg) = group_laplacian {
                            for (j, &a) in (1..).zip(&ops.series) {
                                if a == 0.0 {
                                    continue;
                                }
                                let part: f64 = (0..=j)
                                    .map(|i| {
                                        let zi = &z[j - i];
                                        (0..n)
                                            .filter(|&v| !ops.fixed[v])
                                            .map(|v| rl[i][v].dot(&lg.row_dot(v, zi)))
                                            .sum::<f64>()
                                    })
                                    .sum();
                                sum += damping * a * part;
                            }
                        }
                        *out -= sum / stiffness;
                    }
                }
                Resolved::Density { unit_masses } => {
                    *out -= (0..n)
                        .filter(|&i| unit_masses[i] != 0.0)
                        .map(|i| {
                            let dr =
                                (x[i] - y[i]) / (h * h) + (x[i] - anchor[i]) * (damping * d.mass);
                            unit_masses[i] * lambda[i].dot(&dr)
                        })
                        .sum::<f64>();
                    // The series' M^-1: with G = d M^-1 / d rho = -U M^-2,
                    // lambda^T dP_j e = sum_(i=1..j) (L rl_(i-1))^T G (L
                    // z_(j-i)) = -sum_(i=1..j) sum_v u_v rl_i[v] . z_(j-i+1)[v]
                    // (L_ff z_m = M z_(m+1) on the free vertices).
                    for (j, &a) in (1..).zip(&ops.series) {
                        if a == 0.0 {
                            continue;
                        }
                        let part: f64 = (1..=j)
                            .map(|i| {
                                (0..n)
                                    .filter(|&v| unit_masses[v] != 0.0 && !ops.fixed[v])
                                    .map(|v| unit_masses[v] * rl[i][v].dot(&z[j - i + 1][v]))
                                    .sum::<f64>()
                            })
                            .sum();
                        *out += damping * a * part;
                    }
                }
                Resolved::Gravity => {}
                Resolved::InitialPositions | Resolved::InitialVelocities => {}
            }
        }
        gravity_bar += (0..n)
            .map(|i| lambda[i] * (masses[i] * energy))
            .sum::<Point>();
        // State s is done: nothing earlier reads its adjoints.
        xbar[s] = Vec::new();
        vbar[s] = Vec::new();
    }
    mask_fixed(&mut vbar[0], &ops.fixed);
    let (xbar0, vbar0) = (std::mem::take(&mut xbar[0]), std::mem::take(&mut vbar[0]));
    let gradients = resolved
        .iter()
        .zip(&scalars)
        .map(|(r, &value)| match r {
            Resolved::InitialPositions => ParameterGradient::Points(xbar0.clone()),
            Resolved::InitialVelocities => ParameterGradient::Points(vbar0.clone()),
            Resolved::Gravity => ParameterGradient::Points(vec![gravity_bar]),
            _ => ParameterGradient::Scalar(value),
        })
        .collect();
    Ok(LossGradient {
        loss: loss_value,
        gradients,
        forward_s,
        backward_s: backward_start.elapsed().as_secs_f64(),
        adjoint_iterations,
        fallback_steps,
        adjoint_residual,
        forward_iterations,
        forward_retries,
        unconverged_steps,
    })
}

/// The inertial target `y` and the damping anchor `x_hat` of step `k` (from
/// state `k` to `k + 1`), every vertex (docs/design/integrators.md).
fn targets(
    scheme: Scheme,
    c: StepCoefficients,
    h: f64,
    gravity: Point,
    states: &[State],
    k: usize,
) -> (Vec<Point>, Vec<Point>) {
    let (x_n, v_n) = (&states[k].positions, &states[k].velocities);
    let accel = gravity * (c.c1 * c.c2 * h * h);
    match scheme {
        Scheme::BackwardEuler | Scheme::Midpoint => {
            let y = x_n
                .iter()
                .zip(v_n)
                .map(|(x, v)| x + v * h + accel)
                .collect();
            (y, x_n.clone())
        }
        Scheme::Bdf2 => {
            let (x_o, v_o) = (&states[k - 1].positions, &states[k - 1].velocities);
            let anchor: Vec<Point> = x_n
                .iter()
                .zip(x_o)
                .map(|(x, xo)| (x * 4.0 - xo) / 3.0)
                .collect();
            let y = anchor
                .iter()
                .zip(v_n.iter().zip(v_o))
                .map(|(a, (v, vo))| a + (v * 8.0 - vo * 2.0) * (h / 9.0) + accel)
                .collect();
            (y, anchor)
        }
    }
}

#[cfg(test)]
mod tests {
    use pd_damping::LaplacianDamping;
    use pd_integrators::ImplicitMidpoint;
    use pd_mesh::generators;
    use pd_solver::{Model, Settings};

    use super::*;

    /// Every parameter reads back from the path it is written as.
    #[test]
    fn parameters_round_trip_through_their_paths() {
        let all = [
            Parameter::DampingMass,
            Parameter::DampingStiffness,
            Parameter::DampingSeries(0),
            Parameter::DampingSeries(4),
            Parameter::ConstraintStiffness {
                body: 3,
                constraint: 12,
            },
            Parameter::Density { body: 1 },
            Parameter::InitialPositions,
            Parameter::InitialVelocities,
            Parameter::ExternalForce,
        ];
        for p in all {
            assert_eq!(p.to_string().parse::<Parameter>(), Ok(p));
        }
        for bad in [
            "body[x].density",
            "body[0].constraints[1]",
            "damping",
            "",
            "damping.series[",
            "damping.series[x]",
            "damping.series[1].5",
        ] {
            assert!(bad.parse::<Parameter>().is_err(), "{bad}");
        }
    }

    /// The step-matrix check sees a damping term 1% off what it assumes,
    /// and nothing when the assumption is right.
    #[test]
    fn step_matrix_check_sees_an_unknown_term() {
        let beam = generators::box_tets([1.0, 0.2, 0.2], [3, 1, 1]).unwrap();
        let masses = beam.lumped_masses(1000.0).unwrap();
        let mut model = Model::new();
        let body = model.add_body(beam, masses).unwrap();
        model.add_tet_strain(body, 1e5, None).unwrap();
        model.add_attachments(body, &[0, 1], 1e3).unwrap();
        model.fix_vertices(body, &[2]).unwrap();
        let damping = LaplacianDamping::new(0.02, 0.5, false).unwrap();
        let settings = Settings::default();
        let mut sim = Simulation::new(
            model,
            Box::new(ImplicitMidpoint),
            Box::new(damping),
            settings,
        )
        .unwrap();
        let d = sim.damping_model().implicit_matrix();
        let (worst, scale) = step_matrix_misfit(&mut sim, d).unwrap();
        assert!(worst <= 1e-12 * scale, "{worst:e} against {scale:e}");
        let off = pd_damping::DampingMatrix {
            damping_laplacian: 1.01 * d.damping_laplacian,
            ..d
        };
        let (worst, scale) = step_matrix_misfit(&mut sim, off).unwrap();
        assert!(worst > 1e-6 * scale, "{worst:e} against {scale:e}");
        assert!(check_step_matrix(&mut sim).is_ok());
    }
}
