//! The part of [`BodyContact`] that prepares a step's fast detection: the
//! live candidate entries (docs/design/contact.md, "Detection and the
//! broad phase"), each listed entry's start plane and start verdict, taken
//! once per step, and the entries that can give a pair, compacted vertex
//! by vertex for the fast detection of `bodies/listed.rs`.

use pd_mesh::Point;

use super::BodyContact;
use super::listed::{StartHit, start_hit};

/// A candidate entry that can give a pair in this step (it has a start
/// plane and is not [`StartHit::Never`]), with what the step's start told
/// of it ([`BodyContact::fill_start_planes`]): the fast detection visits
/// these only, in the lists' order.
#[derive(Debug, Clone, Copy)]
pub(super) struct LiveEntry {
    pub(super) face: usize,
    pub(super) plane: (Point, f64),
    pub(super) known: StartHit,
}

impl BodyContact {
    /// Each candidate entry's start verdict for this step, from its start plane
    /// ([`BodyContact::start_plane`]: it depends on `x_n` only), for the
    /// vertices with candidates and without a pair (pairs are dropped only
    /// at a step's start or a restore, which clear `start_planes_fresh`,
    /// so no other vertex searches before the next fill), and the
    /// vertices of their candidates (`needed`).
    pub(super) fn fill_start_planes(&mut self, x_n: &[Point], thickness: f64) {
        self.start_hits.clear();
        self.start_hits
            .resize(self.candidates.entry_count(), StartHit::Unknown);
        self.needed.clear();
        self.live.clear();
        self.live_vertices.clear();
        self.live_of.clear();
        self.live_of.resize(x_n.len(), (0, 0));
        for &v in self.candidates.listed() {
            if self.pairs[v].is_some() {
                continue;
            }
            let from = self.live.len();
            for e in self.candidates.entries(v) {
                let face = self.faces[self.candidates.face(e)];
                let [i, j, k] = face.vertices;
                let start = [x_n[i], x_n[j], x_n[k]];
                let Some(plane) = self.start_plane(&face, &start, &x_n[v], thickness) else {
                    continue;
                };
                // An entry without a start plane or never hit reads no
                // segment box.
                self.start_hits[e] = start_hit(plane, &start, &x_n[v], thickness);
                if let StartHit::Never = self.start_hits[e] {
                    continue;
                }
                self.live.push(LiveEntry {
                    face: self.candidates.face(e),
                    plane,
                    known: self.start_hits[e],
                });
                for i in face.vertices {
                    if !self.in_needed[i] {
                        self.in_needed[i] = true;
                        self.needed.push(i);
                    }
                }
            }
            // Counts far below `u32::MAX`: at most the entries of the lists,
            // which `Candidates::build` keeps below it.
            if self.live.len() > from {
                self.live_of[v] = (from as u32, self.live.len() as u32);
                self.live_vertices.push(v);
            }
        }
        for &i in &self.needed {
            self.in_needed[i] = false;
        }
        self.start_planes_fresh = true;
    }
}
