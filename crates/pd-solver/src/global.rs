//! The global step: the constant operators restricted to the free vertices,
//! the global matrix `A = alpha M + beta L_sys + delta L_d`
//! (docs/design/formulation.md, "The global step"),
//! and its cached factorisations.

use std::sync::Arc;

use crate::projection_scatter::ProjectionOperator;
use crate::weights::combine_weighted;
use crate::{SolverError, local::LocalStep};
use pd_constraints::{CsrMatrix, Triplet, assembly, assembly::LaplacianKind};
use pd_damping::HIGHER_SERIES_TERMS;
use pd_linalg::cholesky::{LowerPattern, NumericFactor, SymbolicFactor, dissection_candidates};

/// Marks a fixed vertex in the free-vertex map.
pub(crate) const FIXED: usize = usize::MAX;

/// The coefficients that determine the global matrix
/// `A = mass M + system L_sys + damping L_d + sum_j series[j] P_(j+1)`
/// (`P_j = L_d (M^-1 L_d)^j` over the free vertices, the Caughey series'
/// terms); a factorisation is cached per distinct value (compared bit for
/// bit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MatrixCoefficients {
    pub mass: f64,
    pub system: f64,
    pub damping: f64,
    /// The part of `mass` that is damping, `c1 c2 gamma a1` (1/s^2): what
    /// per-body weights scale (`weights.rs`).
    pub mass_damping: f64,
    /// `c1 c2 gamma a_(j+3)` of the series terms, zero without series.
    pub series: [f64; HIGHER_SERIES_TERMS],
}

/// How many values [`MatrixCoefficients::bits`] holds.
pub(crate) const COEFFICIENT_COUNT: usize = 4 + HIGHER_SERIES_TERMS;

impl MatrixCoefficients {
    /// Every coefficient's bits (mass, system, damping, mass damping, then
    /// the series').
    pub(crate) fn bits(&self) -> [u64; COEFFICIENT_COUNT] {
        let mut bits = [0; COEFFICIENT_COUNT];
        bits[..4].copy_from_slice(&[
            self.mass.to_bits(),
            self.system.to_bits(),
            self.damping.to_bits(),
            self.mass_damping.to_bits(),
        ]);
        for (b, s) in bits[4..].iter_mut().zip(&self.series) {
            *b = s.to_bits();
        }
        bits
    }
}

/// Operators over the free vertices and the factorisation machinery.
#[derive(Debug)]
pub(crate) struct GlobalSystem {
    /// Global index of each free vertex.
    pub free: Vec<usize>,
    /// Free index of each vertex, or [`FIXED`].
    pub free_index: Vec<usize>,
    /// The lower-triangle pattern over the free vertices (shared with the
    /// symbolic factor, not copied).
    pub pattern: Arc<LowerPattern>,
    /// Rows of `L_d` (the translation-invariant constraints) for the free
    /// vertices (all columns): the damping Laplacian, and with
    /// `anchoring_rows` the system Laplacian `L_sys = L_d + L_anchor`, so
    /// that the step can apply the translation-invariant part on
    /// differences (`CsrMatrix::row_dot_relative`).
    pub damping_rows: CsrMatrix,
    /// Rows of `L_anchor` (attachments) for the free vertices (all columns).
    pub anchoring_rows: CsrMatrix,
    /// The projection operator `B`'s rows for the free vertices, stored
    /// for the scatter of `B p` (on more threads one range of vertices per
    /// thread) or, on more threads when most elements would straddle two
    /// ranges, for the row gather (`projection_scatter.rs`).
    pub projection_rows: ProjectionOperator,
    /// Per pattern slot: the mass on the diagonal, else 0.
    pub mass_part: Vec<f64>,
    /// Per pattern slot: the entry of `L_sys`.
    pub system_part: Vec<f64>,
    /// Per pattern slot: the entry of `L_d`.
    pub damping_part: Vec<f64>,
    /// The elimination order chosen for the scalar system (free indices in
    /// pivot order), offered to the lagged 3n system as a candidate.
    pub order: Option<Vec<usize>>,
    /// Per-body damping weights, when the damping model has them.
    pub weights: Option<crate::weights::DampingWeights>,
    /// The Caughey series' matrices `P_j = L_ff (M_f^-1 L_ff)^j`,
    /// `j = 1, 2, ...` (`L_ff` the damping Laplacian among the free
    /// vertices): rows of the free vertices, columns by vertex; empty
    /// without series.
    pub series_rows: Vec<CsrMatrix>,
    /// Per pattern slot, for each `P_j`: its entry.
    pub series_parts: Vec<Vec<f64>>,
    symbolic: SymbolicFactor,
    cache: Vec<([u64; 4 + HIGHER_SERIES_TERMS], NumericFactor)>,
}

