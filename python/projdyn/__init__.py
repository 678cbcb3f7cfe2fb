"""projdyn: Projective Dynamics with Laplacian damping, from Python and NumPy.

The simulator of the ``pd`` command-line tool, built from the same Rust
crates: the same scene format and the same results, bit for bit.

    >>> import projdyn
    >>> sim = projdyn.Simulation.from_scene("scenes/cantilever.toml")
    >>> sim.step(100)                 # releases the GIL while it runs
    >>> x = sim.positions             # (N, 3) float64, a copy
    >>> sim.energies()["total"]       # J

Build a model from arrays with :class:`Model` and simulate it with
``Simulation(model, dt=..., ...)``; keyword arguments are the scene's keys
and tables, in its units (docs/reference/scene-format.md).
:func:`gradient` differentiates a probe loss on a run by the adjoint
method (docs/design/gradients.md).
"""

from ._projdyn import DivergenceError, Model, Simulation, gradient, modes

__all__ = ["DivergenceError", "Model", "Simulation", "gradient", "modes"]
