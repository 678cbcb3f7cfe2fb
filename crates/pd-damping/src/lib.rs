//! Damping models for Projective Dynamics, one [`Damping`] implementation
//! each, every model's behaviour in its own file.
//!
//! A model can contribute in four ways, and the step asks for each:
//! 1. a **constant implicit matrix** `D = a1 M + a2 L_d`
//!    ([`Damping::implicit_matrix`]), a mix of the lumped mass matrix and the
//!    damping Laplacian that enters the global step and is factored once per
//!    (integrator, h, coefficients);
//! 2. a **per-step implicit matrix**, here the lagged stiffness term
//!    `a3 K(x_n)` ([`DampingMatrix::lagged_stiffness`]), which makes the
//!    solver assemble the elastic Hessian and refactorise every step;
//! 3. at the **start of the step** ([`Damping::begin_step`]): an explicit
//!    force folded into the inertial target ([`Damping::add_explicit_force`]);
//! 4. at the **end of the step** ([`Damping::end_step`]): a velocity filter
//!    after the solve ([`Damping::filter_velocities`]: explicit ether drag,
//!    PBD).
//!
//! A model may also ask the solver to leave the bodies' rigid rotations out
//! of its `L_d` term ([`Damping::preserves_rotation`], the
//! rotation-preserving Laplacian variant).
//!
//! How each enters each integrator's global step is derived in
//! `docs/design/damping.md`. A model of your own is a type implementing [`Damping`]
//! outside this crate (see `examples/custom_damping.rs` of `pd-solver`).
//!
//! ```
//! use pd_damping::{Damping, NoDamping};
//! let none = NoDamping;
//! assert_eq!(none.name(), pd_damping::registry::UNDAMPED);
//! assert!(none.implicit_matrix().is_zero());
//! ```

mod error;
mod ether_drag;
mod laplacian;
mod none;
mod pbd;
pub mod per_body;
pub mod ratio;
mod rayleigh_lagged;
pub mod registry;
pub mod rigid;

pub use error::DampingError;
pub use ether_drag::EtherDrag;
pub use laplacian::LaplacianDamping;
pub use none::NoDamping;
pub use pbd::PbdDamping;
pub use per_body::PerBodyDamping;
pub use rayleigh_lagged::RayleighLagged;

use std::ops::Range;

use nalgebra::Vector3;

/// A position, velocity or force of one vertex (SI units).
pub type Point = Vector3<f64>;

/// The most terms a Caughey series `a1 M + a2 L_d + a3 L_d M^-1 L_d + ...`
/// may have (`a1` to `a8`).
pub const MAX_SERIES_TERMS: usize = 8;

/// The series terms beyond `a1 M + a2 L_d`: `a3` to `a8`.
pub const HIGHER_SERIES_TERMS: usize = MAX_SERIES_TERMS - 2;

/// Coefficients of an implicit damping matrix
/// `D = mass M + damping_laplacian L_d + sum_j series_j L_d (M^-1 L_d)^(j+1)
/// + lagged_stiffness K(x_n)` (`series_j` the entry `j` of `series`, from 0).
///
/// The `series` terms continue Laplacian damping into a Caughey series in
/// `M^-1 L_d` (`docs/design/damping.md`, "Caughey series"): its entry 0 is
/// `a3` (s^3) of `L_d M^-1 L_d`, entry 1 is `a4` (s^5) of
/// `L_d M^-1 L_d M^-1 L_d`, and so on; all zero for every other model.
/// `L_d` and `M` are restricted to the free vertices there.
///
/// ```
/// use pd_damping::DampingMatrix;
/// let d = DampingMatrix { mass: 0.1, damping_laplacian: 0.01, ..DampingMatrix::default() }
///     .with_series(&[1e-6, 2e-9]);
/// assert_eq!(d.series_powers(), 2);
/// assert_eq!(d.series_coefficients(), vec![0.1, 0.01, 1e-6, 2e-9]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DampingMatrix {
    /// `a1` in 1/s: mass-proportional (implicit ether) damping.
    pub mass: f64,
    /// `a2` in s: the paper's Laplacian damping, times the damping Laplacian
    /// `L_d` of the translation-invariant constraints.
    pub damping_laplacian: f64,
    /// `a3` in s: times the elastic Hessian at the start of the step
    /// (lagged Rayleigh damping). Non-zero forces a refactorisation per step.
    pub lagged_stiffness: f64,
    /// `a3, a4, ...`: the Caughey series' coefficients of
    /// `L_d (M^-1 L_d)^(j+1)` (units s^(2j+3)), trailing zeros unused.
    pub series: [f64; HIGHER_SERIES_TERMS],
}

