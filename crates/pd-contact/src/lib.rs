//! Contact for Projective Dynamics, keeping the prefactored global matrix
//! (docs/design/contact.md): static colliders (plane, sphere, box, and
//! triangle mesh with the `mesh-collider` feature, through parry3d-f64),
//! contact between bodies and self-contact, with Coulomb friction and
//! restitution. It knows nothing of the simulation that drives it: the
//! solver (pd-solver, behind its `contact` feature) holds a
//! [`ContactState`] and calls its hooks at fixed points of a step:
//! [`ContactState::begin_step`] once the step's targets are known,
//! [`ContactState::apply`] in every local-global iteration between the
//! right-hand side and the solve, [`ContactState::report`] and
//! [`ContactState::project`] on the iterations' result, and
//! [`ContactState::filter_velocities`] inside the integrator's velocity
//! filter; [`ContactState::save`] and [`ContactState::load`] carry the
//! warm-started forces through checkpoints.
//!
//! Each contact vertex carries a force `r` in the global step's right-hand
//! side (units of `A dx`, i.e. `c1 c2` times newtons). After every global
//! solve it is updated by one projected Uzawa step with the vertex's own
//! mass stiffness, over-relaxed, `rho = 1.5 m / h^2`, which converges
//! because the global matrix is at least `M / h^2`:
//!
//! `r <- Proj_cone(r + rho (x_target - x))`,
//!
//! where the target is the contact point on the surface thickened by the
//! contact thickness (plus a lift for restitution) and, tangentially, the
//! point where the vertex met the collider, moved with the collider's
//! velocity over the step; the cone is Coulomb's, `|r_t| <= mu r_n`,
//! `r_n >= 0`. Forces of contacts that stay active are warm-started from the
//! previous step. Detection is continuous: the segment from `x_n` to the
//! current iterate is tested against every collider. After the iterations,
//! what they left behind a contact plane is projected onto it, and the
//! normal velocity of every contact is clamped to `[0, bounce]`. Contact
//! between bodies and self-contact are vertex-triangle pairs in the same
//! framework (`bodies.rs`).
//!
//! With an accuracy target the solver turns on the Delassus solve
//! ([`ContactState::set_delassus`], `delassus.rs`): each iteration solves
//! without the collider forces, finds them by projected Gauss-Seidel on the
//! contacts' Delassus operator (columns of the global matrix's inverse the
//! solver provides), and solves again; the one Uzawa step can cycle with
//! the elastic iteration under a large frictional load.

mod bodies;
mod candidates;
mod checkpoint;
mod clearance;
mod collider_force;
mod delassus;
mod end_plane;
mod error;
mod geometry;
mod grid;
mod mesh;
mod neighbourhood;
mod settings;
mod surface;

pub use bodies::BodySurface;
pub use checkpoint::{ContactCheckpoint, SavedContact};
pub use delassus::DEFAULT_DELASSUS_MEMORY;
pub use error::ContactError;
pub use geometry::ColliderShape;
pub use mesh::TriangleSurface;
pub use settings::{BodyContactSettings, Collider, ContactSettings, unit_vector};
pub use surface::SurfacePairs;

use pd_mesh::Point;

use geometry::Hit;

/// Over-relaxation of the Uzawa step `rho = RELAXATION m / h^2`. With
/// `A >= M / h^2` the eigenvalues of `(m / h^2) W` (`W` the contact block of
/// `A^-1`) lie in `(0, 1]`, so any value in `(0, 2)` converges; 1.5 was the
/// best of 0.5, 1, 1.5 and 1.9 on the contact tests (docs/design/contact.md).
const RELAXATION: f64 = 1.5;

/// One vertex's contact during a step.
#[derive(Debug, Clone, Copy)]
struct Slot {
    collider: usize,
    hit: Hit,
    /// The force in the right-hand side (`A dx` units).
    force: Point,
    /// Extra normal distance the vertex must reach (restitution), m.
    lift: f64,
    /// Largest normal speed it may leave with, m/s (restitution).
    bounce: f64,
    /// Met its collider this step faster than the resting speed: an impact,
    /// whatever the restitution.
    impact: bool,
    /// Moved onto its contact plane after the iterations.
    projected: bool,
    /// Carried over from the previous step (its force is kept as is in the
    /// first iteration, whose iterate is the inertial target, not a solve).
    warm: bool,
}

