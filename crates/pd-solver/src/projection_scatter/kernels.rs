//! The scatter's inner loop: one group's projections, times its values,
//! added into its outputs' accumulators.
//!
//! An accumulator ([`Acc`]) holds an output's x, y and z in the first
//! three of four lanes (the fourth is scratch that nothing reads), so that with AVX2 one 4-wide load, three 4-wide
//! multiplies and adds and one 4-wide store update an output for a tet's
//! three projections (the projections' lanes are loaded once per group).
//! Each lane takes exactly the plain path's operations in the same order:
//! `o + p0 v0`, then `+ p1 v1`, then `+ p2 v2`, a multiply then an add per
//! term (Rust does not contract them into fused multiply-adds), so both
//! paths, and the row gather, give the same bits.

use std::sync::{Mutex, TryLockError};

use pd_mesh::Point;

use pd_linalg::simd::Avx2 as Simd;

/// An output's running sum: x, y, z and a fourth lane that nothing reads
/// (32 bytes: one 4-wide load and store).
pub(super) type Acc = [f64; 4];

/// The scatter's accumulators, kept between calls so that a call
/// allocates nothing (a call that finds them in use, by another call on
/// the same operator at the same time, takes its own).
#[derive(Debug, Default)]
pub(super) struct Scratch(Mutex<Vec<Acc>>);

impl Clone for Scratch {
    fn clone(&self) -> Self {
        Self::new(self.len())
    }
}

impl Scratch {
    pub fn new(outputs: usize) -> Self {
        Self(Mutex::new(vec![[0.0; 4]; outputs]))
    }

    fn len(&self) -> usize {
        match self.0.try_lock() {
            Ok(acc) => acc.len(),
            Err(TryLockError::Poisoned(acc)) => acc.into_inner().len(),
            Err(TryLockError::WouldBlock) => 0,
        }
    }

    /// Runs `f` on `outputs` accumulators (their values are stale).
    pub fn with<R>(&self, outputs: usize, f: impl FnOnce(&mut [Acc]) -> R) -> R {
        match self.0.try_lock() {
            Ok(mut acc) if acc.len() == outputs => f(&mut acc),
            Err(TryLockError::Poisoned(acc)) if acc.get_ref().len() == outputs => {
                f(&mut acc.into_inner())
            }
            _ => f(&mut vec![[0.0; 4]; outputs]),
        }
    }
}

/// One group as the scatter reads it: its projections, its outputs and its
/// values (output by output, for each output projection by projection).
pub(super) struct Group<'a> {
    pub projections: &'a [Point],
    pub targets: &'a [u32],
    pub values: &'a [f64],
}

impl<'a> Group<'a> {
    /// The group as a tet's: three projections on four outputs.
    #[inline(always)]
    fn as_tet(&self) -> Option<Tet<'a>> {
        Some(Tet {
            projections: self.projections.try_into().ok()?,
            targets: self.targets.try_into().ok()?,
            values: self.values.try_into().ok()?,
        })
    }
}

/// A group of a tet's shape (three projections on four outputs), with
/// lengths the compiler knows: its loops unroll, without bounds checks.
pub(super) struct Tet<'a> {
    pub projections: &'a [Point; 3],
    pub targets: &'a [u32; 4],
    pub values: &'a [f64; 12],
}

/// The accumulator of output `t` in `acc`, whose first slot is output
/// `first`. With `CHECK`, `None` for an output outside `acc` (a group that
/// straddles two threads' outputs); without, every output must be inside.
#[inline(always)]
fn slot<const CHECK: bool>(acc: &mut [Acc], t: u32, first: u32) -> Option<&mut Acc> {
    let i = t.wrapping_sub(first) as usize;
    if CHECK {
        acc.get_mut(i)
    } else {
        Some(&mut acc[i])
    }
}

/// Adds `group`'s projections times its values into the accumulators of
/// its outputs (`acc[t - first]` for output `t`), with AVX2 when `simd` is
/// given; the same bits either way. With `CHECK`, outputs outside `acc`
/// are skipped.
#[inline(always)]
pub(super) fn add_group<const CHECK: bool>(
    simd: Option<Simd>,
    group: &Group<'_>,
    first: u32,
    acc: &mut [Acc],
) {
    if let Some(tet) = group.as_tet() {
        return add_tet::<CHECK>(simd, &tet, first, acc);
    }
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = simd {
        return add_group_wide::<CHECK>(simd, group, first, acc);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    add_group_plain::<CHECK>(group, first, acc);
}

/// [`add_group`] for a group of a tet's shape.
#[inline(always)]
pub(super) fn add_tet<const CHECK: bool>(
    simd: Option<Simd>,
    tet: &Tet<'_>,
    first: u32,
    acc: &mut [Acc],
) {
    #[cfg(target_arch = "x86_64")]
    if let Some(s) = simd {
        use pulp::cast;
        let [p0, p1, p2] = tet.projections.each_ref().map(lanes);
        for (k, &t) in tet.targets.iter().enumerate() {
            if let Some(a) = slot::<CHECK>(acc, t, first) {
                let v = &tet.values[3 * k..3 * k + 3];
                let o = term(s, cast(*a), p0, v[0]);
                let o = term(s, o, p1, v[1]);
                *a = cast(term(s, o, p2, v[2]));
            }
        }
        return;
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    let [p0, p1, p2] = tet.projections;
    for (k, &t) in tet.targets.iter().enumerate() {
        if let Some(a) = slot::<CHECK>(acc, t, first) {
            let v = &tet.values[3 * k..3 * k + 3];
            for lane in 0..3 {
                a[lane] = a[lane] + p0[lane] * v[0] + p1[lane] * v[1] + p2[lane] * v[2];
            }
        }
    }
}

/// A point's coordinates in the first three of four lanes (the fourth, a
/// copy of z, feeds the accumulators' unread lane: one blend fewer than a
/// zero).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn lanes(q: &Point) -> pulp::f64x4 {
    pulp::cast([q.x, q.y, q.z, q.z])
}

/// `o + q v` lane by lane: a multiply, then an add.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn term(s: Simd, o: pulp::f64x4, q: pulp::f64x4, v: f64) -> pulp::f64x4 {
    s.add_f64x4(o, s.mul_f64x4(q, s.splat_f64x4(v)))
}