impl DampingMatrix {
    /// Whether the matrix is zero (no implicit damping).
    pub fn is_zero(&self) -> bool {
        self.mass == 0.0
            && self.damping_laplacian == 0.0
            && self.lagged_stiffness == 0.0
            && !self.has_series()
    }

    /// The same matrix with the series terms `a3, a4, ...` set to `higher`
    /// (at most [`HIGHER_SERIES_TERMS`]; more are ignored).
    pub fn with_series(mut self, higher: &[f64]) -> Self {
        self.series = [0.0; HIGHER_SERIES_TERMS];
        for (s, a) in self.series.iter_mut().zip(higher) {
            *s = *a;
        }
        self
    }

    /// Whether the series has a term beyond `a2 L_d`.
    pub fn has_series(&self) -> bool {
        self.series.iter().any(|a| *a != 0.0)
    }

    /// How many products `M^-1 L_d` the highest series term holds: 0 without
    /// series, 1 with `a3` the last non-zero term, 2 with `a4`, ...
    pub fn series_powers(&self) -> usize {
        self.series
            .iter()
            .rposition(|a| *a != 0.0)
            .map_or(0, |j| j + 1)
    }

    /// The series' coefficients `[a1, a2, a3, ...]` up to the last non-zero
    /// higher term (just `[a1, a2]` without series).
    pub fn series_coefficients(&self) -> Vec<f64> {
        let mut all = vec![self.mass, self.damping_laplacian];
        all.extend_from_slice(&self.series[..self.series_powers()]);
        all
    }

    /// The modal damping `sum_k a_k Q_k` (1/s) of a mode with series
    /// quotients `quotients = [1, phi^T L_d phi, phi^T L_d M^-1 L_d phi,
    /// ...]` (a mass-normalised `phi`, 1/s^(2k-2)); terms beyond the
    /// quotients given count as 0. The lagged term is not included.
    pub fn series_damping(&self, quotients: &[f64]) -> f64 {
        self.series_coefficients()
            .iter()
            .zip(quotients)
            .map(|(a, q)| a * q)
            .sum()
    }

    /// Whether the matrix changes from step to step.
    pub fn is_lagged(&self) -> bool {
        self.lagged_stiffness != 0.0
    }
}

/// What a damping model may read about the system.
#[derive(Debug, Clone, Copy)]
pub struct DampingContext<'a> {
    /// Time step h in s.
    pub h: f64,
    /// Lumped vertex masses in kg.
    pub masses: &'a [f64],
    /// Vertex ranges of the bodies, in scene order.
    pub bodies: &'a [Range<usize>],
    /// Vertex lists of the connected components (fixed vertices excluded).
    pub components: &'a [Vec<usize>],
    /// Whether each vertex is hard-fixed (its velocity must stay 0).
    pub fixed: &'a [bool],
}

