"""`projdyn.Model`: a model built from NumPy arrays is the model the scene
loader builds from a file naming the same mesh; simulations take copies;
arrays out are copies; pickling round-trips bit for bit."""

import pickle

import numpy as np
import pytest

import projdyn
from conftest import ARMADILLO, SCENES, bits, box_tets, read_tetgen, write_tetgen

# The scene both ways: a beam clamped at x = 0 with Laplacian damping.
SETTINGS = dict(dt=0.01, integrator="implicit-midpoint", iterations=10, tolerance=0.0, threads=1)
DAMPING = {"model": "laplacian", "ratio": 0.05}


def scene_text(mesh_file, clamp_max_x):
    return f"""
[simulation]
dt = 0.01
steps = 10
integrator = "implicit-midpoint"
iterations = 10
tolerance = 0.0
threads = 1

[damping]
model = "laplacian"
ratio = 0.05

[[body]]
mesh = {{ file = "{mesh_file}" }}
density = 1000.0
constraints = [ {{ kind = "tet-strain", stiffness = 1.0e6 }} ]
fixed = {{ box = {{ min = [-1e9, -1e9, -1e9], max = [{clamp_max_x!r}, 1e9, 1e9] }} }}
"""


def model_of(vertices, tets, clamp_max_x):
    model = projdyn.Model()
    b = model.add_body(vertices, tets=tets, density=1000.0)
    model.add_tet_strain(b, stiffness=1.0e6)
    model.fix(b, np.flatnonzero(vertices[:, 0] <= clamp_max_x))
    return model


def compare_model_and_scene(tmp_path, vertices, tets, scene_mesh, clamp_max_x, steps):
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text(scene_mesh, clamp_max_x))
    from_file = projdyn.Simulation.from_scene(scene)
    from_arrays = projdyn.Simulation(model_of(vertices, tets, clamp_max_x), damping=DAMPING, **SETTINGS)
    assert bits(from_arrays.positions) == bits(from_file.positions)
    from_file.step(steps)
    from_arrays.step(steps)
    assert bits(from_arrays.positions) == bits(from_file.positions)
    assert bits(from_arrays.velocities) == bits(from_file.velocities)
    assert from_arrays.energies() == from_file.energies()


def test_model_from_arrays_equals_the_scene_naming_the_file(tmp_path):
    vertices, tets = box_tets([1.0, 0.2, 0.2], [10, 2, 2])
    write_tetgen(tmp_path / "beam", vertices, tets)
    compare_model_and_scene(tmp_path, vertices, tets, tmp_path / "beam.node", 1e-3, steps=10)


def test_armadillo_from_numpy_equals_the_scene_naming_it(tmp_path):
    if not (ARMADILLO.with_suffix(".node").exists() and ARMADILLO.with_suffix(".ele").exists()):
        pytest.skip(f"the armadillo mesh is not at {ARMADILLO} (.node/.ele); this copy of shared/ lacks it")
    vertices, tets = read_tetgen(ARMADILLO)
    # Clamp the lowest tenth of the body.
    low, high = vertices[:, 0].min(), vertices[:, 0].max()
    clamp = float(low + 0.1 * (high - low))
    compare_model_and_scene(tmp_path, vertices, tets, ARMADILLO, clamp, steps=3)


def test_a_model_can_feed_several_simulations_each_a_copy():
    vertices, tets = box_tets([1.0, 0.2, 0.2], [5, 1, 1])
    model = model_of(vertices, tets, 1e-3)
    first = projdyn.Simulation(model, damping=DAMPING, **SETTINGS)
    # Changing the model afterwards does not change the simulation made.
    model.add_tet_strain(0, stiffness=1.0e9)
    second = projdyn.Simulation(model, damping=DAMPING, **SETTINGS)
    again = projdyn.Simulation(model_of(vertices, tets, 1e-3), damping=DAMPING, **SETTINGS)
    for sim in (first, second, again):
        sim.step(5)
    assert bits(first.positions) == bits(again.positions)
    assert bits(first.positions) != bits(second.positions)


def test_positions_and_velocities_are_copies():
    sim = projdyn.Simulation.from_scene(SCENES / "cantilever.toml")
    x, v = sim.positions, sim.velocities
    assert x.dtype == np.float64 and x.shape == (sim.num_vertices, 3)
    assert v.dtype == np.float64 and v.shape == (sim.num_vertices, 3)
    kept = x.copy()
    sim.step(3)
    # An array kept from before the step does not change with the simulation...
    assert bits(x) == bits(kept)
    assert bits(sim.positions) != bits(kept)
    # ...and writing to one does not change the simulation.
    now = sim.positions
    x[:] = 0.0
    now[:] = 0.0
    assert np.abs(sim.positions).max() > 0.0
    assert not np.shares_memory(sim.positions, sim.positions)


