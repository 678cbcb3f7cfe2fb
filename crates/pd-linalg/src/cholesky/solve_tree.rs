//! How the supernodal solve splits its work between two threads: disjoint
//! subtrees of the supernodal elimination tree, dealt into two bins of
//! about equal cost, and the remaining top of the tree, which runs after
//! (forward) or before (backward) the bins, on one thread. A subtree's
//! columns need not be contiguous (faer does not always postorder the
//! tree), so each bin works on its own compact copy of its columns.
//!
//! The split depends only on the factor's structure, never on the number
//! of threads: with one thread the two bins run one after the other, so the
//! arithmetic, and the result, is the same bit for bit.

// The split balances stored values read plus the ordering's fitted fixed
// cost of a supernode (`SUPERNODE_COST`, docs/design/performance.md), the same
// model that chose the order.
use super::SUPERNODE_COST;

/// How many supernodes may be moved from the bins to the top while the
/// split is searched: each move takes the largest subtree apart.
const MAX_MOVES: usize = 256;

/// Below this total cost (stored values) a solve takes some tens of
/// microseconds and a split does not pay for handing work to a thread.
const MIN_SPLIT_COST: usize = 50_000;

/// A split is used only if its critical path is at most this fraction of
/// the whole solve.
const MAX_CRITICAL_PATH: f64 = 0.9;

/// Marks a column of the top in [`TreeSplit::slot`].
pub(crate) const TOP: u32 = u32::MAX;

/// The split: each bin's supernodes and columns (ascending), the top's
/// supernodes and columns (ascending), and where each column sits.
#[derive(Debug, Clone, Default)]
pub(crate) struct TreeSplit {
    pub bins: [Vec<usize>; 2],
    pub bin_columns: [Vec<usize>; 2],
    pub top: Vec<usize>,
    pub top_columns: Vec<usize>,
    /// A bin column's index in its bin's compact copy; [`TOP`] for a column
    /// of the top. Empty when the solve is not split.
    pub slot: Vec<u32>,
    /// A top column's position in `top_columns` (where each bin sums its
    /// updates of it); unused for bin columns. Empty when the solve is not
    /// split.
    pub top_position: Vec<u32>,
}

impl TreeSplit {
    /// The split for a factor whose supernode `s` holds columns
    /// `begin[s]..begin[s + 1]` and whose parent is `parent[s]` (`None` at a
    /// root), with `cost[s]` its stored values. No split (everything at the
    /// top, the plain sequential solve) when the factor is small, or no
    /// split shortens the critical path enough.
    pub fn new(begin: &[usize], parent: &[Option<usize>], cost: &[usize]) -> Self {
        let n = parent.len();
        let columns = begin.get(n).copied().unwrap_or(0);
        let cost: Vec<usize> = cost.iter().map(|c| c + SUPERNODE_COST).collect();
        let sequential = Self {
            top: (0..n).collect(),
            top_columns: (0..columns).collect(),
            ..Self::default()
        };
        let total: usize = cost.iter().sum();
        let fits = u32::try_from(columns).is_ok_and(|c| c < TOP);
        let Some(tree) = Tree::new(parent, &cost).filter(|_| total >= MIN_SPLIT_COST && fits)
        else {
            return sequential;
        };
        let Some((frontier, mut top)) = tree.best_split(total) else {
            return sequential;
        };
        let mut bins: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
        for (root, bin) in deal(&frontier, &tree.subtree_cost) {
            tree.collect_subtree(root, &mut bins[bin]);
        }
        let mut slot = vec![TOP; columns];
        let bin_columns = bins.each_mut().map(|bin| {
            bin.sort_unstable();
            let cols: Vec<usize> = bin.iter().flat_map(|&s| begin[s]..begin[s + 1]).collect();
            for (i, &c) in cols.iter().enumerate() {
                slot[c] = i as u32;
            }
            cols
        });
        top.sort_unstable();
        let top_columns: Vec<usize> = top.iter().flat_map(|&s| begin[s]..begin[s + 1]).collect();
        let mut top_position = vec![0; columns];
        for (i, &c) in top_columns.iter().enumerate() {
            top_position[c] = i as u32;
        }
        Self {
            bins,
            bin_columns,
            top,
            top_columns,
            slot,
            top_position,
        }
    }

    /// Whether the solve is split at all.
    pub fn is_split(&self) -> bool {
        !self.slot.is_empty()
    }
}

/// The elimination tree of the supernodes.
struct Tree {
    children: Vec<Vec<usize>>,
    roots: Vec<usize>,
    subtree_cost: Vec<usize>,
    cost: Vec<usize>,
}

impl Tree {
    /// `None` unless every parent comes after its children, as in any
    /// elimination tree (a guard against a layout this code does not know).
    fn new(parent: &[Option<usize>], cost: &[usize]) -> Option<Self> {
        let n = parent.len();
        let mut children = vec![Vec::new(); n];
        let mut roots = Vec::new();
        let mut subtree_cost = cost.to_vec();
        for s in 0..n {
            match parent[s] {
                Some(p) if p > s && p < n => {
                    children[p].push(s);
                    subtree_cost[p] += subtree_cost[s];
                }
                Some(_) => return None,
                None => roots.push(s),
            }
        }
        Some(Self {
            children,
            roots,
            subtree_cost,
            cost: cost.to_vec(),
        })
    }