impl Slot {
    pub(crate) fn active(&self) -> bool {
        self.force.dot(&self.hit.normal) > 0.0
    }

    /// Whether the velocity filter acts on it: active or projected.
    fn filtered(&self) -> bool {
        self.active() || self.projected
    }
}

/// The contact state of a simulation: settings, per-vertex contacts, and
/// the step's copies of what detection needs. The solver calls its hooks
/// (the crate's documentation says where in a step).
#[derive(Debug)]
pub struct ContactState {
    settings: ContactSettings,
    slots: Vec<Option<Slot>>,
    /// Free-vertex index of each vertex (`usize::MAX` for fixed ones).
    free_index: Vec<usize>,
    /// How many vertices are free (the global step's unknowns).
    free_count: usize,
    velocities: Vec<Point>,
    anchor: Vec<Point>,
    h: f64,
    /// The end velocity is `gamma (x - x_n - anchor - velocity_weight v_n)`
    /// ([`ContactState::begin_step`]).
    gamma: f64,
    velocity_weight: f64,
    /// Below this approach speed a hit does not bounce (2 |g| h), m/s.
    rest_speed: f64,
    iteration: usize,
    /// Contact between bodies, when asked for (`bodies.rs`).
    bodies: Option<bodies::BodyContact>,
    /// With bodies: the free vertices holding a collider contact after this
    /// iteration's detection (`detect_bodies`), in increasing order.
    occupied: Vec<usize>,
    /// Forces frozen ([`ContactState::freeze_forces`]): the contacts'
    /// forces are added as they are, and nothing else runs.
    frozen: bool,
    /// The step's collider clearances (`clearance.rs`).
    clearance: clearance::Clearance,
    /// The Delassus solve of the collider contacts, with an accuracy
    /// target (`delassus.rs`).
    delassus: delassus::Delassus,
}

/// What the contacts of a finished step measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactReport {
    /// The active contacts (with colliders and between surfaces).
    pub contacts: usize,
    /// The deepest penetration of a free vertex into a thickened collider
    /// or pair, m (0 if none).
    pub penetration: f64,
}

impl ContactState {
    /// Contact with `settings` (validated: [`ContactSettings::validated`])
    /// for `vertices` vertices, of which `free` lists the free ones in the
    /// order of the global step's unknowns (the rows of the right-hand side
    /// [`ContactState::apply`] adds to); no contact between surfaces until
    /// [`ContactState::set_surfaces`].
    pub fn new(settings: ContactSettings, vertices: usize, free: &[usize]) -> Self {
        let mut free_index = vec![usize::MAX; vertices];
        for (f, &v) in free.iter().enumerate() {
            free_index[v] = f;
        }
        Self {
            settings,
            slots: vec![None; vertices],
            free_index,
            free_count: free.len(),
            velocities: vec![Point::zeros(); vertices],
            anchor: vec![Point::zeros(); vertices],
            h: 0.0,
            gamma: 0.0,
            velocity_weight: 0.0,
            rest_speed: 0.0,
            iteration: 0,
            bodies: None,
            occupied: Vec::new(),
            frozen: false,
            clearance: clearance::Clearance::default(),
            delassus: delassus::Delassus::default(),
        }
    }

    /// The settings.
    pub fn settings(&self) -> &ContactSettings {
        &self.settings
    }