/// [`add_group`] one lane at a time.
#[inline(always)]
fn add_group_plain<const CHECK: bool>(group: &Group<'_>, first: u32, acc: &mut [Acc]) {
    let Group {
        projections: p,
        targets,
        values,
    } = *group;
    match p {
        // A tet's three rows: the common case, unrolled.
        [p0, p1, p2] => {
            for (&t, v) in targets.iter().zip(values.chunks_exact(3)) {
                let Some(a) = slot::<CHECK>(acc, t, first) else {
                    continue;
                };
                for lane in 0..3 {
                    a[lane] = a[lane] + p0[lane] * v[0] + p1[lane] * v[1] + p2[lane] * v[2];
                }
            }
        }
        _ => {
            for (&t, v) in targets.iter().zip(values.chunks_exact(p.len())) {
                let Some(a) = slot::<CHECK>(acc, t, first) else {
                    continue;
                };
                for (p, &v) in p.iter().zip(v) {
                    for lane in 0..3 {
                        a[lane] += p[lane] * v;
                    }
                }
            }
        }
    }
}

/// [`add_group`] four lanes at a time (AVX2).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn add_group_wide<const CHECK: bool>(s: Simd, group: &Group<'_>, first: u32, acc: &mut [Acc]) {
    use pulp::{cast, f64x4};
    let Group {
        projections: p,
        targets,
        values,
    } = *group;
    let term = |o: f64x4, q: f64x4, v: f64| term(s, o, q, v);
    match p {
        [p0, p1, p2] => {
            let (p0, p1, p2) = (lanes(p0), lanes(p1), lanes(p2));
            for (&t, v) in targets.iter().zip(values.chunks_exact(3)) {
                let Some(a) = slot::<CHECK>(acc, t, first) else {
                    continue;
                };
                let o = term(cast(*a), p0, v[0]);
                let o = term(o, p1, v[1]);
                *a = cast(term(o, p2, v[2]));
            }
        }
        [p0] => {
            let p0 = lanes(p0);
            for (&t, &v) in targets.iter().zip(values) {
                if let Some(a) = slot::<CHECK>(acc, t, first) {
                    *a = cast(term(cast(*a), p0, v));
                }
            }
        }
        _ => {
            for (&t, v) in targets.iter().zip(values.chunks_exact(p.len())) {
                let Some(a) = slot::<CHECK>(acc, t, first) else {
                    continue;
                };
                let mut o = cast(*a);
                for (q, &v) in p.iter().zip(v) {
                    o = term(o, lanes(q), v);
                }
                *a = cast(o);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::ProjectionScatter;
    use super::super::tests::element_operator;
    use super::*;

    /// The plain and the 4-wide path give the same bits, group by group
    /// (heights 1 to 4), with and without the range check.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn both_paths_give_the_same_bits() {
        let Some(simd) = pulp::x86::V3::try_new() else {
            return; // No AVX2 here: only the plain path runs.
        };
        let (b, columns) = element_operator(200, 500);
        let scatter = ProjectionScatter::new(&b).unwrap();
        let projections: Vec<Point> = (0..columns)
            .map(|i| {
                Point::new(
                    (i as f64).sin() * 1e3,
                    (i as f64 * 0.3).cos(),
                    1e-3 * i as f64,
                )
            })
            .collect();
        let groups = &scatter.groups;
        let mut heights = [false; 4];
        for (first, len) in [(0, 200), (50, 70)] {
            let mut plain = vec![[0.5, -0.25, 1e-3, 0.0]; len];
            let mut wide = plain.clone();
            let mut value_start = 0;
            for g in 0..groups.sources.len() {
                let group = groups.group(g, value_start, &projections);
                value_start += group.values.len();
                heights[group.projections.len() - 1] = true;
                if len == 200 {
                    add_group::<false>(None, &group, first, &mut plain);
                    add_group::<false>(Some(simd), &group, first, &mut wide);
                } else {
                    add_group::<true>(None, &group, first, &mut plain);
                    add_group::<true>(Some(simd), &group, first, &mut wide);
                }
            }
            let bits = |a: &[Acc]| -> Vec<[u64; 3]> {
                a.iter()
                    .map(|a| [a[0], a[1], a[2]].map(f64::to_bits))
                    .collect()
            };
            assert_eq!(bits(&plain), bits(&wide));
        }
        assert_eq!(heights, [true; 4]);
    }
}
