"""Homogenized tensors of the unit-cell problems (docs/model.md section 3): the listed properties.

Solvers live on ``MPI.COMM_WORLD`` so that ``mpirun -n 2 ... pytest`` exercises the distributed
cell mesh; each geometry is meshed once per module (``solver`` fixture) and ``solve`` is reused.

Where tolerances come from (measured on the reference cell, E = 1, nu = 0.3, w = 0.05, against
resolution 6, see ``test_convergence_under_refinement``):
- discretization error of moduli at resolution 3: E1, G12 ~0.19%, nu12 ~0.006%, K ~0.02%
  (always too stiff: conforming displacement FE);
- solver round-off: one LU solve of a system with condition number <~1e8 (thin walls, P2),
  measured <1e-13 relative on identities that hold exactly for the discrete solution.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI
from results_json import write_results

from plantgrowth.base.tensors import isotropic_tensor, orthotropic_moduli
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell.solver import CellSolver

E_WALL, NU_WALL = 1.0, 0.3
MU_WALL = E_WALL / (2 * (1 + NU_WALL))
REFERENCE = HoneycombCell()
# Relative error of round-off size for identities exact in the discrete problem (measured <1e-13,
# margin for MUMPS in parallel and for thin walls).
ROUND_OFF = 1e-10
# Discretization error of E1 and G12 at resolution 3 (0.19% measured against resolution 6, which
# is itself ~0.05% off): two meshes of the same cell can differ by at most about that much.
DISCRETIZATION_RES3 = 2.5e-3


@pytest.fixture(scope="module")
def solver():
    """``solver(cell, resolution=3, shape=..., origin=..., comm=...)``: one CellSolver per key."""
    cache: dict = {}

    def get(
        cell: HoneycombCell = REFERENCE,
        resolution: int = 3,
        shape: str = "hexagon",
        origin: tuple[float, float] = (0.0, 0.0),
        comm: MPI.Comm = MPI.COMM_WORLD,
    ) -> CellSolver:
        key = (cell, resolution, shape, tuple(origin), comm == MPI.COMM_WORLD)
        if key not in cache:
            cache[key] = CellSolver(cell, resolution, comm, shape=shape, origin=origin)
        return cache[key]

    yield get
    cache.clear()


def _mandel(T: np.ndarray) -> np.ndarray:
    """3x3 matrix of a (2,2,2,2) tensor in the basis e11, e22, sqrt2 e12 (shear scaled)."""
    s2 = math.sqrt(2.0)
    idx = [(0, 0), (1, 1), (0, 1)]
    scale = [1.0, 1.0, s2]
    return np.array(
        [[scale[a] * scale[b] * T[idx[a] + idx[b]] for b in range(3)] for a in range(3)]
    )


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest component difference relative to the largest component."""
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / np.abs(np.asarray(b)).max())


def _moduli(result) -> dict:
    return orthotropic_moduli(result.E_voigt)


SHEAR = np.array([[1.2, 0.3], [0.0, 1.0]])
CASES = [
    (REFERENCE, None),
    (HoneycombCell(l1=2.0), None),
    (HoneycombCell(theta_deg=45.0), None),
    (REFERENCE, np.diag([1.5, 1.0])),
    (REFERENCE, SHEAR),
    (HoneycombCell(theta_deg=45.0, l1=1.5), SHEAR),
]
CASE_IDS = ["reference", "l1=2", "theta=45", "grown", "sheared", "theta=45-l1=1.5-sheared"]


# --- wall tensor -----------------------------------------------------------------------------


def test_wall_tensor_is_plane_stress_isotropic():
    C = isotropic_tensor(2.0, 0.25)
    mu, lam = 2.0 / 2.5, 2.0 * 0.25 / (1 - 0.0625)  # docs/model.md section 1
    e = np.array([[0.3, -0.7], [-0.7, 1.1]])
    np.testing.assert_allclose(
        np.einsum("ijkl,kl->ij", C, e), lam * np.trace(e) * np.eye(2) + 2 * mu * e, rtol=1e-14
    )