    /// Start of a step: keeps the contacts that ended the last step active
    /// (re-anchored at `x_n`, forces warm-started), drops the others, and
    /// copies the velocities and `x_hat - x_n` that restitution needs.
    /// `(gamma, w)` give the step's end velocity,
    /// `v_{n+1} = gamma (x - x_hat - w v_n)`
    /// (`pd_integrators::Integrator::end_velocity`): a bouncing vertex is
    /// placed where its end velocity is the bounce.
    pub fn begin_step(
        &mut self,
        x_n: &[Point],
        v_n: &[Point],
        anchor_displacement: &[Point],
        (h, (gamma, w), gravity): (f64, (f64, f64), Point),
    ) {
        if self.frozen {
            return;
        }
        self.h = h;
        self.gamma = gamma;
        self.velocity_weight = w;
        self.rest_speed = 2.0 * gravity.norm() * h;
        self.iteration = 0;
        self.velocities.copy_from_slice(v_n);
        self.anchor.copy_from_slice(anchor_displacement);
        let thickness = self.settings.thickness;
        for (slot, x) in self.slots.iter_mut().zip(x_n) {
            *slot = slot.filter(Slot::active).map(|s| {
                let (gap, normal) = self.settings.colliders[s.collider].shape.gap(x, thickness);
                Slot {
                    hit: Hit {
                        t: 0.0,
                        point: x - normal * gap,
                        normal,
                    },
                    lift: 0.0,
                    bounce: 0.0,
                    // An impact goes on for one more step: the vertices
                    // above the stopped ones stop in it (a stiff body
                    // within about a step), and a multistep history that
                    // still held the approach would throw the body back
                    // up (BDF-2: 23 mm from 0.2 m, against 0.05 mm).
                    impact: s.impact && !s.warm,
                    projected: false,
                    warm: true,
                    ..s
                }
            });
        }
        if let Some(bodies) = &mut self.bodies {
            bodies.begin_step(x_n);
        }
    }

    /// After the right-hand side of an iteration is built, before its
    /// solve: detects new contacts on the segments `x_n -> x_n + dx`,
    /// updates every contact force and adds it to `rhs` (one point per free
    /// vertex).
    // Not inlined: inlined into the iteration, it slowed the contact-free
    // step (measured: 0.674 -> 0.746 ms per step without any contact).
    #[inline(never)]
    pub fn apply(&mut self, x_n: &[Point], masses: &[f64], dx: &[Point], rhs: &mut [Point]) {
        if self.frozen {
            self.add_frozen_forces(rhs);
            return;
        }
        let first = self.iteration == 0;
        let motion = clearance::largest_motion(dx);
        if first {
            let (settings, slots) = (&self.settings, &self.slots);
            (self.clearance).take(settings, (x_n, motion), &self.free_index, slots);
        }
        self.iteration += 1;
        let h = self.h;
        let with_bodies = self.bodies.is_some();
        let threshold = self.clearance.threshold(motion);
        if with_bodies {
            self.detect_bodies(x_n, dx, (motion, threshold));
        }
        // With bodies, detection ran before (`detect_bodies`) and only the
        // vertices it left with a contact are visited (each adds to its own
        // entry of `rhs`: the order does not change a bit).
        // Without bodies, the vertices near a collider (`Clearance::visits`).
        let (near, count) = if with_bodies {
            (false, self.occupied.len())
        } else {
            self.clearance.visits(threshold, x_n.len())
        };
        for k in 0..count {
            let v = if with_bodies {
                self.occupied[k]
            } else {
                self.clearance.vertex(k, near)
            };
            if !with_bodies && self.clearance.skips(v, threshold) {
                continue;
            }
            let f = self.free_index[v];
            if f == usize::MAX {
                continue;
            }
            let x = x_n[v] + dx[v];
            if self.slots[v].is_none() {
                if self.misses_all(&x_n[v], &x) {
                    continue;
                }
                let Some(slot) = self.detect(v, &x_n[v], &x) else {
                    continue;
                };
                self.slots[v] = Some(slot);
                self.clearance.hold(v);
            }
            // With the Delassus solve, the forces are found after the
            // solve without them ([`ContactState::solve_contacts`]).
            if self.delassus.on {
                continue;
            }
            self.uzawa_step(v, x, masses[v], first, &mut rhs[f]);
        }
        // Contacts beyond the Delassus solve's memory budget: this
        // iteration and the rest of the step take the Uzawa step.
        if self.delassus.on && !self.delassus_fits_slots() {
            self.fall_back_to_uzawa();
            for v in 0..self.slots.len() {
                let f = self.free_index[v];
                if self.slots[v].is_some() && f != usize::MAX {
                    self.uzawa_step(v, x_n[v] + dx[v], masses[v], first, &mut rhs[f]);
                }
            }
        }
        if let Some(bodies) = &mut self.bodies {
            let settings = (h, RELAXATION, self.settings.thickness);
            bodies.apply(x_n, dx, settings, first, &self.free_index, rhs);
        }
    }

