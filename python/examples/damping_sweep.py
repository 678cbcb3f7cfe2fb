"""A parameter sweep over a damping-ratio grid, in parallel.

Each job builds the released cantilever (``scenes/cantilever_release.toml``)
with Laplacian damping at one ratio, runs it, and returns how much of the
initial swing is left. ``Simulation.step`` releases the GIL, so a
``concurrent.futures.ThreadPoolExecutor`` runs the jobs on all cores of one
machine without copying anything between processes.

The same function runs on a Dask cluster unchanged: ``sweep_dask`` uses a
``LocalCluster(processes=False)`` (threads in this process) when the
``distributed`` package is installed. To spread the sweep over many
machines, point ``Client`` at a real scheduler instead (``Client("tcp://
scheduler:8786")``) with projdyn installed on the workers.

    python python/examples/damping_sweep.py [--steps 150] [--workers 2] [--dask]
"""

import argparse
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

import projdyn

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "scenes" / "cantilever_release.toml"
TIP = 524
RATIOS = [0.0, 0.01, 0.02, 0.05, 0.1, 0.2]


def job(ratio, steps=150):
    """The released beam with Laplacian damping at `ratio`: the tip's swing
    (peak to peak, m) over the last third of `steps`, against the first."""
    sim = projdyn.Simulation.from_scene(
        SCENE, threads=1, damping={"model": "laplacian", "ratio": ratio}
    )
    heights = np.empty(steps + 1)
    heights[0] = sim.positions[TIP, 1]
    for i in range(1, steps + 1):
        sim.step()
        heights[i] = sim.positions[TIP, 1]
    third = steps // 3
    return float(np.ptp(heights[-third:]) / np.ptp(heights[:third]))


def sweep_threads(ratios=RATIOS, steps=150, workers=2):
    """The sweep on a thread pool: {ratio: swing left}."""
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return dict(zip(ratios, pool.map(lambda r: job(r, steps), ratios)))


def sweep_dask(ratios=RATIOS, steps=150, workers=2):
    """The same sweep on a Dask cluster of threads in this process."""
    from dask.distributed import Client, LocalCluster

    with LocalCluster(processes=False, n_workers=1, threads_per_worker=workers) as cluster:
        with Client(cluster) as client:
            futures = client.map(job, ratios, steps=steps, pure=False)
            return dict(zip(ratios, client.gather(futures)))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=150)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dask", action="store_true", help="run on a Dask LocalCluster")
    args = parser.parse_args(argv)
    sweep = sweep_dask if args.dask else sweep_threads
    for ratio, left in sweep(steps=args.steps, workers=args.workers).items():
        print(f"ratio {ratio:5.2f}: {100 * left:5.1f}% of the swing left")


if __name__ == "__main__":
    main()
