//! Per-body damping: one model per body (`[[body]] damping = { ... }`),
//! each acting on its own body's vertices only.
//!
//! The implicit channels stay one constant global matrix: body `b`'s
//! `D_b = a1_b M_b + a2_b L_d,b` is a block of the block-diagonal
//! `D = sum_b D_b` (bodies share no damping Laplacian entry), so the solver
//! scales the mass and Laplacian terms per body
//! ([`Damping::body_coefficients`]) and factors the result once. The lagged
//! channel (`a3 K(x_n)`) is not offered per body: [`PerBodyDamping::new`]
//! refuses it. Which bodies keep their rigid rotations out of the `L_d`
//! term is asked body by body ([`Damping::preserves_rotation_of_body`]).
//! The explicit channels (ether drag, PBD) run each body's model on
//! a view of that body alone: its slices of the positions, velocities,
//! masses and targets, its components and rigid bodies renumbered from 0.

use std::ops::Range;

use crate::rigid::RigidBody;
use crate::{
    Damping, DampingContext, DampingError, DampingMatrix, DampingReport, DampingTargets, Point,
    StepContext,
};

/// The name the per-body composite reports (scenes never write it: they
/// give each body its own `damping` table).
pub const NAME: &str = "per-body";

/// One model per body, in scene order, each acting on its own body only.
///
/// [`Damping::implicit_matrix`] is the largest coefficient of each term over
/// the bodies (the scale the solver's weights are relative to), and
/// [`Damping::body_coefficients`] gives every body's own.
///
/// ```
/// use pd_damping::{Damping, LaplacianDamping, NoDamping, PerBodyDamping};
/// let damping = PerBodyDamping::new(vec![
///     Box::new(NoDamping),
///     Box::new(LaplacianDamping::new(0.01, 0.0, false)?),
/// ])?;
/// assert_eq!(damping.implicit_matrix().damping_laplacian, 0.01);
/// let per_body = damping.body_coefficients().unwrap();
/// assert_eq!(per_body[0].damping_laplacian, 0.0);
/// assert_eq!(per_body[1].damping_laplacian, 0.01);
/// # Ok::<(), pd_damping::DampingError>(())
/// ```
#[derive(Debug)]
pub struct PerBodyDamping {
    models: Vec<Box<dyn Damping>>,
    coefficients: Vec<DampingMatrix>,
    reference: DampingMatrix,
    explicit: bool,
    /// Each body's components and rigid bodies renumbered from the body's
    /// first vertex, built at the first step (the topology is fixed).
    views: Vec<BodyView>,
}

/// What one body's model sees of the topology, renumbered.
#[derive(Debug, Default)]
struct BodyView {
    components: Vec<Vec<usize>>,
    rigid_bodies: Vec<RigidBody>,
}

impl PerBodyDamping {
    /// The composite of `models`, one per body in scene order.
    ///
    /// # Errors
    /// [`DampingError::Conflict`] naming `model` when a body's model has a
    /// lagged stiffness term (`rayleigh-lagged`): its matrix changes every
    /// step and is not scaled per body; use it in `[damping]` for every body.
    /// [`DampingError::Conflict`] naming `ratios` when a body's model has
    /// Caughey series terms (`a3`, ...), which are not scaled per body.
    pub fn new(models: Vec<Box<dyn Damping>>) -> Result<Self, DampingError> {
        let coefficients: Vec<DampingMatrix> = models.iter().map(|m| m.implicit_matrix()).collect();
        if let Some(b) = coefficients.iter().position(DampingMatrix::is_lagged) {
            return Err(DampingError::Conflict {
                parameter: "model",
                reason: format!(
                    "body {b}'s model \"{}\" refactorises a lagged stiffness matrix every step, \
                     which is not available per body; give it in [damping] for all bodies",
                    models[b].name()
                ),
            });
        }
        if let Some(b) = coefficients.iter().position(DampingMatrix::has_series) {
            return Err(DampingError::Conflict {
                parameter: "ratios",
                reason: format!(
                    "body {b}'s Caughey series (three or more ratios, or band) is not available \
                     per body next to other damping; give it in [damping] for all bodies"
                ),
            });
        }
        let reference = coefficients
            .iter()
            .fold(DampingMatrix::default(), |r, c| DampingMatrix {
                mass: r.mass.max(c.mass),
                damping_laplacian: r.damping_laplacian.max(c.damping_laplacian),
                lagged_stiffness: 0.0,
                series: [0.0; crate::HIGHER_SERIES_TERMS],
            });
        let explicit = models.iter().any(|m| m.has_explicit_force());
        Ok(Self {
            models,
            coefficients,
            reference,
            explicit,
            views: Vec::new(),
        })
    }

