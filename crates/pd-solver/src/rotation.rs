//! The rotation-preserving Laplacian damping (`preserve_rotation`,
//! docs/design/damping.md, "The rotation-preserving variant"): the step
//! damps `(I - P)^T L_d (I - P)` instead of `L_d`, with `P` the
//! mass-orthogonal projection on the rigid rotations each body may perform,
//! built at the start of the step from `x_n`.
//!
//! For one body with rotation columns `R` (column `j` at vertex `i`:
//! `a_j x (x_i - p)`, `p` the centre of mass of a free body, its pivot, or a
//! point of its hinge; `a_j` the principal axes of the inertia about `p`, or
//! the hinge's axis alone), `G = R^T M R = diag(lambda_j)` and
//! `P = R G^-1 R^T M`:
//!
//! `(I - P)^T L (I - P) = L - U C U^T`, `U = [L R, M R G^-1]`,
//! `C = [[0, I], [I, -S]]`, `S = R^T L R`,
//!
//! so the step matrix is `A' = A - c U C U^T` (`c` the coefficient of `L_d`
//! in `A`), solved with `A`'s factor by Woodbury:
//!
//! `A'^-1 b = A^-1 b + Z K^-1 U^T A^-1 b`, `Z = A^-1 U`,
//! `K = C^-1 / c - U^T Z`, `C^-1 = [[S, I], [I, 0]]`.
//!
//! `A` is a scalar matrix per vertex pair (the same on x, y and z), so
//! `A^-1` commutes with the cross product by a fixed axis: `Z`'s columns are
//! `a_j x Y_L` and `a_j x Y_M / lambda_j` with `Y_L = A^-1 L r` and
//! `Y_M = A^-1 M r` (one solve of points for every body at once, as `A`
//! does not couple different bodies; where nothing anchors a body, `A =
//! alpha M + s L` on it gives `Y_L = (r - alpha Y_M) / s`, otherwise a
//! second solve). A solve then costs `O(n)` more.
//!
//! The lever arms `r` are not solved for every step: `A^-1` also commutes
//! with one linear map `F` applied at every vertex, so for arms `r = F
//! r_ref` the step maps the reference's `L r_ref`, `Y_M` and `Y_L` by `F`
//! (and the reference's `3 x 3` sums behind `K`), exactly, in `O(n)`. `F`
//! is fitted to the step's own arms by mass-weighted least squares; when
//! they are further than [`ARM_MISMATCH_TOLERANCE`] from `F r_ref`, or the
//! step matrix changed, the step rebuilds the reference from its own arms
//! (the solve). The rule depends on the state and the reference only, which
//! a checkpoint saves ([`RotationState`]).

use nalgebra::{Matrix3, SMatrix, SVector, SymmetricEigen};
use pd_damping::rigid::{INERTIA_RELATIVE_CUTOFF, RigidBody, RigidFreedom};
use pd_mesh::Point;

use crate::global::{COEFFICIENT_COUNT, FIXED, GlobalSystem, MatrixCoefficients};
use crate::{RotationState, SolverError};

/// Rows and columns of a body's Woodbury system: `2 k`, `k <= 3` rotation
/// axes; unused axes get an identity row.
const WIDTH: usize = 6;
type Capacitance = SMatrix<f64, WIDTH, WIDTH>;
type Pair = SVector<f64, WIDTH>;

/// Iteration cap of the 3 x 3 symmetric eigensolver (it converges in a
/// handful; the cap only guards against non-convergence).
const EIGEN_MAX_ITERATIONS: usize = 256;

/// Largest mass-weighted relative mismatch `|r - F r_ref|_M / |r|_M`
/// between a body's lever arms and its reference arms mapped by the fitted
/// linear map `F` at which the reference is kept; beyond it the step
/// rebuilds the reference from its own arms (one solve). The damping exerts
/// no torque about the mapped arms, so the mismatch bounds the lever arm
/// error of its torque about the body's own. On the spinning, wobbling beam
/// of `tests/rotation_preserving_damping.rs` the angular momentum drift is
/// 3.01e-5 with a rebuild every step and at this tolerance, 3.30e-5 at
/// 1e-3, 1.9e-4 at 3e-3 (docs/design/damping.md, "Cost, measured").
pub(crate) const ARM_MISMATCH_TOLERANCE: f64 = 1e-4;

