//! The [`Constraint`] trait: one PD energy term `w/2 |G x - P(G x)|^2`.

use pd_mesh::Point;

/// One Projective Dynamics constraint: a weight `w`, a stencil of vertices,
/// a linear operator `G` (ROWS x STENCIL, applied to each of the x, y, z
/// columns alike) and a projection `P` onto the constraint set. Its energy is
/// `E(x) = w/2 |G x - P(G x)|^2` and, because `P` is the closest-point
/// projection, its gradient is `w G^T (G x - P(G x))`
/// (`docs/design/constraints.md`).
///
/// Implementations describe a single constraint; [`crate::ConstraintSet`]
/// stores many of one kind contiguously and runs the loops.
pub trait Constraint: Clone + std::fmt::Debug + Send + Sync + 'static {
    /// Number of vertices in the stencil.
    const STENCIL: usize;
    /// Number of rows of `G x` (and of the projection).
    const ROWS: usize;
    /// Whether `G 1 = 0`: the constraint sees only relative positions, so it
    /// exerts no net force and belongs in the damping Laplacian.
    const TRANSLATION_INVARIANT: bool;
    /// Short name of the kind, as scenes spell it (`tet-strain`).
    const KIND: &'static str;

    /// How [`Constraint::vertices`] hands out the stencil: `&'a [usize]`
    /// for a kind storing `usize` indices, [`crate::Stencil`] (by value)
    /// for one storing them more compactly (tet strain: 32-bit).
    type Vertices<'a>: std::ops::Deref<Target = [usize]>
    where
        Self: 'a;

    /// The stencil: `STENCIL` vertex indices.
    fn vertices(&self) -> Self::Vertices<'_>;
    /// The weight `w` (N/m for springs and attachments, N/m^2 x m^3 = N m for
    /// strain).
    fn weight(&self) -> f64;
    /// Entry `(row, column)` of `G`, `row < ROWS`, `column < STENCIL`.
    fn operator(&self, row: usize, column: usize) -> f64;
    /// Projects `gx` (the `ROWS` rows of `G x`) onto the constraint set,
    /// writing `ROWS` rows into `out`.
    fn project(&self, gx: &[Point], out: &mut [Point]);

    /// The local step for a run of constraints: projects each of
    /// `constraints` at the positions `q`, writing its `ROWS` rows into
    /// `out` (`out.len() == constraints.len() * ROWS`). The default
    /// projects one at a time; a kind overrides it to batch several into
    /// SIMD lanes (tet strain), with results identical to the default.
    fn project_many(constraints: &[Self], q: &[Point], out: &mut [Point]) {
        project_one_by_one(constraints, q, out);
    }

    /// The energies `w/2 |G q - p|^2` of a run of constraints at the
    /// positions `q` from their projections `p` (`ROWS` rows each, as
    /// [`Constraint::project_many`] wrote them), one per constraint into
    /// `out`, in J. The default computes one at a time; a kind may batch
    /// several into SIMD lanes (tet strain), with results identical to the
    /// default to the bit.
    fn energies_many(constraints: &[Self], q: &[Point], projections: &[Point], out: &mut [f64]) {
        energies_one_by_one(constraints, q, projections, out);
    }

    /// [`Constraint::project_many`] and then [`Constraint::energies_many`]
    /// from the projections just written, with the same results to the
    /// bit; a kind may compute both in one pass (tet strain).
    fn project_many_with_energies(
        constraints: &[Self],
        q: &[Point],
        out: &mut [Point],
        energies: &mut [f64],
    ) {
        Self::project_many(constraints, q, out);
        Self::energies_many(constraints, q, out, energies);
    }

    /// Hessian of `w/2 |gx - P(gx)|^2` with respect to `gx`: a
    /// `3 ROWS x 3 ROWS` row-major matrix, index `3 r + a` for row `r`, axis
    /// `a`, written into `out`. With `project_psd` its negative eigenvalues
    /// are clamped to zero (`docs/design/constraints.md`). The weight `w` is
    /// included.
    fn gx_hessian(&self, gx: &[Point], project_psd: bool, out: &mut [f64]);
}

/// The default [`Constraint::project_many`]: one [`Constraint::project`]
/// at a time (also what a batched kind does with the elements its lanes
/// leave over).
pub(crate) fn project_one_by_one<C: Constraint>(constraints: &[C], q: &[Point], out: &mut [Point]) {
    let mut gx = [Point::zeros(); crate::MAX_ROWS];
    for (c, rows) in constraints.iter().zip(out.chunks_exact_mut(C::ROWS)) {
        apply_operator(c, q, &mut gx[..C::ROWS]);
        c.project(&gx[..C::ROWS], rows);
    }
}

/// The default [`Constraint::energies_many`]: `w/2 |G q - p|^2` one
/// constraint at a time.
pub(crate) fn energies_one_by_one<C: Constraint>(
    constraints: &[C],
    q: &[Point],
    projections: &[Point],
    out: &mut [f64],
) {
    let mut gx = [Point::zeros(); crate::MAX_ROWS];
    for ((c, p), e) in constraints
        .iter()
        .zip(projections.chunks_exact(C::ROWS))
        .zip(out)
    {
        apply_operator(c, q, &mut gx[..C::ROWS]);
        let distance2: f64 = (0..C::ROWS).map(|r| (gx[r] - p[r]).norm_squared()).sum();
        *e = 0.5 * c.weight() * distance2;
    }
}

/// Computes the `ROWS` rows of `G q` for one constraint into `gx`.
#[inline]
pub(crate) fn apply_operator<C: Constraint>(c: &C, q: &[Point], gx: &mut [Point]) {
    for (row, out) in gx.iter_mut().enumerate() {
        *out = c
            .vertices()
            .iter()
            .enumerate()
            .fold(Point::zeros(), |acc, (col, &v)| {
                acc + q[v] * c.operator(row, col)
            });
    }
}
