//! Time integrators for Projective Dynamics, all in one form: each step
//! minimises
//!
//! `g(x) = 1/(2h^2) |x - y|_M^2 + c1 E(x_n + c2 (x - x_n)) + Phi(x)`
//!
//! where `y` is the inertial target (external forces folded in), `E` the PD
//! energy and `Phi` the implicit damping potential
//! `1/2 c1 c2 gamma (x - x_hat)^T D (x - x_hat)`. (docs/design/formulation.md
//! writes the energy's argument `c2 x + z`; every one-leg method here has
//! `z = (1 - c2) x_n`.) An [`Integrator`] supplies `c1`, `c2`, `gamma`, the
//! targets `y` and `x_hat` as displacements from `x_n`, and the velocity
//! update; it owns whatever history it needs. The coefficient table and the
//! derivation are in `docs/design/integrators.md`.
//!
//! Targets are displacements, not positions, so that the solver can work
//! with the step's displacement `x - x_n` throughout: round-off then scales
//! with how far a body moves in a step, not with how far it is from the
//! origin (`docs/design/solver.md`).
//!
//! ```
//! use pd_integrators::{BackwardEuler, Integrator, StepTargets};
//! use nalgebra::Vector3;
//!
//! let mut be = BackwardEuler::new();
//! let c = be.coefficients(0.1);
//! assert_eq!((c.c1, c.c2), (1.0, 1.0));
//!
//! // One vertex at rest under gravity: the inertial target is x_n + h^2 g.
//! let x = [Vector3::zeros()];
//! let v = [Vector3::zeros()];
//! let mut targets = StepTargets::with_len(1);
//! let g = Vector3::new(0.0, -10.0, 0.0);
//! be.prepare(0.1, &x, &v, g, &mut targets);
//! assert!((targets.inertial_displacement[0].y + 0.1).abs() < 1e-15);
//! ```

mod backward_euler;
mod bdf2;
mod implicit_midpoint;
pub mod registry;

pub use backward_euler::BackwardEuler;
pub use bdf2::Bdf2;
pub use implicit_midpoint::ImplicitMidpoint;

use nalgebra::Vector3;

/// A position, velocity or acceleration of one vertex (SI units).
pub type Point = Vector3<f64>;

/// The scalars of one step's objective (docs/design/formulation.md, "The
/// step objective").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepCoefficients {
    /// Factor `c1` of the elastic energy.
    pub c1: f64,
    /// Factor `c2` of the step inside the energy, `E(x_n + c2 (x - x_n))`.
    pub c2: f64,
    /// `gamma` in 1/s: the damping force is evaluated at the velocity
    /// `gamma (x - x_hat)`.
    pub gamma: f64,
}

/// The per-vertex targets of one step, computed by [`Integrator::prepare`].
/// Buffers are sized once and reused, so preparing a step allocates nothing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepTargets {
    /// The inertial target `y` minus `x_n` (m).
    pub inertial_displacement: Vec<Point>,
    /// The damping anchor `x_hat` minus `x_n` (m): zero for one-step
    /// methods, whose damping velocity is `gamma (x - x_n)`.
    pub anchor_displacement: Vec<Point>,
}

impl StepTargets {
    /// Zeroed targets for `n` vertices.
    pub fn with_len(n: usize) -> Self {
        Self {
            inertial_displacement: vec![Point::zeros(); n],
            anchor_displacement: vec![Point::zeros(); n],
        }
    }

    /// The targets of a one-step method: `y - x_n = h v_n + displacement`
    /// (the external acceleration's share, `h^2 a` for backward Euler,
    /// `h^2 a / 2` for implicit midpoint) and `x_hat = x_n`.
    pub(crate) fn set_one_step(&mut self, h: f64, velocities: &[Point], displacement: Point) {
        for (y, v) in self.inertial_displacement.iter_mut().zip(velocities) {
            *y = v * h + displacement;
        }
        self.anchor_displacement
            .iter_mut()
            .for_each(|a| *a = Point::zeros());
    }
}

/// One integrator of the form above.
///
/// A step is `coefficients()`, then `prepare(...)`, then the solver's
/// minimisation, then `finish(...)`, which computes the new velocities and
/// updates the history, then `filter_velocities(...)`, which runs any
/// explicit velocity filter and keeps the history consistent with it.
pub trait Integrator: std::fmt::Debug + Send + Sync {
    /// Name as scenes spell it (`backward-euler`): the type's `NAME`, the
    /// name of its [`registry`] entry.
    fn name(&self) -> &'static str;

    /// Coefficients of the coming step of length `h` (s). They may change
    /// between steps (a multistep method's start-up), so the solver keys its
    /// cached factorisations on them.
    fn coefficients(&self, h: f64) -> StepCoefficients;

    /// Fills `targets` (displacements from `x_n`) for a step of length `h`
    /// (s) from positions `x_n`, velocities `v_n` and a uniform external
    /// acceleration (m/s^2).
    fn prepare(
        &self,
        h: f64,
        positions: &[Point],
        velocities: &[Point],
        acceleration: Point,
        targets: &mut StepTargets,
    );

