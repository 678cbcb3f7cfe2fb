//! Contiguous storage of one constraint kind and the object-safe interface
//! the solver iterates over.

use std::ops::Range;
use std::sync::Arc;

use pd_mesh::Point;

use crate::{Constraint, MAX_STENCIL, Stencil, Triplet, constraint::apply_operator};

/// Largest `ROWS` of any constraint kind: the local step keeps `G q` and the
/// projection of one constraint on the stack.
pub const MAX_ROWS: usize = 4;

/// Largest `STENCIL` whose operator [`ConstraintBlock::hessian_range`]
/// copies to the stack (plate bending has 6).
const MAX_HESSIAN_STENCIL: usize = 8;

/// Constraints projected together when an energy is evaluated
/// ([`ConstraintBlock::energy_range`]): a multiple of the tet strain's
/// four SIMD lanes, small enough for the stack (16 x 4 points).
const ENERGY_BATCH: usize = 16;

/// Merges the energies of constraints `first, first + 1, ...` into `bound`
/// one by one, in order (the same bits as merging them singly); returns
/// the index after the last.
fn merge_in_order(bound: &mut EnergyBound, first: usize, energies: &[f64]) -> usize {
    for (index, &energy) in (first..).zip(energies) {
        bound.merge(&EnergyBound {
            total: energy,
            worst: index,
            worst_energy: energy,
        });
    }
    first + energies.len()
}

/// Many constraints of one kind `C`, stored contiguously so that the loops
/// over them are monomorphic. The storage is shared: a clone (a model's
/// blocks handed to a simulation) costs a reference count, not a copy of
/// every constraint (13 MB for 100k tets).
#[derive(Debug, Clone)]
pub struct ConstraintSet<C: Constraint> {
    constraints: Arc<Vec<C>>,
}

impl<C: Constraint> ConstraintSet<C> {
    /// The entries of `sum_i w_i G_i^T G_i`, constraint by constraint, in
    /// stencil order; with `lower_only` only those with `row >= column`
    /// (the same values, in the same order, as filtering the full list).
    fn laplacian_entries(&self, lower_only: bool, out: &mut Vec<Triplet>) {
        for c in self.constraints.iter() {
            let w = c.weight();
            for (a, &va) in c.vertices().iter().enumerate() {
                for (b, &vb) in c.vertices().iter().enumerate() {
                    if lower_only && va < vb {
                        continue;
                    }
                    let value: f64 = (0..C::ROWS)
                        .map(|r| c.operator(r, a) * c.operator(r, b))
                        .sum();
                    out.push(Triplet::new(va, vb, w * value));
                }
            }
        }
    }

    /// Wraps a vector of constraints of one kind.
    pub fn new(constraints: Vec<C>) -> Self {
        Self::shared(Arc::new(constraints))
    }

    /// Wraps constraints of one kind held elsewhere too.
    pub fn shared(constraints: Arc<Vec<C>>) -> Self {
        const { assert!(C::ROWS <= MAX_ROWS && C::STENCIL <= MAX_STENCIL) };
        Self { constraints }
    }

    /// The constraints.
    pub fn constraints(&self) -> &[C] {
        &self.constraints
    }
}

/// An upper bound of the energy of some constraints and the constraint
/// with the largest term ([`ConstraintBlock::energy_bound_range`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EnergyBound {
    /// `sum w_i/2 |G_i q - p_i|^2` in J.
    pub total: f64,
    /// Index (within its block) of the constraint with the largest term.
    pub worst: usize,
    /// That constraint's term in J.
    pub worst_energy: f64,
}

impl EnergyBound {
    /// Adds `other`'s total and keeps the larger worst term (the earlier one
    /// on a tie, so that the result does not depend on how work was split).
    pub fn merge(&mut self, other: &EnergyBound) {
        self.total += other.total;
        // `!(a <= b)` also takes a NaN term: it is the one to report.
        if !(other.worst_energy <= self.worst_energy) {
            self.worst = other.worst;
            self.worst_energy = other.worst_energy;
        }
    }
}