    /// The bodies' models, in scene order.
    pub fn models(&self) -> &[Box<dyn Damping>] {
        &self.models
    }

    /// Renumbers the topology per body, once.
    fn ensure_views(&mut self, step: &StepContext<'_>) {
        if self.views.len() == self.models.len() {
            return;
        }
        let bodies = step.base.bodies;
        self.views = (0..self.models.len())
            .map(|b| {
                let Some(range) = bodies.get(b) else {
                    return BodyView::default();
                };
                let inside =
                    |vertices: &[usize]| vertices.first().is_some_and(|v| range.contains(v));
                let shift = |vertices: &[usize]| vertices.iter().map(|v| v - range.start).collect();
                BodyView {
                    components: step
                        .base
                        .components
                        .iter()
                        .filter(|c| inside(c))
                        .map(|c| shift(c))
                        .collect(),
                    rigid_bodies: step
                        .rigid_bodies
                        .iter()
                        .filter(|r| inside(&r.vertices))
                        .map(|r| RigidBody {
                            vertices: shift(&r.vertices),
                            freedom: r.freedom,
                        })
                        .collect(),
                }
            })
            .collect();
    }
}

/// Body `range`'s view of `step`, with `view`'s renumbered topology.
fn body_step<'a>(
    step: &StepContext<'a>,
    range: &Range<usize>,
    view: &'a BodyView,
    whole: &'a [Range<usize>],
) -> StepContext<'a> {
    let base = DampingContext {
        h: step.base.h,
        masses: &step.base.masses[range.clone()],
        bodies: whole,
        components: &view.components,
        fixed: &step.base.fixed[range.clone()],
    };
    StepContext::new(
        base,
        &view.rigid_bodies,
        (step.gamma, step.force_scale, step.c2),
        step.damping_stencil,
    )
}

impl Damping for PerBodyDamping {
    fn name(&self) -> &'static str {
        NAME
    }

    fn implicit_matrix(&self) -> DampingMatrix {
        self.reference
    }

    fn body_coefficients(&self) -> Option<&[DampingMatrix]> {
        Some(&self.coefficients)
    }

    fn preserves_rotation(&self) -> bool {
        self.models.iter().any(|m| m.preserves_rotation())
    }

    fn preserves_rotation_of_body(&self, body: usize) -> bool {
        self.models
            .get(body)
            .is_some_and(|m| m.preserves_rotation())
    }

    fn has_explicit_force(&self) -> bool {
        self.explicit
    }

    fn begin_step(
        &mut self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &[Point],
        targets: DampingTargets<'_>,
    ) {
        self.ensure_views(step);
        for (b, model) in self.models.iter_mut().enumerate() {
            let Some(range) = step.base.bodies.get(b) else {
                continue;
            };
            let r = range.clone();
            // The body is the whole world its model sees.
            let whole = 0..r.len();
            let sub = body_step(step, &r, &self.views[b], std::slice::from_ref(&whole));
            let sub_targets = DampingTargets::new(
                &mut targets.inertial_displacement[r.clone()],
                &mut targets.anchor_displacement[r.clone()],
                &mut targets.laplacian_anchor[r.clone()],
                &mut targets.scratch[r.clone()],
            );
            model.begin_step(&sub, &positions[r.clone()], &velocities[r], sub_targets);
        }
    }

    fn end_step(
        &mut self,
        step: &StepContext<'_>,
        positions: &[Point],
        velocities: &mut [Point],
    ) -> DampingReport {
        self.ensure_views(step);
        for (b, model) in self.models.iter_mut().enumerate() {
            let Some(range) = step.base.bodies.get(b) else {
                continue;
            };
            let r = range.clone();
            // The body is the whole world its model sees.
            let whole = 0..r.len();
            let sub = body_step(step, &r, &self.views[b], std::slice::from_ref(&whole));
            model.end_step(&sub, &positions[r.clone()], &mut velocities[r]);
        }
        DampingReport::default()
    }
}
