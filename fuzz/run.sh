#!/bin/sh
# Usage: fuzz/run.sh TARGET SECONDS [libFuzzer options...]
#
# Builds the fuzz target TARGET (scene, tetgen, obj, gmsh, medit,
# checkpoint, state) with coverage instrumentation, seeds its corpus from the
# repository's scenes, fixtures and fuzz/seeds/TARGET, and runs libFuzzer for
# SECONDS at the lowest priority, with a 10 s limit per input (a slower input
# is reported as a hang). The corpus grows in fuzz/corpus/TARGET, crashes go
# to fuzz/artifacts/TARGET, the log to fuzz/logs/TARGET.log; the last
# `#N DONE cov: ... ft: ...` line of the log is the run's summary.
# CARGO_TARGET_DIR (default: the repository's target/) is used with a
# `fuzz` subfolder.
#
# With FUZZ_WITH=cargo-fuzz the target is built and run by cargo-fuzz on the
# nightly toolchain instead (`cargo +nightly fuzz run`, AddressSanitizer,
# debug assertions, optimised), with the same corpus, options and log; it
# needs `cargo install cargo-fuzz` and a nightly toolchain.
set -eu
if [ $# -lt 2 ]; then
    echo "usage: $0 TARGET SECONDS [libFuzzer options...]" >&2
    exit 2
fi
target=$1
seconds=$2
shift 2
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
case $target in
scene | tetgen | obj | gmsh | medit | checkpoint | state) ;;
*)
    echo "$0: unknown target '$target' (scene, tetgen, obj, gmsh, medit, checkpoint, state)" >&2
    exit 2
    ;;
esac

with=${FUZZ_WITH:-build.sh}
case $with in
build.sh)
    "$here/build.sh" --bin "$target"
    triple=$(rustc -vV | sed -n 's/^host: //p')
    binary="${CARGO_TARGET_DIR:-$root/target}/fuzz/$triple/release/$target"
    ;;
cargo-fuzz)
    export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}/cargo-fuzz"
    (cd "$here" && cargo +nightly fuzz build --sanitizer address --debug-assertions "$target")
    triple=$(rustc +nightly -vV | sed -n 's/^host: //p')
    binary="$CARGO_TARGET_DIR/$triple/release/$target"
    ;;
*)
    echo "$0: FUZZ_WITH must be build.sh or cargo-fuzz, not '$with'" >&2
    exit 2
    ;;
esac

corpus="$here/corpus/$target"
artifacts="$here/artifacts/$target"
mkdir -p "$corpus" "$artifacts" "$here/logs"

# seed NAME FILE...: the concatenation of FILEs as one corpus entry.
seed() {
    name=$1
    shift
    cat "$@" >"$corpus/seed-$name"
}
# Files of the repository (scenes/, test fixtures) with an extension, small
# enough to mutate quickly.
files() {
    find "$root/scenes" "$root"/crates/*/tests -type f -name "*.$1" -size -32k 2>/dev/null | sort
}
printf '\000' >"$corpus/.nul"
printf '\001' >"$corpus/.one"
case $target in
scene)
    # First byte: even is TOML, odd is JSON.
    for f in $(files toml); do seed "$(basename "$f")" "$corpus/.nul" "$f"; done
    for f in $(files json); do seed "$(basename "$f")" "$corpus/.one" "$f"; done
    ;;
tetgen)
    # Mode byte (even: .ele, odd: .face), .node, NUL, elements.
    for node in $(files node); do
        base=${node%.node}
        [ -f "$base.ele" ] && seed "$(basename "$base").ele" "$corpus/.nul" "$node" "$corpus/.nul" "$base.ele"
        [ -f "$base.face" ] && seed "$(basename "$base").face" "$corpus/.one" "$node" "$corpus/.nul" "$base.face"
    done
    ;;
obj) for f in $(files obj); do seed "$(basename "$f")" "$f"; done ;;
gmsh) for f in $(files msh); do seed "$(basename "$f")" "$f"; done ;;
medit) for f in $(files mesh); do seed "$(basename "$f")" "$f"; done ;;
state) for f in $(files json); do grep -q '"positions"' "$f" && seed "$(basename "$f")" "$f"; done ;;
checkpoint) ;;
esac
rm -f "$corpus/.nul" "$corpus/.one"
if [ -d "$here/seeds/$target" ]; then
    for f in "$here/seeds/$target"/*; do seed "own-$(basename "$f")" "$f"; done
fi

cd "$here"
nice -n 19 "$binary" "$corpus" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix="$artifacts/" -print_final_stats=1 "$@" \
    2>&1 | tee "$here/logs/$target.log" | grep -E 'INITED|DONE|pulse|NEW_FUNC|ERROR|panicked|SUMMARY|Test unit written' || true
tail -n 40 "$here/logs/$target.log" | grep -E '^#[0-9]+.*DONE|stat::' || true
