//! The part of [`BodyContact`] that counts contacts: the contact counts of
//! [`BodyContact::detect`] (the number of contacts each vertex takes part
//! in, which shares the Uzawa steps) and the list of paired vertices, kept
//! from one iteration to the next within a step (docs/design/contact.md,
//! "Detection and the broad phase"), and the order in which the pairs are
//! visited ([`BodyContact::pair_slots`]).
//!
//! Why it is the same as a pass over every vertex. Within a step, contacts
//! are only added: a pair is made only for a vertex without one (by
//! detection, which lists it in `found`), and dropped only at a step's
//! start or a restore (which clear `counted`); a collider contact is never
//! dropped within a step, so this iteration's list of collider contacts
//! holds the last one's. A count is a sum of integers over the contacts,
//! so adding the new contacts' terms to the last counts gives the full
//! pass's integers; `paired` gets the new vertices merged in increasing
//! order. The first detection of a step (and any after a restore) takes
//! the full pass. Also the active pairs of a step's report.

use pd_mesh::Point;

use super::BodyContact;

impl BodyContact {
    /// Updates `count` and `paired` for this iteration's contacts:
    /// `collider` lists the vertices holding a collider contact (each
    /// once), `found` the vertices that got a pair in this detection.
    pub(super) fn count_contacts(&mut self, collider: &[usize]) {
        if !self.counted {
            self.count_every_vertex(collider);
            self.counted = true;
            return;
        }
        for &v in collider {
            if !self.has_collider[v] {
                self.has_collider[v] = true;
                self.count[v] += 1;
            }
        }
        if self.found.is_empty() {
            return;
        }
        for k in 0..self.found.len() {
            let v = self.found[k];
            self.add_pair_terms(v);
        }
        // Both lists are in increasing order and disjoint (a vertex found
        // had no pair): merged from the back, in place.
        let (old, new) = (self.paired.len(), self.found.len());
        self.paired.resize(old + new, 0);
        let (mut i, mut j) = (old, new);
        for slot in (0..old + new).rev() {
            let from_new = j > 0 && (i == 0 || self.found[j - 1] > self.paired[i - 1]);
            self.paired[slot] = if from_new {
                j -= 1;
                self.found[j]
            } else {
                i -= 1;
                self.paired[i]
            };
        }
    }

    /// The counts and `paired` from a pass over every vertex.
    fn count_every_vertex(&mut self, collider: &[usize]) {
        // Counts are integers: the order they are taken in changes nothing.
        self.count.iter_mut().for_each(|c| *c = 0);
        self.has_collider.iter_mut().for_each(|c| *c = false);
        for &v in collider {
            self.count[v] = 1;
            self.has_collider[v] = true;
        }
        self.paired.clear();
        for v in 0..self.pairs.len() {
            if self.pairs[v].is_some() {
                self.paired.push(v);
                self.add_pair_terms(v);
            }
        }
    }

    /// Adds vertex `v`'s pair to the counts: one at `v`, one at each
    /// triangle vertex of non-zero weight.
    fn add_pair_terms(&mut self, v: usize) {
        let Some(p) = &self.pairs[v] else { return };
        self.count[v] += 1;
        for (&i, &w) in self.faces[p.face].vertices.iter().zip(&p.weights) {
            self.count[i] += u32::from(w != 0.0);
        }
    }

    /// The pair slots a pass over the pairs visits, in increasing order:
    /// with `listed`, the `k`-th of the count is `paired[k]` (while the
    /// counts are current, `paired` holds exactly the vertices with a
    /// pair: pairs are added only by detection, which lists them, and
    /// dropped only by a step's start or a restore, which clear
    /// `counted`), otherwise `k` itself (every slot). The other slots are
    /// empty, so a pass that skips empty slots does the same in the same
    /// order ([`BodyContact::pair_slot`]).
    pub(super) fn pair_slots(&self) -> (bool, usize) {
        if self.counted {
            (true, self.paired.len())
        } else {
            (false, self.pairs.len())
        }
    }

    /// The `k`-th slot visited ([`BodyContact::pair_slots`]).
    #[inline]
    pub(super) fn pair_slot(&self, k: usize, listed: bool) -> usize {
        if listed { self.paired[k] } else { k }
    }

    /// Active pairs and the deepest penetration (below the thickness) of
    /// a pair at `positions`, m.
    pub fn report(&self, positions: &[Point], thickness: f64) -> (usize, f64) {
        let mut deepest = 0.0_f64;
        let mut active = 0;
        let (listed, count) = self.pair_slots();
        for v in (0..count).map(|k| self.pair_slot(k, listed)) {
            let Some(pair) = &self.pairs[v] else { continue };
            active += usize::from(pair.active());
            let tri = self.faces[pair.face].vertices;
            let r = positions[v]
                - (0..3)
                    .map(|k| positions[tri[k]] * pair.weights[k])
                    .sum::<Point>();
            deepest = deepest.max(thickness - pair.normal.dot(&r));
        }
        (active, deepest)
    }
}
