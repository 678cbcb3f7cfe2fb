//! Shared pieces of the robustness (fuzz) tests: the case count, and a
//! proptest strategy that mutates a valid input file.
//!
//! The readers must answer every input with `Ok` or an `Err`, never a
//! panic; proptest turns a panic inside a case into a failure and shrinks
//! it, and the shrunk input is kept in the test's `.proptest-regressions`
//! file.

// Each fuzz test crate uses only some of these helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::Config;

/// Cases per fuzz target: `PROPTEST_CASES` if set (for long runs, e.g.
/// `PROPTEST_CASES=100000 cargo test -p pd-io --test fuzz_tetgen`), else a
/// count that keeps each target to about a second in the dev profile.
pub fn config(default_cases: u32) -> Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default_cases);
    Config {
        cases,
        max_shrink_iters: 2000,
        ..Config::default()
    }
}

/// A fresh, empty directory for one fuzz target.
pub fn scratch_dir(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("pd-io-fuzz")
        .join(test);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A path inside the repository, from this crate's manifest directory.
pub fn repo_file(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(relative)
}

/// Replacement tokens that probe the edges of number and structure
/// handling: signs, zero, huge counts and indices, overflow to infinity,
/// subnormals, NaN spellings, wrong types.
const TOKENS: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1",
    "2",
    "3",
    "4",
    "5",
    "-4",
    "0.5",
    "1e309",
    "-1e309",
    "1e-320",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "2147483648",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999",
    "1.7976931348623157e308",
    "0x10",
    "\"x\"",
    "[]",
    "{}",
    "true",
    "",
    " ",
    "\n",
    "#",
    "\u{0}",
    "\u{feff}",
    "é",
];

/// One edit of a byte string.
#[derive(Debug, Clone)]
pub enum Mutation {
    /// Flip one bit of one byte.
    FlipBit(Index, u8),
    /// Set one byte.
    SetByte(Index, u8),
    /// Insert bytes.
    Insert(Index, Vec<u8>),
    /// Delete up to `len` bytes.
    Delete(Index, usize),
    /// Copy a range to another place.
    Duplicate(Index, usize, Index),
    /// Cut the input short.
    Truncate(Index),
    /// Replace a number (a run of `0-9 . e E + -` holding a digit) with one
    /// of [`TOKENS`].
    ReplaceNumber(Index, Index),
    /// Insert one of [`TOKENS`].
    InsertToken(Index, Index),
}

/// A strategy for one [`Mutation`].
pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<Index>(), 0u8..8).prop_map(|(i, b)| Mutation::FlipBit(i, b)),
        (any::<Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::SetByte(i, b)),
        (any::<Index>(), proptest::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        (any::<Index>(), 1usize..64).prop_map(|(i, n)| Mutation::Delete(i, n)),
        (any::<Index>(), 1usize..64, any::<Index>())
            .prop_map(|(i, n, j)| Mutation::Duplicate(i, n, j)),
        any::<Index>().prop_map(Mutation::Truncate),
        (any::<Index>(), any::<Index>()).prop_map(|(i, t)| Mutation::ReplaceNumber(i, t)),
        (any::<Index>(), any::<Index>()).prop_map(|(i, t)| Mutation::InsertToken(i, t)),
    ]
}

/// Byte ranges of the numbers in `bytes`.
fn numbers(bytes: &[u8]) -> Vec<(usize, usize)> {
    let is_number_byte =
        |b: u8| b.is_ascii_digit() || matches!(b, b'.' | b'e' | b'E' | b'+' | b'-');
    let mut ranges = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if is_number_byte(bytes[i]) {
            let start = i;
            while i < bytes.len() && is_number_byte(bytes[i]) {
                i += 1;
            }
            if bytes[start..i].iter().any(u8::is_ascii_digit) {
                ranges.push((start, i));
            }
        } else {
            i += 1;
        }
    }
    ranges
}

/// Applies `mutations` in order to a copy of `input`.
pub fn apply(input: &[u8], mutations: &[Mutation]) -> Vec<u8> {
    let mut bytes = input.to_vec();
    for m in mutations {
        // Positions index the current bytes (one past the end allowed for
        // insertions).
        let len = bytes.len();
        match m {
            Mutation::FlipBit(i, bit) if len > 0 => bytes[i.index(len)] ^= 1 << bit,
            Mutation::SetByte(i, b) if len > 0 => bytes[i.index(len)] = *b,
            Mutation::Insert(i, new) => {
                let at = i.index(len + 1);
                bytes.splice(at..at, new.iter().copied());
            }
            Mutation::Delete(i, n) if len > 0 => {
                let at = i.index(len);
                bytes.drain(at..(at + n).min(len));
            }
            Mutation::Duplicate(i, n, j) if len > 0 => {
                let at = i.index(len);
                let copy = bytes[at..(at + n).min(len)].to_vec();
                let to = j.index(len + 1);
                bytes.splice(to..to, copy);
            }
            Mutation::Truncate(i) => bytes.truncate(i.index(len + 1)),
            Mutation::ReplaceNumber(i, t) => {
                let ranges = numbers(&bytes);
                if !ranges.is_empty() {
                    let (start, end) = ranges[i.index(ranges.len())];
                    let token = TOKENS[t.index(TOKENS.len())].as_bytes();
                    bytes.splice(start..end, token.iter().copied());
                }
            }
            Mutation::InsertToken(i, t) => {
                let at = i.index(len + 1);
                let token = TOKENS[t.index(TOKENS.len())].as_bytes();
                bytes.splice(at..at, token.iter().copied());
            }
            _ => {}
        }
    }
    bytes
}

/// Up to `max` mutations.
pub fn mutations(max: usize) -> impl Strategy<Value = Vec<Mutation>> {
    proptest::collection::vec(mutation(), 1..=max)
}