/// What the step's start tells the projection, all by vertex.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StepMotion<'a> {
    /// `x_n` in m.
    pub positions: &'a [Point],
    /// Lumped masses in kg.
    pub masses: &'a [f64],
    /// `y - x_n` in m: the step's predicted motion.
    pub inertial_displacement: &'a [Point],
    /// The integrator's `c2`: the fraction of the step at which its
    /// forces act (`x_n + c2 (x - x_n)`), over which the body is turned.
    pub turn_time: f64,
}

/// `I^+ b` for a symmetric positive semi-definite 3 x 3 `I`, eigenvalues
/// at or below [`INERTIA_RELATIVE_CUTOFF`] times `scale` (kg m^2) dropped.
fn pseudo_solve(inertia: &Matrix3<f64>, b: &Point, scale: f64) -> Point {
    let Some(eigen) = SymmetricEigen::try_new(*inertia, f64::EPSILON, EIGEN_MAX_ITERATIONS) else {
        return Point::zeros();
    };
    let mut x = Point::zeros();
    for k in 0..3 {
        let lambda = eigen.eigenvalues[k];
        if lambda > INERTIA_RELATIVE_CUTOFF * scale {
            let a: Point = eigen.eigenvectors.column(k).into_owned();
            x += a * (a.dot(b) / lambda);
        }
    }
    x
}

/// One body whose rotations the projection leaves undamped.
#[derive(Debug, Clone)]
struct ProjectedBody {
    /// Index into the simulation's rigid bodies.
    rigid: usize,
    /// How the body may move (the projection's rotations).
    freedom: RigidFreedom,
    /// Range of this body's vertices in the projection's per-vertex arrays.
    start: usize,
    end: usize,
    /// The rotation axes of this step (unit, mass-orthogonal columns), the
    /// first `used` of them used: the reference's turned by `turn`.
    axes: [Point; 3],
    /// This step's fitted map `F` of the reference arms.
    map: Matrix3<f64>,
    /// `C = sum_i m_i r_ref,i r_ref,i^T` (kg m^2).
    second_moment: Matrix3<f64>,
    /// `sum_i q_i p_i^T` of the reference for `T(r, L r)`, `T(m r, Y_M)`,
    /// `T(m r, Y_L)`, `T(L r, Y_L)` and `T(L r, Y_M)` (`T` as in [`gram`]).
    sums: [Matrix3<f64>; 5],
    /// `sum_i m_i |r_i|^2` of this step's arms (kg m^2).
    spread: f64,
    /// `c` of this step with the body's damping weight, whether or not the
    /// body can turn.
    damping: f64,
    used: usize,
    /// `1 / lambda_j`, `lambda_j = a_j^T I_p a_j` (kg m^2).
    inverse_inertia: [f64; 3],
    /// `c` of this body (per-body damping weights included), 0 when it is
    /// not damped by `L_d` (nothing to correct).
    coefficient: f64,
    /// `T(r, L r)`, whose form on the axes is `S = R^T L_ff R`.
    laplacian_gram: Matrix3<f64>,
    /// Whether an anchoring constraint (an attachment) acts on the body:
    /// then `A^-1 L_ff r` takes a solve of its own.
    anchored: bool,
    /// `A`'s coefficients on this body, `A = alpha M + stiffness L_ff`
    /// where nothing anchors it.
    alpha: f64,
    stiffness: f64,
    /// LU factors of `K` (identity rows for unused axes).
    capacitance: Option<nalgebra::linalg::LU<f64, nalgebra::U6, nalgebra::U6>>,
}

