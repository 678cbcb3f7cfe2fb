"""The overhead of a Python `step(1)` call: its time against `step(100)/100`
on the default scene (scenes/cantilever.toml), which runs the same steps
inside one call. The difference is what crossing from Python into Rust
costs per call (argument parsing, the GIL released and taken again).

    python python/benchmarks/step_overhead.py [--repeats 5] [--json]

With `--json` it prints one JSON object instead (what `cargo xtask
bench-report` reads).
"""

import argparse
import json
import platform
import time
from pathlib import Path

import projdyn

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "cantilever.toml"
STEPS = 100


def per_step(calls):
    """Median over repeats of seconds per step, for `calls(sim)` on a fresh
    simulation that runs STEPS steps."""

    def once():
        sim = projdyn.Simulation.from_scene(SCENE)
        sim.step(5)  # first-touch allocations out of the timing
        start = time.perf_counter()
        calls(sim)
        return (time.perf_counter() - start) / STEPS

    return once


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)

    def one_by_one(sim):
        for _ in range(STEPS):
            sim.step(1)

    def all_at_once(sim):
        sim.step(STEPS)

    def median(f):
        times = sorted(f() for _ in range(args.repeats))
        return times[len(times) // 2]

    single = median(per_step(one_by_one))
    batched = median(per_step(all_at_once))
    if args.json:
        print(
            json.dumps(
                {
                    "scene": SCENE.name,
                    "steps": STEPS,
                    "repeats": args.repeats,
                    "python": platform.python_version(),
                    "step1_us": single * 1e6,
                    "batched_us": batched * 1e6,
                }
            )
        )
        return
    print(f"scene: {SCENE.name}, {STEPS} steps, median of {args.repeats}")
    print(f"step(1):       {single * 1e6:9.1f} us per step")
    print(f"step(100)/100: {batched * 1e6:9.1f} us per step")
    print(f"overhead:      {(single - batched) * 1e6:9.1f} us per call ({100 * (single - batched) / batched:+.2f}%)")


if __name__ == "__main__":
    main()
