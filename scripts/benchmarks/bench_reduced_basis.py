"""Can a reduced-basis (RB) Galerkin solve replace the fibred cell solve of ``CellSolver.solve``?

Question: on the reference cell (resolution 2, the ``balanced`` preset, E = 1, nu = 0.3, fibre
stiffness 5, pressure problem and strain averages), over the stretch ``Fg = stretch(s)``, s1 in
[0, 0.15], s2 in [-0.015, 0.04], and the director angle b in [65, 120] degrees (the stress-feedback
scene) or [0, 180), does an RB solve reach a relative error <= 1e-5 (the surrogate tolerates 1e-3),
and at what cost per solve, single and batched, against the full solve?

Method: the full solve's matrix is ``diagonal + sum_k theta_k(Fg, b) B_k`` (30 basis products) and
its loads and averages are moments (:mod:`plantgrowth.unitcell.gradient_basis`). Offline, full
solves at a training set (uniform random, its own seed, per angle range) give the four reduced,
stored-order solutions the KSP returns; each is scaled to unit norm and a POD (SVD) gives the
orthonormal basis V. The reduced operators ``V^T B_k V``, ``V^T diagonal V``, the load moments
``V^T reduced[f]`` and the average moments ``U^T full[f]`` (U: V's columns back-substituted by the
MPC, a linear map) are precomputed. Online: the r x r matrix, four right-hand sides, a dense
solve, and the post-processing of ``CellSolver.solve``. Before measuring, the RB solve on the span
of a few training points' snapshots must reproduce those full solves to 1e-10. Errors: largest
over E_hom (Voigt), K_hom, dbar_w, dbar_v of the relative Frobenius differences of the packed
results (``homogenization._pack``), as the surrogate measures them; the largest over a random test
set (its own seed), and over a set on the faces and corners of the parameter box.

    PYTHONPATH=. nice -n 19 .venv/bin/python scripts/benchmarks/bench_reduced_basis.py \
        [--train 300] [--test 256] [--sizes 5 10 15 20 30 40 60 80]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.machine import machine_description
from plantgrowth.base.tensors import isotropic_tensor, unit_strain, voigt_matrix
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell.gradient_basis import GradientBasis
from plantgrowth.unitcell.homogenization import _pack
from plantgrowth.unitcell.solver import (
    STRAIN_PROBLEMS,
    CellResult,
    CellSolver,
    growth_map,
    tensor_weights,
)
from plantgrowth.unitcell.surrogate import stretch

REPO = Path(__file__).resolve().parents[2]
OUTPUT = REPO / "benchmarks" / "results" / "reduced_basis.json"
E, NU, FIBRE = 1.0, 0.3, 5.0
RANGES = {
    "b in [65, 120]": np.array([[0.0, 0.15], [-0.015, 0.04], [65.0, 120.0]]),
    "b in [0, 180)": np.array([[0.0, 0.15], [-0.015, 0.04], [0.0, 180.0]]),
}
SEGMENTS = {"E_hom": slice(0, 9), "K_hom": slice(14, 18), "dbar_w": slice(18, 34),
            "dbar_v": slice(34, 38)}  # fmt: skip
"""Of the packed vector (E_voigt 9, phi_w 1, P2 4, K 4, dbar_w 16, dbar_v 4); phi_w and P2 do
not depend on the solve."""
PAIRS = np.array(GradientBasis.PAIRS)
HALF = np.where(PAIRS[:, 0] == PAIRS[:, 1], 0.5, 1.0)  # GradientBasis.matrix's coefficients


class SnapshotSolver(CellSolver):
    """A CellSolver that keeps the reduced, stored-order solutions its KSP returns."""

    snapshots: list[np.ndarray]

    def _gradient_integrals(self, loads: np.ndarray) -> np.ndarray:
        """CellSolver._gradient_integrals (one rank), recording each load column's reduced
        solution x: the back-substituted z in stored order, ``x = z[order]``, but 0 on the
        periodic constraint's slaves (the back-substitution fills only those)."""
        integrals = super()._gradient_integrals(loads)
        slave = np.isin(self.basis.order, self.mpc.slaves)
        self.snapshots = [np.where(slave, 0.0, z[self.basis.order]) for z in self._solutions]
        return integrals


