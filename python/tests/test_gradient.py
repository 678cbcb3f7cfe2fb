"""projdyn.gradient: the adjoint gradient of a probe loss against central
finite differences of the same loss computed here with projdyn, and its
errors."""

import numpy as np
import pytest

import projdyn
from conftest import SCENES

SCENE = SCENES / "fit_beam.toml"  # converged steps (Newton, accuracy 1e-9)
PROBES = [4, 12, 19]
STEPS = 20


def targets():
    """The probes' rest positions at every step."""
    sim = projdyn.Simulation.from_scene(SCENE)
    return np.repeat(sim.positions[PROBES][None, :, :], STEPS, axis=0)


def loss(sim, goal):
    """Mean squared probe distance over steps 1..STEPS, m^2 (steps `sim`)."""
    total = 0.0
    for s in range(STEPS):
        sim.step(1)
        total += float(((sim.positions[PROBES] - goal[s]) ** 2).sum())
    return total / (STEPS * len(PROBES))


def damped(stiffness):
    return projdyn.Simulation.from_scene(
        SCENE, damping={"model": "laplacian", "stiffness": stiffness, "mass": 0.6}
    )


def test_the_adjoint_gradient_matches_central_differences():
    goal = targets()
    sim = projdyn.Simulation.from_scene(SCENE)
    result = projdyn.gradient(
        sim, STEPS, PROBES, goal, ["damping.stiffness", "initial velocities", "gravity"]
    )
    assert sim.steps == 0, "the simulation itself is not stepped"
    assert result["loss"] == pytest.approx(loss(damped(1.5e-4), goal), rel=1e-8)
    # Central differences of the loss of converged runs. Truncation:
    # h^2/6 of the third derivative over the first, ~1e-8 relative at a
    # relative step of 1e-4; noise: the runs are converged to ~1e-9, which
    # the quotient amplifies by 1/(2h) to ~1e-5; the adjoint's own forward
    # run (converged to 1e-10 by another method) agrees to ~1e-10. So 1e-3
    # relative leaves a margin of 100 over the noise.
    a2, h = 1.5e-4, 1e-4
    central = (loss(damped(a2 * (1 + h)), goal) - loss(damped(a2 * (1 - h)), goal)) / (
        2 * h * a2
    )
    assert result["gradients"]["damping.stiffness"] == pytest.approx(central, rel=1e-3)

    # One initial velocity component: the tip's z velocity (m/s).
    dv = result["gradients"]["initial velocities"]
    assert dv.shape == (sim.num_vertices, 3)
    vertex, step = 19, 1e-4

    def moved(sign):
        s = projdyn.Simulation.from_scene(SCENE)
        v = s.velocities
        v[vertex, 2] += sign * step
        s.set_state(s.positions, v)
        return loss(s, goal)

    central = (moved(1) - moved(-1)) / (2 * step)
    assert dv[vertex, 2] == pytest.approx(central, rel=1e-3)
    assert result["gradients"]["gravity"].shape == (3,)
    assert result["backward_s"] > 0 and result["forward_s"] > 0


def test_bad_arguments_and_unsupported_scenes_are_value_errors():
    sim = projdyn.Simulation.from_scene(SCENE)
    goal = targets()
    with pytest.raises(ValueError, match=r"targets: expected a \(20, 3, 3\) array"):
        projdyn.gradient(sim, STEPS, PROBES, goal[:, :2], ["damping.mass"])
    with pytest.raises(ValueError, match="parameters: "):
        projdyn.gradient(sim, STEPS, PROBES, goal, ["damping.bogus"])
    with pytest.raises(ValueError, match="probes: vertex 999 is out of range"):
        projdyn.gradient(sim, STEPS, [4, 12, 999], goal, ["damping.mass"])
    with pytest.raises(ValueError, match="steps: must be at least 1"):
        projdyn.gradient(sim, 0, PROBES, goal, ["damping.mass"])
    stack = projdyn.Simulation.from_scene(SCENES / "contact_stack.toml")
    with pytest.raises(ValueError, match="contact"):
        projdyn.gradient(stack, 2, [0], np.zeros((2, 1, 3)), ["damping.mass"])
