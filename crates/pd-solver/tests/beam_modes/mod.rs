//! Shared pieces of the beam validations (docs/design/validation.md, sections 4
//! and 5): a clamped tet beam, the stiffness matrix `K` of its PD energy at
//! rest (from the constraints' exact Hessians), its lumped mass and its
//! damping Laplacian `L_d` over the free degrees of freedom, an inverse
//! iteration for one generalized eigenpair of `(K, M)`, and a free-vibration
//! run started in a mode that returns the modal coordinate of every step.

// Each test crate uses only some of these helpers.
#![allow(dead_code)]

use faer::Mat;
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use pd_constraints::assembly::{self, LaplacianKind};
use pd_damping::Damping;
use pd_integrators::ImplicitMidpoint;
use pd_mesh::{Point, VertexSelection, generators};
use pd_solver::{Model, Settings, Simulation, State};

/// Density, kg/m^3.
pub const DENSITY: f64 = 1000.0;
/// The tet-strain stiffness, Pa. The corotational energy density is
/// `stiffness/2 |F - R|^2 = stiffness/2 |sym grad u|^2 + O(|grad u|^3)`,
/// i.e. linear elasticity with `mu = stiffness/2`, `lambda = 0`: Young's
/// modulus `E = 2 mu (1 + nu) = stiffness`, Poisson ratio 0.
pub const YOUNGS_MODULUS: f64 = 1.0e6;

/// A beam `size` with `cells`, regular Kuhn tets (no jitter: the
/// refinement study needs nested, similar meshes), density [`DENSITY`],
/// tet strain of [`YOUNGS_MODULUS`], the face x = 0 clamped (every vertex
/// on it fixed in x, y and z).
pub fn beam(size: [f64; 3], cells: [usize; 3]) -> Model {
    let mesh = generators::box_tets(size, cells).unwrap();
    let clamp = VertexSelection::Box {
        min: [-1.0; 3],
        max: [1e-9, size[1] + 1.0, size[2] + 1.0],
    }
    .resolve(&mesh)
    .unwrap();
    let masses = mesh.lumped_masses(DENSITY).unwrap();
    let mut model = Model::new();
    let body = model.add_body(mesh, masses).unwrap();
    model.add_tet_strain(body, YOUNGS_MODULUS, None).unwrap();
    model.fix_vertices(body, &clamp).unwrap();
    model
}

/// Solves `A x = b` in place for a one-column `b`.
type Solver = Box<dyn Fn(&mut Mat<f64>)>;

/// A symmetric sparse matrix as rows of `(column, value)`.
pub struct Rows(pub Vec<Vec<(usize, f64)>>);

impl Rows {
    fn from_triplets(n: usize, triplets: &[(usize, usize, f64)]) -> Self {
        let mut rows = vec![Vec::<(usize, f64)>::new(); n];
        for &(r, c, v) in triplets {
            match rows[r].iter_mut().find(|(col, _)| *col == c) {
                Some(entry) => entry.1 += v,
                None => rows[r].push((c, v)),
            }
        }
        Self(rows)
    }

    /// `A x`.
    pub fn mul(&self, x: &[f64]) -> Vec<f64> {
        self.0
            .iter()
            .map(|row| row.iter().map(|&(c, v)| v * x[c]).sum())
            .collect()
    }

    /// `x^T A y`.
    pub fn form(&self, x: &[f64], y: &[f64]) -> f64 {
        dot(x, &self.mul(y))
    }
}

/// Euclidean dot product.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The linearised model over the free degrees of freedom, dof `3 i + a`
/// for the `i`-th free vertex and axis `a`.
pub struct Linearised {
    /// Global index of each free vertex.
    pub free: Vec<usize>,
    /// Rest positions of every vertex.
    pub rest: Vec<Point>,
    /// Lumped mass per dof, kg.
    pub mass: Vec<f64>,
    /// Stiffness matrix at rest: the Hessian of the PD energy, N/m.
    pub stiffness: Rows,
    /// Damping Laplacian `L_d (x) I_3` restricted to the free dofs, N/m.
    pub laplacian: Rows,
}

