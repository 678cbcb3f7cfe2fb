"""The examples run, and say what they should: more damping leaves less
swing; the PNG written without matplotlib is a valid image."""

import importlib.util
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_damping_compare_png_without_matplotlib(tmp_path):
    compare = load("damping_compare")
    times, curves = compare.trajectories(steps=40)
    assert set(curves) == {"ether-drag", "pbd", "laplacian"}
    assert all(len(c) == 41 for c in curves.values())
    out = tmp_path / "plot.png"
    compare.write_png(out, curves, times, width=120, height=60)
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    assert (width, height) == (120, 60)
    # The image data: one filter byte and 3 bytes per pixel, every row.
    idat = data.index(b"IDAT")
    (length,) = struct.unpack(">I", data[idat - 4 : idat])
    pixels = zlib.decompress(data[idat + 4 : idat + 4 + length])
    assert len(pixels) == height * (1 + 3 * width)


def test_sweep_on_threads_damps_more_with_a_larger_ratio():
    sweep = load("damping_sweep")
    result = sweep.sweep_threads(ratios=[0.0, 0.2], steps=60, workers=2)
    # The undamped beam keeps nearly all its swing (implicit midpoint does
    # not damp); at ratio 0.2 of the first mode, over 0.4 s between the
    # thirds (about 0.4 periods at omega = 6.4 rad/s), the amplitude falls
    # by exp(-0.2 * 6.4 * 0.4) = 0.6: clearly less.
    assert result[0.2] < result[0.0]


def test_sweep_on_dask_matches_threads():
    pytest.importorskip("distributed", reason="Dask's distributed is not installed")
    sweep = load("damping_sweep")
    ratios = [0.0, 0.1]
    assert sweep.sweep_dask(ratios, steps=30) == sweep.sweep_threads(ratios, steps=30)