/// What the step tells a damping model at its start and end, besides the
/// [`DampingContext`].
#[derive(Debug, Clone, Copy)]
#[non_exhaustive]
pub struct StepContext<'a> {
    /// Time step, masses, bodies, components and fixed vertices.
    pub base: DampingContext<'a>,
    /// Every connected component with what holds it
    /// ([`rigid::RigidFreedom`]): free bodies (no fixed vertex, no
    /// attachment: nothing outside exerts a torque on them besides uniform
    /// gravity, which exerts none about the centre of mass), bodies that can
    /// swing about a pivot or a hinge, and held ones.
    pub rigid_bodies: &'a [rigid::RigidBody],
    /// `gamma` in 1/s of the integrator: the damping force is evaluated at the
    /// velocity `gamma (x - x_hat)`.
    pub gamma: f64,
    /// `c1 c2 h^2` in s^2: a force `f` (N) on a vertex of mass `m` enters the
    /// inertial target as `force_scale f / m` (docs/design/formulation.md,
    /// "The step objective").
    pub force_scale: f64,
    /// The integrator's `c2` (dimensionless): the step's energy is evaluated
    /// at `x_n + c2 (x - x_n)`.
    pub c2: f64,
    /// The coefficients of `x_{n+1}, x_n, x_{n-1}, ...` in `x - x_hat`
    /// (`pd_integrators::Integrator::damping_stencil`): `[1, -1]` for
    /// one-step methods, `[1, -4/3, 1/3]` for BDF-2.
    pub damping_stencil: &'a [f64],
}

impl<'a> StepContext<'a> {
    /// The context of one step (for solvers; models only read it), with
    /// `gamma`, `force_scale` and `c2` as documented on the fields and
    /// `damping_stencil` as in [`StepContext::damping_stencil`].
    pub fn new(
        base: DampingContext<'a>,
        rigid_bodies: &'a [rigid::RigidBody],
        (gamma, force_scale, c2): (f64, f64, f64),
        damping_stencil: &'a [f64],
    ) -> Self {
        Self {
            base,
            rigid_bodies,
            gamma,
            force_scale,
            c2,
            damping_stencil,
        }
    }

    /// The factor by which this step multiplies the momentum (linear, or
    /// angular about the centre of mass) of a free body on which the only
    /// force is the mass-proportional damping `-a1 M v` (`a1` in 1/s):
    /// summing the global equations over the body leaves
    /// `sum m (x - x_n) = (sum m (y - x_n) + k h^2 sum m (x_hat - x_n)) /
    /// (1 + k h^2)` with `k = c1 c2 gamma a1`, and the velocity update
    /// `v = (x - x_n) / (c2 h) - (1/c2 - 1) v_n` of the one-leg methods
    /// gives `1 / (c2 (1 + k h^2)) - 1/c2 + 1`: backward Euler
    /// `1 / (1 + a1 h)`, implicit midpoint `(1 - a1 h/2) / (1 + a1 h/2)`,
    /// and BDF-2 `3 / (3 + 2 a1 h)` for a body whose previous momentum equals
    /// the current one (`docs/design/damping.md`).
    pub fn mass_damping_factor(&self, a1: f64) -> f64 {
        let k_h2 = self.force_scale * self.gamma * a1;
        1.0 / (self.c2 * (1.0 + k_h2)) - 1.0 / self.c2 + 1.0
    }
}

/// The targets of a step a damping model may change at its start, as
/// displacements from `x_n` (m), and a scratch buffer. All have one entry
/// per vertex.
#[derive(Debug)]
#[non_exhaustive]
pub struct DampingTargets<'a> {
    /// `y - x_n`: the inertial target, where explicit forces go.
    pub inertial_displacement: &'a mut [Point],
    /// `x_hat - x_n`: the damping anchor of the mass term `a1 M` and the
    /// lagged `K(x_n)` (the damping velocity is `gamma (x - x_hat)`).
    pub anchor_displacement: &'a mut [Point],
    /// The damping anchor of the Laplacian term `a2 L_d`, equal to
    /// `anchor_displacement` on entry: a model that measures the `L_d` term's
    /// damping velocity from another anchor moves it.
    pub laplacian_anchor: &'a mut [Point],
    /// Scratch, contents unspecified on entry.
    pub scratch: &'a mut [Point],
}

impl<'a> DampingTargets<'a> {
    /// The targets of one step (for solvers; models only change them).
    pub fn new(
        inertial_displacement: &'a mut [Point],
        anchor_displacement: &'a mut [Point],
        laplacian_anchor: &'a mut [Point],
        scratch: &'a mut [Point],
    ) -> Self {
        Self {
            inertial_displacement,
            anchor_displacement,
            laplacian_anchor,
            scratch,
        }
    }
}