# --- 1. symmetries and positive definiteness ---------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("cell, Fg", CASES, ids=CASE_IDS)
def test_symmetries_and_positive_definiteness(solver, cell, Fg):
    r = solver(cell).solve(Fg, E_WALL, NU_WALL)
    E = r.E_hom
    # major symmetry holds for the discrete solution too (symmetric Galerkin form, exact
    # quadrature of P1 x P1 integrands): round-off only
    assert _rel(E, E.transpose(2, 3, 0, 1)) < ROUND_OFF
    assert _rel(E, E.transpose(1, 0, 2, 3)) < ROUND_OFF
    assert _rel(E, E.transpose(0, 1, 3, 2)) < ROUND_OFF
    assert _rel(r.K_hom, r.K_hom.T) < ROUND_OFF
    assert _rel(r.dbar_w, r.dbar_w.transpose(1, 0, 2, 3)) < ROUND_OFF
    assert _rel(r.dbar_w, r.dbar_w.transpose(0, 1, 3, 2)) < ROUND_OFF
    assert _rel(r.dbar_v, r.dbar_v.T) < ROUND_OFF
    eigs = np.linalg.eigvalsh(_mandel(E))
    # smallest/largest eigenvalue is ~0.005-0.02 here (bending vs stretching of thin walls),
    # many orders above round-off
    assert eigs.min() > 1e-4 * eigs.max() > 0
    # the pressure problem stores energy: int E[d v]:d v = -int tr d v  => tr dbar_v < 0
    assert np.trace(r.dbar_v) < 0


@pytest.mark.parametrize("cell, Fg", CASES, ids=CASE_IDS)
def test_reciprocity_K_equals_trace_of_dbar_w(solver, cell, Fg):
    """Betti: testing [UC_weak] with v and [UCw_weak] with w^ij gives K_ij = tr dbar[w^ij].

    Jg is constant and cancels, so this holds for any Fg and for the discrete solution exactly.
    """
    r = solver(cell).solve(Fg, E_WALL, NU_WALL)
    assert _rel(np.einsum("ijkk->ij", r.dbar_w), r.K_hom) < ROUND_OFF


# --- 2. isotropy of the regular hexagon ---------------------------------------------------------


def test_regular_hexagon_is_isotropic(solver):
    r = solver().solve(None, E_WALL, NU_WALL)
    E1111, E2222, E1122, E1212, E1112, E2212 = r.E_voigt
    m = _moduli(r)
    # The mesh is not exactly invariant under the hexagon's 60 degree rotation; the anisotropy
    # it introduces is bounded by the discretization error (0.19% on E1, G12 at resolution 3),
    # we allow 1e-3 (measured: ~1e-9, the mesh is nearly symmetric).
    tol = 1e-3
    assert E2222 == pytest.approx(E1111, rel=tol)
    assert m["E2"] == pytest.approx(m["E1"], rel=tol)
    assert abs(E1112) < tol * m["E1"]
    assert abs(E2212) < tol * m["E1"]
    assert m["G12"] == pytest.approx(m["E1"] / (2 * (1 + m["nu12"])), rel=tol)
    K = r.K_hom
    assert K[1, 1] == pytest.approx(K[0, 0], rel=tol)
    assert abs(K[0, 1]) < tol * abs(K[0, 0])
    # sanity values of docs/model.md section 2 (resolution-3 values, 0.2% discretization error)
    assert r.phi_w == pytest.approx(0.11214, abs=1e-5)
    assert m["E1"] == pytest.approx(2.32e-3, rel=5e-3)
    assert m["nu12"] == pytest.approx(0.961, abs=1e-3)


def test_P2_matrix_is_void_fraction(solver):
    """int_Gamma y_j N_i = -|Y_c| delta_ij (divergence theorem, N out of the walls), so
    P2_matrix = (1 - phi_w) I; exact for straight facets up to round-off."""
    for cell, Fg in [(REFERENCE, None), (HoneycombCell(l1=2.0), SHEAR)]:
        r = solver(cell).solve(Fg, E_WALL, NU_WALL)
        np.testing.assert_allclose(r.P2_matrix, (1 - r.phi_w) * np.eye(2), atol=1e-12)
        # the meshed walls are exactly the polygonal walls
        assert r.phi_w == pytest.approx(cell.phi_w, abs=1e-12)
        np.testing.assert_allclose(r.P2vec([0.3, -2.0]), (1 - r.phi_w) * np.array([0.3, -2.0]))


# --- 3. isotropic growth -----------------------------------------------------------------------