impl Linearised {
    /// Assembles `K`, `M` and `L_d` of `model` at rest.
    pub fn of(model: &Model) -> Self {
        let rest = model.rest_positions().to_vec();
        let n = rest.len();
        let mut index = vec![usize::MAX; n];
        let free: Vec<usize> = (0..n).filter(|&v| !model.fixed()[v]).collect();
        for (i, &v) in free.iter().enumerate() {
            index[v] = i;
        }
        let dofs = 3 * free.len();
        let mass = free.iter().flat_map(|&v| [model.masses()[v]; 3]).collect();
        let blocks = model.constraint_blocks();
        let mut k = Vec::new();
        for block in &blocks {
            let len = block.hessian_len();
            let mut out = vec![0.0; len * block.len()];
            // At rest every element's Hessian is already PSD (it is the
            // linear-elastic stiffness); no projection, so this is the
            // exact Hessian.
            block.hessian_range(&rest, 0, false, &mut out);
            for i in 0..block.len() {
                let stencil = block.stencil(i);
                let size = 3 * stencil.len();
                for a in 0..size {
                    let ia = index[stencil[a / 3]];
                    if ia == usize::MAX {
                        continue;
                    }
                    for b in 0..size {
                        let ib = index[stencil[b / 3]];
                        if ib == usize::MAX {
                            continue;
                        }
                        k.push((3 * ia + a % 3, 3 * ib + b % 3, out[i * len + a * size + b]));
                    }
                }
            }
        }
        let l_d = assembly::laplacian(&blocks, n, LaplacianKind::Damping);
        let mut l = Vec::new();
        for (r, &v) in free.iter().enumerate() {
            for (c, value) in l_d.row(v) {
                let ic = index[c];
                if ic != usize::MAX {
                    for a in 0..3 {
                        l.push((3 * r + a, 3 * ic + a, value));
                    }
                }
            }
        }
        Self {
            free,
            rest,
            mass,
            stiffness: Rows::from_triplets(dofs, &k),
            laplacian: Rows::from_triplets(dofs, &l),
        }
    }

    /// Number of free dofs.
    pub fn dofs(&self) -> usize {
        self.mass.len()
    }

    /// `x^T M y`.
    pub fn mass_form(&self, x: &[f64], y: &[f64]) -> f64 {
        x.iter()
            .zip(y)
            .zip(&self.mass)
            .map(|((a, b), m)| a * b * m)
            .sum()
    }

    /// The generalized eigenpair `K phi = lambda M phi` with `lambda`
    /// closest to `shift` (rad^2/s^2), by shifted inverse iteration from
    /// `start`. Returns `(lambda, phi, bound)`, `phi` M-normalised and
    /// `bound` the residual bound `|M^-1/2 (K phi - lambda M phi)|`: some
    /// eigenvalue lies within `bound` of `lambda` (symmetric-definite pencil).
    pub fn eigenpair(&self, shift: f64, start: Vec<f64>) -> (f64, Vec<f64>, f64) {
        let n = self.dofs();
        let mut triplets = Vec::new();
        for (r, row) in self.stiffness.0.iter().enumerate() {
            for &(c, v) in row {
                triplets.push(Triplet::new(r, c, v));
            }
            triplets.push(Triplet::new(r, r, -shift * self.mass[r]));
        }
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).unwrap();
        let solve: Solver = if shift == 0.0 {
            let llt = matrix.sp_cholesky(faer::Side::Lower).unwrap();
            Box::new(move |x| llt.solve_in_place(x.as_mut()))
        } else {
            let lu = matrix.sp_lu().unwrap();
            Box::new(move |x| lu.solve_in_place(x.as_mut()))
        };
        let mut phi = start;
        for _ in 0..300 {
            let norm = self.mass_form(&phi, &phi).sqrt();
            phi.iter_mut().for_each(|p| *p /= norm);
            // Stop on the residual, not on the Rayleigh quotient (which
            // converges twice as fast as the vector).
            if self.residual_bound(&phi) <= 1e-10 * self.stiffness.form(&phi, &phi) {
                break;
            }
            let mut x = Mat::<f64>::from_fn(n, 1, |i, _| self.mass[i] * phi[i]);
            solve(&mut x);
            phi = (0..n).map(|i| x[(i, 0)]).collect();
        }
        let norm = self.mass_form(&phi, &phi).sqrt();
        phi.iter_mut().for_each(|p| *p /= norm);
        let lambda = self.stiffness.form(&phi, &phi);
        let bound = self.residual_bound(&phi);
        (lambda, phi, bound)
    }

    /// `|M^-1/2 (K phi - lambda M phi)|` for an M-normalised `phi` and its
    /// Rayleigh quotient `lambda`.
    fn residual_bound(&self, phi: &[f64]) -> f64 {
        let lambda = self.stiffness.form(phi, phi);
        self.stiffness
            .mul(phi)
            .iter()
            .zip(phi)
            .zip(&self.mass)
            .map(|((kp, p), m)| (kp - lambda * m * p).powi(2) / m)
            .sum::<f64>()
            .sqrt()
    }

    /// A dof vector from a displacement field.
    pub fn field(&self, u: impl Fn(&Point) -> Point) -> Vec<f64> {
        self.free
            .iter()
            .flat_map(|&v| {
                let d = u(&self.rest[v]);
                [d.x, d.y, d.z]
            })
            .collect()
    }

    /// Fraction of `phi`'s M-norm in axis `axis`.
    pub fn axis_fraction(&self, phi: &[f64], axis: usize) -> f64 {
        let part: f64 = (0..self.free.len())
            .map(|i| self.mass[3 * i + axis] * phi[3 * i + axis].powi(2))
            .sum();
        part / self.mass_form(phi, phi)
    }
}

