"""Why irregular micro tissues stopped at step 0 (issue 34, round 2; docs/real_tissues.md).

For generated tissues ``{voronoi = Nx^2/2, seed, regularity = r}`` under P1 = 0.001 (stress law,
``micro.resolution = 1``), the first solve (t = 0, Fg = I) in linear and finite kinematics:

- the walls mesh: its triangles' vertex-sharing graph's components (1: one conforming piece);
- max |u| over the P2 nodes;
- the walls' elastic strain range: the smallest and largest principal value of ``eps_el``
  (linear) or of ``Ee = (Fe^T Fe - I) / 2`` (finite) over the DG2 samples;
- the walls' rotation: ``omega = (du1/dx2 - du2/dx1) / 2`` (linear: the infinitesimal rotation)
  or the polar rotation angle of ``F = I + grad u`` (finite), its maximum and median |.|, and
  the median at the non-elliptic samples;
- the ellipticity check (plantgrowth.models.micro.wall_stability): the smallest normalised
  acoustic eigenvalue, whether a run would stop (a non-elliptic set), its message, and the sets'
  area fraction.

A solve that fails (Newton) is recorded with its error. Results: JSON with the machine.

    python scripts/studies/micro_stability.py [--nx 4 8] [--r 0 0.25 0.5 1] [--seeds 1 2 3]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from plantgrowth.base.errors import RunError
from plantgrowth.base.machine import machine_description
from plantgrowth.base.mesh_samples import MeshSamples
from plantgrowth.models.micro.model import MicroModel
from plantgrowth.scene import parse_scene

REPO = Path(__file__).resolve().parents[2]


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nx", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--r", type=float, nargs="+", default=[0.0, 0.25, 0.5, 1.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--P1", type=float, default=0.001)
    parser.add_argument(
        "--json", type=Path, default=REPO / "benchmarks/results/micro_stability.json"
    )
    return parser.parse_args(argv)


def scene_data(nx: int, r: float, seed: int, kinematics: str, P1: float) -> dict:
    return {
        "model": "micro", "kinematics": kinematics, "growth": {"law": "stress"},
        "time": {"t_max": 1.0, "dt": 1.0}, "micro": {"resolution": 1},
        "pressure": {"P1": P1},
        "tissue": {"cells": {"voronoi": nx * nx // 2, "seed": seed, "regularity": r}},
    }  # fmt: skip


def mesh_components(model: MicroModel) -> int:
    """Connected components of the walls' triangles (two share a vertex: connected)."""
    c2v = model.mesh.topology.connectivity(2, 0).array.reshape(-1, 3)
    n, m = len(c2v), int(c2v.max()) + 1
    graph = coo_matrix(
        (np.ones(3 * n), (np.repeat(np.arange(n), 3), n + c2v.ravel())), shape=(n + m, n + m)
    )
    labels = connected_components(graph, directed=False)[1]
    return len(np.unique(labels[:n]))


def rotation(model: MicroModel) -> np.ndarray:
    """|rotation| at the DG2 samples (module docstring)."""
    g = ufl.grad(model.u)
    s = {(i, j): MeshSamples(g[i, j], model.mesh, 2).values() for i in (0, 1) for j in (0, 1)}
    if model.finite:
        return np.abs(np.arctan2(s[1, 0] - s[0, 1], 2.0 + s[0, 0] + s[1, 1]))
    return np.abs(0.5 * (s[0, 1] - s[1, 0]))


def strains(model: MicroModel) -> np.ndarray:
    """(n, 2) principal elastic strains at the DG2 samples (module docstring)."""
    T = np.stack([p.values() for p in model.stability._parts], axis=1).reshape(-1, 2, 2)
    if model.finite:  # T is Fe
        T = 0.5 * (np.einsum("nki,nkj->nij", T, T) - np.eye(2))
    return np.linalg.eigvalsh(0.5 * (T + np.swapaxes(T, 1, 2)))


def one(nx: int, r: float, seed: int, kinematics: str, P1: float) -> dict:
    row: dict = {"nx": nx, "r": r, "seed": seed, "kinematics": kinematics}
    model = MicroModel(parse_scene(scene_data(nx, r, seed, kinematics, P1)), MPI.COMM_SELF)
    row["components"] = mesh_components(model)
    try:
        result = model.step(model.initial_growth())
    except RunError as e:
        return row | {"error": str(e)[:200]}
    e = result.ellipticity
    eps, omega = strains(model), rotation(model)
    bad = model.stability.values(screened=False) < 0.0
    return row | {
        "max_u": float(np.linalg.norm(model.u.x.array.reshape(-1, 2), axis=1).max()),
        "strain_min": float(eps[:, 0].min()), "strain_max": float(eps[:, 1].max()),
        "rotation_max": float(omega.max()), "rotation_median": float(np.median(omega)),
        "rotation_median_nonelliptic": float(np.median(omega[bad])) if bad.any() else None,
        "smallest": e.smallest, "stops": e.lost,
        "stop_message": e.describe(0.0) if e.lost else None,
        "nonelliptic_fraction": e.nonelliptic_area_fraction + e.singular_area_fraction,
    }  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    rows = []
    for nx in args.nx:
        for r in args.r:
            for seed in args.seeds if r > 0.0 else args.seeds[:1]:  # r = 0: no randomness
                for kinematics in ("linear", "finite"):
                    rows.append(one(nx, r, seed, kinematics, args.P1))
                    print(json.dumps(rows[-1]), flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"machine": machine_description(), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