/// The projection of every rotation-preserving body, refreshed each step.
#[derive(Debug, Clone, Default)]
pub(crate) struct RotationProjection {
    bodies: Vec<ProjectedBody>,
    /// Per projected vertex (bodies one after the other): vertex index.
    vertex: Vec<usize>,
    /// Free index of each projected vertex.
    free: Vec<usize>,
    /// Lumped mass (kg).
    mass: Vec<f64>,
    /// This step's lever arms `x_n - p`, turned by the predicted rotation
    /// (m).
    current: Vec<Point>,
    /// The lever arms `r` of the projection: the reference turned by each
    /// body's fitted `Q` (m).
    r: Vec<Point>,
    /// `M r` (kg m) and `L_ff r`.
    mr: Vec<Point>,
    lr: Vec<Point>,
    /// `A^-1 M r` and `A^-1 L_ff r`.
    ym: Vec<Point>,
    yl: Vec<Point>,
    /// The reference arms `r_ref` (the lever arms of the last step that
    /// rebuilt them), `L_ff r_ref`, `A^-1 M r_ref` and `A^-1 L_ff r_ref`.
    reference: Vec<Point>,
    reference_lr: Vec<Point>,
    reference_ym: Vec<Point>,
    reference_yl: Vec<Point>,
    /// The bits of the step matrix's coefficients the reference was solved
    /// with (`None`: no reference yet).
    key: Option<[u64; COEFFICIENT_COUNT]>,
    /// Whether the reference arms are newer than what was solved with them
    /// (set by a rebuild and by a restored checkpoint).
    rebuild: bool,
    /// `r` by vertex (zero elsewhere), to apply `L_ff` to it.
    r_by_vertex: Vec<Point>,
    /// Two right-hand sides over the free vertices.
    solve_m: Vec<Point>,
    solve_l: Vec<Point>,
    /// Whether [`RotationProjection::update`] ran for the current step.
    active: bool,
}

/// `T(p, q) = sum_i (p_i . q_i) I - q_i p_i^T` from `W = sum_i q_i p_i^T`:
/// `tr(W) I - W`, so that `a^T T b = sum_i (a x p_i) . (b x q_i)`.
fn gram(w: &Matrix3<f64>) -> Matrix3<f64> {
    Matrix3::identity() * w.trace() - w
}

impl RotationProjection {
    /// The structure of the projection: the rigid bodies among `rigid` for
    /// which `projected` says yes and that can turn (free, pivoted or
    /// hinged).
    ///
    /// # Errors
    /// [`SolverError::Unsupported`] naming `damping.preserve_rotation` when
    /// a constraint couples a projected body with another one (the step
    /// matrix would not be block-diagonal by body, which the cheap solve of
    /// `Z` relies on).
    pub fn new(
        system: &GlobalSystem,
        rigid: &[RigidBody],
        projected: impl Fn(usize) -> bool,
    ) -> Result<Self, SolverError> {
        let n = system.free_index.len();
        let mut owner = vec![usize::MAX; n];
        for (b, body) in rigid.iter().enumerate() {
            for &v in &body.vertices {
                owner[v] = b;
            }
        }
        let mut projection = Self::default();
        for (b, body) in rigid.iter().enumerate() {
            if !projected(b) || body.freedom == RigidFreedom::Held {
                continue;
            }
            let start = projection.vertex.len();
            let mut anchored = false;
            for &v in &body.vertices {
                let f = system.free_index[v];
                anchored |= system.anchoring_rows.row(f).next().is_some();
                for rows in [&system.damping_rows, &system.anchoring_rows] {
                    for (c, _) in rows.row(f) {
                        if system.free_index[c] != FIXED && owner[c] != b {
                            return Err(SolverError::Unsupported {
                                what: format!(
                                    "damping.preserve_rotation with a constraint between \
                                     vertices {v} and {c} of different connected components: \
                                     the rotations are projected body by body"
                                ),
                            });
                        }
                    }
                }
                projection.vertex.push(v);
                projection.free.push(f);
            }
            projection.bodies.push(ProjectedBody {
                rigid: b,
                freedom: body.freedom,
                start,
                end: projection.vertex.len(),
                axes: [Point::zeros(); 3],
                map: Matrix3::identity(),
                second_moment: Matrix3::zeros(),
                sums: [Matrix3::zeros(); 5],
                spread: 0.0,
                damping: 0.0,
                used: 0,
                inverse_inertia: [0.0; 3],
                coefficient: 0.0,
                anchored,
                alpha: 0.0,
                stiffness: 0.0,
                laplacian_gram: Matrix3::zeros(),
                capacitance: None,
            });
        }
        let m = projection.vertex.len();
        for buffer in [
            &mut projection.current,
            &mut projection.r,
            &mut projection.mr,
            &mut projection.lr,
            &mut projection.ym,
            &mut projection.yl,
            &mut projection.reference,
            &mut projection.reference_lr,
            &mut projection.reference_ym,
            &mut projection.reference_yl,
        ] {
            *buffer = vec![Point::zeros(); m];
        }
        projection.mass = vec![0.0; m];
        projection.r_by_vertex = vec![Point::zeros(); n];
        projection.solve_m = vec![Point::zeros(); system.free.len()];
        projection.solve_l = vec![Point::zeros(); system.free.len()];
        Ok(projection)
    }