    /// Writes the new velocities for the solved positions and records the
    /// step in the history.
    fn finish(
        &mut self,
        h: f64,
        previous_positions: &[Point],
        previous_velocities: &[Point],
        positions: &[Point],
        velocities: &mut [Point],
    );

    /// The coming step's end velocity `v_{n+1}` as a function of its
    /// positions: `(g, w)` with `v_{n+1} = g (x - x_hat - w v_n)`, `x_hat`
    /// the damping anchor of [`StepTargets`]. The default `(gamma, 0)` holds where
    /// the damping velocity is the end velocity (backward Euler, BDF-2);
    /// implicit midpoint's damping velocity is the step's mean velocity.
    /// Contact's restitution places a bouncing vertex where its end velocity
    /// is the bounce (docs/design/contact.md).
    fn end_velocity(&self, h: f64) -> (f64, f64) {
        (self.coefficients(h).gamma, 0.0)
    }

    /// The damping velocity `gamma (x - x_hat)` of the coming step as a
    /// combination of positions, divided by `gamma`: the coefficients of
    /// `x_{n+1}, x_n, x_{n-1}, ...` in `x - x_hat`. One-step methods (and a
    /// multistep method's start-up) have `x_hat = x_n`: `[1, -1]`. A damping
    /// model that must leave a rigid motion undamped applies it to that
    /// motion's trajectory (`pd_damping`'s rotation-preserving variant).
    fn damping_stencil(&self) -> &'static [f64] {
        &[1.0, -1.0]
    }

    /// Runs `filter`, an explicit change of the velocities written by
    /// [`Integrator::finish`] (a velocity filter such as explicit ether drag
    /// or PBD damping, then any velocity constraint), on `velocities`, and
    /// keeps the history consistent with what it did, for a step of length
    /// `h` (s).
    ///
    /// One-step methods keep no history, so the default only runs the
    /// filter. A multistep method whose next step reads previous positions
    /// and velocities must see the filtered motion there too, or the
    /// filter's effect is partly undone (BDF-2: `docs/design/integrators.md`).
    fn filter_velocities(
        &mut self,
        h: f64,
        velocities: &mut [Point],
        filter: &mut dyn FnMut(&mut [Point]),
    ) {
        let _ = h;
        filter(velocities);
    }

    /// Forgets the history (after the state is replaced from outside).
    fn reset(&mut self) {}

    /// The history the next step depends on, for a checkpoint: the previous
    /// states `(x, v)`, most recent first (empty for one-step methods and
    /// before a multistep method's first step).
    fn history(&self) -> History {
        History::default()
    }

    /// Restores a history saved by [`Integrator::history`] of an integrator
    /// of the same kind, so that the next step is bit for bit the one the
    /// saved integrator would have taken.
    ///
    /// # Errors
    /// [`HistoryError`] for a history this integrator cannot hold: more
    /// previous states than it keeps, a state whose length is not
    /// `vertices`, or one with a NaN or infinite coordinate.
    fn restore_history(&mut self, history: &History, vertices: usize) -> Result<(), HistoryError> {
        let _ = vertices;
        if history.states.is_empty() {
            self.reset();
            Ok(())
        } else {
            Err(HistoryError::TooManyStates {
                integrator: self.name(),
                kept: 0,
                given: history.states.len(),
            })
        }
    }
}

/// Why [`Integrator::restore_history`] refused a history.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum HistoryError {
    /// The history holds more previous states than the integrator keeps.
    #[error("{integrator} keeps {kept} previous state(s), but {given} were given")]
    TooManyStates {
        /// The integrator's name as scenes spell it.
        integrator: &'static str,
        /// How many previous states it keeps.
        kept: usize,
        /// How many the history holds.
        given: usize,
    },
    /// A previous state does not have one position and one velocity per
    /// vertex.
    #[error(
        "{integrator} previous state {state} has {positions} positions and {velocities} \
         velocities for {vertices} vertices"
    )]
    WrongLength {
        /// The integrator's name as scenes spell it.
        integrator: &'static str,
        /// Which previous state, 0 for the most recent.
        state: usize,
        /// Number of positions in it.
        positions: usize,
        /// Number of velocities in it.
        velocities: usize,
        /// Number of vertices of the simulation.
        vertices: usize,
    },
    /// A previous state holds a NaN or infinite coordinate.
    #[error("{integrator} previous state {state}: the {quantity} of vertex {vertex} is not finite")]
    NonFinite {
        /// The integrator's name as scenes spell it.
        integrator: &'static str,
        /// Which previous state, 0 for the most recent.
        state: usize,
        /// `"position"` or `"velocity"`.
        quantity: &'static str,
        /// The first vertex with a non-finite coordinate.
        vertex: usize,
    },
}

/// An integrator's history: previous states `(positions, velocities)`, most
/// recent first (SI units, global vertex numbering).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct History {
    /// `(x_{n-1}, v_{n-1}), (x_{n-2}, v_{n-2}), ...`.
    pub states: Vec<(Vec<Point>, Vec<Point>)>,
}