/// What a damping model reports about one step (nothing yet: the type
/// leaves room for a model's own measures).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct DampingReport {}

/// A damping model.
///
/// The step calls, in order: [`Damping::implicit_matrix`] (for the global
/// matrix), [`Damping::begin_step`] after the integrator prepared its
/// targets, the position solve, the integrator's velocity update, then
/// [`Damping::end_step`]. Every method has a default that does nothing, so a
/// model implements only the channels it uses.
pub trait Damping: std::fmt::Debug + Send + Sync {
    /// Name as scenes spell it (`none`, `laplacian`, ...).
    fn name(&self) -> &'static str;

    /// The implicit damping matrix this model puts into the global step.
    fn implicit_matrix(&self) -> DampingMatrix {
        DampingMatrix::default()
    }

    /// Each body's own implicit matrix, in scene order, for a model that
    /// damps bodies differently ([`PerBodyDamping`]); `None` (the default)
    /// when [`Damping::implicit_matrix`] holds for every body. Each term of
    /// each body is at most that of [`Damping::implicit_matrix`], and the
    /// lagged term is the same for every body.
    fn body_coefficients(&self) -> Option<&[DampingMatrix]> {
        None
    }

    /// Adds an explicit damping force (N), evaluated at the start of the step,
    /// to `forces`. Called by the default [`Damping::begin_step`] when
    /// [`Damping::has_explicit_force`] says so.
    fn add_explicit_force(
        &self,
        _context: &DampingContext<'_>,
        _positions: &[Point],
        _velocities: &[Point],
        _forces: &mut [Point],
    ) {
    }

    /// Whether the model leaves the bodies' rigid rotations out of its
    /// `L_d` term: the solver then damps `(I - P)^T L_d (I - P)`, `P` the
    /// mass-orthogonal projection on the rotations each body may perform
    /// (the rotation-preserving Laplacian variant,
    /// `docs/design/damping.md`).
    fn preserves_rotation(&self) -> bool {
        false
    }

    /// Whether the model leaves the rigid rotations of body `body` (scene
    /// order) out of its `L_d` term; [`Damping::preserves_rotation`] for
    /// every body by default ([`PerBodyDamping`] asks the body's model).
    fn preserves_rotation_of_body(&self, _body: usize) -> bool {
        self.preserves_rotation()
    }

    /// Whether [`Damping::add_explicit_force`] does anything, so the step
    /// can skip it.
    fn has_explicit_force(&self) -> bool {
        false
    }

    /// Adjusts the velocities after the solve (explicit ether drag, PBD).
    /// Called by the default [`Damping::end_step`].
    fn filter_velocities(
        &self,
        _context: &DampingContext<'_>,
        _positions: &[Point],
        _velocities: &mut [Point],
    ) {
    }

    /// The start of a step, at positions `x_n` (m) and velocities `v_n`
    /// (m/s), after the integrator prepared its targets. The default folds
    /// the explicit force into the inertial target: `y += force_scale f / m`.
    fn begin_step(
        &mut self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &[Point],
        targets: DampingTargets<'_>,
    ) {
        if !self.has_explicit_force() {
            return;
        }
        let forces = targets.scratch;
        forces.iter_mut().for_each(|f| *f = Point::zeros());
        self.add_explicit_force(&step.base, positions, velocities, forces);
        let masses = step.base.masses;
        for ((y, f), m) in targets
            .inertial_displacement
            .iter_mut()
            .zip(forces.iter())
            .zip(masses)
        {
            if *m > 0.0 {
                *y += f * (step.force_scale / m);
            }
        }
    }

    /// The end of a step: `velocities` (m/s) are the integrator's new ones at
    /// the new `positions` (m), fixed vertices at zero; the step zeroes them
    /// again afterwards. The default applies
    /// [`Damping::filter_velocities`].
    fn end_step(
        &mut self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &mut [Point],
    ) -> DampingReport {
        self.filter_velocities(&step.base, positions, velocities);
        DampingReport::default()
    }
}