impl GlobalSystem {
    /// Assembles the operators and analyses the pattern (once per model).
    /// `rest` (the rest positions) steers the nested-dissection ordering;
    /// `threads` (the step's thread count) picks how `B p` is computed
    /// (scatter or row gather: the same bits). `series_powers` is the
    /// highest power `j` of the Caughey series' `P_j` the damping needs (0
    /// without series: then the pattern is that of `L_sys` alone).
    pub fn new(
        local: &LocalStep,
        masses: &[f64],
        fixed: &[bool],
        rest: &[pd_mesh::Point],
        threads: usize,
        series_powers: usize,
    ) -> Result<Self, SolverError> {
        let n = masses.len();
        let mut free_index = vec![FIXED; n];
        let mut free = Vec::with_capacity(n);
        for v in 0..n {
            if !fixed[v] {
                // `Simulation::new` checked the masses by body
                // (`Model::check_free_masses`), before this system.
                debug_assert!(masses[v] > 0.0, "free vertex {v} without mass");
                free_index[v] = free.len();
                free.push(v);
            }
        }
        if free.is_empty() {
            let reason = if masses.is_empty() {
                "the model has no vertices: nothing to simulate"
            } else {
                "every vertex is fixed: nothing to simulate"
            };
            return Err(SolverError::InvalidModel {
                reason: reason.into(),
            });
        }
        // L_sys = L_d + L_anchor: the two parts are kept apart (the step
        // applies L_d to differences), and L_sys is their sum slot by slot.
        // Each operator is cut to the free vertices' rows as soon as it is
        // built (kept as it is when every vertex is free), so no full copy
        // outlives its assembly; the projection operator is built for those
        // rows directly.
        let damping_rows =
            assembly::laplacian(local.blocks(), n, LaplacianKind::Damping).into_rows(&free);
        let anchoring_rows =
            assembly::laplacian(local.blocks(), n, LaplacianKind::Anchoring).into_rows(&free);

        // Lower triangle over free vertices: diagonal plus every L_sys entry
        // (and every entry of the series' P_j).
        let nf = free.len();
        let series_rows = series_matrices(&damping_rows, &free, &free_index, masses, series_powers);
        let mut per_column: Vec<Vec<usize>> = (0..nf).map(|j| vec![j]).collect();
        let entries = |rows| free_entries(rows, &free_index);
        let series_entries = series_rows.iter().flat_map(&entries);
        for (fr, fc, _) in entries(&damping_rows)
            .chain(entries(&anchoring_rows))
            .chain(series_entries)
        {
            if fc != FIXED && fr > fc {
                per_column[fc].push(fr);
            }
        }
        let mut col_ptr = Vec::with_capacity(nf + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for rows in &mut per_column {
            rows.sort_unstable();
            rows.dedup();
            row_idx.extend_from_slice(rows);
            col_ptr.push(row_idx.len());
        }
        drop(per_column);
        let pattern = LowerPattern {
            n: nf,
            col_ptr,
            row_idx,
        };
        let slot = |row: usize, col: usize| -> usize {
            pattern
                .slot(row, col)
                .expect("every entry of L_sys is in the pattern")
        };
        let len = pattern.row_idx.len();
        let mut mass_part = vec![0.0; len];
        let mut system_part = vec![0.0; len];
        let mut damping_part = vec![0.0; len];
        for (f, &v) in free.iter().enumerate() {
            mass_part[slot(f, f)] = masses[v];
        }
        for (rows, is_damping) in [(&damping_rows, true), (&anchoring_rows, false)] {
            for (fr, fc, value) in entries(rows) {
                if fc != FIXED && fr >= fc {
                    let k = slot(fr, fc);
                    system_part[k] += value;
                    if is_damping {
                        damping_part[k] += value;
                    }
                }
            }
        }
        let series_parts = series_rows
            .iter()
            .map(|rows| {
                let mut part = vec![0.0; len];
                for (fr, fc, value) in entries(rows) {
                    if fc != FIXED && fr >= fc {
                        part[slot(fr, fc)] += value;
                    }
                }
                part
            })
            .collect();
        let free_rest: Vec<pd_mesh::Point> = free.iter().map(|&v| rest[v]).collect();
        let candidates = dissection_candidates(&pattern, &free_rest);
        drop(free_rest);
        let pattern = Arc::new(pattern);
        let symbolic = SymbolicFactor::analyse(pattern.clone(), &candidates)?;
        drop(candidates);
        let order = symbolic.order();
        let projection_rows = ProjectionOperator::new(local.blocks(), &free, &free_index, threads);
        Ok(Self {
            pattern,
            damping_rows,
            anchoring_rows,
            projection_rows,
            free,
            free_index,
            mass_part,
            system_part,
            damping_part,
            order,
            weights: None,
            series_rows,
            series_parts,
            symbolic,
            cache: Vec::new(),
        })
    }

    /// Number of stored values of one Cholesky factor (packed, as
    /// [`Self::prepare_factor`] keeps it: what a solve reads).
    pub fn factor_len(&self) -> usize {
        self.symbolic.packed_len()
    }

    /// Structural non-zeros of one Cholesky factor (see
    /// `SymbolicFactor::factor_nnz`).
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.factor_nnz()
    }