/// What the solver needs of a set of constraints, independent of their kind.
/// One virtual call covers a whole range of constraints, so dynamic dispatch
/// never sits in the inner loop.
pub trait ConstraintBlock: std::fmt::Debug + Send + Sync {
    /// The kind's name, as scenes spell it.
    fn kind(&self) -> &'static str;
    /// Number of constraints.
    fn len(&self) -> usize;
    /// Whether the block holds no constraint.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Projection rows per constraint (`ROWS`).
    fn rows_per_constraint(&self) -> usize;
    /// Whether every constraint has `G 1 = 0` (no net force).
    fn translation_invariant(&self) -> bool;
    /// Whether the block is an *energy element* (a hyperelastic material,
    /// [`crate::MaterialSet`]) rather than a PD constraint: its projection is
    /// the identity, so a local-global iteration sees none of its force, and
    /// its energy, gradient and Hessian are the material's. Only solvers that
    /// add [`ConstraintBlock::add_gradient`] to the local-global gradient
    /// (L-BFGS, Newton) can run it.
    fn is_energy_element(&self) -> bool {
        false
    }
    /// Largest vertex index used, if any.
    fn max_vertex(&self) -> Option<usize>;
    /// Appends the entries of `sum_i w_i G_i^T G_i` (n x n, duplicates to be
    /// summed).
    fn add_laplacian(&self, out: &mut Vec<Triplet>);
    /// Appends the entries of `sum_i w_i G_i^T S_i`, the operator that maps
    /// the stacked projections to the right-hand side: entry (vertex, row),
    /// with this block's projection rows starting at `first_row`.
    fn add_projection_operator(&self, first_row: usize, out: &mut Vec<Triplet>);
    /// Appends the entries of [`ConstraintBlock::add_laplacian`] on or below
    /// the diagonal (`row >= column`), in the same order: what
    /// `add_laplacian` followed by a `retain` of those keeps, without the
    /// entries above the diagonal ever being stored (the assembly's peak
    /// memory is its triplet list). The default goes through
    /// `add_laplacian`.
    fn add_lower_laplacian(&self, out: &mut Vec<Triplet>) {
        let start = out.len();
        self.add_laplacian(out);
        let mut kept = start;
        for i in start..out.len() {
            if out[i].row >= out[i].column {
                out[kept] = out[i];
                kept += 1;
            }
        }
        out.truncate(kept);
    }
    /// Calls `entry(vertex, row, value)` for each entry that
    /// [`ConstraintBlock::add_projection_operator`] appends, in the same
    /// order, without a list of them (the projection operator is then built
    /// in place: `CsrMatrix::from_entry_stream`). The default goes through
    /// `add_projection_operator`.
    fn for_each_projection_entry(
        &self,
        first_row: usize,
        entry: &mut dyn FnMut(usize, usize, f64),
    ) {
        let mut triplets = Vec::new();
        self.add_projection_operator(first_row, &mut triplets);
        for t in triplets {
            entry(t.row, t.column, t.value);
        }
    }
    /// Local step for constraints `first..first + out.len() / ROWS`: projects
    /// each at the positions `q`, writing its rows into `out`.
    fn project_range(&self, q: &[Point], first: usize, out: &mut [Point]);
    /// Energy `sum w_i/2 |G_i q - P_i(G_i q)|^2` of the constraints in `range`, in J.
    fn energy_range(&self, q: &[Point], range: Range<usize>) -> f64;
    /// An upper bound of the energy at `q` of constraints
    /// `first..first + projections.len() / ROWS`, from points `p_i` of their
    /// constraint sets found earlier (a local step's projections, in its
    /// layout): `sum w_i/2 |G_i q - p_i|^2`. It bounds the energy because
    /// the projection is the closest point of the set. No projection is
    /// computed, so it costs a fraction of [`ConstraintBlock::energy_range`].
    fn energy_bound_range(&self, q: &[Point], first: usize, projections: &[Point]) -> EnergyBound;
    /// [`ConstraintBlock::project_range`] followed by
    /// [`ConstraintBlock::energy_bound_range`] at the same `q` from the
    /// projections just written (so the bound is the energy itself), with
    /// the same results to the bit; a kind may compute both in one pass
    /// (tet strain: from the SIMD lanes of its projection).
    fn project_energy_range(&self, q: &[Point], first: usize, out: &mut [Point]) -> EnergyBound {
        self.project_range(q, first, out);
        self.energy_bound_range(q, first, out)
    }
    /// Adds the energy gradient `w_i G_i^T (G_i q - P_i(G_i q))` of every
    /// constraint to `gradient` (one entry per vertex, in N).
    fn add_gradient(&self, q: &[Point], gradient: &mut [Point]);
    /// The stencil of constraint `i` (by value: a kind may store its
    /// indices more compactly than `usize`).
    fn stencil(&self, i: usize) -> Stencil;
    /// Values in one constraint's stencil Hessian: `(3 STENCIL)^2`.
    fn hessian_len(&self) -> usize;
    /// Energy Hessians with respect to the stencil positions, at `q`, of
    /// constraints `first..first + out.len() / hessian_len()`: each a
    /// `3 STENCIL x 3 STENCIL` row-major matrix, index `3 k + a` for stencil
    /// vertex `k`, axis `a`. With `project_psd`, each is positive
    /// semi-definite (N/m).
    fn hessian_range(&self, q: &[Point], first: usize, project_psd: bool, out: &mut [f64]);
    /// A boxed copy of the block (blocks are kept as trait objects).
    fn boxed_clone(&self) -> Box<dyn ConstraintBlock>;
}

