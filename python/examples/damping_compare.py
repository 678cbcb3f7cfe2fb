"""The released cantilever under three damping models, notebook style.

The beam of ``scenes/cantilever_release.toml`` starts bent and swings
freely (no gravity). Each model is set to the same damping ratio of the
beam's first bending mode, so that they remove the same energy from that
mode; what differs is what they do to the rest of the motion:

- ``ether-drag`` (rate c = 2 zeta omega, 1/s) drags every velocity, rigid
  motion included;
- ``pbd`` (factor k = 1 - exp(-2 zeta omega dt) per step) removes a fraction
  of the non-rigid velocity each step;
- ``laplacian`` (ratio zeta) damps strain rates, more for higher modes.

The tip's vertical position over time is plotted with matplotlib when it
is installed, and otherwise drawn into a PNG by the small writer below.

    python python/examples/damping_compare.py [--steps 300] [--out damping_compare.png]
"""

import argparse
import math
import struct
import zlib
from pathlib import Path

import numpy as np

import projdyn

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "scenes" / "cantilever_release.toml"
TIP = 524  # the scene's probe: a vertex at the free end
RATIO = 0.05


def damping_models(omega, dt, ratio=RATIO):
    """The three models, each at damping ratio `ratio` of the mode of
    angular frequency `omega` (rad/s) at time step `dt` (s)."""
    rate = 2.0 * ratio * omega
    return {
        "ether-drag": {"model": "ether-drag", "rate": rate},
        "pbd": {"model": "pbd", "factor": 1.0 - math.exp(-rate * dt)},
        "laplacian": {"model": "laplacian", "ratio": ratio},
    }


def trajectories(steps, threads=1):
    """The tip's height (m) every step under each model, and the times (s)."""
    first = projdyn.modes(SCENE, count=1)
    omega, dt = first["modes"][0]["omega_rad_s"], first["dt"]
    curves = {}
    for name, damping in damping_models(omega, dt).items():
        sim = projdyn.Simulation.from_scene(SCENE, threads=threads, damping=damping)
        heights = [sim.positions[TIP, 1]]
        for _ in range(steps):
            sim.step()
            heights.append(sim.positions[TIP, 1])
        curves[name] = np.array(heights)
    return np.arange(steps + 1) * dt, curves


# Line colours of the PNG writer, in the order of the curves: blue,
# orange, green (matplotlib's first three).
COLOURS = [("blue", (31, 119, 180)), ("orange", (255, 127, 14)), ("green", (44, 160, 44))]


def write_png(path, curves, times, width=800, height=400):
    """A line plot of `curves` (name -> values over `times`) as an RGB PNG,
    written without any plotting package; the curves take `COLOURS` in
    order."""
    colours = [rgb for _, rgb in COLOURS]
    image = np.full((height, width, 3), 255, dtype=np.uint8)
    low = min(c.min() for c in curves.values())
    high = max(c.max() for c in curves.values())
    span = (high - low) or 1.0
    margin = 20

    def pixel(t, y):
        px = margin + (t - times[0]) / (times[-1] - times[0]) * (width - 2 * margin)
        py = height - margin - (y - low) / span * (height - 2 * margin)
        return int(round(px)), int(round(py))

    image[height - margin, margin : width - margin] = 0  # time axis
    image[margin : height - margin, margin] = 0  # height axis
    for colour, values in zip(colours, curves.values()):
        points = [pixel(t, y) for t, y in zip(times, values)]
        for (x0, y0), (x1, y1) in zip(points, points[1:]):
            n = max(abs(x1 - x0), abs(y1 - y0), 1)
            for i in range(n + 1):
                x = x0 + (x1 - x0) * i // n
                y = y0 + (y1 - y0) * i // n
                image[max(y - 1, 0) : y + 1, max(x - 1, 0) : x + 1] = colour
    rows = b"".join(b"\x00" + image[r].tobytes() for r in range(height))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b"")
    Path(path).write_bytes(png)


def plot(times, curves, out):
    """Plots with matplotlib if it is installed, else with `write_png`;
    returns which was used."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        write_png(out, curves, times)
        legend = ", ".join(f"{name} {colour}" for name, (colour, _) in zip(curves, COLOURS))
        return f"png writer: {legend}"
    fig, ax = plt.subplots(figsize=(8, 4))
    for name, values in curves.items():
        ax.plot(times, values, label=name)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tip height (m)")
    ax.set_title(f"Released cantilever, damping ratio {RATIO} of the first mode")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return "matplotlib"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--out", type=Path, default=Path("damping_compare.png"))
    args = parser.parse_args(argv)
    times, curves = trajectories(args.steps)
    how = plot(times, curves, args.out)
    for name, values in curves.items():
        print(f"{name:>10}: tip height at the end {values[-1]:+.4f} m, swing {np.ptp(values[len(values) // 2 :]):.4f} m in the second half")
    print(f"wrote {args.out} ({how})")


if __name__ == "__main__":
    main()