/// Result of [`vibrate`].
pub struct Vibration {
    /// Modal coordinate `phi^T M (x_n - X)` of every step, from step 0.
    pub q: Vec<f64>,
    /// Largest `|x_n - X - q_n phi|_M / max |q|` over the run: how far the
    /// motion left the mode.
    pub off_mode: f64,
    /// Most local-global iterations any step took.
    pub max_iterations: usize,
}

/// Runs `steps` steps of implicit midpoint, gravity off, solved to the
/// relative tolerance `tolerance`, from rest displaced by `amplitude phi`
/// (`phi` M-normalised, over `lin`'s free dofs). Asserts convergence.
#[allow(clippy::too_many_arguments)]
pub fn vibrate(
    model: Model,
    lin: &Linearised,
    damping: Box<dyn Damping>,
    phi: &[f64],
    amplitude: f64,
    dt: f64,
    steps: usize,
    tolerance: f64,
) -> Vibration {
    let settings = Settings {
        dt,
        iterations: 5000,
        tolerance,
        gravity: Point::zeros(),
        threads: 1,
        ..Settings::default()
    };
    let mut sim = Simulation::new(model, Box::new(ImplicitMidpoint), damping, settings).unwrap();
    let mut positions = lin.rest.clone();
    for (i, &v) in lin.free.iter().enumerate() {
        positions[v] += Point::new(phi[3 * i], phi[3 * i + 1], phi[3 * i + 2]) * amplitude;
    }
    let n = positions.len();
    sim.set_state(State {
        positions,
        velocities: vec![Point::zeros(); n],
    })
    .unwrap();
    let displacement = |sim: &Simulation| -> Vec<f64> {
        lin.free
            .iter()
            .flat_map(|&v| {
                let d = sim.state().positions[v] - lin.rest[v];
                [d.x, d.y, d.z]
            })
            .collect()
    };
    let mut q = Vec::with_capacity(steps + 1);
    let mut off = 0.0f64;
    let mut max_iterations = 0;
    for step in 0..=steps {
        if step > 0 {
            let stats = sim.step().unwrap();
            assert!(stats.converged, "step {step}: {stats:?}");
            max_iterations = max_iterations.max(stats.iterations);
        }
        let u = displacement(&sim);
        let qn = lin.mass_form(phi, &u);
        let rest: Vec<f64> = u.iter().zip(phi).map(|(a, p)| a - qn * p).collect();
        off = off.max(lin.mass_form(&rest, &rest).sqrt());
        q.push(qn);
    }
    let peak = q.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    Vibration {
        q,
        off_mode: off / peak,
        max_iterations,
    }
}

/// The per-step eigenvalue `mu = exp(l + i t)` of `q_n = Re(C mu^n)`, from
/// the Casoratian (for `l`) and the summed recurrence (for `t`) over
/// `q[1..len-1]` (the identities of `validation_spring_chain.rs`).
pub fn step_eigenvalue(q: &[f64]) -> (f64, f64) {
    let last = q.len() - 2;
    let first = 1;
    let casoratian = |n: usize| q[n] * q[n] - q[n - 1] * q[n + 1];
    let log_modulus = (casoratian(last) / casoratian(first)).ln() / (2.0 * (last - first) as f64);
    let modulus = log_modulus.exp();
    let (mut cross, mut square) = (0.0, 0.0);
    for n in first..=last {
        cross += q[n] * (q[n + 1] + modulus * modulus * q[n - 1]);
        square += q[n] * q[n];
    }
    let angle = (cross / (2.0 * modulus * square)).clamp(-1.0, 1.0).acos();
    (log_modulus, angle)
}

/// The continuous eigenvalue `lambda` whose implicit midpoint (Cayley) map
/// is `mu = exp(l + i t)`: `lambda = (2/h) (mu - 1)/(mu + 1)`. Returns
/// `(omega, zeta)` with `lambda = -zeta omega + i omega sqrt(1 - zeta^2)`.
pub fn undo_midpoint(log_modulus: f64, angle: f64, dt: f64) -> (f64, f64) {
    let mu = nalgebra::Complex::from_polar(log_modulus.exp(), angle);
    let lambda = (mu - 1.0) / (mu + 1.0) * (2.0 / dt);
    let omega = lambda.norm();
    (omega, -lambda.re / omega)
}
