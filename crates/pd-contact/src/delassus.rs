//! The contact forces of a step with an accuracy target: every
//! local-global iteration solves the collider contacts against the exact
//! response of the global step (docs/design/contact.md, "Friction with an
//! accuracy target").
//!
//! The global step is `A dx = b + U r`, `U` placing each contact force `r_i`
//! on its vertex's row. With `b` fixed, contact `i` moves by
//! `sum_j W_ij r_j`, `W = U^T A^-1 U` the Delassus operator of the
//! contacts: `W_ij = [A^-1]_(f_i f_j)` (the matrix acts on each coordinate
//! alike, so `W` is scalar). An iteration solves once without the collider
//! forces, `x_free = A^-1 b`, finds forces for which the contact
//! positions `x_free + W r` satisfy every contact's law (Signorini and
//! Coulomb), by projected Gauss-Seidel on `W`, and solves again with them.
//! Each local step of Gauss-Seidel is the exact solution of one contact
//! with the others held: the projected Uzawa step of `update_force` with
//! `rho = 1 / W_ii` (for an isotropic compliance, clamping the normal part
//! and scaling the tangential part onto the cone is the exact solution of
//! Coulomb's law, whose slip is tangential).
//!
//! The elastic projections of `b` are then the only thing an iteration
//! leaves behind, and the iteration converges as the elastic local-global
//! iteration does; with the mass step `rho = 1.5 m / h^2` of the
//! fixed-iteration mode the forces lag behind the slow elastic modes and can
//! cycle. Gauss-Seidel starts from the forces of the previous iteration and
//! stops after [`SWEEPS`] sweeps or once a sweep moves no contact by more
//! than [`SETTLED`] of the largest contact displacement; a fixed point of
//! the iteration is one where a sweep changes nothing, so it satisfies the
//! contact laws whatever the sweeps left within one iteration.

use pd_mesh::Point;

use crate::{ContactState, collider_force};

/// Most Gauss-Seidel sweeps over the contacts in one iteration. On the
/// armadillo drop (docs/design/contact.md) 4 sweeps took 4,038 iterations
/// and 53-60 s of CPU, 20 sweeps 3,586 iterations and 61 s: the sweeps a
/// step leaves undone, the next iterations do, at less cost.
pub(crate) const SWEEPS: usize = 4;

/// A sweep that moves no contact by more than this fraction of the largest
/// displacement of a contact vertex in the step ends the sweeps.
pub(crate) const SETTLED: f64 = 1e-10;

/// The memory the Delassus solve of one step may hold by default, bytes
/// ([`ContactState::set_delassus_memory`]): 1 GiB. The armadillo drop of
/// docs/design/contact.md holds at most 102 MB (868 contacts over 14,779
/// free vertices).
pub const DEFAULT_DELASSUS_MEMORY: usize = 1 << 30;

/// The Delassus operator of the current contacts and the scratch of the
/// solve; sized as contacts appear (not per iteration).
#[derive(Debug, Default)]
pub(crate) struct Delassus {
    /// Whether the step solves its contacts this way (set by the solver).
    pub on: bool,
    /// The memory budget in bytes; `None`: [`DEFAULT_DELASSUS_MEMORY`].
    budget: Option<usize>,
    /// Whether this step's contacts did not fit the budget.
    fell_back: bool,
    /// `(vertex, free index)` of every collider contact of the iteration.
    pub vertices: Vec<(usize, usize)>,
    /// The contacts `w` was built for.
    built: Vec<(usize, usize)>,
    /// `W`, row-major over `built`.
    w: Vec<f64>,
    /// The contact positions `x_free + W r`, one per contact.
    y: Vec<Point>,
}

impl ContactState {
    /// Whether every iteration solves the collider contacts against the
    /// Delassus operator ([`ContactState::solve_contacts`]) instead of one
    /// projected Uzawa step per contact. The solver sets it at the start of
    /// every step: on for a step with an accuracy target and a constant
    /// global matrix; off, the step is the fixed-iteration mode's, bit for
    /// bit. The operator is rebuilt in the step's first iteration (the matrix
    /// may have changed with the step's coefficients).
    pub fn set_delassus(&mut self, on: bool) {
        self.delassus.on = on;
        self.delassus.fell_back = false;
        self.delassus.built.clear();
    }

    /// Caps the memory the Delassus solve may hold in one step at `bytes`:
    /// the columns of `A^-1` it caches (8 bytes per free vertex for each
    /// contact vertex) and the operator itself (8 bytes per pair of
    /// contacts). A step whose contacts would need more falls back to one
    /// projected Uzawa step per contact and iteration
    /// ([`ContactState::delassus_fell_back`]).
    pub fn set_delassus_memory(&mut self, bytes: usize) {
        self.delassus.budget = Some(bytes);
    }

    /// The memory budget of the Delassus solve, bytes
    /// ([`ContactState::set_delassus_memory`]).
    pub fn delassus_memory(&self) -> usize {
        self.delassus.budget.unwrap_or(DEFAULT_DELASSUS_MEMORY)
    }

