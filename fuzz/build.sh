#!/bin/sh
# Builds every fuzz target with libFuzzer's coverage instrumentation on the
# stable toolchain (no -Z flags: sanitizer-coverage passes through codegen
# options). AddressSanitizer needs -Zsanitizer=address (nightly), so it is
# not used; Rust's own bounds and overflow checks still abort on misuse.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$here/../target}/fuzz"
export RUSTFLAGS="--cfg fuzzing -Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 -Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table -Cllvm-args=-sanitizer-coverage-trace-compares -Cdebug-assertions -Coverflow-checks"
cd "$here"
# An explicit --target keeps RUSTFLAGS off build scripts and proc macros
# (they run on the host and have no libFuzzer runtime to link).
cargo build --release --locked --target "$(rustc -vV | sed -n "s/^host: //p")" "$@"
