"""Errors: `ValueError` with the scene loader's messages naming the
argument, `DivergenceError` with the step and the reason."""

import numpy as np
import pytest

import projdyn
from conftest import SCENES, write_tetgen

TET = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def add(vertices, tets):
    projdyn.Model().add_body(vertices, tets=tets, density=1000.0)


def loader_message(tmp_path, vertices, tets, body=""):
    """The message of the scene loader for a scene naming these arrays as a
    TetGen file, without the file name it starts with."""
    write_tetgen(tmp_path / "m", vertices, tets)
    scene = tmp_path / "scene.toml"
    scene.write_text(
        "[simulation]\ndt = 0.01\nsteps = 1\n\n[[body]]\n"
        f'mesh = {{ file = "{tmp_path / "m.node"}" }}\ndensity = 1000.0\n{body}'
    )
    with pytest.raises(ValueError) as info:
        projdyn.Simulation.from_scene(scene)
    return str(info.value)


def test_vertices_not_n_by_3():
    with pytest.raises(ValueError, match=r"^vertices: expected an \(N, 3\) array, got shape \(4, 2\)$"):
        add(TET[:, :2], [[0, 1, 2, 3]])
    with pytest.raises(ValueError, match=r"^vertices: expected an \(N, 3\) array, got shape \(12,\)$"):
        add(TET.ravel(), [[0, 1, 2, 3]])


def test_nan_coordinate():
    vertices = TET.copy()
    vertices[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"^vertices: vertex 2 has a non-finite coordinate$"):
        add(vertices, [[0, 1, 2, 3]])


def test_tet_index_out_of_range():
    with pytest.raises(
        ValueError,
        match=r"^tets: tetrahedron 0 refers to vertex 9, but the mesh has 4 vertices$",
    ):
        add(TET, [[0, 1, 2, 9]])
    with pytest.raises(ValueError, match=r"^tets: row 0 has the negative index -1$"):
        add(TET, [[0, 1, 2, -1]])
    with pytest.raises(ValueError, match=r"^tets: expected an \(M, 4\) array of vertex indices, got shape \(1, 3\)$"):
        add(TET, [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"^tets: expected integer vertex indices, got an array of dtype float64$"):
        add(TET, [[0.0, 1.0, 2.0, 3.0]])


def test_inverted_tet_has_the_loaders_message(tmp_path):
    inverted = [[0, 2, 1, 3]]
    with pytest.raises(ValueError) as info:
        add(TET, inverted)
    message = str(info.value)
    assert message.startswith("tets: tetrahedron 0 has non-positive rest volume")
    # The scene loader reads the same tetrahedron from a file and says the
    # same after the file's name.
    loader = loader_message(tmp_path, TET, inverted)
    assert loader.endswith(message[len("tets: "):]), (loader, message)


def test_constraint_values_have_the_loaders_message_and_field(tmp_path):
    model = projdyn.Model()
    b = model.add_body(TET, tets=[[0, 1, 2, 3]], density=1000.0)
    model.add_tet_strain(b, stiffness=-5.0)
    with pytest.raises(ValueError) as info:
        projdyn.Simulation(model, dt=0.01)
    message = str(info.value)
    assert "body[0].constraints[0].stiffness" in message
    loader = loader_message(
        tmp_path, TET, [[0, 1, 2, 3]], 'constraints = [ { kind = "tet-strain", stiffness = -5.0 } ]\n'
    )
    # The same field and message after the source's name.
    assert message.split(": ", 1)[1] == loader.split(": ", 1)[1]


def test_simulation_keywords_are_checked_as_scene_keys():
    model = projdyn.Model()
    model.add_body(TET, tets=[[0, 1, 2, 3]], density=1000.0)
    with pytest.raises(ValueError, match=r"simulation\.dt: must be finite and > 0, got NaN"):
        projdyn.Simulation(model, dt=float("nan"))
    with pytest.raises(ValueError, match=r"simulation\.integrator: unknown integrator \"rk4\""):
        projdyn.Simulation(model, dt=0.01, integrator="rk4")
    with pytest.raises(ValueError, match=r"damping"):
        projdyn.Simulation(model, dt=0.01, damping={"model": "laplacian", "ratio": -1.0})
    with pytest.raises(ValueError, match=r"^dt: given both as a keyword and in simulation=$"):
        projdyn.Simulation(model, dt=0.01, simulation={"dt": 0.02})


def test_fixed_vertex_out_of_range_names_the_field():
    model = projdyn.Model()
    b = model.add_body(TET, tets=[[0, 1, 2, 3]], density=1000.0)
    model.fix(b, [7])
    with pytest.raises(ValueError, match=r"body\[0\]\.fixed"):
        projdyn.Simulation(model, dt=0.01)
    with pytest.raises(IndexError, match=r"^body: there is no body 3; the model has 1$"):
        model.fix(3, [0])


def test_missing_scene_file_is_an_os_error(tmp_path):
    with pytest.raises(OSError, match="nothing.toml"):
        projdyn.Simulation.from_scene(tmp_path / "nothing.toml")


def test_set_state_shapes():
    sim = projdyn.Simulation.from_scene(SCENES / "cantilever.toml")
    n = sim.num_vertices
    with pytest.raises(ValueError, match=rf"^positions: expected an \({n}, 3\) array, got shape \(3, 3\)$"):
        sim.set_state(np.zeros((3, 3)))
    bad = sim.positions
    bad[5, 0] = np.inf
    with pytest.raises(ValueError, match=r"positions of vertex 5 are not finite"):
        sim.set_state(bad)


def test_divergence_is_its_own_exception_with_step_and_reason():
    assert issubclass(projdyn.DivergenceError, RuntimeError)
    sim = projdyn.Simulation.from_scene(SCENES / "cantilever.toml")
    sim.step(2)
    before = sim.positions
    # Velocities near the largest float: one step moves a vertex to inf.
    sim.set_state(sim.positions, np.full((sim.num_vertices, 3), 1e308))
    with pytest.raises(projdyn.DivergenceError) as info:
        sim.step(5)
    error = info.value
    assert error.step == 3
    assert "not finite" in error.reason or "energy" in error.reason
    assert str(error.step) in str(error)
    # The simulation is left at the last good step.
    assert sim.steps == 2
