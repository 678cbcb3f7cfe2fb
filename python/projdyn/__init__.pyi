"""Type stubs of projdyn (the Rust extension projdyn._projdyn)."""

from os import PathLike
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_Array = npt.ArrayLike
_Table = Mapping[str, Any]

__all__ = ["DivergenceError", "Model", "Simulation", "modes"]

class DivergenceError(RuntimeError):
    """The simulation diverged; the state is that of the last good step."""

    step: int
    """The step that failed, from 1."""
    time: float
    """Simulated time at the end of that step, s."""
    reason: str
    """What was detected, naming the vertex where there is one."""

class Model:
    """Bodies given as NumPy arrays with their constraints, under the scene
    format's names and units; each Simulation takes a copy."""

    def __init__(self) -> None: ...
    def add_body(
        self,
        vertices: _Array,
        *,
        tets: Optional[_Array] = None,
        triangles: Optional[_Array] = None,
        edges: Optional[_Array] = None,
        density: Optional[float] = None,
        vertex_mass: Optional[float] = None,
        name: Optional[str] = None,
        initial_velocity: Optional[Sequence[float]] = None,
        angular_velocity: Optional[Sequence[float]] = None,
        damping: Optional[_Table] = None,
    ) -> int:
        """Adds a body (vertices (N, 3) m; tets (M, 4), triangles (M, 3) or
        edges (M, 2)); density or vertex_mass; returns its index."""
    def add_constraint(self, body: int, kind: str, **params: Any) -> None:
        """Adds a constraint of any scene kind with the keys of its entry."""
    def add_tet_strain(
        self, body: int, stiffness: float, *, limits: Optional[Tuple[float, float]] = None
    ) -> None:
        """Corotational strain on every tetrahedron: stiffness in Pa."""
    def add_springs(self, body: int, stiffness: float) -> None:
        """A spring along every edge: stiffness in N/m."""
    def add_triangle_strain(
        self, body: int, stiffness: float, *, limits: Optional[Tuple[float, float]] = None
    ) -> None:
        """Membrane strain on every triangle: E t in N/m."""
    def add_bending(self, body: int, stiffness: float) -> None:
        """Bending on every interior edge: flexural rigidity in N m."""
    def add_area(self, body: int, stiffness: float) -> None:
        """Area preservation of every triangle: N/m."""
    def add_volume(self, body: int, stiffness: float) -> None:
        """Volume preservation of every tetrahedron: Pa."""
    def add_material(self, body: int, kind: str, young: float, poisson: float) -> None:
        """A hyperelastic material ("neo-hookean", "stvk", "corotated")."""
    def add_attachment(
        self,
        body: int,
        stiffness: float,
        *,
        vertices: Optional[_Array] = None,
        box: Optional[_Table] = None,
    ) -> None:
        """Attaches vertices to their rest positions: stiffness in N/m."""
    def fix(self, body: int, indices: Optional[_Array] = None, *, box: Optional[_Table] = None) -> None:
        """Fixes vertices (indices within the body, or those inside box)."""
    @property
    def num_bodies(self) -> int: ...
    @property
    def num_vertices(self) -> int: ...
    def body_toml(self, body: int) -> str:
        """The body's scene entry (without its mesh) as TOML text."""

class Simulation:
    """A Projective Dynamics simulation; positions and velocities are copies."""

    def __init__(
        self,
        model: Model,
        *,
        dt: Optional[float] = None,
        steps: Optional[int] = None,
        integrator: Optional[str] = None,
        gravity: Optional[Sequence[float]] = None,
        iterations: Optional[int] = None,
        tolerance: Optional[float] = None,
        accuracy: Optional[float] = None,
        threads: Optional[int] = None,
        divergence_energy_factor: Optional[float] = None,
        damping: Optional[_Table] = None,
        solver: Optional[_Table] = None,
        contact: Optional[_Table] = None,
        colliders: Optional[Sequence[_Table]] = None,
        output: Optional[_Table] = None,
        simulation: Optional[_Table] = None,
    ) -> None: ...
    @staticmethod
    def from_scene(
        path: _Path, *, steps: Optional[int] = None, threads: Optional[int] = None
    ) -> "Simulation":
        """The scene file's simulation, as `pd run` builds it."""
    def step(self, n: int = 1) -> None:
        """Advances n steps with the GIL released; DivergenceError on divergence."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """(N, 3) positions in m: a new array (copy)."""
    @property
    def velocities(self) -> npt.NDArray[np.float64]:
        """(N, 3) velocities in m/s: a new array (copy)."""
    @property
    def time(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def dt(self) -> float: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def scene_steps(self) -> int: ...
    @property
    def method(self) -> str: ...
    def energies(self) -> Dict[str, float]:
        """kinetic, elastic, gravity and total, J."""
    def set_state(self, positions: _Array, velocities: Optional[_Array] = None) -> None:
        """Replaces the state (arrays copied; velocities zero when left out)."""
    def save_frame(self, path: _Path) -> None:
        """Writes one frame (.vtk, .vtu, .obj or .ply by extension)."""
    def run(self, out: _Path, steps: Optional[int] = None) -> None:
        """Runs to step `steps` writing the output folder as `pd run` does."""
    def checkpoint_json(self) -> str:
        """The state in the checkpoint format of `pd resume` (JSON text)."""

def modes(sim_or_scene: Union[Simulation, _Path], count: int = 6) -> Dict[str, Any]:
    """The lowest elastic modes as `pd modes` reports them in modes.json."""

def gradient(
    sim: Simulation,
    steps: int,
    probes: Sequence[int],
    targets: npt.ArrayLike,
    parameters: Sequence[str],
) -> Dict[str, Any]:
    """The loss (mean squared distance of `probes` to `targets[s, p]` over
    steps 1..steps, m^2) of a converged run from the simulation's current
    state (the simulation itself is not stepped), and its gradient by the
    adjoint method with respect to `parameters`, named as the scene names
    them: "damping.mass", "damping.stiffness", "damping.series[k]",
    "body[i].constraints[j].stiffness", "body[i].density",
    "initial positions", "initial velocities", "gravity".

    Returns {"loss", "gradients" (by name: float, or an (N, 3) / (3,)
    array), "forward_s", "backward_s", "adjoint_iterations",
    "forward_retries"}. Raises ValueError for malformed arguments and for
    scenes the adjoint method does not differentiate (contact, materials,
    velocity filters, lagged, per-body or rotation-preserving damping)."""