def test_set_state_then_step(tmp_path):
    sim = projdyn.Simulation.from_scene(SCENES / "cantilever.toml")
    sim.step(4)
    x, v = sim.positions, sim.velocities
    other = projdyn.Simulation.from_scene(SCENES / "cantilever.toml")
    other.set_state(x, v)
    assert bits(other.positions) == bits(x) and bits(other.velocities) == bits(v)
    # Backward Euler (the scene's integrator) steps from the state alone:
    # the two go on identically.
    sim.step(3)
    other.step(3)
    assert bits(other.positions) == bits(sim.positions)


def test_energies_are_a_dict_of_joules():
    sim = projdyn.Simulation.from_scene(SCENES / "cantilever.toml")
    sim.step(5)
    e = sim.energies()
    assert set(e) == {"kinetic", "elastic", "gravity", "total"}
    assert e["kinetic"] > 0.0 and e["elastic"] > 0.0
    assert e["total"] == e["kinetic"] + e["elastic"] + e["gravity"]


@pytest.mark.parametrize("scene", ["cantilever.toml", "contact_drop.toml", "cloth_flag.toml"])
def test_pickle_round_trips_bit_for_bit(scene):
    sim = projdyn.Simulation.from_scene(SCENES / scene)
    sim.step(7)
    copy = pickle.loads(pickle.dumps(sim))
    assert (copy.steps, copy.time) == (sim.steps, sim.time)
    assert bits(copy.positions) == bits(sim.positions)
    assert bits(copy.velocities) == bits(sim.velocities)
    # The copy goes on as the original does, bit for bit.
    sim.step(5)
    copy.step(5)
    assert bits(copy.positions) == bits(sim.positions)
    assert bits(copy.velocities) == bits(sim.velocities)


def test_pickle_of_a_model_built_simulation():
    vertices, tets = box_tets([1.0, 0.2, 0.2], [5, 1, 1])
    model = model_of(vertices, tets, 1e-3)
    sim = projdyn.Simulation(model, damping=DAMPING, **SETTINGS)
    sim.step(4)
    copy = pickle.loads(pickle.dumps(sim))
    sim.step(4)
    copy.step(4)
    assert bits(copy.positions) == bits(sim.positions)
    model_copy = pickle.loads(pickle.dumps(model))
    assert model_copy.body_toml(0) == model.body_toml(0)
    assert model_copy.num_vertices == model.num_vertices


def test_colliders_and_contact_as_dicts_equal_the_scene(tmp_path):
    # A cube falling 0.02 m onto a floor with friction: the scene's
    # [[collider]] and [contact] tables as dicts.
    vertices, tets = box_tets([0.2, 0.2, 0.2], [3, 3, 3])
    vertices = vertices + [-0.1, 0.02, -0.1]
    write_tetgen(tmp_path / "cube", vertices, tets)
    scene = tmp_path / "drop.toml"
    scene.write_text(f"""
[simulation]
dt = 0.005
steps = 40
integrator = "backward-euler"
iterations = 20

[[collider]]
shape = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
friction = 0.5

[contact]
thickness = 0.001

[[body]]
mesh = {{ file = "{tmp_path / 'cube.node'}" }}
density = 1000.0
constraints = [ {{ kind = "tet-strain", stiffness = 1.0e5 }} ]
""")
    model = projdyn.Model()
    b = model.add_body(vertices, tets=tets, density=1000.0)
    model.add_tet_strain(b, 1.0e5)
    from_arrays = projdyn.Simulation(
        model,
        dt=0.005,
        steps=40,
        integrator="backward-euler",
        iterations=20,
        colliders=[{"shape": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "friction": 0.5}],
        contact={"thickness": 0.001},
    )
    from_file = projdyn.Simulation.from_scene(scene)
    for sim in (from_arrays, from_file):
        sim.step(40)
    # The cube reached the floor (free fall covers 0.02 m in 0.064 s, under
    # the 0.2 s run) and stays above it but for the contact thickness.
    assert from_file.positions[:, 1].min() > -0.001
    assert from_file.positions[:, 1].min() < 0.005
    assert bits(from_arrays.positions) == bits(from_file.positions)