@pytest.mark.parametrize("cell", [REFERENCE, HoneycombCell(l1=1.5, theta_deg=45.0)], ids=str)
@pytest.mark.parametrize("g", [1.3, 2.0])
def test_isotropic_growth_changes_nothing(solver, cell, g):
    """Fg = g I: the solution is g times the Fg = I one, in the same FE space; round-off only."""
    s = solver(cell)
    r1 = s.solve(None, E_WALL, NU_WALL)
    rg = s.solve(g * np.eye(2), E_WALL, NU_WALL)
    for name in ("E_hom", "K_hom", "dbar_w", "dbar_v"):
        assert _rel(getattr(rg, name), getattr(r1, name)) < ROUND_OFF, name


# --- 4. Voigt bound ------------------------------------------------------------------------------


@pytest.mark.parametrize("cell, Fg", CASES, ids=CASE_IDS)
def test_voigt_bound(solver, cell, Fg):
    """e:E_hom:e = min_w (1/|Y|) int E[e + d w]:(e + d w) <= phi_w e:E:e (w = 0 is admissible).

    The FE solution minimises over a subspace that contains 0, so the bound holds for the
    discrete tensor too: only round-off may violate it. Likewise the pressure tensor obeys
    (e:K)^2 <= (-tr dbar_v) phi_w e:E:e (Cauchy-Schwarz in the energy inner product with
    int E[d v]:d v = -|Y| tr dbar_v), exact for the discrete solution.
    """
    r = solver(cell).solve(Fg, E_WALL, NU_WALL)
    C_voigt = r.phi_w * isotropic_tensor(E_WALL, NU_WALL)
    gap = np.linalg.eigvalsh(_mandel(C_voigt) - _mandel(r.E_hom))
    assert gap.min() > -ROUND_OFF * np.abs(_mandel(C_voigt)).max()
    rng = np.random.default_rng(7)
    for _ in range(20):
        e = rng.standard_normal((2, 2))
        e = 0.5 * (e + e.T)
        wall = np.einsum("ij,ijkl,kl", e, C_voigt, e)
        assert np.einsum("ij,ijkl,kl", e, r.E_hom, e) <= wall * (1 + ROUND_OFF)
        assert np.sum(e * r.K_hom) ** 2 <= -np.trace(r.dbar_v) * wall * (1 + ROUND_OFF)


# --- 5. monotone in w ---------------------------------------------------------------------------


def test_moduli_increase_with_wall_thickness(solver):
    # successive moduli differ by factors >= 4 (bending ~ w^3), far beyond the 0.2% error
    moduli = [_moduli(solver(HoneycombCell(w=w)).solve()) for w in (0.03, 0.05, 0.1, 0.2)]
    for key in ("E1", "E2", "G12"):
        values = [m[key] for m in moduli]
        assert all(np.diff(values) > 0), (key, values)


# --- 6. void vanishing --------------------------------------------------------------------------


def test_moduli_tend_to_the_wall_as_the_void_vanishes(solver):
    distances, phis = [], []
    for ratio in (0.8, 0.95, 0.99):
        r = solver(HoneycombCell(w=ratio * REFERENCE.w_max)).solve(None, E_WALL, NU_WALL)
        m = _moduli(r)
        d = max(
            abs(m["E1"] / E_WALL - 1),
            abs(m["E2"] / E_WALL - 1),
            abs(m["nu12"] / NU_WALL - 1),
            abs(m["G12"] / MU_WALL - 1),
        )
        distances.append(d)
        phis.append(r.phi_w)
    assert all(np.diff(distances) < 0), distances
    # at w = 0.99 w_max the void fills 1 - phi_w = 1e-4 of the cell; a dilute hole softens by
    # a few times its area fraction (3 f for a circular hole), so ~3e-4; allow 1e-3
    assert distances[-1] < 1e-3, distances
    assert all(np.diff(phis) > 0)
    # similar hexagon of apothem c - w: 1 - phi_w = (1 - w/w_max)^2 = 1e-4 (exact, polygonal)
    assert 1 - phis[-1] == pytest.approx(1e-4, rel=1e-6)


# --- 7. independence of the periodic cell -------------------------------------------------------


