//! [`Stencil`]: a constraint's vertex indices held by value, for kinds that
//! store them more compactly than `usize` (tet strain's 32-bit indices).

use std::fmt;
use std::ops::Deref;

/// Largest `STENCIL` of any constraint kind (plate bending has 6):
/// [`crate::ConstraintSet`] checks it at compile time.
pub const MAX_STENCIL: usize = 8;

/// Up to [`MAX_STENCIL`] vertex indices, by value; dereferences to
/// `&[usize]`, so it reads like the slice a kind storing `usize` indices
/// lends ([`crate::Constraint::vertices`],
/// [`crate::ConstraintBlock::stencil`]). Formats as that slice.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Stencil {
    len: usize,
    vertices: [usize; MAX_STENCIL],
}

impl Stencil {
    /// The first `vertices.len()` of at most [`MAX_STENCIL`] entries
    /// (further ones are dropped: callers pass a kind's `STENCIL`, which
    /// `ConstraintSet` keeps at most `MAX_STENCIL`).
    pub fn new(vertices: &[usize]) -> Self {
        let len = vertices.len().min(MAX_STENCIL);
        let mut all = [0; MAX_STENCIL];
        all[..len].copy_from_slice(&vertices[..len]);
        Self { len, vertices: all }
    }

    /// Four 32-bit indices (a tetrahedron's), widened.
    #[inline]
    pub fn from_u32x4(vertices: [u32; 4]) -> Self {
        let mut all = [0; MAX_STENCIL];
        for (a, &v) in all.iter_mut().zip(&vertices) {
            // Lossless: `usize` is at least 32 bits on every target pd builds for.
            *a = v as usize;
        }
        Self {
            len: 4,
            vertices: all,
        }
    }
}

impl Deref for Stencil {
    type Target = [usize];

    #[inline]
    fn deref(&self) -> &[usize] {
        &self.vertices[..self.len]
    }
}

impl<'a> IntoIterator for &'a Stencil {
    type Item = &'a usize;
    type IntoIter = std::slice::Iter<'a, usize>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl fmt::Debug for Stencil {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&**self, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_prints_as_its_slice() {
        let s = Stencil::new(&[4, 1, 7]);
        assert_eq!(&*s, &[4, 1, 7]);
        assert_eq!(format!("{s:?}"), "[4, 1, 7]");
        let t = Stencil::from_u32x4([3, u32::MAX, 0, 9]);
        assert_eq!(&*t, &[3, u32::MAX as usize, 0, 9]);
        assert_eq!((&t).into_iter().count(), 4);
    }
}
