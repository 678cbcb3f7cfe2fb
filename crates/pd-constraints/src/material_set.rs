//! [`MaterialSet`]: hyperelastic tetrahedra as an *energy element* block.
//!
//! A material is not a Projective Dynamics constraint, but it sits in the
//! same block list so that everything that sums energies, gradients and
//! Hessians over blocks (the step objective, the divergence check, Newton's
//! Hessian, the energy reports) sees it without a second code path. Its
//! block answers:
//!
//! - energy, energy bound, gradient, Hessian: the material's
//!   (`V Psi(F)`, `V P(F)` through `G^T`, `G^T (V d^2Psi/dF^2) G`);
//! - projection: the identity `P(G q) = G q`, so that in a local-global
//!   iteration the material exerts no force and only adds the proximal term
//!   `w G^T G` to the matrix: its Laplacian, with weight
//!   `w = (2 mu + lambda) * rest volume`, is the *preconditioner* that the L-BFGS
//!   initial Hessian and the global solve use (Liu, Bouaziz and Kavan 2017
//!   use such a PD matrix for hyperelastic materials);
//! - [`ConstraintBlock::is_energy_element`]: `true`, so that a solver knows
//!   it must add the material gradient ([`ConstraintBlock::add_gradient`])
//!   to the local-global one, and plain PD methods refuse to run it.

use std::ops::Range;

use nalgebra::Matrix3;
use pd_mesh::Point;

use crate::material::{Lame, MaterialKind, MaterialPoint, StressHessian, project_psd};
use crate::{ConstraintBlock, ConstraintError, EnergyBound, Stencil, Triplet};

/// One hyperelastic tetrahedron: its stencil, the operator `G = B^T [-1 | I]`
/// (the rows of `G x` are the columns of `F`, as for
/// [`crate::TetStrain`]) and its rest volume.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialTet {
    vertices: [usize; 4],
    operator: [[f64; 4]; 3],
    volume: f64,
}

impl MaterialTet {
    /// The element of tetrahedron `tet` at rest positions `rest`.
    ///
    /// # Errors
    /// [`ConstraintError::DegenerateElement`] for a flat or inverted rest shape.
    pub fn new(rest: &[Point], tet: [usize; 4]) -> Result<Self, ConstraintError> {
        crate::tet_strain::check_vertices(rest, &tet)?;
        let [x0, x1, x2, x3] = tet.map(|v| rest[v]);
        let edges = Matrix3::from_columns(&[x1 - x0, x2 - x0, x3 - x0]);
        let volume = edges.determinant() / 6.0;
        let degenerate = || ConstraintError::DegenerateElement {
            vertices: tet.to_vec(),
        };
        if !(volume > 0.0) {
            return Err(degenerate());
        }
        let inverse = edges.try_inverse().ok_or_else(degenerate)?;
        let mut operator = [[0.0; 4]; 3];
        for (row, g) in operator.iter_mut().enumerate() {
            g[0] = -(0..3).map(|j| inverse[(j, row)]).sum::<f64>();
            for j in 0..3 {
                g[j + 1] = inverse[(j, row)];
            }
        }
        Ok(Self {
            vertices: tet,
            operator,
            volume,
        })
    }

    /// The rest volume, m^3.
    pub fn volume(&self) -> f64 {
        self.volume
    }

    /// The stencil.
    pub fn vertices(&self) -> [usize; 4] {
        self.vertices
    }

    /// The deformation gradient `F` at positions `q`.
    pub fn deformation_gradient(&self, q: &[Point]) -> Matrix3<f64> {
        let column = |g: &[f64; 4]| {
            let mut acc = Point::zeros();
            for (k, &v) in self.vertices.iter().enumerate() {
                acc += q[v] * g[k];
            }
            acc
        };
        Matrix3::from_columns(&[
            column(&self.operator[0]),
            column(&self.operator[1]),
            column(&self.operator[2]),
        ])
    }
}

/// Hyperelastic tetrahedra of one material law and one pair of Lame
/// parameters (one scene constraint entry), as a [`ConstraintBlock`] (module
/// documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialSet {
    kind: MaterialKind,
    lame: Lame,
    young: f64,
    tets: Vec<MaterialTet>,
}

impl MaterialSet {
    /// The elements `tets` of law `kind` with Young's modulus `young` (Pa)
    /// and Poisson's ratio `poisson`.
    ///
    /// # Errors
    /// Invalid `young` or `poisson` ([`Lame::from_young_poisson`]).
    pub fn new(
        kind: MaterialKind,
        young: f64,
        poisson: f64,
        tets: Vec<MaterialTet>,
    ) -> Result<Self, ConstraintError> {
        let lame = Lame::from_young_poisson(young, poisson)?;
        Ok(Self {
            kind,
            lame,
            young,
            tets,
        })
    }

    /// The law.
    pub fn material(&self) -> MaterialKind {
        self.kind
    }

    /// The Lame parameters, Pa.
    pub fn lame(&self) -> Lame {
        self.lame
    }

    /// The elements.
    pub fn tets(&self) -> &[MaterialTet] {
        &self.tets
    }