@pytest.mark.parametrize(
    "cell, Fg",
    [(REFERENCE, None), (HoneycombCell(l1=1.5), np.diag([1.4, 1.0]))],
    ids=["reference", "l1=1.5-grown"],
)
def test_fundamental_domain_does_not_matter(solver, cell, Fg):
    """Hexagon vs two parallelograms: different meshes of the same periodic walls.

    Each result carries its own discretization error (<= DISCRETIZATION_RES3, same sign: too
    stiff), so the results may differ by up to that much (measured: 3.4e-4 on E1, <7e-5 on
    tensor components relative to the largest one).
    """
    results = [
        solver(cell, shape=shape, origin=origin).solve(Fg, E_WALL, NU_WALL)
        for shape, origin in [
            ("hexagon", (0.0, 0.0)),
            ("parallelogram", (-0.3, -0.2)),
            ("parallelogram", (0.1, -0.45)),
        ]
    ]
    ref = results[0]
    for r in results[1:]:
        assert r.phi_w == pytest.approx(ref.phi_w, abs=1e-12)  # same polygonal walls
        assert r.P2_matrix is None
        for name in ("E_hom", "K_hom", "dbar_w", "dbar_v"):
            assert _rel(getattr(r, name), getattr(ref, name)) < DISCRETIZATION_RES3, name
        m, m_ref = _moduli(r), _moduli(ref)
        for key in ("E1", "E2", "nu12", "G12"):
            assert m[key] == pytest.approx(m_ref[key], rel=DISCRETIZATION_RES3), key


@pytest.mark.mpi
def test_comm_self_equals_comm_world(solver):
    """The distributed solve (MUMPS under mpirun) reproduces the rank-local one (PETSc LU)."""
    Fg = np.array([[1.3, 0.1], [0.0, 1.0]])
    cell = HoneycombCell(l1=1.5, theta_deg=40.0)
    r_self = solver(cell, comm=MPI.COMM_SELF).solve(Fg, E_WALL, NU_WALL)
    r_world = solver(cell, comm=MPI.COMM_WORLD).solve(Fg, E_WALL, NU_WALL)
    assert r_world.ndofs == r_self.ndofs
    for name in ("E_hom", "K_hom", "dbar_w", "dbar_v"):
        assert _rel(getattr(r_world, name), getattr(r_self, name)) < ROUND_OFF, name
    # derived moduli lose ~1 digit to the cancellation in E1111 - E1122^2/E2222
    m_self, m_world = _moduli(r_self), _moduli(r_world)
    for key in m_self:
        assert m_world[key] == pytest.approx(m_self[key], rel=1e-8), key


# --- 8. convergence -----------------------------------------------------------------------------


@pytest.mark.convergence
def test_convergence_under_refinement(solver, mpi_tmp_path):
    """Resolutions 1-4 against 6 on the reference cell.

    Moduli are energy quantities: error ~ h^(2 lambda) at least, lambda ~ 0.62 at the wall
    joints' re-entrant 240 degree corners, ~h^2-h^4 while bending dominates (measured rates 1.6,
    2.9, 2.0; the last is lowered by the reference's own ~0.05% error).
    """
    resolutions = [1, 2, 3, 4]
    ref = _moduli(solver(REFERENCE, 6).solve(None, E_WALL, NU_WALL))
    keys = ("E1", "nu12", "G12")
    errors = {k: [] for k in keys}
    errors["K11"] = []
    ref_K = solver(REFERENCE, 6).solve(None, E_WALL, NU_WALL).K_hom[0, 0]
    for res in resolutions:
        r = solver(REFERENCE, res).solve(None, E_WALL, NU_WALL)
        m = _moduli(r)
        for k in keys:
            errors[k].append(abs(m[k] / ref[k] - 1))
        errors["K11"].append(abs(r.K_hom[0, 0] / ref_K - 1))
    h = 1.0 / np.array(resolutions, dtype=float)
    rates = {
        k: (np.log(np.array(e[:-1]) / np.array(e[1:])) / np.log(h[:-1] / h[1:])).tolist()
        for k, e in errors.items()
    }
    if MPI.COMM_WORLD.rank == 0:
        print(f"\ncell convergence vs resolution 6: resolutions {resolutions}")
        for k in errors:
            print(f"  {k:5s} errors {np.array(errors[k])}  rates {np.round(rates[k], 2)}")
        data = {
            "cell": "reference (l1 = l2 = 1, theta = 30, w = 0.05), E = 1, nu = 0.3",
            "reference_resolution": 6,
            "resolutions": resolutions,
            "relative_errors": errors,
            "observed_rates": rates,
        }
        write_results("cell_convergence.json", data, mpi_tmp_path)
    for k, e in errors.items():
        assert all(np.diff(e) < 0), (k, e)
    # the corner singularity bounds the rate from below by 2 lambda ~ 1.2; allow 1.0
    assert all(rate > 1.0 for rate in rates["E1"]), rates["E1"]
    assert errors["E1"][-1] < 2e-3
    assert errors["E1"][0] < 3e-2  # resolution 1: ~2% (house-style measurement for P2, 1 across)