def full_solve(solver: CellSolver, s: np.ndarray, b: float) -> CellResult:
    """The reference: ``CellSolver.solve`` at stretch s and angle b."""
    return solver.solve(stretch(s), E, NU, True, True, FIBRE, b)


@dataclass(frozen=True)
class ReducedModel:
    """Reduced operators on the first r columns of an orthonormal basis (r <= its width)."""

    products: np.ndarray  # (parts * 10, R, R)  V^T B^f_pq V, in GradientBasis.matrix's order
    diagonal: np.ndarray  # (R, R)               V^T diagonal V
    loads: np.ndarray  # (parts, R, 4)           V^T reduced[f]
    averages: np.ndarray  # (parts, R, 4)        (back-substituted V)^T full[f]

    def truncated(self, r: int) -> ReducedModel:
        """The model on the first r basis vectors (leading blocks: the basis is nested)."""
        return ReducedModel(self.products[:, :r, :r], self.diagonal[:r, :r], self.loads[:, :r],
                            self.averages[:, :r])  # fmt: skip


def scipy_matrix(M: PETSc.Mat) -> sp.csr_matrix:
    """A stored (SBAIJ, upper triangle) PETSc matrix as a full scipy CSR matrix."""
    aij = M.convert("aij", PETSc.Mat())  # a new matrix (without out: in place)
    I, J, values = (a.copy() for a in aij.getValuesCSR())
    shape = aij.getSize()
    aij.destroy()
    return sp.csr_matrix((values, J, I), shape=shape)


def project(solver: CellSolver, V: np.ndarray) -> ReducedModel:
    """The reduced operators of the orthonormal stored-order basis V (n, R)."""
    basis = solver.basis
    products = np.stack([V.T @ (scipy_matrix(B) @ V) for part in basis.products for B in part])
    diagonal = V.T @ (scipy_matrix(basis.diagonal) @ V)
    z = fem.Function(solver.mpc.function_space)
    U = np.zeros_like(V)
    for i in range(V.shape[1]):  # the MPC's back-substitution of each basis vector (linear)
        z.x.array[:] = 0.0
        z.x.array[basis.order] = V[:, i]
        z.x.scatter_forward()
        solver.mpc.backsubstitution(z.vector)
        U[:, i] = z.vector.array_r
    loads = np.einsum("ni,fnp->fip", V, basis.reduced)
    averages = np.einsum("ni,fnp->fip", U, basis.full)
    return ReducedModel(products, diagonal, loads, averages)


@dataclass(frozen=True)
class ReducedSolution:
    """The reduced solution y (r, 4) at U = stretch(s) and angle b, and what it was made of:
    U, the wall tensors, their C[b_ij] per part and the loads (parts, 4, 4)."""

    y: np.ndarray
    Fg: np.ndarray
    walls: list[np.ndarray]
    wall_b: np.ndarray
    loads: np.ndarray


def reduced_solution(
    solver: CellSolver, model: ReducedModel, s: np.ndarray, b: float
) -> ReducedSolution:
    """``CellSolver.solve``'s system with the reduced matrix and load moments, solved."""
    Fg = stretch(s)
    walls = solver.wall_tensors(Fg, E, NU, FIBRE, b)
    S = np.stack([tensor_weights(Fg, C) for C in walls])
    theta = (S[:, PAIRS[:, 0], PAIRS[:, 1]] * HALF).ravel()
    A = model.diagonal + np.tensordot(theta, model.products, 1)
    wall_b = np.array(
        [[np.einsum("klmn,mn->kl", C, unit_strain(i, j)) for i, j in STRAIN_PROBLEMS]
         for C in walls]
    )  # fmt: skip
    columns = [[x.ravel() for x in list(b_f) + [np.eye(2)]] for b_f in wall_b]
    X = np.stack([np.stack(part, axis=1) for part in columns])
    loads = -np.linalg.det(Fg) * growth_map(Fg).T @ X
    y = np.linalg.solve(A, np.einsum("fip,fpk->ik", model.loads, loads))
    return ReducedSolution(y, Fg, walls, wall_b, loads)


