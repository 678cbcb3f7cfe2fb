//! METIS's multilevel nested dissection (`METIS_NodeND`, the ordering
//! CHOLMOD uses by default) through the raw bindings of `metis-sys`, which
//! builds METIS from vendored C source with 32-bit indices.
//!
//! This is the crate's only foreign call, hence `unsafe` code (the only
//! other is the call into the solve's AVX-512 function, `solve_wide.rs`):
//! the arrays handed to METIS are owned, correctly sized Rust vectors, and
//! METIS keeps no pointer to them after it returns.
#![allow(unsafe_code)]

use metis_sys::{
    METIS_NOPTIONS, METIS_NodeND, METIS_SetDefaultOptions, idx_t,
    moptions_et_METIS_OPTION_NUMBERING, rstatus_et_METIS_OK,
};

/// METIS's fill-reducing order of the graph with adjacency `(start,
/// neighbours)` (symmetric, no self loops; see `super::adjacency`), as old
/// indices in pivot order, or `None` if the graph is too large for 32-bit
/// indices or METIS reports an error. Deterministic: METIS's default options
/// use a fixed random seed.
pub(super) fn node_nd(start: &[usize], neighbours: &[usize]) -> Option<Vec<usize>> {
    node_nd_with(start, neighbours, &[])
}

/// [`node_nd`] with some of METIS's options set: `(option, value)` pairs,
/// `option` one of `metis_sys`' `moptions_et_METIS_OPTION_*` indices (the
/// numbering option is set to 0 first and must not be overridden).
pub(super) fn node_nd_with(
    start: &[usize],
    neighbours: &[usize],
    overrides: &[(i32, idx_t)],
) -> Option<Vec<usize>> {
    let n = start.len().checked_sub(1)?;
    let to_idx = |x: usize| idx_t::try_from(x).ok();
    let mut vertices = to_idx(n)?;
    to_idx(neighbours.len())?;
    let mut xadj: Vec<idx_t> = start.iter().map(|&s| to_idx(s)).collect::<Option<_>>()?;
    let mut adjncy: Vec<idx_t> = neighbours
        .iter()
        .map(|&v| to_idx(v))
        .collect::<Option<_>>()?;
    let mut options = [0 as idx_t; METIS_NOPTIONS as usize];
    // SAFETY: `options` has the METIS_NOPTIONS entries METIS writes.
    let status = unsafe { METIS_SetDefaultOptions(options.as_mut_ptr()) };
    if status != rstatus_et_METIS_OK {
        return None;
    }
    options[moptions_et_METIS_OPTION_NUMBERING as usize] = 0;
    for &(option, value) in overrides {
        options[option as usize] = value;
    }
    let mut perm: Vec<idx_t> = vec![0; n];
    let mut iperm: Vec<idx_t> = vec![0; n];
    // SAFETY: `xadj` has n + 1 entries and `adjncy` xadj[n] entries, all
    // below n (the adjacency of an n-vertex pattern); `perm` and `iperm`
    // have n entries; a null vertex-weight pointer means unit weights.
    let status = unsafe {
        METIS_NodeND(
            &mut vertices,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != rstatus_et_METIS_OK {
        return None;
    }
    // METIS's `perm[new] = old`; checked to be a permutation before faer
    // sees it.
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for &old in &perm {
        let old = usize::try_from(old).ok().filter(|&v| v < n && !seen[v])?;
        seen[old] = true;
        order.push(old);
    }
    Some(order)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_a_path_as_a_permutation_with_a_separator_last() {
        // A path 0 - 1 - ... - 999: nested dissection eliminates its top
        // separator, one vertex that splits the path into two nearly
        // balanced halves, last (METIS orders only parts below about 120
        // vertices by minimum degree, so the path must be longer).
        let n = 1000;
        let mut start = vec![0];
        let mut neighbours = Vec::new();
        for v in 0..n {
            if v > 0 {
                neighbours.push(v - 1);
            }
            if v + 1 < n {
                neighbours.push(v + 1);
            }
            start.push(neighbours.len());
        }
        let order = node_nd(&start, &neighbours).expect("a valid graph");
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>());
        let last = *order.last().unwrap();
        assert!((n / 4..3 * n / 4).contains(&last), "last pivot {last}");
    }
}