    /// Index in the cache of the factorisation for `coefficients`,
    /// factorising (and returning `true`) only if it is not cached yet.
    pub fn prepare_factor(
        &mut self,
        coefficients: MatrixCoefficients,
    ) -> Result<(usize, bool), SolverError> {
        let key = coefficients.bits();
        if let Some(i) = self.cache.iter().position(|(k, _)| *k == key) {
            return Ok((i, false));
        }
        // The matrix's values live only while they are factorised.
        let values = self.values(coefficients);
        let mut factor = self.symbolic.factorise(&values)?;
        drop(values);
        // Solved three columns at a time, so packed (`SymbolicFactor::pack`).
        self.symbolic.pack(&mut factor);
        // Constant coefficients factorise once (a new value is rare): the
        // factorisation's scratch is not kept through the steps.
        self.symbolic.release_factor_scratch();
        self.cache.push((key, factor));
        Ok((self.cache.len() - 1, true))
    }

    /// Recomputes the numeric factorisation for `coefficients` into its
    /// cache slot (factorising into a new slot on a cache miss). The values
    /// are the same, so the cached factor stays valid bit for bit; used to
    /// time a numeric factorisation on its own (`Simulation::profile_factorise`).
    pub fn refactorise_cached(
        &mut self,
        coefficients: MatrixCoefficients,
    ) -> Result<(), SolverError> {
        let (index, factorised) = self.prepare_factor(coefficients)?;
        if factorised {
            return Ok(());
        }
        let values = self.values(coefficients);
        let (_, factor) = &mut self.cache[index];
        self.symbolic.refactorise(&values, factor)?;
        Ok(())
    }

    /// The global matrix's lower-triangle values for `coefficients`, in
    /// pattern order.
    fn values(&self, coefficients: MatrixCoefficients) -> Vec<f64> {
        let mut values = vec![0.0; self.pattern.row_idx.len()];
        self.values_into(coefficients, &mut values);
        values
    }

    /// [`Self::values`] written over `values` (one per pattern entry),
    /// without allocating.
    pub(crate) fn values_into(&self, coefficients: MatrixCoefficients, values: &mut [f64]) {
        combine_weighted(
            values,
            coefficients,
            [&self.mass_part, &self.system_part, &self.damping_part],
            self.weights.as_ref(),
        );
        // The series' terms (none without series: the values above stay
        // bit for bit what they were).
        for (part, &a) in self.series_parts.iter().zip(&coefficients.series) {
            if a != 0.0 {
                for (value, p) in values.iter_mut().zip(part) {
                    *value += a * p;
                }
            }
        }
    }

