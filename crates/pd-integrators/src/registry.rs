//! The registry of integrators: the one list of every integrator by name,
//! with a one-line summary and a constructor.
//!
//! Scene files, the command line, the benchmarks and xtask all reach the
//! integrators through this list; none of them names an integrator itself.
//! Each integrator's name is the `NAME` constant of its type, in its own
//! file.
//!
//! Adding an integrator: write its file with its type, its [`Integrator`]
//! implementation and its `NAME`; add a variant to [`IntegratorKind`] and
//! one [`Entry`] to `ENTRIES` here, at the same place in the order.
//!
//! ```
//! use pd_integrators::registry::{self, IntegratorKind};
//!
//! assert_eq!(
//!     registry::names(),
//!     ["backward-euler", "implicit-midpoint", "bdf2"]
//! );
//! let entry = registry::by_name("bdf2").expect("an integrator");
//! assert_eq!(entry.kind, IntegratorKind::Bdf2);
//! assert_eq!(entry.create().name(), "bdf2");
//! assert_eq!(registry::by_short_name("im").map(|e| e.name), Some("implicit-midpoint"));
//! assert!(registry::by_name("forward-euler").is_none());
//! ```

use crate::{BackwardEuler, Bdf2, ImplicitMidpoint, Integrator};

/// Integrators a scene can name: the key of the registry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum IntegratorKind {
    /// `backward-euler`.
    BackwardEuler,
    /// `implicit-midpoint`.
    ImplicitMidpoint,
    /// `bdf2`.
    Bdf2,
}

impl IntegratorKind {
    /// Every integrator, in registry order (the order scenes list them).
    pub const ALL: [IntegratorKind; 3] = [Self::BackwardEuler, Self::ImplicitMidpoint, Self::Bdf2];

    /// The registry entry of this integrator.
    pub fn entry(self) -> &'static Entry {
        // `ENTRIES` holds one entry per kind, in the order of `ALL`
        // (its length is `ALL.len()`; a unit test checks the order).
        &ENTRIES[self as usize]
    }

    /// The name scenes use.
    pub fn name(self) -> &'static str {
        self.entry().name
    }

    /// The integrator a scene name stands for.
    pub fn parse(name: &str) -> Option<Self> {
        by_name(name).map(|e| e.kind)
    }

    /// A fresh integrator of this kind.
    pub fn create(self) -> Box<dyn Integrator> {
        self.entry().create()
    }
}

/// One integrator of the registry.
#[derive(Debug, Clone, Copy)]
pub struct Entry {
    /// Its kind.
    pub kind: IntegratorKind,
    /// The name, the type's `NAME` (`backward-euler`).
    pub name: &'static str,
    /// The short name the benchmark probe takes and reports (`be`).
    pub short_name: &'static str,
    /// What it is, one line.
    pub summary: &'static str,
    build: fn() -> Box<dyn Integrator>,
}

impl Entry {
    /// A fresh integrator of this entry (without history).
    pub fn create(&self) -> Box<dyn Integrator> {
        (self.build)()
    }
}

/// Every integrator, in the order of [`IntegratorKind::ALL`].
static ENTRIES: [Entry; IntegratorKind::ALL.len()] = [
    Entry {
        kind: IntegratorKind::BackwardEuler,
        name: BackwardEuler::NAME,
        short_name: "be",
        summary: "backward Euler: first order, numerical damping of about h omega / 2",
        build: || Box::new(BackwardEuler::new()),
    },
    Entry {
        kind: IntegratorKind::ImplicitMidpoint,
        name: ImplicitMidpoint::NAME,
        short_name: "im",
        summary: "implicit midpoint: second order and symplectic, no numerical damping",
        build: || Box::new(ImplicitMidpoint::new()),
    },
    Entry {
        kind: IntegratorKind::Bdf2,
        name: Bdf2::NAME,
        short_name: "bdf2",
        summary: "BDF-2: second order, two-step (its first step is backward Euler)",
        build: || Box::new(Bdf2::new()),
    },
];

/// Every integrator, in registry order.
pub fn entries() -> &'static [Entry] {
    &ENTRIES
}

/// The names of every integrator, in registry order.
pub fn names() -> [&'static str; IntegratorKind::ALL.len()] {
    ENTRIES.each_ref().map(|e| e.name)
}

/// The short names of every integrator (`be`, `im`, `bdf2`), in registry
/// order.
pub fn short_names() -> [&'static str; IntegratorKind::ALL.len()] {
    ENTRIES.each_ref().map(|e| e.short_name)
}

/// The integrator called `name`.
pub fn by_name(name: &str) -> Option<&'static Entry> {
    ENTRIES.iter().find(|e| e.name == name)
}

/// The integrator whose short name is `short_name`.
pub fn by_short_name(short_name: &str) -> Option<&'static Entry> {
    ENTRIES.iter().find(|e| e.short_name == short_name)
}

#[cfg(test)]
mod tests {
    use super::{ENTRIES, IntegratorKind, by_name};

    #[test]
    fn entries_follow_the_kinds_and_build_their_integrator() {
        for (entry, kind) in ENTRIES.iter().zip(IntegratorKind::ALL) {
            assert_eq!(entry.kind, kind);
            assert_eq!(kind.entry().name, entry.name);
            assert_eq!(entry.create().name(), entry.name);
            assert_eq!(IntegratorKind::parse(entry.name), Some(kind));
            assert_eq!(by_name(entry.name).map(|e| e.kind), Some(kind));
        }
    }
}