    /// The preconditioner weight of an element: the P-wave modulus times
    /// the rest volume, `(2 mu + lambda) V` (N m; docs/design/materials.md for the
    /// measured choice).
    fn weight(&self, tet: &MaterialTet) -> f64 {
        (2.0 * self.lame.mu + self.lame.lambda) * tet.volume
    }

    fn point(&self, tet: &MaterialTet, q: &[Point]) -> MaterialPoint {
        MaterialPoint::new(self.kind, self.lame, tet.deformation_gradient(q))
    }

    /// The element's energy `V Psi(F)` at `q`, J.
    pub fn element_energy(&self, i: usize, q: &[Point]) -> f64 {
        let tet = &self.tets[i];
        tet.volume * self.point(tet, q).energy_density()
    }

    /// The element's 12 x 12 Hessian at `q` (N/m), row-major, index `3 k + a`
    /// for stencil vertex `k`, axis `a`; with `psd` the 9 x 9 `d^2Psi/dF^2`
    /// is eigen-clamped first, which makes the 12 x 12 congruence PSD.
    pub fn element_hessian(&self, i: usize, q: &[Point], psd: bool, out: &mut [f64]) {
        let tet = &self.tets[i];
        let mut h9: StressHessian = self.point(tet, q).stress_hessian() * tet.volume;
        if psd {
            h9 = project_psd(&h9);
        }
        let g = &tet.operator;
        // H[(k,a),(l,b)] = sum_{r,s} G[r][k] G[s][l] H9[(3r+a),(3s+b)].
        for k in 0..4 {
            for a in 0..3 {
                for l in 0..4 {
                    for b in 0..3 {
                        let mut sum = 0.0;
                        for r in 0..3 {
                            for s in 0..3 {
                                sum += g[r][k] * g[s][l] * h9[(3 * r + a, 3 * s + b)];
                            }
                        }
                        out[(3 * k + a) * 12 + 3 * l + b] = sum;
                    }
                }
            }
        }
    }
}

impl ConstraintBlock for MaterialSet {
    fn kind(&self) -> &'static str {
        self.kind.name()
    }

    fn len(&self) -> usize {
        self.tets.len()
    }

    fn rows_per_constraint(&self) -> usize {
        3
    }

    fn translation_invariant(&self) -> bool {
        true
    }

    fn is_energy_element(&self) -> bool {
        true
    }

    fn max_vertex(&self) -> Option<usize> {
        self.tets.iter().flat_map(|t| t.vertices).max()
    }

    fn add_laplacian(&self, out: &mut Vec<Triplet>) {
        out.reserve(self.tets.len() * 16);
        for t in &self.tets {
            let w = self.weight(t);
            for (a, &va) in t.vertices.iter().enumerate() {
                for (b, &vb) in t.vertices.iter().enumerate() {
                    let value: f64 = (0..3).map(|r| t.operator[r][a] * t.operator[r][b]).sum();
                    out.push(Triplet::new(va, vb, w * value));
                }
            }
        }
    }

    fn add_projection_operator(&self, first_row: usize, out: &mut Vec<Triplet>) {
        out.reserve(self.tets.len() * 12);
        for (i, t) in self.tets.iter().enumerate() {
            let w = self.weight(t);
            for (a, &va) in t.vertices.iter().enumerate() {
                for r in 0..3 {
                    out.push(Triplet::new(
                        va,
                        first_row + 3 * i + r,
                        w * t.operator[r][a],
                    ));
                }
            }
        }
    }

    fn project_range(&self, q: &[Point], first: usize, out: &mut [Point]) {
        for (t, rows) in self.tets[first..].iter().zip(out.chunks_exact_mut(3)) {
            let f = t.deformation_gradient(q);
            for (r, row) in rows.iter_mut().enumerate() {
                *row = f.column(r).into_owned();
            }
        }
    }

    fn energy_range(&self, q: &[Point], range: Range<usize>) -> f64 {
        range.map(|i| self.element_energy(i, q)).sum()
    }

    fn energy_bound_range(&self, q: &[Point], first: usize, projections: &[Point]) -> EnergyBound {
        let mut bound = EnergyBound::default();
        for i in first..first + projections.len() / 3 {
            let energy = self.element_energy(i, q);
            bound.merge(&EnergyBound {
                total: energy,
                worst: i,
                worst_energy: energy,
            });
        }
        bound
    }

    fn add_gradient(&self, q: &[Point], gradient: &mut [Point]) {
        for t in &self.tets {
            let p = self.point(t, q).stress() * t.volume;
            for (k, &v) in t.vertices.iter().enumerate() {
                let mut g = Point::zeros();
                for r in 0..3 {
                    g += p.column(r) * t.operator[r][k];
                }
                gradient[v] += g;
            }
        }
    }

    fn stencil(&self, i: usize) -> Stencil {
        Stencil::new(&self.tets[i].vertices)
    }

    fn hessian_len(&self) -> usize {
        144
    }

    fn hessian_range(&self, q: &[Point], first: usize, project_psd: bool, out: &mut [f64]) {
        for (i, h) in out.chunks_exact_mut(144).enumerate() {
            self.element_hessian(first + i, q, project_psd, h);
        }
    }

    fn boxed_clone(&self) -> Box<dyn ConstraintBlock> {
        Box::new(self.clone())
    }
}