    /// The reference arms and the coefficients they were solved with, for a
    /// checkpoint (both empty when there is no reference).
    pub fn save(&self) -> RotationState {
        match self.key {
            Some(key) => RotationState {
                arms: self.reference.clone(),
                key: key.iter().map(|&b| f64::from_bits(b)).collect(),
            },
            None => RotationState::default(),
        }
    }

    /// Checks a checkpoint's [`RotationState`] against this projection.
    ///
    /// # Errors
    /// The reason, naming the field, when the arms are not one per
    /// projected vertex, the key not one value per coefficient, or a value
    /// is not finite.
    pub fn check(&self, state: &RotationState) -> Result<(), String> {
        if state.arms.is_empty() && state.key.is_empty() {
            return Ok(());
        }
        if state.arms.len() != self.vertex.len() {
            return Err(format!(
                "rotation.arms holds {} points; the projection has {} vertices",
                state.arms.len(),
                self.vertex.len()
            ));
        }
        if state.key.len() != COEFFICIENT_COUNT {
            return Err(format!(
                "rotation.key holds {} values; it must hold {COEFFICIENT_COUNT}",
                state.key.len()
            ));
        }
        if let Some(k) = state
            .arms
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(format!("rotation.arms[{k}] is not finite"));
        }
        if let Some(k) = state.key.iter().position(|c| !c.is_finite()) {
            return Err(format!("rotation.key[{k}] is not finite"));
        }
        Ok(())
    }

    /// Takes a checked [`RotationState`]: the next step solves with the
    /// restored reference arms (or rebuilds them, as the saved run would
    /// have).
    pub fn load(&mut self, state: &RotationState) {
        self.active = false;
        if state.arms.is_empty() {
            self.key = None;
            self.rebuild = false;
            return;
        }
        self.reference.copy_from_slice(&state.arms);
        let mut key = [0; COEFFICIENT_COUNT];
        for (k, v) in key.iter_mut().zip(&state.key) {
            *k = v.to_bits();
        }
        self.key = Some(key);
        self.rebuild = true;
    }

    /// `(L_ff w)` on the row of free vertex `f` (`w` by vertex; columns of
    /// fixed vertices dropped).
    fn laplacian_at(system: &GlobalSystem, f: usize, w: &[Point]) -> Point {
        let mut sum = Point::zeros();
        for (c, value) in system.damping_rows.row(f) {
            if system.free_index[c] != FIXED {
                sum += w[c] * value;
            }
        }
        sum
    }

    /// Starts this step's projection from `motion`.
    /// Returns the right-hand sides `M r_ref` and, when an attachment acts
    /// on a projected body, `L_ff r_ref` on those bodies (one point per
    /// free vertex) when the reference arms `r_ref` are rebuilt this step,
    /// for the caller to solve with `A` in place before
    /// [`RotationProjection::finish_update`]; `None` when the step turns the
    /// reference instead (the projection is then ready) or when nothing is
    /// projected. `coefficients` are the step matrix's, `weight(v)` the
    /// per-body damping weights (mass, Laplacian) of vertex `v`.
    pub fn begin_update(
        &mut self,
        system: &GlobalSystem,
        rigid: &[RigidBody],
        motion: StepMotion<'_>,
        coefficients: MatrixCoefficients,
        weight: impl Fn(usize) -> (f64, f64),
    ) -> Option<(&mut [Point], Option<&mut [Point]>)> {
        let coefficient = coefficients.damping;
        let StepMotion {
            positions,
            masses,
            inertial_displacement,
            turn_time,
        } = motion;
        self.active = false;
        if self.bodies.is_empty() || coefficient == 0.0 {
            return None;
        }
        for body in &mut self.bodies {
            let range = body.start..body.end;
            let vertices = &self.vertex[range.clone()];
            let mass: f64 = vertices.iter().map(|&v| masses[v]).sum();
            let centre = match rigid[body.rigid].freedom {
                RigidFreedom::Pivot { point } | RigidFreedom::Hinge { point, .. } => point,
                _ => {
                    vertices
                        .iter()
                        .map(|&v| positions[v] * masses[v])
                        .sum::<Point>()
                        / mass
                }
            };
            let mut inertia = Matrix3::zeros();
            let mut spread = 0.0;
            for ((r, m), &v) in self.current[range.clone()]
                .iter_mut()
                .zip(&mut self.mass[range.clone()])
                .zip(vertices)
            {
                *r = positions[v] - centre;
                *m = masses[v];
                inertia -= *r * r.transpose() * *m;
                spread += *m * r.norm_squared();
            }
            for k in 0..3 {
                inertia[(k, k)] += spread;
            }
            // The body turned by the rotation the step predicts over
            // `turn_time`: the lever arms of the integrator's angular
            // momentum balance, where the damping force must exert no torque.
            let mut moment = Point::zeros();
            for (r, &v) in self.current[range.clone()].iter().zip(vertices) {
                moment += r.cross(&inertial_displacement[v]) * masses[v];
            }
            let omega = match rigid[body.rigid].freedom {
                RigidFreedom::Hinge { axis, .. } => {
                    let a = axis.normalize();
                    let moment_of_inertia = a.dot(&(inertia * a));
                    if moment_of_inertia > INERTIA_RELATIVE_CUTOFF * spread {
                        a * (a.dot(&moment) / moment_of_inertia)
                    } else {
                        Point::zeros()
                    }
                }
                _ => pseudo_solve(&inertia, &moment, spread),
            };
            // `inertial_displacement` is a displacement over the step, so
            // `omega` is the turn over one step (rad).
            if turn_time != 0.0 && omega != Point::zeros() {
                let turn = nalgebra::Rotation3::new(omega * turn_time);
                for r in &mut self.current[range.clone()] {
                    *r = turn * *r;
                }
            }
            body.spread = spread;
            let (w_mass, w_laplacian) = weight(vertices.first().copied().unwrap_or(0));
            body.damping = coefficient * w_laplacian;
            // A = (1/h^2 + c a1 W1) M + c1 c2^2 L_sys + c W2 L_d on the body
            // (weights.rs), L_sys = L_d where nothing anchors it.
            body.alpha = coefficients.mass + coefficients.mass_damping * (w_mass - 1.0);
            body.stiffness = coefficients.system + coefficient * w_laplacian;
        }
        let key = coefficients.bits();
        let mut refresh = self.key != Some(key);
        if !refresh {
            for b in 0..self.bodies.len() {
                refresh |= self.fit_map(b) > ARM_MISMATCH_TOLERANCE;
            }
        }
        if refresh {
            self.reference.copy_from_slice(&self.current);
            self.key = Some(key);
            self.rebuild = true;
        }
        if !self.rebuild {
            self.map_reference();
            return None;
        }
        for (k, r) in self.reference.iter().enumerate() {
            self.r_by_vertex[self.vertex[k]] = *r;
        }
        self.solve_m.iter_mut().for_each(|p| *p = Point::zeros());
        self.solve_l.iter_mut().for_each(|p| *p = Point::zeros());
        let mut second = false;
        for body in &self.bodies {
            for k in body.start..body.end {
                let f = self.free[k];
                let lr = Self::laplacian_at(system, f, &self.r_by_vertex);
                self.reference_lr[k] = lr;
                self.solve_m[f] = self.reference[k] * self.mass[k];
                if body.anchored {
                    self.solve_l[f] = lr;
                    second = true;
                }
            }
        }
        for k in 0..self.vertex.len() {
            self.r_by_vertex[self.vertex[k]] = Point::zeros();
        }
        Some((&mut self.solve_m, second.then_some(&mut self.solve_l[..])))
    }

    /// Fits body `b`'s map `F` from its reference arms to this step's: the
    /// linear map (a turn, a stretch, a shear) that minimises `sum_i m_i
    /// |r_i - F r_ref,i|^2`, `F = H C^+` with `H = sum_i m_i r_i r_ref,i^T`
    /// and `C = sum_i m_i r_ref,i r_ref,i^T` (directions of `C` at or below
    /// [`INERTIA_RELATIVE_CUTOFF`] of its trace dropped: a flat or straight
    /// body's reference spans no more). Returns the mass-weighted relative
    /// mismatch `|r - F r_ref|_M / |r|_M`.
    fn fit_map(&mut self, b: usize) -> f64 {
        let body = &mut self.bodies[b];
        let range = body.start..body.end;
        let (current, reference) = (&self.current[range.clone()], &self.reference[range.clone()]);
        let masses = &self.mass[range];
        let (mut h, mut c) = (Matrix3::zeros(), Matrix3::zeros());
        for ((r, q), &m) in current.iter().zip(reference).zip(masses) {
            let mq = q * m;
            h += r * mq.transpose();
            c += q * mq.transpose();
        }
        body.second_moment = c;
        body.map = Matrix3::identity();
        if body.spread <= 0.0 {
            return 0.0;
        }
        let Some(eigen) = SymmetricEigen::try_new(c, f64::EPSILON, EIGEN_MAX_ITERATIONS) else {
            return f64::INFINITY;
        };
        let mut inverse = Matrix3::zeros();
        for k in 0..3 {
            let lambda = eigen.eigenvalues[k];
            if lambda > INERTIA_RELATIVE_CUTOFF * c.trace() {
                let a: Point = eigen.eigenvectors.column(k).into_owned();
                inverse += a * a.transpose() / lambda;
            }
        }
        let map = h * inverse;
        body.map = map;
        let mut gap = 0.0;
        for ((r, q), &m) in current.iter().zip(reference).zip(masses) {
            gap += m * (r - map * q).norm_squared();
        }
        (gap / body.spread).sqrt()
    }

    /// This step's projection from the reference: the arms, their Laplacian,
    /// `A^-1 M r` and `A^-1 L_ff r` mapped by each body's fitted `F` (`A`
    /// is the same on x, y and z, so it commutes with `F` applied at every
    /// vertex: `A^-1 M (F r_ref) = F A^-1 M r_ref`), and the axes and the
    /// capacitance matrix from the reference's sums mapped by `F` (`sum_i
    /// F q_i (F p_i)^T = F (sum_i q_i p_i^T) F^T`, `O(1)` per body).
    fn map_reference(&mut self) {
        for body in &mut self.bodies {
            let f = body.map;
            let mapped = |w: &Matrix3<f64>| f * w * f.transpose();
            for k in body.start..body.end {
                self.r[k] = f * self.reference[k];
                self.mr[k] = self.r[k] * self.mass[k];
                self.lr[k] = f * self.reference_lr[k];
                self.ym[k] = f * self.reference_ym[k];
                self.yl[k] = f * self.reference_yl[k];
            }
            let c = mapped(&body.second_moment);
            let spread = c.trace();
            let inertia = Matrix3::identity() * spread - c;
            body.used = 0;
            let keep = |axis: Point, lambda: f64, body: &mut ProjectedBody| {
                if lambda > INERTIA_RELATIVE_CUTOFF * spread && lambda > 0.0 {
                    body.axes[body.used] = axis;
                    body.inverse_inertia[body.used] = 1.0 / lambda;
                    body.used += 1;
                }
            };
            match body.freedom {
                RigidFreedom::Hinge { axis, .. } => {
                    let a = axis.normalize();
                    keep(a, a.dot(&(inertia * a)), body);
                }
                _ => {
                    if let Some(eigen) =
                        SymmetricEigen::try_new(inertia, f64::EPSILON, EIGEN_MAX_ITERATIONS)
                    {
                        for k in 0..3 {
                            let a: Point = eigen.eigenvectors.column(k).into_owned();
                            keep(a, eigen.eigenvalues[k], body);
                        }
                    }
                }
            }
            body.coefficient = if body.used == 0 { 0.0 } else { body.damping };
            let [s, t_mr_ym, t_mr_yl, t_lr_yl, t_lr_ym] =
                body.sums.each_ref().map(|w| gram(&mapped(w)));
            body.laplacian_gram = s;
            body.capacitance = None;
            if body.coefficient == 0.0 {
                continue;
            }
            let c = body.coefficient;
            let mut k = Capacitance::identity();
            let form = |t: &Matrix3<f64>, j: usize, l: usize| body.axes[j].dot(&(t * body.axes[l]));
            for j in 0..body.used {
                let gj = body.inverse_inertia[j];
                for l in 0..body.used {
                    let gl = body.inverse_inertia[l];
                    let delta = if j == l { 1.0 / c } else { 0.0 };
                    k[(j, l)] = form(&s, j, l) / c - form(&t_lr_yl, j, l);
                    k[(j, 3 + l)] = delta - form(&t_lr_ym, j, l) * gl;
                    k[(3 + j, l)] = delta - form(&t_mr_yl, j, l) * gj;
                    k[(3 + j, 3 + l)] = -form(&t_mr_ym, j, l) * gj * gl;
                }
            }
            body.capacitance = Some(k.lu());
        }
        self.active = true;
    }

    /// Ends [`RotationProjection::begin_update`] once its right-hand sides
    /// hold `A^-1 M r_ref` and `A^-1 L_ff r_ref`: the reference's sums, then
    /// this step's projection.
    pub fn finish_update(&mut self) {
        for body in &mut self.bodies {
            let mut sums = [Matrix3::zeros(); 5];
            for k in body.start..body.end {
                let f = self.free[k];
                let ym = self.solve_m[f];
                // Where nothing anchors the body, `A r = alpha M r +
                // stiffness L_ff r` gives `A^-1 L_ff r` without a solve.
                let yl = if body.anchored {
                    self.solve_l[f]
                } else {
                    (self.reference[k] - ym * body.alpha) / body.stiffness
                };
                self.reference_ym[k] = ym;
                self.reference_yl[k] = yl;
                let (r, lr) = (self.reference[k], self.reference_lr[k]);
                let mr = r * self.mass[k];
                // `sum q p^T` of T(r, L r), T(m r, Y_M), T(m r, Y_L),
                // T(L r, Y_L) and T(L r, Y_M).
                sums[0] += lr * r.transpose();
                sums[1] += ym * mr.transpose();
                sums[2] += yl * mr.transpose();
                sums[3] += yl * lr.transpose();
                sums[4] += ym * lr.transpose();
            }
            body.sums = sums;
        }
        self.rebuild = false;
        for b in 0..self.bodies.len() {
            self.fit_map(b);
        }
        self.map_reference();
    }

    /// `x <- x + Z K^-1 U^T x` for the solution `x = A^-1 b` (one point per
    /// free vertex): `x` becomes `A'^-1 b`.
    pub fn correct_solution(&self, x: &mut [Point]) {
        if !self.active {
            return;
        }
        for body in &self.bodies {
            let Some(lu) = &body.capacitance else {
                continue;
            };
            let range = body.start..body.end;
            let free = &self.free[range.clone()];
            let (mut t1, mut t2) = (Point::zeros(), Point::zeros());
            for ((&f, lr), mr) in free
                .iter()
                .zip(&self.lr[range.clone()])
                .zip(&self.mr[range.clone()])
            {
                let xi = x[f];
                t1 += lr.cross(&xi);
                t2 += mr.cross(&xi);
            }
            let mut t = Pair::zeros();
            for j in 0..body.used {
                t[j] = body.axes[j].dot(&t1);
                t[3 + j] = body.axes[j].dot(&t2) * body.inverse_inertia[j];
            }
            let Some(s) = lu.solve(&t) else {
                continue;
            };
            let (mut turn_l, mut turn_m) = (Point::zeros(), Point::zeros());
            for j in 0..body.used {
                turn_l += body.axes[j] * s[j];
                turn_m += body.axes[j] * (s[3 + j] * body.inverse_inertia[j]);
            }
            for ((&f, yl), ym) in free
                .iter()
                .zip(&self.yl[range.clone()])
                .zip(&self.ym[range])
            {
                x[f] += turn_l.cross(yl) + turn_m.cross(ym);
            }
        }
    }

    /// The rotation `omega` (rad, per unit of `w`) of a body whose
    /// projection `P w` is `omega x r`: `G^-1 R^T M w` on the axes.
    fn rotation_part(&self, body: &ProjectedBody, w: impl Fn(usize) -> Point) -> Point {
        let mut moment = Point::zeros();
        for k in body.start..body.end {
            moment += self.mr[k].cross(&w(k));
        }
        let mut omega = Point::zeros();
        for j in 0..body.used {
            omega += body.axes[j] * (body.axes[j].dot(&moment) * body.inverse_inertia[j]);
        }
        omega
    }

    /// `w <- (I - P) w` for `w` by vertex (m, or any unit): each projected
    /// body loses its rigid rotation in the mass-weighted sense.
    pub fn project(&self, w: &mut [Point]) {
        if !self.active {
            return;
        }
        for body in self.bodies.iter().filter(|b| b.coefficient != 0.0) {
            let omega = self.rotation_part(body, |k| w[self.vertex[k]]);
            for k in body.start..body.end {
                w[self.vertex[k]] -= omega.cross(&self.r[k]);
            }
        }
    }

    /// `out -= c U C U^T w` on the free rows (`w` by vertex, zero at fixed
    /// vertices; `out` one point per free vertex): turns `A w` into
    /// `A' w`, and `c L_d w` into `c (I - P)^T L_d (I - P) w`.
    pub fn add_product_correction(&self, w: &[Point], out: &mut [Point]) {
        if !self.active {
            return;
        }
        for body in self.bodies.iter().filter(|b| b.coefficient != 0.0) {
            // u1 = R^T L w = (L R)^T w (L_ff symmetric, and it couples the
            // body to no other free vertex), u2 = G^-1 R^T M w (as vectors
            // on the axes).
            let mut moment_l = Point::zeros();
            for k in body.start..body.end {
                moment_l += self.lr[k].cross(&w[self.vertex[k]]);
            }
            let turn = self.rotation_part(body, |k| w[self.vertex[k]]);
            // C [u1; u2] = [u2; u1 - S u2]; U times it.
            let mut second = Point::zeros();
            for j in 0..body.used {
                let a = body.axes[j];
                let u1 = a.dot(&moment_l);
                let s_u2 = a.dot(&(body.laplacian_gram * turn));
                second += a * ((u1 - s_u2) * body.inverse_inertia[j]);
            }
            let c = body.coefficient;
            for k in body.start..body.end {
                let correction = turn.cross(&self.lr[k]) + second.cross(&self.mr[k]);
                out[self.free[k]] -= correction * c;
            }
        }
    }
}