impl<C: Constraint> ConstraintBlock for ConstraintSet<C> {
    fn kind(&self) -> &'static str {
        C::KIND
    }

    fn len(&self) -> usize {
        self.constraints.len()
    }

    fn rows_per_constraint(&self) -> usize {
        C::ROWS
    }

    fn translation_invariant(&self) -> bool {
        C::TRANSLATION_INVARIANT
    }

    fn max_vertex(&self) -> Option<usize> {
        self.constraints
            .iter()
            .filter_map(|c| c.vertices().iter().copied().max())
            .max()
    }

    fn add_laplacian(&self, out: &mut Vec<Triplet>) {
        out.reserve(self.constraints.len() * C::STENCIL * C::STENCIL);
        self.laplacian_entries(false, out);
    }

    fn add_lower_laplacian(&self, out: &mut Vec<Triplet>) {
        out.reserve(self.constraints.len() * C::STENCIL * (C::STENCIL + 1) / 2);
        self.laplacian_entries(true, out);
    }

    fn add_projection_operator(&self, first_row: usize, out: &mut Vec<Triplet>) {
        out.reserve(self.constraints.len() * C::STENCIL * C::ROWS);
        self.for_each_projection_entry(first_row, &mut |row, column, value| {
            out.push(Triplet::new(row, column, value));
        });
    }

    fn for_each_projection_entry(
        &self,
        first_row: usize,
        entry: &mut dyn FnMut(usize, usize, f64),
    ) {
        for (i, c) in self.constraints.iter().enumerate() {
            let w = c.weight();
            for (a, &va) in c.vertices().iter().enumerate() {
                for r in 0..C::ROWS {
                    entry(va, first_row + i * C::ROWS + r, w * c.operator(r, a));
                }
            }
        }
    }

    fn project_range(&self, q: &[Point], first: usize, out: &mut [Point]) {
        let count = out.len() / C::ROWS;
        C::project_many(&self.constraints[first..first + count], q, out);
    }

    fn energy_range(&self, q: &[Point], range: Range<usize>) -> f64 {
        // The projections come from `project_many` (the SIMD lanes for tet
        // strain), a batch at a time on the stack: the same bits as
        // `project` one by one (its contract), and the energies are summed
        // in the same order, so the value is the one-at-a-time sum exactly.
        let mut gx = [Point::zeros(); MAX_ROWS];
        let mut p = [Point::zeros(); ENERGY_BATCH * MAX_ROWS];
        self.constraints[range]
            .chunks(ENERGY_BATCH)
            .flat_map(|batch| {
                let rows = &mut p[..batch.len() * C::ROWS];
                C::project_many(batch, q, rows);
                let mut energies = [0.0; ENERGY_BATCH];
                for ((c, p), e) in batch
                    .iter()
                    .zip(rows.chunks_exact(C::ROWS))
                    .zip(&mut energies)
                {
                    apply_operator(c, q, &mut gx[..C::ROWS]);
                    let distance2: f64 = (0..C::ROWS).map(|r| (gx[r] - p[r]).norm_squared()).sum();
                    *e = 0.5 * c.weight() * distance2;
                }
                energies.into_iter().take(batch.len())
            })
            .sum()
    }

    fn boxed_clone(&self) -> Box<dyn ConstraintBlock> {
        Box::new(self.clone())
    }

    fn project_energy_range(&self, q: &[Point], first: usize, out: &mut [Point]) -> EnergyBound {
        // A batch at a time: projections and energies in one pass
        // (`Constraint::project_many_with_energies`), merged in order.
        let count = out.len() / C::ROWS;
        let mut energies = [0.0; ENERGY_BATCH];
        let mut bound = EnergyBound::default();
        let mut index = first;
        for (batch, rows) in self.constraints[first..first + count]
            .chunks(ENERGY_BATCH)
            .zip(out.chunks_mut(ENERGY_BATCH * C::ROWS))
        {
            let energies = &mut energies[..batch.len()];
            C::project_many_with_energies(batch, q, rows, energies);
            index = merge_in_order(&mut bound, index, energies);
        }
        bound
    }

    fn energy_bound_range(&self, q: &[Point], first: usize, projections: &[Point]) -> EnergyBound {
        // The energies a batch at a time (`Constraint::energies_many`, SIMD
        // lanes for tet strain, the same bits), merged one by one in order.
        let count = projections.len() / C::ROWS;
        let mut energies = [0.0; ENERGY_BATCH];
        let mut bound = EnergyBound::default();
        let mut index = first;
        for (batch, p) in self.constraints[first..first + count]
            .chunks(ENERGY_BATCH)
            .zip(projections.chunks(ENERGY_BATCH * C::ROWS))
        {
            let energies = &mut energies[..batch.len()];
            C::energies_many(batch, q, p, energies);
            index = merge_in_order(&mut bound, index, energies);
        }
        bound
    }

    fn add_gradient(&self, q: &[Point], gradient: &mut [Point]) {
        let mut gx = [Point::zeros(); MAX_ROWS];
        let mut p = [Point::zeros(); MAX_ROWS];
        for c in self.constraints.iter() {
            apply_operator(c, q, &mut gx[..C::ROWS]);
            c.project(&gx[..C::ROWS], &mut p[..C::ROWS]);
            for (a, &v) in c.vertices().iter().enumerate() {
                let g: Point = (0..C::ROWS)
                    .map(|r| (gx[r] - p[r]) * c.operator(r, a))
                    .sum();
                gradient[v] += g * c.weight();
            }
        }
    }

    fn stencil(&self, i: usize) -> Stencil {
        Stencil::new(&self.constraints[i].vertices())
    }

    fn hessian_len(&self) -> usize {
        9 * C::STENCIL * C::STENCIL
    }

    fn hessian_range(&self, q: &[Point], first: usize, project_psd: bool, out: &mut [f64]) {
        const { assert!(C::STENCIL <= MAX_HESSIAN_STENCIL) };
        let len = self.hessian_len();
        let count = out.len() / len;
        let size = 3 * C::STENCIL;
        let mut gx = [Point::zeros(); MAX_ROWS];
        let mut h_gx = [0.0; 9 * MAX_ROWS * MAX_ROWS];
        let rows3 = 3 * C::ROWS;
        // `T`'s rows (3 ROWS of `size`), overwritten for each constraint.
        let mut t = [0.0; 9 * MAX_ROWS * MAX_HESSIAN_STENCIL];
        for (c, h) in self.constraints[first..first + count]
            .iter()
            .zip(out.chunks_exact_mut(len))
        {
            apply_operator(c, q, &mut gx[..C::ROWS]);
            c.gx_hessian(&gx[..C::ROWS], project_psd, &mut h_gx[..rows3 * rows3]);
            // Chain rule: d(gx)_{r,a} / d(x_k)_{a'} = G[r][k] delta_{a a'}, so
            // H[(k,a),(l,b)] = sum_{r,s} G[r][k] G[s][l] H_gx[(r,a),(s,b)].
            // A congruence of a PSD matrix stays PSD.
            // The operator is read once per constraint rather than per term
            // (a kind may compute an entry: tet strain recomputes its first
            // column).
            let mut g = [[0.0; MAX_ROWS]; MAX_HESSIAN_STENCIL];
            for (k, g) in g.iter_mut().enumerate().take(C::STENCIL) {
                for (r, g) in g.iter_mut().enumerate().take(C::ROWS) {
                    *g = c.operator(r, k);
                }
            }
            // In two stages, `T = H_gx (G (x) I_3)` then `H = (G (x) I_3)^T T`:
            // T[(r,a),(l,b)] = sum_s H_gx[(r,a),(s,b)] G[s][l], and
            // H[(k,a),(l,b)] = sum_r G[r][k] T[(r,a),(l,b)]: 9 ROWS STENCIL
            // (ROWS + STENCIL) products per element instead of 18 (ROWS
            // STENCIL)^2 for the sums over r and s at once.
            for r in 0..C::ROWS {
                for a in 0..3 {
                    let h_row = &h_gx[(3 * r + a) * rows3..][..rows3];
                    let t_row = &mut t[(3 * r + a) * size..][..size];
                    for l in 0..C::STENCIL {
                        for b in 0..3 {
                            let mut sum = 0.0;
                            for s in 0..C::ROWS {
                                sum += h_row[3 * s + b] * g[l][s];
                            }
                            t_row[3 * l + b] = sum;
                        }
                    }
                }
            }
            for k in 0..C::STENCIL {
                for a in 0..3 {
                    let h_row = &mut h[(3 * k + a) * size..][..size];
                    h_row.fill(0.0);
                    for r in 0..C::ROWS {
                        let gk = g[k][r];
                        for (out, t) in h_row.iter_mut().zip(&t[(3 * r + a) * size..][..size]) {
                            *out += gk * t;
                        }
                    }
                }
            }
        }
    }
}