# --- 9. Gibson-Ashby thin-wall limit -----------------------------------------------------------


@pytest.mark.mpi
def test_gibson_ashby_thin_walls(solver):
    """E1/E -> (t/l)^3 cos(theta) / ((l1/l2 + sin theta) sin^2 theta), t = 2w, and nu12 -> 1.

    The beam estimate ignores the joints: rigid joints of size ~t shorten the bending length to
    l - O(t), so E1 is higher by ~3 O(1) t/l (a few percent at t/l = 0.025); axial and shear
    compliance lower it by O((t/l)^2). Discretization adds ~+0.2% (resolution 3). Hence a
    positive deviation below 10% that shrinks with t/l (measured: +0.76% and +0.64%).
    For nu12 the axial compliance enters as O((t/l)^2) with an O(1) geometric factor (measured
    1 - nu12 = 4.0 (t/l)^2): bounded by 10 (t/l)^2 and shrinking.
    """
    th = math.radians(30.0)
    deviations, nu_gaps = [], []
    for w in (0.0125, 0.01):
        t = 2 * w
        m = _moduli(solver(HoneycombCell(w=w)).solve(None, E_WALL, NU_WALL))
        estimate = E_WALL * t**3 * math.cos(th) / ((1 + math.sin(th)) * math.sin(th) ** 2)
        deviations.append(m["E1"] / estimate - 1)
        nu_gaps.append(1 - m["nu12"])
        assert 0 < 1 - m["nu12"] < 10 * t**2
    if MPI.COMM_WORLD.rank == 0:
        print(f"\nGibson-Ashby relative deviations (w = 0.0125, 0.01): {deviations}")
        print(f"1 - nu12: {nu_gaps}")
    assert all(0 < d < 0.1 for d in deviations), deviations
    assert deviations[1] < deviations[0]
    assert nu_gaps[1] < nu_gaps[0]


# --- 10. qualitative facts of docs/model.md section 3 ---------------------------------------------


def test_elongation_along_x2_lowers_E1_nu12_G12(solver):
    # successive values differ by >= 20%, far beyond the 0.2% discretization error
    moduli = [_moduli(solver(HoneycombCell(l1=l1)).solve()) for l1 in (1.0, 1.5, 2.0)]
    for key in ("E1", "nu12", "G12"):
        values = [m[key] for m in moduli]
        assert all(np.diff(values) < 0), (key, values)


def test_growth_along_x1(solver):
    """Fg = diag(g, 1): E1 up, E2 down, |K11| down, |K22| up, nu12 up (steps of >= 4%)."""
    s = solver()
    results = [s.solve(np.diag([g, 1.0]), E_WALL, NU_WALL) for g in (1.0, 1.25, 1.5, 2.0)]
    moduli = [_moduli(r) for r in results]
    E1, E2, nu12 = ([m[k] for m in moduli] for k in ("E1", "E2", "nu12"))
    K11 = [abs(r.K_hom[0, 0]) for r in results]
    K22 = [abs(r.K_hom[1, 1]) for r in results]
    assert all(np.diff(E1) > 0), E1
    assert all(np.diff(E2) < 0), E2
    assert all(np.diff(K11) < 0), K11
    assert all(np.diff(K22) > 0), K22
    assert all(np.diff(nu12) > 0), nu12


def test_G12_is_non_monotonic_in_growth_along_x1(solver):
    """G12 rises from g = 1 to a maximum near g = 1.4-1.5 (+21%) and then falls (-49% at g = 3);
    both changes are two orders above the 0.2% discretization error."""
    s = solver()
    gs = [1.0, 1.25, 1.5, 2.0, 3.0]
    G12 = [_moduli(s.solve(np.diag([g, 1.0]), E_WALL, NU_WALL))["G12"] for g in gs]
    top = int(np.argmax(G12))
    assert 0 < top < len(gs) - 1, G12
    assert all(np.diff(G12[: top + 1]) > 0), G12
    assert all(np.diff(G12[top:]) < 0), G12
