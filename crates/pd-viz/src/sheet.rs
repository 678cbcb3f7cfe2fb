//! Open surfaces (cloth and shells): their boundary edges, drawn as an
//! outline, and the tint that tells a sheet's back from its front. A
//! closed surface (the boundary of a solid) has no boundary edge and is
//! drawn exactly as before.

/// The edges used by exactly one triangle, each as a sorted vertex pair,
/// in sorted order (so the drawing does not depend on triangle order).
pub(crate) fn open_edges(triangles: &[[usize; 3]]) -> Vec<[usize; 2]> {
    let mut edges: Vec<[usize; 2]> = triangles
        .iter()
        .flat_map(|t| (0..3).map(move |j| [t[j].min(t[(j + 1) % 3]), t[j].max(t[(j + 1) % 3])]))
        .collect();
    edges.sort_unstable();
    let mut open = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j] == edges[i] {
            j += 1;
        }
        if j - i == 1 {
            open.push(edges[i]);
        }
        i = j;
    }
    open
}

/// The colour of a sheet's back side: the front colour mixed 45 % with
/// white, so that the two sides of a folded cloth read apart.
pub(crate) fn back_side(colour: [f64; 3]) -> [f64; 3] {
    colour.map(|c| 0.55 * c + 0.45 * 255.0)
}

/// The outline colour of a sheet: its colour darkened to 45 %.
pub(crate) fn outline(colour: [f64; 3]) -> [u8; 3] {
    colour.map(|c| (0.45 * c).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boundary_of_a_square_and_of_a_closed_tetrahedron() {
        let square = [[0, 1, 2], [0, 2, 3]];
        assert_eq!(open_edges(&square), vec![[0, 1], [0, 3], [1, 2], [2, 3]]);
        let tetrahedron = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        assert!(open_edges(&tetrahedron).is_empty());
    }
}