def rb_solve(solver: CellSolver, model: ReducedModel, s: np.ndarray, b: float) -> CellResult:
    """One RB solve: ``CellSolver.solve``'s math with the reduced matrix and moments."""
    start = time.perf_counter()
    return rb_result(solver, model, reduced_solution(solver, model, s, b), start)


def rb_result(
    solver: CellSolver, model: ReducedModel, solution: ReducedSolution, start: float
) -> CellResult:
    """``CellSolver.solve``'s averages of a reduced solution (its time from ``start``, a
    ``time.perf_counter()``)."""
    walls, wall_b = solution.walls, solution.wall_b
    integrals = growth_map(solution.Fg) @ np.einsum("fip,ik->fpk", model.averages, solution.y)
    # from here on CellSolver.solve's post-processing, unchanged
    grad_g = integrals.transpose(0, 2, 1).reshape(len(walls), -1, 2, 2)
    dbar_parts = 0.5 * (grad_g + grad_g.transpose(0, 1, 3, 2)) / solver.area
    dbar = dbar_parts.sum(axis=0)
    stress = sum(np.einsum("klmn,smn->skl", C, d) for C, d in zip(walls, dbar_parts, strict=True))
    wall_mean = np.einsum("f,fskl->skl", solver.part_fractions, wall_b)
    E_hom, dbar_w = np.zeros((2, 2, 2, 2)), np.zeros((2, 2, 2, 2))
    for k, (i, j) in enumerate(STRAIN_PROBLEMS):
        E_hom[i, j] = E_hom[j, i] = wall_mean[k] + stress[k]
        dbar_w[i, j] = dbar_w[j, i] = dbar[k]
    return CellResult(E_hom, stress[3], dbar_w, dbar[3], solver.wall_area / solver.area,
                      solver.P2_matrix, solver.ndofs, time.perf_counter() - start)  # fmt: skip


def stretches(s: np.ndarray) -> np.ndarray:
    """:func:`surrogate.stretch` of n stretches s (n, 2) at once: (n, 2, 2)."""
    r = np.hypot(s[:, 0], s[:, 1])
    ratio = np.divide(np.sinh(r), r, out=np.ones_like(r), where=r > 0.0)
    S = np.stack([np.stack([s[:, 0], s[:, 1]], -1), np.stack([s[:, 1], -s[:, 0]], -1)], -2)
    return np.cosh(r)[:, None, None] * np.eye(2) + ratio[:, None, None] * S


