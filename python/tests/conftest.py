"""Shared helpers of the projdyn tests: the repository's paths, the `pd`
command-line tool (run through cargo, as a user runs it), small meshes
made with NumPy and written as TetGen files."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "scenes"
# The shared folder sits beside the repository's checkout (CI copies it
# there too); the armadillo is not in every copy of it.
ARMADILLO = REPO.parent / "shared" / "meshes" / "armadillo" / "armadillo"


def pd(*args, cwd=REPO):
    """Runs the `pd` command-line tool of this repository with `args`."""
    command = ["cargo", "run", "--quiet", "--locked", "--", *map(str, args)]
    result = subprocess.run(command, cwd=cwd, capture_output=True, text=True)
    if result.returncode != 0:
        raise AssertionError(
            f"{' '.join(command)} failed ({result.returncode}):\n{result.stderr}"
        )
    return result


def pd_run(scene, steps, out):
    """`pd run SCENE --steps STEPS --out OUT`; returns the final state file."""
    pd("run", scene, "--steps", steps, "--out", out, "--quiet")
    with open(Path(out) / "final_state.json") as f:
        state = json.load(f)
    return (
        np.array(state["positions"], dtype=np.float64),
        np.array(state["velocities"], dtype=np.float64),
    )


def box_tets(size, cells):
    """A box of `cells` cubes filling `size` (m), six positively oriented
    tetrahedra per cube, made with NumPy (not by the package under test)."""
    nx, ny, nz = cells
    xs = np.linspace(0.0, size[0], nx + 1)
    ys = np.linspace(0.0, size[1], ny + 1)
    zs = np.linspace(0.0, size[2], nz + 1)
    grid = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), axis=-1).reshape(-1, 3)

    def index(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    # The six tetrahedra around the cube's diagonal from corner 0 to 7.
    paths = [(1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6)]
    tets = []
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                corner = [index(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)) for c in range(8)]
                for a, b in paths:
                    tet = [corner[0], corner[a], corner[b], corner[7]]
                    p = grid[tet]
                    if np.dot(p[1] - p[0], np.cross(p[2] - p[0], p[3] - p[0])) < 0:
                        tet[1], tet[2] = tet[2], tet[1]
                    tets.append(tet)
    return grid, np.array(tets, dtype=np.int64)


def write_tetgen(base, vertices, tets):
    """Writes BASE.node and BASE.ele (0-based, coordinates in repr, which
    reads back to the same bits)."""
    base = Path(base)
    with open(base.with_suffix(".node"), "w") as f:
        f.write(f"{len(vertices)} 3 0 0\n")
        for i, p in enumerate(vertices):
            f.write(f"{i} {float(p[0])!r} {float(p[1])!r} {float(p[2])!r}\n")
    with open(base.with_suffix(".ele"), "w") as f:
        f.write(f"{len(tets)} 4 0\n")
        for i, t in enumerate(tets):
            f.write(f"{i} {t[0]} {t[1]} {t[2]} {t[3]}\n")


def read_tetgen(base):
    """Reads BASE.node and BASE.ele with NumPy: vertices and 0-based tets
    (the node file's first index decides the base)."""

    def rows(path):
        lines = []
        with open(path) as f:
            for line in f:
                line = line.split("#", 1)[0].strip()
                if line:
                    lines.append(line.split())
        return lines

    node = rows(Path(str(base) + ".node"))
    ele = rows(Path(str(base) + ".ele"))
    count = int(node[0][0])
    nodes = np.array([[float(x) for x in r[1:4]] for r in node[1 : count + 1]])
    first = int(node[1][0])
    tet_count = int(ele[0][0])
    tets = np.array([[int(x) for x in r[1:5]] for r in ele[1 : tet_count + 1]], dtype=np.int64)
    return nodes, tets - first




def bits(a):
    """The exact bytes of a float64 array (so -0.0 and 0.0 differ)."""
    return np.ascontiguousarray(a, dtype=np.float64).tobytes()


