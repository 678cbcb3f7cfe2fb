//! [`Model::fingerprint`]: a 64-bit hash that tells one model from another,
//! so that a checkpoint of one is not restored into a simulation of another
//! that happens to have as many vertices.

use pd_mesh::Point;

use super::Model;
use crate::hash::Fnv1a;

/// Hashing of the model's numbers.
trait HashNumbers {
    fn usize(&mut self, value: usize);
    fn point(&mut self, p: &Point);
}

impl HashNumbers for Fnv1a {
    fn usize(&mut self, value: usize) {
        self.write_bytes(&(value as u64).to_le_bytes());
    }

    fn point(&mut self, p: &Point) {
        p.iter().for_each(|&c| self.write_f64(c));
    }
}

/// A pseudo-random number in `[-1, 1)` for vertex `v` and axis `axis`
/// (SplitMix64's finaliser): integer arithmetic only, so the same on every
/// machine.
fn jitter(v: usize, axis: usize) -> f64 {
    let mut z = (v as u64)
        .wrapping_mul(3)
        .wrapping_add(axis as u64)
        .wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    // The top 53 bits as a fraction in [0, 1), then to [-1, 1).
    (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

impl Model {
    /// A 64-bit hash of everything that defines the model: the bodies
    /// (vertex ranges, element counts), rest positions, masses, fixed
    /// vertices, and for every constraint block its kind, size, the entries
    /// of its weighted operator `sum_i w_i G_i^T S_i` (topology, weights,
    /// rest shapes) and its energy at a fixed, slightly jittered
    /// configuration (which also sees what the operator does not: targets
    /// of attachments, rest lengths, strain limits, a material's law and
    /// parameters).
    ///
    /// Two models built the same way have the same fingerprint on every
    /// machine; models that differ in any of these differ in it except by
    /// a hash collision (about one chance in 2^64). A [`crate::Checkpoint`]
    /// carries it, and [`crate::Simulation::restore`] refuses a checkpoint
    /// of another model.
    ///
    /// ```
    /// use pd_mesh::generators;
    /// use pd_solver::Model;
    ///
    /// let build = |stiffness| {
    ///     let chain = generators::chain(4, 1.0).unwrap();
    ///     let mut model = Model::new();
    ///     let body = model.add_body(chain, vec![0.1; 4]).unwrap();
    ///     model.add_springs(body, stiffness).unwrap();
    ///     model
    /// };
    /// assert_eq!(build(50.0).fingerprint(), build(50.0).fingerprint());
    /// assert_ne!(build(50.0).fingerprint(), build(60.0).fingerprint());
    /// ```
    pub fn fingerprint(&self) -> u64 {
        let mut hash = Fnv1a::new();
        hash.usize(self.num_vertices());
        hash.usize(self.bodies.len());
        for body in &self.bodies {
            let mesh = &body.mesh;
            hash.usize(body.offset);
            hash.usize(mesh.tets().len());
            hash.usize(mesh.triangles().len());
            hash.usize(mesh.edges().len());
        }
        self.rest_positions.iter().for_each(|p| hash.point(p));
        self.masses.iter().for_each(|&m| hash.write_f64(m));
        for &fixed in &self.fixed {
            hash.write_bytes(&[u8::from(fixed)]);
        }
        // The probe configuration: every vertex moved by up to 1 % of the
        // model's size, so that every kind of constraint is strained.
        let (mut lo, mut hi) = (
            Point::repeat(f64::INFINITY),
            Point::repeat(f64::NEG_INFINITY),
        );
        for p in &self.rest_positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let size = if self.rest_positions.is_empty() {
            0.0
        } else {
            (hi - lo).norm()
        };
        let amplitude = if size > 0.0 && size.is_finite() {
            0.01 * size
        } else {
            0.01
        };
        let probe: Vec<Point> = self
            .rest_positions
            .iter()
            .enumerate()
            .map(|(v, p)| p + amplitude * Point::new(jitter(v, 0), jitter(v, 1), jitter(v, 2)))
            .collect();
        let mut rows = 0;
        for block in self.constraint_blocks() {
            hash.write_bytes(block.kind().as_bytes());
            hash.usize(block.len());
            hash.usize(block.rows_per_constraint());
            block.for_each_projection_entry(rows, &mut |vertex, row, value| {
                hash.usize(vertex);
                hash.usize(row);
                hash.write_f64(value);
            });
            rows += block.len() * block.rows_per_constraint();
            hash.write_f64(block.energy_range(&probe, 0..block.len()));
        }
        hash.finish()
    }
}