    /// One projected Uzawa step of vertex `v`'s collider contact at its
    /// iterate `x` (mass `mass`), whose force is then added to `rhs` (its
    /// row). The first iterate is the inertial target, reached without the
    /// warm-started force: that force is applied as is once, and updated
    /// from the first solve on.
    #[inline]
    fn uzawa_step(&mut self, v: usize, x: Point, mass: f64, first: bool, rhs: &mut Point) {
        let h = self.h;
        let mut rho = RELAXATION * mass / (h * h);
        if let Some(bodies) = &self.bodies {
            rho /= f64::from(bodies.count[v].max(1));
        }
        // Updated in place (no copy of the slot in and out).
        let Some(slot) = &mut self.slots[v] else {
            return;
        };
        if !(first && slot.warm) {
            let collider = &self.settings.colliders[slot.collider];
            slot.force = collider_force::update_force(slot, collider, &x, rho, h);
        }
        *rhs += slot.force;
    }

    /// Whether the segment `a -> b` surely hits no collider
    /// ([`ColliderShape::misses`]): a cheap test run before
    /// [`ContactState::detect`] (most vertices are far from every
    /// collider), with the same verdict where it answers.
    #[inline]
    fn misses_all(&self, a: &Point, b: &Point) -> bool {
        let thickness = self.settings.thickness;
        (self.settings.colliders.iter()).all(|c| c.shape.misses(a, b, thickness))
    }

    /// The earliest hit of the segment `a -> b` among the colliders, as a
    /// new contact of vertex `v`.
    fn detect(&self, v: usize, a: &Point, b: &Point) -> Option<Slot> {
        let thickness = self.settings.thickness;
        let (collider, hit) = self
            .settings
            .colliders
            .iter()
            .enumerate()
            .filter_map(|(c, collider)| collider.shape.first_hit(a, b, thickness).map(|h| (c, h)))
            .min_by(|p, q| p.1.t.total_cmp(&q.1.t))?;
        let col = &self.settings.colliders[collider];
        let n = hit.normal;
        let speed = -(self.velocities[v] - col.velocity(&hit.point)).dot(&n);
        let impact = speed > self.rest_speed;
        let (lift, bounce) = if col.restitution > 0.0 && impact {
            let bounce = col.restitution * speed;
            let x_hat = a + self.anchor[v] + self.velocities[v] * self.velocity_weight;
            (
                (n.dot(&(x_hat - hit.point)) + bounce / self.gamma).max(0.0),
                bounce,
            )
        } else {
            (0.0, 0.0)
        };
        Some(Slot {
            collider,
            hit,
            force: Point::zeros(),
            lift,
            bounce,
            impact,
            projected: false,
            warm: false,
        })
    }

    /// After the iterations: moves every contact vertex that the
    /// iterations left behind its contact plane back onto it, along the
    /// normal (the velocity filter then removes the normal speed this
    /// creates). Returns the deepest such correction, m.
    pub fn project(&mut self, positions: &mut [Point]) -> f64 {
        if self.frozen {
            return 0.0;
        }
        let mut deepest = 0.0_f64;
        for (slot, x) in self.slots.iter_mut().zip(positions.iter_mut()) {
            let Some(slot) = slot else { continue };
            let depth = slot.lift - slot.hit.normal.dot(&(*x - slot.hit.point));
            slot.projected = depth > 0.0;
            if slot.projected {
                let collider = &self.settings.colliders[slot.collider];
                collider_force::project_onto_plane(slot, collider, x, depth, self.h);
                deepest = deepest.max(depth);
            }
        }
        if self.bodies.is_some() {
            deepest = deepest.max(self.project_after_bodies(positions));
        }
        deepest
    }