    /// Whether the collider contacts of the iteration (every slot of a free
    /// vertex) fit the memory budget: `n` contacts over `free` free
    /// vertices hold `8 n (free + n)` bytes.
    pub(crate) fn delassus_fits_slots(&self) -> bool {
        let free = self.free_count;
        let n = (self.slots.iter().zip(&self.free_index))
            .filter(|(slot, f)| slot.is_some() && **f != usize::MAX)
            .count();
        let bytes = n
            .checked_add(free)
            .and_then(|width| width.checked_mul(n))
            .and_then(|entries| entries.checked_mul(std::mem::size_of::<f64>()));
        bytes.is_some_and(|b| b <= self.delassus_memory())
    }

    /// Turns the Delassus solve off for the rest of the step (its contacts
    /// do not fit the budget) and releases its operator; the step reports
    /// it ([`ContactState::delassus_fell_back`]).
    pub(crate) fn fall_back_to_uzawa(&mut self) {
        let d = &mut self.delassus;
        d.on = false;
        d.fell_back = true;
        d.built.clear();
        d.vertices.clear();
        d.w = Vec::new();
        d.y = Vec::new();
    }

    /// Whether this step's contacts did not fit the Delassus solve's memory
    /// budget, so that it took one projected Uzawa step per contact and
    /// iteration; the caller may then drop the columns of `A^-1` it cached.
    pub fn delassus_fell_back(&self) -> bool {
        self.delassus.fell_back
    }

    /// Whether [`ContactState::set_delassus`] turned the Delassus solve on
    /// (and forces are not frozen).
    pub fn delassus(&self) -> bool {
        self.delassus.on && !self.frozen
    }

    /// Collects the collider contacts of this iteration (after
    /// [`ContactState::apply`]'s detection), whose rows
    /// [`ContactState::contact_rows`] lists; none unless
    /// [`ContactState::delassus`].
    pub fn collect_contact_rows(&mut self) {
        let d = &mut self.delassus;
        d.vertices.clear();
        if d.on && !self.frozen {
            for (v, slot) in self.slots.iter().enumerate() {
                let f = self.free_index[v];
                if slot.is_some() && f != usize::MAX {
                    d.vertices.push((v, f));
                }
            }
        }
    }

    /// The free indices of the contacts collected by
    /// [`ContactState::collect_contact_rows`], increasing: the rows
    /// [`ContactState::solve_contacts`] needs the free solution of.
    pub fn contact_rows(&self) -> impl Iterator<Item = usize> + '_ {
        self.delassus.vertices.iter().map(|&(_, f)| f)
    }

    /// Whether free index `f` is one of [`ContactState::contact_rows`].
    pub fn is_contact_row(&self, f: usize) -> bool {
        (self.delassus.vertices)
            .binary_search_by_key(&f, |&(_, g)| g)
            .is_ok()
    }

    /// The collider contacts' forces of this iteration, added to `rhs`:
    /// `free[i]` is the displacement of the `i`-th row of
    /// [`ContactState::contact_rows`] in the solve without collider forces,
    /// `entry(f, g)` gives `[A^-1]_fg` (free indices; `f` is always the row
    /// whose column the caller solves for, so that an entry does not depend
    /// on the order contacts appeared in). Returns whether it added any
    /// force (then the caller solves again).
    pub fn solve_contacts(
        &mut self,
        x_n: &[Point],
        free: &[Point],
        entry: &mut dyn FnMut(usize, usize) -> f64,
        rhs: &mut [Point],
    ) -> bool {
        let d = &mut self.delassus;
        let n = d.vertices.len();
        if n == 0 || !d.on || self.frozen {
            return false;
        }
        if d.vertices != d.built {
            d.w.clear();
            d.w.reserve(n * n);
            for &(_, f) in &d.vertices {
                d.w.extend(d.vertices.iter().map(|&(_, g)| entry(f, g)));
            }
            d.built.clone_from(&d.vertices);
        }
        d.y.clear();
        let mut largest = 0.0_f64;
        for (&(v, _), u) in d.vertices.iter().zip(free) {
            d.y.push(x_n[v] + u);
            largest = largest.max(u.norm());
        }
        for (i, &(v, _)) in d.vertices.iter().enumerate() {
            let r = self.slots[v].map_or_else(Point::zeros, |s| s.force);
            if r != Point::zeros() {
                let row = &d.w[i * n..(i + 1) * n];
                d.y.iter_mut().zip(row).for_each(|(y, w)| *y += r * *w);
            }
        }
        let settled = SETTLED * largest;
        for _ in 0..SWEEPS {
            let mut moved = 0.0_f64;
            for (i, &(v, _)) in d.vertices.iter().enumerate() {
                let Some(slot) = &mut self.slots[v] else {
                    continue;
                };
                let row = &d.w[i * n..(i + 1) * n];
                let collider = &self.settings.colliders[slot.collider];
                let force =
                    collider_force::update_force(slot, collider, &d.y[i], 1.0 / row[i], self.h);
                let change = force - slot.force;
                if change != Point::zeros() {
                    slot.force = force;
                    d.y.iter_mut().zip(row).for_each(|(y, w)| *y += change * *w);
                    moved = moved.max(change.norm() * row[i]);
                }
            }
            if moved <= settled {
                break;
            }
        }
        for &(v, f) in &d.vertices {
            if let Some(slot) = &self.slots[v] {
                rhs[f] += slot.force;
            }
        }
        true
    }
}