def rb_batch(solver: CellSolver, model: ReducedModel, params: np.ndarray) -> np.ndarray:
    """Packed results (n, 38) of n RB solves at params (n, 3) = (s1, s2, b), vectorized."""
    n = len(params)
    Fg = stretches(params[:, :2])
    det = np.linalg.det(Fg)
    a = np.radians(params[:, 2])
    m = np.stack([np.cos(a), np.sin(a)], -1)
    tg = np.einsum("nij,fj->nfi", Fg, np.array(solver.cell.wall_tangents()))
    tg /= np.linalg.norm(tg, axis=-1, keepdims=True)
    q = FIBRE * E * np.einsum("ni,nfi->nf", m, tg) ** 2
    tt = tg[..., :, None] * tg[..., None, :]  # t_g x t_g
    walls = (
        isotropic_tensor(E, NU)
        + (q[..., None, None] * tt)[..., None, None] * tt[..., None, None, :, :]
    )
    L = np.zeros((n, 4, 4))
    L[:, :2, :2] = L[:, 2:, 2:] = np.linalg.inv(Fg).transpose(0, 2, 1)
    S = det[:, None, None, None] * np.einsum("nqp,nfqr,nrs->nfps", L, walls.reshape(n, -1, 4, 4), L)
    theta = (S[:, :, PAIRS[:, 0], PAIRS[:, 1]] * HALF).reshape(n, -1)
    A = np.einsum("nk,kij->nij", theta, model.products)
    if model.diagonal.any():  # zero: V vanishes on the Dirichlet and slave rows
        A += model.diagonal
    strains = np.array([unit_strain(i, j) for i, j in STRAIN_PROBLEMS])
    wall_b = np.einsum("nfklij,sij->nfskl", walls, strains)
    X = np.concatenate([wall_b, np.broadcast_to(np.eye(2), (*wall_b.shape[:2], 1, 2, 2))], 2)
    X = X.reshape(n, -1, 4, 4).transpose(0, 1, 3, 2)  # (n, parts, p, column)
    loads = -det[:, None, None, None] * np.einsum("nqp,nfqk->nfpk", L, X)
    y = np.linalg.solve(A, np.einsum("fip,nfpk->nik", model.loads, loads))
    integrals = np.einsum("npq,nfqk->nfpk", L, np.einsum("fiq,nik->nfqk", model.averages, y))
    grad_g = integrals.transpose(0, 1, 3, 2).reshape(n, -1, 4, 2, 2)
    dbar_parts = 0.5 * (grad_g + grad_g.transpose(0, 1, 2, 4, 3)) / solver.area
    dbar = dbar_parts.sum(axis=1)
    stress = np.einsum("nfklij,nfsij->nskl", walls, dbar_parts)
    mean = np.einsum("f,nfskl->nskl", solver.part_fractions, wall_b) + stress[:, :3]
    E_hom, dbar_w = np.zeros((n, 2, 2, 2, 2)), np.zeros((n, 2, 2, 2, 2))
    for k, (i, j) in enumerate(STRAIN_PROBLEMS):
        E_hom[:, i, j] = E_hom[:, j, i] = mean[:, k]
        dbar_w[:, i, j] = dbar_w[:, j, i] = dbar[:, k]
    fixed = np.concatenate([[solver.wall_area / solver.area], solver.P2_matrix.ravel()])
    return np.concatenate([voigt_matrix(E_hom).reshape(n, 9), np.tile(fixed, (n, 1)),
                           stress[:, 3].reshape(n, 4), dbar_w.reshape(n, 16),
                           dbar[:, 3].reshape(n, 4)], axis=1)  # fmt: skip


