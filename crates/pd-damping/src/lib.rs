//! Damping models for Projective Dynamics, one [`Damping`] implementation
//! each.
//!
//! A model can contribute in four ways, and the solver asks for each:
//! 1. a **constant implicit matrix** `D = a1 M + a2 L_d`
//!    ([`Damping::implicit_matrix`]), a mix of the lumped mass matrix and the
//!    damping Laplacian that enters the global step and is factored once per
//!    (integrator, h, coefficients);
//! 2. a **per-step implicit matrix**, here the lagged stiffness term
//!    `a3 K(x_n)` ([`DampingMatrix::lagged_stiffness`]), which forces a
//!    numeric refactorisation every step;
//! 3. an **explicit force** added to the right-hand side
//!    ([`Damping::add_explicit_force`]);
//! 4. a **velocity filter** after the solve ([`Damping::filter_velocities`]).
//!
//! How each enters each integrator's global step is derived in
//! `docs/damping.md`.
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
mod rayleigh_lagged;
pub mod registry;
pub mod rigid;

pub use error::DampingError;
pub use ether_drag::EtherDrag;
pub use laplacian::LaplacianDamping;
pub use none::NoDamping;
pub use pbd::PbdDamping;
pub use rayleigh_lagged::RayleighLagged;

use std::ops::Range;

use nalgebra::Vector3;

/// A position, velocity or force of one vertex (SI units).
pub type Point = Vector3<f64>;

/// Coefficients of an implicit damping matrix
/// `D = mass M + damping_laplacian L_d + lagged_stiffness K(x_n)`.
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
}

impl DampingMatrix {
    /// Whether the matrix is zero (no implicit damping).
    pub fn is_zero(&self) -> bool {
        self.mass == 0.0 && self.damping_laplacian == 0.0 && self.lagged_stiffness == 0.0
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

/// A damping model.
pub trait Damping: std::fmt::Debug + Send + Sync {
    /// Name as scenes spell it (`none`, `laplacian`, ...).
    fn name(&self) -> &'static str;

    /// The implicit damping matrix this model puts into the global step.
    fn implicit_matrix(&self) -> DampingMatrix {
        DampingMatrix::default()
    }

    /// Adds an explicit damping force (N), evaluated at the start of the step,
    /// to `forces`.
    fn add_explicit_force(
        &self,
        _context: &DampingContext<'_>,
        _positions: &[Point],
        _velocities: &[Point],
        _forces: &mut [Point],
    ) {
    }

    /// Whether the solver should restore, per body, the angular momentum that
    /// the implicit damping force removed (the rotation-preserving Laplacian
    /// variant, `docs/damping.md`).
    fn preserves_rotation(&self) -> bool {
        false
    }

    /// Whether [`Damping::add_explicit_force`] does anything, so the solver
    /// can skip it.
    fn has_explicit_force(&self) -> bool {
        false
    }

    /// Adjusts the velocities after the solve (explicit ether drag, PBD).
    fn filter_velocities(
        &self,
        _context: &DampingContext<'_>,
        _positions: &[Point],
        _velocities: &mut [Point],
    ) {
    }
}