    /// With contact between bodies: the pairs' corrections, then the
    /// colliders once more, since a pair's correction can push a vertex
    /// (one resting on the floor, under a crushed body) behind a collider:
    /// colliders are static, so they win. A vertex found behind a collider
    /// without a contact gets one, marked projected, so that the velocity
    /// filter clamps it.
    fn project_after_bodies(&mut self, positions: &mut [Point]) -> f64 {
        let thickness = self.settings.thickness;
        let mut deepest = match &mut self.bodies {
            Some(bodies) => bodies.project(positions, thickness),
            None => 0.0,
        };
        for (v, x) in positions.iter_mut().enumerate() {
            if self.free_index[v] == usize::MAX {
                continue;
            }
            if let Some(slot) = &mut self.slots[v] {
                let depth = slot.lift - slot.hit.normal.dot(&(*x - slot.hit.point));
                if depth > 0.0 {
                    let collider = &self.settings.colliders[slot.collider];
                    collider_force::project_onto_plane(slot, collider, x, depth, self.h);
                    slot.projected = true;
                    deepest = deepest.max(depth);
                }
                continue;
            }
            for (c, collider) in self.settings.colliders.iter().enumerate() {
                let (gap, normal) = collider.shape.gap(x, thickness);
                if gap < 0.0 {
                    *x -= normal * gap;
                    deepest = deepest.max(-gap);
                    self.slots[v] = Some(Slot {
                        collider: c,
                        hit: Hit {
                            t: 0.0,
                            point: *x,
                            normal,
                        },
                        force: Point::zeros(),
                        lift: 0.0,
                        bounce: 0.0,
                        impact: false,
                        projected: true,
                        warm: false,
                    });
                }
            }
        }
        deepest
    }

    /// End of step, inside the integrator's velocity filter: the normal
    /// velocity of every active contact relative to its collider is clamped
    /// to `[0, bounce]`, and so is that of every vertex moved by
    /// [`ContactState::project`] (never adds kinetic energy: it only shrinks the
    /// normal component).
    pub fn filter_velocities(&self, velocities: &mut [Point]) {
        if self.frozen {
            return;
        }
        for (slot, v) in self.slots.iter().zip(velocities.iter_mut()) {
            let Some(slot) = slot.filter(Slot::filtered) else {
                continue;
            };
            let n = slot.hit.normal;
            let collider = &self.settings.colliders[slot.collider];
            let relative = (*v - collider.velocity(&slot.hit.point)).dot(&n);
            let clamped = relative.clamp(0.0, slot.bounce);
            if clamped != relative {
                *v += n * (clamped - relative);
            }
        }
        if let Some(bodies) = &self.bodies {
            bodies.filter_velocities(velocities);
        }
    }

    /// Whether a contact of this step bounced (met its collider faster than
    /// the resting speed, with restitution): its vertex's end velocity was
    /// set by the bounce, not by the integrator's history, which a
    /// multistep method should then forget.
    pub fn bounced(&self) -> bool {
        !self.frozen && self.slots.iter().flatten().any(|s| s.bounce > 0.0)
    }

    /// Whether a contact of this step or the previous one stopped a vertex:
    /// it met its collider faster than the resting speed (`2 |g| h`),
    /// without restitution, and ended the step in contact. A multistep method's end velocity then
    /// extrapolates the approach through the stop (BDF-2's
    /// `(3 x_{n+1} - 4 x_n + x_{n-1}) / 2h` is up to half the approach
    /// speed, away from the collider, for a body that stopped within the
    /// step), so it should take the step's velocity as a one-step method
    /// does and forget its history. A resting contact is not an impact.
    pub fn stopped(&self) -> bool {
        !self.frozen
            && (self.slots.iter().flatten()).any(|s| s.impact && s.bounce == 0.0 && s.filtered())
    }

    /// The active contacts and the deepest penetration of a free vertex of
    /// `positions` into a thickened collider, m (0 if none).
    pub fn report(&self, positions: &[Point]) -> ContactReport {
        if self.frozen {
            return ContactReport::default();
        }
        let thickness = self.settings.thickness;
        let mut penetration = 0.0_f64;
        for (x, &f) in positions.iter().zip(&self.free_index) {
            if f == usize::MAX {
                continue;
            }
            for collider in &self.settings.colliders {
                penetration = penetration.max(-collider.shape.gap(x, thickness).0);
            }
        }
        let mut contacts = self.slots.iter().flatten().filter(|s| s.active()).count();
        if let Some(bodies) = &self.bodies {
            let (active, deepest) = bodies.report(positions, thickness);
            contacts += active;
            penetration = penetration.max(deepest);
        }
        ContactReport {
            contacts,
            penetration,
        }
    }
}
