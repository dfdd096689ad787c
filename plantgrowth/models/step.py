"""What a growth model reports to the time loop: one step's result, the model protocol, the
fields it writes on a second mesh, and the tissue measures shared by both models."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.models.elastic_strain import StrainPeak, principal_magnitude
from plantgrowth.models.stability import Ellipticity

if TYPE_CHECKING:
    from plantgrowth.base.blocks import Block


@dataclass
class SideMesh:
    """Fields on a second, small mesh that every rank holds whole, with its own XDMF index: the
    macro model's coarse grid (E_hom's components at its nodes, ``coarse.xdmf``) or the micro
    model's cell outlines (``cells.xdmf``). The model puts each step's ``values`` here.

    Attributes:
        index: the XDMF file name.
        group: the mesh's group in fields.h5 (``/<group>/geometry``, ``/<group>/topology``).
        prefix: the fields' group in each step file (``/<prefix>/<name>``).
        points: (n_nodes, 2) node coordinates.
        cells: (n_cells, k) node numbers: triangles (k = 3) or line segments (k = 2).
        fields: name -> (center, components): "Node" or "Cell", 1 (scalar) or 2 (vector).
        values: name -> this step's values, (n, components) or (n,).
    """

    index: str
    group: str
    prefix: str
    points: np.ndarray
    cells: np.ndarray
    fields: dict[str, tuple[str, int]]
    values: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class LoadBalance:
    """The x1 resultants of the applied loads at one step, in the configuration the forms use.

    Attributes:
        resultants: edge -> its load's x1 force.
        lengths: edge -> its length in that configuration.
        length: "grown" (linear kinematics) or "current" (finite).
    """

    resultants: dict[str, float]
    lengths: dict[str, float]
    length: str = "grown"  # what the tractions are given per: "grown" or "current" length

    @property
    def net(self) -> float:
        return sum(self.resultants.values())

    @property
    def imbalance(self) -> float:
        """|net x1 force| over the largest edge's |x1 force| (0 without x1 forces)."""
        largest = max(abs(f) for f in self.resultants.values())
        return abs(self.net) / largest if largest > 0.0 else 0.0

    def describe(self) -> str:
        """What the pinned point carries and the change of one load that would balance it."""
        edge = max(self.resultants, key=lambda e: abs(self.resultants[e]))
        change = -self.net
        return (
            f"the loads' net x1 force is {self.net:.6g}, {self.imbalance:.1%} of the largest "
            f"edge force (loads.{edge}): the pinned point carries it as a point force. Tractions "
            f"act per {self.length} length, so edges that grow or stretch unequally pull "
            f"unequally; at this step, {change:+.6g} on loads.{edge}'s x1 force (its x1 "
            f"traction {change / self.lengths[edge]:+.6g}) would balance it. Loads given as "
            "each edge's total force, loads.<edge> = {force = [F1, F2]}, stay balanced"
        )


@dataclass
class StepResult:
    """What a model reports for one step at the current Fg."""

    G: np.ndarray  # (n_units, 2, 2) growth rate of each growth unit
    reason: int  # PETSc converged reason of the linear solve
    residual: float  # true relative residual of the linear solve
    n_cell_solves: int = 0
    seconds: dict[str, float] = field(default_factory=dict)  # seconds_cells, _solve, _growth
    elastic_strain: StrainPeak | None = None  # largest principal |eps_el| (or |Ee|) and where
    clamped_fraction: float | None = None  # area fraction where some |G_ij| reaches the clamp M
    newton_iterations: int = 0  # finite kinematics: Newton iterations of the step's solve
    newton_residual: float = 0.0  # finite kinematics: its final relative residual
    load_balance: LoadBalance | None = None  # macro with loads: their x1 resultants
    ellipticity: Ellipticity | None = None  # where the material law is strongly elliptic
    held_force: tuple[float, float] | None = None  # macro with [supports]: the held edges' force


class GrowthModel(Protocol):
    """A tissue model the loop can drive."""

    output_space: fem.FunctionSpace  # P1 vector space numbering the written mesh
    outputs: list[fem.Function]
    side_output: SideMesh | None  # fields on a second mesh (macro: E_hom at the coarse nodes;
    # micro: the cell outlines)
    cell_table: CellTable | None  # micro: one row per biological cell and written step

    def initial_growth(self) -> np.ndarray:
        """(n_units, 2, 2) Fg at t = 0."""

    def step(self, Fg: np.ndarray) -> StepResult:
        """Solve at the given Fg, fill the output functions, return G."""

    def measures(self, Fg: np.ndarray, G: np.ndarray) -> dict[str, float]:
        """Tissue measures: area, growth_rate_11/22/area, u1_max, u2_max, det_Fg_min."""

    def check_growth(self, Fg: np.ndarray) -> None:
        """Raise RunError (collectively) if the advanced Fg is not finite or inverted."""

    def end_step(self, dt: float) -> None:
        """Advance the model's own state other than Fg over the step dt, from the step just
        solved (macro: the fibre director's feedback), before the step's state is saved."""

    def substep(self, dt: float, remaining: float) -> None:
        """The next solve advances the model's own state (the water) by dt from the state kept
        last, ending ``remaining`` before the step's end (the adaptive integrator's sub-steps;
        end_step makes the next solve's the whole step again)."""

    def keep(self, kept: bool) -> None:
        """After a sub-step's solve: its state is the one the next solve starts from (kept), or
        the state before it is (a rejected sub-step)."""

    def state(self, Fg: np.ndarray, G: np.ndarray) -> dict[str, Block]:
        """What --resume needs to continue after this step: this rank's blocks of the saved
        arrays (collective; the same keys on every rank)."""

    def restore(self, state: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """(Fg, G) of this rank's growth units from a saved state."""


class CellTable(Protocol):
    """Rows of ``cells.csv``: one per biological cell at a written step."""

    columns: list[str]  # starting with "step", "t"

    def rows(self, step: int, t: float) -> list[dict[str, float]]:
        """The rows of the step just solved (collective; every rank gets them)."""


def max_abs_components(u: fem.Function, comm: MPI.Comm) -> tuple[float, float]:
    """max |u_1|, max |u_2| over the owned dofs of all ranks."""
    owned = u.x.array.reshape(-1, 2)[: u.function_space.dofmap.index_map.size_local]
    local = np.abs(owned).max(axis=0) if len(owned) else np.zeros(2)
    return tuple(comm.allreduce(float(v), op=MPI.MAX) for v in local)


def largest_strain(eps: np.ndarray, comm: MPI.Comm) -> float:
    """Largest principal magnitude of symmetric (n, 2, 2) strains over all ranks."""
    local = float(principal_magnitude(eps).max(initial=0.0))
    return comm.allreduce(local, op=MPI.MAX)


def clamped_fraction(G: np.ndarray, clamp: float, weights: np.ndarray, comm: MPI.Comm) -> float:
    """Weighted fraction of growth units where the clamp is active (some ``|G_ij| >= M``);
    ``G`` and ``weights`` are this rank's share (pass MPI.COMM_SELF for replicated values)."""
    hit = np.any(np.abs(G) >= clamp, axis=(1, 2))
    sums = comm.allreduce(np.array([weights[hit].sum(), weights.sum()]), op=MPI.SUM)
    return float(sums[0] / sums[1]) if sums[1] > 0.0 else 0.0