    /// The global matrix for `coefficients` (free vertices, full symmetric).
    pub fn matrix(&self, coefficients: MatrixCoefficients) -> CsrMatrix {
        self.pattern.to_symmetric(&self.values(coefficients))
    }

    /// Solves in place with cached factor `index`; `rhs` holds one point
    /// per free vertex.
    pub fn solve_points(&mut self, index: usize, rhs: &mut [pd_mesh::Point]) {
        let (_, factor) = &self.cache[index];
        self.symbolic.solve_points(factor, rhs);
    }
}

/// The entries `(row, column, value)` of `rows` (the rows of an operator
/// over every vertex for the free vertices, in order), with the column in
/// free indices ([`FIXED`] for a fixed vertex).
fn free_entries<'a>(
    rows: &'a CsrMatrix,
    free_index: &'a [usize],
) -> impl Iterator<Item = (usize, usize, f64)> + 'a {
    (0..rows.nrows())
        .flat_map(move |f| rows.row(f).map(move |(c, value)| (f, free_index[c], value)))
}

/// `values = mass * parts[0] + system * parts[1] + damping * parts[2]`.
pub(crate) fn combine(values: &mut [f64], coefficients: MatrixCoefficients, parts: [&[f64]; 3]) {
    for (((value, m), l), d) in values.iter_mut().zip(parts[0]).zip(parts[1]).zip(parts[2]) {
        *value = coefficients.mass * m + coefficients.system * l + coefficients.damping * d;
    }
}

/// The Caughey series' matrices `P_j = L_ff (M_f^-1 L_ff)^j` for
/// `j = 1..=powers` (none for `powers = 0`), each as rows of the free
/// vertices with columns by vertex, from `damping_rows` (the free vertices'
/// rows of `L_d`, all columns).
///
/// `L_ff` drops the columns of fixed vertices: the damping velocity
/// vanishes there, so `D v` on the free rows only reads `L_ff` (and the
/// series is the one in `M_f^-1 L_ff`, the operator of the free modes).
/// Each product is a row-by-row sparse product (Gustavson) with a dense
/// accumulator over the free vertices; it widens the stencil by one ring
/// of neighbours per power.
fn series_matrices(
    damping_rows: &CsrMatrix,
    free: &[usize],
    free_index: &[usize],
    masses: &[f64],
    powers: usize,
) -> Vec<CsrMatrix> {
    if powers == 0 {
        return Vec::new();
    }
    let nf = free.len();
    let n = free_index.len();
    // L_ff by free index: (column, value) per row.
    let lff: Vec<Vec<(usize, f64)>> = (0..nf)
        .map(|f| {
            damping_rows
                .row(f)
                .filter_map(|(c, x)| (free_index[c] != FIXED).then_some((free_index[c], x)))
                .collect()
        })
        .collect();
    let mut accumulator = vec![0.0; nf];
    let mut marker = vec![usize::MAX; nf];
    let mut touched = Vec::new();
    let mut previous = lff.clone();
    let mut out = Vec::with_capacity(powers);
    for _ in 0..powers {
        // next = L_ff M^-1 previous, row f: sum_k L_fk / m_k previous_k.
        let mut next: Vec<Vec<(usize, f64)>> = Vec::with_capacity(nf);
        for (f, row) in lff.iter().enumerate() {
            touched.clear();
            for &(k, l) in row {
                let scale = l / masses[free[k]];
                for &(c, p) in &previous[k] {
                    if marker[c] != f {
                        marker[c] = f;
                        accumulator[c] = 0.0;
                        touched.push(c);
                    }
                    accumulator[c] += scale * p;
                }
            }
            touched.sort_unstable();
            next.push(touched.iter().map(|&c| (c, accumulator[c])).collect());
        }
        marker.iter_mut().for_each(|m| *m = usize::MAX);
        let triplets: Vec<Triplet> = next
            .iter()
            .enumerate()
            .flat_map(|(f, row)| row.iter().map(move |&(c, x)| Triplet::new(f, free[c], x)))
            .collect();
        out.push(CsrMatrix::from_triplet_vec(nf, n, triplets));
        previous = next;
    }
    out
}