def segment_errors(values: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(n, segments) ``|a - b| / |b|`` (Frobenius) of each of SEGMENTS, row by row."""
    return np.stack([np.linalg.norm(values[:, seg] - reference[:, seg], axis=1)
                     / np.linalg.norm(reference[:, seg], axis=1)
                     for seg in SEGMENTS.values()], axis=1)  # fmt: skip


def errors(values: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per row, the largest over SEGMENTS of the relative errors, as the surrogate measures."""
    return segment_errors(values, reference).max(axis=1)


def sample(box: np.ndarray, n: int, seed: int) -> np.ndarray:
    """n uniform random parameters (s1, s2, b) in the box (3, 2)."""
    return box[:, 0] + np.random.default_rng(seed).random((n, 3)) * (box[:, 1] - box[:, 0])


def boundary(box: np.ndarray, n: int, seed: int) -> np.ndarray:
    """The box's 8 corners and n - 8 uniform points each on a random face."""
    corners = np.array(np.meshgrid(*box, indexing="ij")).reshape(3, -1).T
    points = sample(box, n - 8, seed)
    rng = np.random.default_rng(seed + 1)
    face = rng.integers(0, 3, n - 8)
    points[np.arange(n - 8), face] = box[face, rng.integers(0, 2, n - 8)]
    return np.concatenate([corners, points])


def full_results(solver: SnapshotSolver, params: np.ndarray) -> tuple[np.ndarray, list, list]:
    """Packed full results, snapshots (n, 4 per point) and wall times of full solves."""
    packed, snaps, seconds = [], [], []
    for s1, s2, b in params:
        start = time.perf_counter()
        result = full_solve(solver, np.array([s1, s2]), b)
        seconds.append(time.perf_counter() - start)
        packed.append(_pack(result))
        snaps.extend(solver.snapshots)
    return np.array(packed), snaps, seconds


def verify(solver: SnapshotSolver, box: np.ndarray) -> dict:
    """RB on the span of 6 points' 24 snapshots reproduces their full solves (single and
    batched); raises otherwise."""
    params = sample(box, 6, 99)
    reference, snaps, _ = full_results(solver, params)
    V = np.linalg.qr(np.array(snaps).T)[0]
    model = project(solver, V)
    single = np.array([_pack(rb_solve(solver, model, p[:2], p[2])) for p in params])
    batched = rb_batch(solver, model, params)
    out = {"points": 6, "r": V.shape[1], "single_error": float(errors(single, reference).max()),
           "batched_error": float(errors(batched, reference).max()),
           "reduced_diagonal_norm": float(np.linalg.norm(model.diagonal))}  # fmt: skip
    if max(out["single_error"], out["batched_error"]) > 1e-10:
        raise RuntimeError(f"the RB solve does not reproduce the full solve: {out}")
    return out


def median_seconds(call, repeats: int) -> float:
    """Median wall time of ``call()``."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def study_range(solver: SnapshotSolver, box: np.ndarray, args: argparse.Namespace) -> dict:
    """Offline basis, then the errors and online costs per r for one parameter box."""
    start = time.perf_counter()
    train = sample(box, args.train, 1)
    train_ref, snaps, train_seconds = full_results(solver, train)
    snaps = np.array(snaps).T
    snaps /= np.linalg.norm(snaps, axis=0)
    svd = time.perf_counter()
    U, sigma = np.linalg.svd(snaps, full_matrices=False)[:2]
    svd = time.perf_counter() - svd
    model = project(solver, np.ascontiguousarray(U[:, : max(args.sizes)]))
    offline = time.perf_counter() - start
    test = sample(box, args.test, 2)
    test_ref, _, test_seconds = full_results(solver, test)
    edge = boundary(box, 64, 3)
    edge_ref = full_results(solver, edge)[0]
    batch = sample(box, args.batch, 4)
    rows = []
    for r in args.sizes:
        reduced = model.truncated(r)
        e_segments = segment_errors(rb_batch(solver, reduced, test), test_ref)
        e_test = e_segments.max(axis=1)
        per_segment = dict(zip(SEGMENTS, e_segments.max(axis=0).tolist(), strict=True))
        e_edge = errors(rb_batch(solver, reduced, edge), edge_ref)
        e_train = errors(rb_batch(solver, reduced, train), train_ref)
        cycle = iter(np.tile(test, (args.repeats // len(test) + 1, 1)))

        def one(reduced: ReducedModel = reduced, cycle=cycle) -> None:
            p = next(cycle)
            rb_solve(solver, reduced, p[:2], p[2])

        single = median_seconds(one, args.repeats)
        single_vec = median_seconds(lambda reduced=reduced: rb_batch(solver, reduced, test[:1]),
                                    args.repeats)  # fmt: skip
        batched = median_seconds(lambda reduced=reduced: rb_batch(solver, reduced, batch), 3)
        worst = int(np.argmax(e_test))
        rows.append({"r": r, "test_max_error": float(e_test.max()),
                     "test_median_error": float(np.median(e_test)),
                     "test_max_error_per_segment": per_segment,
                     "test_worst_point": test[worst].tolist(),
                     "edge_max_error": float(e_edge.max()),
                     "edge_worst_point": edge[int(np.argmax(e_edge))].tolist(),
                     "train_max_error": float(e_train.max()),
                     "single_seconds": single, "single_vectorized_seconds": single_vec,
                     "batched_seconds_per_solve": batched / len(batch)})  # fmt: skip
        print(f"  r={r:3d} test {e_test.max():.2e} edge {e_edge.max():.2e} train "
              f"{e_train.max():.2e}  single {1e6 * single:6.0f} us ({1e6 * single_vec:4.0f} "
              f"vectorized)  batched {1e6 * batched / len(batch):6.1f} us")  # fmt: skip
    return {"box": box.tolist(), "training_points": args.train, "training_seed": 1,
            "full_solves_offline": args.train, "snapshots": snaps.shape[1],
            "offline_seconds": offline, "offline_full_solve_seconds": sum(train_seconds),
            "offline_svd_seconds": svd,
            "singular_values_relative": (sigma[:100] / sigma[0]).tolist(),
            "test_points": args.test, "test_seed": 2, "edge_points": 64, "edge_seed": 3,
            "full_solve_median_seconds_here": statistics.median(train_seconds + test_seconds),
            "batch_size": args.batch, "rows": rows}  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    """Run the study for both angle ranges and write OUTPUT."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--train", type=int, default=300, help="training points per range")
    parser.add_argument("--test", type=int, default=256, help="random test points per range")
    parser.add_argument("--sizes", type=int, nargs="+", default=[5, 10, 15, 20, 30, 40, 60, 80],
                        help="basis sizes r")  # fmt: skip
    parser.add_argument("--batch", type=int, default=4096, help="parameters per batched call")
    parser.add_argument("--repeats", type=int, default=1000, help="single solves timed per r")
    args = parser.parse_args(argv)
    start, load = time.perf_counter(), os.getloadavg()
    setup = time.perf_counter()
    solver = SnapshotSolver(HoneycombCell(1.0, 1.0, 30.0, 0.05), 2, MPI.COMM_SELF, fibres=True)
    setup = time.perf_counter() - setup
    check = verify(solver, RANGES["b in [65, 120]"])
    print(f"check: RB on the span of {check['r']} snapshots, error {check['single_error']:.1e} "
          f"(single), {check['batched_error']:.1e} (batched)")  # fmt: skip
    p = sample(RANGES["b in [65, 120]"], 1, 5)[0]
    plain = CellSolver(solver.cell, 2, MPI.COMM_SELF, fibres=True)
    full = median_seconds(lambda: full_solve(plain, p[:2], p[2]), 300)
    print(f"full solve (CellSolver.solve) median {1e3 * full:.2f} ms; solver setup {setup:.2f} s")
    result = {"question": __doc__.split("\n\n")[1], "cell": [1.0, 1.0, 30.0, 0.05],
              "resolution": 2, "E": E, "nu": NU, "fibre_stiffness": FIBRE,
              "ndofs": solver.ndofs, "stored_size": len(solver.basis.order),
              "error_measure": "max over " + ", ".join(SEGMENTS) + " of relative Frobenius",
              "check": check, "full_solve_median_seconds": full, "solver_setup_seconds": setup,
              "pod": "unit-norm snapshots, SVD", "ranges": {}}  # fmt: skip
    for name, box in RANGES.items():
        print(name)
        result["ranges"][name] = study_range(solver, box, args)
    result["load_average_before_after"] = [load, os.getloadavg()]
    result["machine"] = machine_description()
    result["script_seconds"] = time.perf_counter() - start
    OUTPUT.parent.mkdir(parents=True, exist_ok=True)
    OUTPUT.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {OUTPUT} in {result['script_seconds']:.0f} s")


if __name__ == "__main__":
    main()
