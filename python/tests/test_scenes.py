"""`Simulation.from_scene` against `pd run`: the same scene and step count
give the same final state, bit for bit, and the same output files."""

import json
from pathlib import Path

import numpy as np
import pytest

import projdyn
from conftest import SCENES, bits, pd_run

# Enough steps for every scene to move (contact scenes reach their
# collider within them is not needed: any difference in the step shows at
# once), few enough that the whole file runs in seconds.
STEPS = 12

ALL_SCENES = sorted(SCENES.glob("*.toml"))


def test_every_bundled_scene_is_covered():
    assert len(ALL_SCENES) >= 10, ALL_SCENES


@pytest.mark.parametrize("scene", ALL_SCENES, ids=lambda p: p.stem)
def test_from_scene_matches_pd_run_bit_for_bit(scene, tmp_path):
    positions, velocities = pd_run(scene, STEPS, tmp_path / "cli")
    with open(tmp_path / "cli" / "summary.json") as f:
        accuracy = json.load(f)["accuracy"]
    # A scene with an accuracy target and no method has it chosen by a
    # timed probe, which two runs may decide differently on a busy
    # machine: the simulation takes the method the run chose, as `pd
    # resume` does.
    solver = {"method": accuracy["method"]} if accuracy["method_probe"] else None
    sim = projdyn.Simulation.from_scene(scene, solver=solver)
    assert sim.method == accuracy["method"]
    sim.step(STEPS)
    assert sim.steps == STEPS
    assert sim.positions.shape == positions.shape
    assert bits(sim.positions) == bits(positions)
    assert bits(sim.velocities) == bits(velocities)


def test_run_writes_the_folder_pd_run_writes(tmp_path):
    scene = SCENES / "cantilever.toml"
    pd_run(scene, 10, tmp_path / "cli")
    sim = projdyn.Simulation.from_scene(scene, steps=10)
    sim.run(tmp_path / "py")
    assert sim.steps == 10
    cli, py = tmp_path / "cli", tmp_path / "py"
    names = lambda d: sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.is_file())
    assert names(py) == names(cli)
    # Frames and the final state hold no timing: identical bytes.
    for name in names(cli):
        if name.startswith("frames/") or name in ("final_state.json", "probes.csv"):
            assert (py / name).read_bytes() == (cli / name).read_bytes(), name
    # metrics.csv: every column but the wall-clock times is the same.
    def untimed(path):
        rows = [line.split(",") for line in path.read_text().splitlines()]
        keep = [i for i, h in enumerate(rows[0]) if not h.endswith("_ms")]
        return [[r[i] for i in keep] for r in rows]

    assert untimed(py / "metrics.csv") == untimed(cli / "metrics.csv")


def test_save_frame_matches_the_frames_of_pd_run(tmp_path):
    scene = SCENES / "cantilever.toml"
    pd_run(scene, 5, tmp_path / "cli")
    sim = projdyn.Simulation.from_scene(scene)
    sim.save_frame(tmp_path / "start.vtk")
    sim.step(5)
    sim.save_frame(tmp_path / "end.obj")
    frames = tmp_path / "cli" / "frames"
    assert (tmp_path / "start.vtk").read_bytes() == (frames / "frame_00000.vtk").read_bytes()
    # The scene writes a frame every 5 steps.
    assert (tmp_path / "end.obj").read_bytes() == (frames / "frame_00001.obj").read_bytes()


def test_save_frame_names_an_unknown_format(tmp_path):
    sim = projdyn.Simulation.from_scene(SCENES / "cantilever.toml")
    with pytest.raises(ValueError, match=r"unknown frame format \"xyz\""):
        sim.save_frame(tmp_path / "frame.xyz")


def test_modes_match_pd_modes(tmp_path):
    import json

    from conftest import pd

    scene = SCENES / "cantilever.toml"
    pd("modes", scene, "--count", 3, "--out", tmp_path / "modes")
    with open(tmp_path / "modes" / "modes.json") as f:
        cli = json.load(f)
    for source in (scene, projdyn.Simulation.from_scene(scene)):
        report = projdyn.modes(source, count=3)
        assert report["frequencies_hz"] == cli["frequencies_hz"]
        assert report["damping_ratios"] == cli["damping_ratios"]
        assert len(report["modes"]) == 3
        assert "animation" not in report["modes"][0]