    /// Appends every supernode of `root`'s subtree to `out`.
    fn collect_subtree(&self, root: usize, out: &mut Vec<usize>) {
        let mut stack = vec![root];
        while let Some(s) = stack.pop() {
            out.push(s);
            stack.extend(&self.children[s]);
        }
    }

    /// Takes the largest subtree apart (its root to the top, its children
    /// to the frontier) up to [`MAX_MOVES`] times and keeps the frontier
    /// whose two-bin critical path (top plus the heavier bin) is shortest.
    fn best_split(&self, total: usize) -> Option<(Vec<usize>, Vec<usize>)> {
        let mut frontier = self.roots.clone();
        let mut top = Vec::new();
        let mut top_cost = 0;
        let mut best: Option<(usize, Vec<usize>, Vec<usize>)> = None;
        for _ in 0..MAX_MOVES {
            let Some(i) = (0..frontier.len()).max_by_key(|&i| {
                (
                    self.subtree_cost[frontier[i]],
                    std::cmp::Reverse(frontier[i]),
                )
            }) else {
                break;
            };
            let s = frontier.swap_remove(i);
            top.push(s);
            top_cost += self.cost[s];
            frontier.extend(&self.children[s]);
            let heavier = deal(&frontier, &self.subtree_cost)
                .into_iter()
                .fold([0usize; 2], |mut load, (root, bin)| {
                    load[bin] += self.subtree_cost[root];
                    load
                })
                .into_iter()
                .max()
                .unwrap_or(0);
            let path = top_cost + heavier;
            if best.as_ref().is_none_or(|(b, _, _)| path < *b) {
                best = Some((path, frontier.clone(), top.clone()));
            }
        }
        let (path, frontier, top) = best?;
        (path as f64 <= MAX_CRITICAL_PATH * total as f64).then_some((frontier, top))
    }
}

/// Deals subtrees into two bins, heaviest first, each to the lighter bin
/// (ties to bin 0; equal costs in ascending root order): `(root, bin)`.
fn deal(roots: &[usize], subtree_cost: &[usize]) -> Vec<(usize, usize)> {
    let mut sorted = roots.to_vec();
    sorted.sort_unstable_by_key(|&r| (std::cmp::Reverse(subtree_cost[r]), r));
    let mut load = [0usize; 2];
    sorted
        .into_iter()
        .map(|root| {
            let bin = usize::from(load[1] < load[0]);
            load[bin] += subtree_cost[root];
            (root, bin)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A complete binary tree of `levels` levels in postorder, one column
    /// per supernode, every supernode costing `cost`.
    fn binary_tree(levels: u32, cost: usize) -> (Vec<usize>, Vec<Option<usize>>, Vec<usize>) {
        fn build(level: u32, parent: &mut Vec<Option<usize>>) -> usize {
            if level == 0 {
                parent.push(None);
                return parent.len() - 1;
            }
            let left = build(level - 1, parent);
            let right = build(level - 1, parent);
            parent.push(None);
            let me = parent.len() - 1;
            parent[left] = Some(me);
            parent[right] = Some(me);
            me
        }
        let mut parent = Vec::new();
        build(levels - 1, &mut parent);
        let n = parent.len();
        ((0..=n).collect(), parent, vec![cost; n])
    }

    #[test]
    fn a_balanced_tree_splits_below_its_root() {
        let (begin, parent, cost) = binary_tree(8, 1000);
        let split = TreeSplit::new(&begin, &parent, &cost);
        assert!(split.is_split());
        // Every supernode is in exactly one place, and the slots number
        // each bin's columns in order.
        let mut seen = vec![0; parent.len()];
        for s in split.top.iter().chain(&split.bins[0]).chain(&split.bins[1]) {
            seen[*s] += 1;
        }
        assert!(seen.iter().all(|&k| k == 1));
        for columns in &split.bin_columns {
            for (i, &c) in columns.iter().enumerate() {
                assert_eq!(split.slot[c], i as u32);
            }
        }
        for &c in &split.top_columns {
            assert_eq!(split.slot[c], TOP);
        }
        // The two halves under the root are the ideal split: the root alone
        // on top, one half per bin.
        assert_eq!(split.top, vec![parent.len() - 1]);
        assert_eq!(split.bins[0].len(), split.bins[1].len());
    }

    #[test]
    fn a_chain_or_a_small_factor_is_not_split() {
        let n = 100;
        let begin: Vec<usize> = (0..=n).collect();
        let chain: Vec<Option<usize>> = (0..n).map(|s| (s + 1 < n).then_some(s + 1)).collect();
        assert!(!TreeSplit::new(&begin, &chain, &vec![10_000; n]).is_split());
        let (begin, parent, cost) = binary_tree(4, 10);
        let small = TreeSplit::new(&begin, &parent, &cost);
        assert!(!small.is_split());
        assert_eq!(small.top, (0..parent.len()).collect::<Vec<_>>());
    }

    #[test]
    fn a_parent_before_its_child_is_not_split() {
        let begin = vec![0, 1, 2, 3];
        let parent = vec![None, Some(0), None];
        assert!(!TreeSplit::new(&begin, &parent, &[100_000; 3]).is_split());
    }
}
