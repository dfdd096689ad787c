"""Held edges, ``[supports]`` (docs/model.md section 4, docs/shapes.md): ``"clamped"`` holds u = 0
on an edge, ``"roller"`` its normal component; a held edge that holds u1 replaces the pinned point,
and the loads then need not balance along x1.

Exact solutions (homogeneous tissue, uniform Fg, so every field below is linear in x and lies in
the P1 space: the discrete u equals it up to the LU solve's round-off on any mesh):

- a strip held by a roller on its left edge (u1 = 0) and the symmetry plane (u2 = 0), pulled by a
  traction f on its right edge, law "none", P1 = 0: uniaxial plane stress, ``sigma = f e1 e1``,
  ``[C11 C12; C12 C22] (e11, e22) = (f, 0)``, ``u = (e11 x1, e22 x2)``; on the rectangle, an
  outline and a mesh file (each of its ways to name an edge);
- the same strip clamped on the left and held by a roller on the top: u2 = 0 everywhere (the
  clamp's u2 = 0 agrees), ``u1 = f x1 / C11``; with finite kinematics ``u1 = (lam - 1) x1``,
  ``lam (lam^2 - 1) / 2 C11 = f`` (first Piola ``P11 = lam S11``, ``S11 = C11 Ee11``; the right
  edge keeps its length, so the traction per current length is per reference length);
- turgor on a homogeneous tissue held by a roller on its left or right edge and the symmetry
  plane gives the field of the free, pinned run up to a translation along x1 (the free run's u1
  vanishes on the left edge: grad u has no 12 entry, the cell being symmetric), at every step,
  linear and finite kinematics.

The held edges' force (summary.csv ``held_force_1``, ``held_force_2``) is the integral of the
exact stress over them, ``-f H`` along x1 where a held edge carries the pull, the confined
strip's ``sigma22 W`` on its top roller, 0 under turgor alone; and while the tissue grows, the
clamp's x1 force balances the pull on the grown right edge (the symmetry plane carries no x1).

Tolerances: ROUND_OFF = 1e-9 of the largest value, as tests/test_macro_exact_solutions.py (LU
round-off, measured 4e-14 to 6e-13 here; Newton's and CG + GAMG's relative tolerance 1e-10,
measured 1.4e-11 and 2.6e-11: the iterative runs set ``solver.macro_rtol = 1e-10``, whose
default 1e-8 leaves 5.4e-9); the cell's shear coupling E1112, E2212, zero for the
mirror-symmetric honeycomb, would break the exact solutions: it is 4e-15 of E1111 (round-off;
checked below 1e-12)."""

from __future__ import annotations

import csv
import shutil
import subprocess
from pathlib import Path

import malformed_inputs as mi
import numpy as np
import pytest
from cli_helpers import ENV, PLANTGROWTH, RANK0, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.base.gather import MeshGather
from plantgrowth.meshes.polygon import write_polygon_msh
from plantgrowth.models import growth
from plantgrowth.models.macro.model import macro_model
from plantgrowth.scene import SceneError, load_scene, parse_scene
from plantgrowth.studies.sweep_file import load_sweep

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "scenes" / "examples" / "held_and_pulled.toml"
ROUND_OFF = 1e-9  # the solvers' round-off and tolerances (module docstring)
STRIP = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]  # edges 0 bottom, 1 right, 2 top, 3 left
PULL = 2e-5  # f: a 1% uniaxial stretch of the reference honeycomb (E1 = 0.00232)
CONFINED_PULL = 6e-4  # f: a 2% confined stretch (C11 = 0.0306: nu12 ~ 0.96 stiffens it 13-fold)


def strip(supports: dict, loads: dict, **more) -> dict:
    """The 2 x 1 strip, no turgor, no growth (law "none": one solve at Fg = I), exact cells."""
    return {
        "tissue": {"width": 2.0, "height": 1.0, "h": 0.25, "H": 1.0},
        "pressure": {"P1": 0.0},
        "growth": {"law": "none"},
        "accuracy": {"cell_resolution": 1, "cell_tolerance": 0.0},
        "supports": supports,
        "loads": loads,
        **more,
    }


def solved(data: dict, directory: Path | None = None):
    """The macro model of a scene after its first solve."""
    model = macro_model(parse_scene(data, directory=directory), MPI.COMM_WORLD)
    model.step(model.initial_growth())
    return model


def nodes_and_u(model) -> tuple[np.ndarray, np.ndarray]:
    """This rank's P1 node coordinates (n, 2) and displacements (n, 2)."""
    V = model.problem.V
    x = V.tabulate_dof_coordinates()[:, :2]
    return x, model.problem.u.x.array.reshape(-1, 2)[: len(x)]


def stiffness(model) -> np.ndarray:
    """The (uniform) Voigt matrix C of E_hom, checked uniform and without shear coupling."""
    C = model.problem.cell_values(model.problem.C).reshape(-1, 3, 3)
    assert np.ptp(C, axis=0).max() <= 1e-12 * C[0, 0, 0]  # Fg = I everywhere: one cell problem
    coupling = np.abs(C[0, :2, 2]).max() / C[0, 0, 0]
    assert coupling < 1e-12, coupling  # measured 4e-15 at cell_resolution 1 (round-off)
    return C[0]


def relative_error(u: np.ndarray, expected: np.ndarray) -> float:
    """max |u - expected| / max |expected| over all ranks."""
    comm = MPI.COMM_WORLD
    error = comm.allreduce(float(np.abs(u - expected).max(initial=0.0)), op=MPI.MAX)
    return error / comm.allreduce(float(np.abs(expected).max(initial=0.0)), op=MPI.MAX)


@pytest.fixture(scope="module")
def strip_msh(tmp_path_factory) -> Path:
    """STRIP as a mesh file with the named edges symmetry, pull, top and held."""
    directory = shared_dir(tmp_path_factory, "strip_msh")
    if MPI.COMM_WORLD.rank == 0:
        names = {"symmetry": [0], "pull": [1], "top": [2], "held": [3]}
        write_polygon_msh(np.array(STRIP), 0.25, names, str(directory / "strip.msh"))
    MPI.COMM_WORLD.Barrier()
    return directory


@pytest.mark.parametrize("shape", ["rectangle", "outline", "mesh"])
def test_a_roller_held_strip_pulled_on_the_other_side_is_in_uniaxial_stress(shape, strip_msh):
    """Roller on the left edge, traction f on the right one: the plane-stress closed form. The
    loads do not balance along x1 (the roller carries f): accepted, and no pinned point."""
    held, pulled = {"rectangle": ("left", "right"), "outline": ("edge3", "edge1"),
                    "mesh": ("held", "pull")}[shape]  # fmt: skip
    data = strip({held: "roller"}, {pulled: [PULL, 0.0]})
    if shape != "rectangle":
        tissue = {"outline": STRIP} if shape == "outline" else {"mesh": "strip.msh"}
        data["tissue"] = tissue | {"h": 0.25, "H": 1.0}
    model = solved(data, strip_msh)
    assert not model.scene.pinned and model.scene.held_components() == {held: (0,)}
    C = stiffness(model)
    e11, e22 = np.linalg.solve(C[:2, :2], [PULL, 0.0])
    assert e11 > 0.005 and e22 < -0.5 * e11  # stretched, and thinner (nu12 ~ 0.96)
    x, u = nodes_and_u(model)
    error = relative_error(u, x * [e11, e22])
    print(f"{shape}: uniaxial plane stress, max |u - u_exact| / max |u_exact| = {error:.2e}")
    assert error <= ROUND_OFF
    F1, F2 = model.problem.held.force()  # the roller carries the pull f on the edge of length 1
    assert abs(F1 + PULL) <= ROUND_OFF * PULL and F2 == 0.0  # a roller on x1 = 0 holds u1 only


def confined_stretch(C11: float, f: float) -> float:
    """lam - 1 of the finite confined pull: the real root of lam (lam^2 - 1) / 2 C11 = f."""
    roots = np.roots([C11 / 2, 0.0, -C11 / 2, -f])
    return float(max(r.real for r in roots if abs(r.imag) < 1e-12)) - 1.0


@pytest.mark.mpi
@pytest.mark.parametrize("solver", ["direct", "iterative"])
@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_a_clamped_strip_with_a_roller_on_top_is_in_confined_tension(kinematics, solver):
    """Clamped on the left, u2 = 0 on the top, pulled on the right: u2 = 0, u1 = e x1 with e =
    f / C11 (linear) or the finite stretch; the two differ by 3% at this pull, far above the
    tolerance, so the finite run must really be finite."""
    f = CONFINED_PULL
    data = strip({"left": "clamped", "top": "roller"}, {"right": [f, 0.0]})
    solver_table = {"macro": solver} | ({"macro_rtol": 1e-10} if solver == "iterative" else {})
    model = solved(data | {"kinematics": kinematics, "solver": solver_table})
    C = stiffness(model)
    C11 = C[0, 0]
    e = f / C11 if kinematics == "linear" else confined_stretch(C11, f)
    assert e > 0.015 and abs(confined_stretch(C11, f) - f / C11) > 0.02 * e
    x, u = nodes_and_u(model)
    error = relative_error(u, x * [e, 0.0])
    print(f"{kinematics}: confined tension e = {e:.6g}, relative error {error:.2e}")
    assert error <= ROUND_OFF
    # the clamp holds the pull on the right edge (length 1); the top roller (length 2) the
    # confined stress sigma22 = C12 e11 (linear) or S22 = C12 Ee11 (finite: F22 = 1)
    strain = e if kinematics == "linear" else e + e * e / 2  # e11 or Ee11 = (lam^2 - 1) / 2
    F1, F2 = model.problem.held.force()
    expected = np.array([-f, 2.0 * C[0, 1] * strain])
    assert expected[1] > 0.5 * f  # nu12 ~ 0.96: the roller holds the top with about 2 f
    assert np.abs([F1, F2] - expected).max() <= ROUND_OFF * f


def turgor_scene(kinematics: str, supports: dict) -> dict:
    """A homogeneous tissue under turgor, growing (stress law, anisotropic Fg0) for 3 steps."""
    return {
        "kinematics": kinematics,
        "tissue": {"width": 3.0, "height": 1.5, "h": 0.25, "H": 1.5},
        "growth": {"law": "stress", "Fg0": [[1.2, 0.0], [0.0, 1.0]]},
        "time": {"t_max": 3.0},
        "accuracy": {"cell_resolution": 1, "cell_tolerance": 0.0},
        "supports": supports,
    }


def displacements(data: dict) -> tuple[np.ndarray, list[np.ndarray]]:
    """Node coordinates and u after each of the scene's steps (growth advanced as a run does),
    global and in the canonical node order on every rank (two runs' partitions may differ);
    the held edges' force must vanish at every step (no load, zero total stress)."""
    scene = parse_scene(data)
    model = macro_model(scene, MPI.COMM_WORLD)
    gather = MeshGather(model.problem.V, root=None)
    Fg, out = model.initial_growth(), []
    for _ in range(scene.time.n_steps):
        result = model.step(Fg)
        out.append(gather.function(model.problem.u))
        if scene.supports:  # scale: the turgor P1 = 0.001 on the held edge's length 1.5
            assert np.abs(result.held_force).max() <= ROUND_OFF * 0.001 * 1.5
        Fg = growth.advance(Fg, result.G, scene.time.dt, scene.time.integrator)
    return gather.points(), out


@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_turgor_on_a_roller_held_tissue_gives_the_free_field_up_to_a_translation(kinematics):
    """Rollers on the left, then on the right edge, against the free run pinned at the origin:
    the same u up to a translation along x1 (0 for the left roller), at every step. A pin kept
    next to the right roller would hold the tissue at both ends and change the field."""
    x, free = displacements(turgor_scene(kinematics, {}))
    right = np.isclose(x[:, 0], 3.0)
    for edge in ("left", "right"):
        _, held = displacements(turgor_scene(kinematics, {edge: "roller"}))
        for step, (a, b) in enumerate(zip(held, free, strict=True)):
            shift = 0.0
            if edge == "right":  # u1 of the free run on the right edge (uniform there)
                shift = b[right, 0][0]
                assert shift > 0.01  # turgor and growth stretch the tissue along x1
            error = relative_error(a, b - [shift, 0.0])
            print(
                f"{kinematics}, roller on {edge}, step {step + 1}: relative difference {error:.2e}"
            )
            assert error <= ROUND_OFF


# --- scenes -------------------------------------------------------------------------------------

BAD_SUPPORTS = {  # name -> (supports, loads of strip(), fragment of the error)
    "unknown edge": ({"bottom_left": "clamped"}, {}, "unknown key 'supports.bottom_left'"),
    "unknown kind": ({"left": "fixed"}, {}, "supports.left = 'fixed' is invalid"),
    "not a string": ({"left": 1}, {}, "supports.left: expected a string"),
    "held and loaded": ({"right": "clamped"}, {"right": [PULL, 0.0]}, "is also loaded"),
    "held and loaded by zero": ({"top": "roller"}, {"top": [0.0, 0.0]}, "is also loaded"),
    "roller on x2 = 0": ({"bottom": "roller"}, {}, "holds u2 = 0 already"),
    "unbalanced, u1 free": ({"top": "roller"}, {"right": [PULL, 0.0]}, "net x1 force"),
}


@pytest.mark.parametrize("name", list(BAD_SUPPORTS))
def test_bad_supports_are_named_errors(name):
    supports, loads, message = BAD_SUPPORTS[name]
    with pytest.raises(SceneError) as e:
        parse_scene(strip(supports, loads))
    assert message in str(e.value)


def test_supports_on_shapes_and_their_limits(strip_msh):
    """Shape edges by name; an inclined roller, a point and the micro model are named errors."""
    slope = [[0.0, 0.0], [3.0, 0.0], [2.0, 1.0], [0.0, 1.0]]  # edge1 inclined
    outline = {"tissue": {"outline": slope, "h": 0.25, "H": 1.0}}
    scene = parse_scene(strip({"edge1": "clamped", "edge0": "clamped"}, {}) | outline)
    assert scene.held_components() == {"edge1": (0, 1), "edge0": (0, 1)} and not scene.pinned
    with pytest.raises(SceneError, match="'edge1' is parallel to neither x1 nor x2"):
        parse_scene(strip({"edge1": "roller"}, {}) | outline)
    mesh = {"tissue": {"mesh": "strip.msh", "h": 0.25, "H": 1.0}}
    with pytest.raises(SceneError, match="unknown key 'supports.pinned'"):
        parse_scene(strip({"pinned": "clamped"}, {}) | mesh, directory=strip_msh)
    assert parse_scene(strip({"top": "roller"}, {}) | mesh, directory=strip_msh).pinned
    for model in ("micro", "both"):
        with pytest.raises(SceneError, match="supports: the micro model"):
            parse_scene(strip({"left": "clamped"}, {}) | {"model": model})


def test_compare_refuses_a_scene_with_held_edges(tmp_path_factory, capsys):
    """``plantgrowth compare`` runs the micro model: a named error, exit 2, nothing written."""
    directory = shared_dir(tmp_path_factory, "compare")
    write(directory / "held.toml", '[growth]\nlaw = "stress"\n[supports]\nleft = "roller"\n')
    argv = ["compare", directory / "held.toml", "--nx", "4", "-o", directory / "out"]
    code, _, err = call(argv, capsys)
    assert code == 2 and not (directory / "out").exists()
    if RANK0:
        assert err.startswith("plantgrowth: error: supports: the micro model")


def test_supports_are_written_back_and_only_when_given():
    scene = parse_scene(strip({"left": "clamped", "top": "roller"}, {"right": [PULL, 0.0]}))
    assert scene.to_dict()["supports"] == {"left": "clamped", "top": "roller"}
    assert parse_scene(scene.to_dict()) == scene
    assert "supports" not in parse_scene(strip({}, {})).to_dict()


def test_the_fuzzer_class_bad_supports_gives_named_errors(tmp_path_factory, capsys):
    """Every case of the class ends with its named error, exit code 2 and nothing written."""
    cases = mi.generate(7, 16, {"bad_supports": 1.0})
    kinds = {"edge": "'supports.", "loaded": "is also loaded", "kind": "supports.",
             "inclined": "parallel to neither", "micro": "supports: the micro model"}  # fmt: skip
    found = {k for c in cases for k, f in kinds.items() if c.expect[-1].startswith(f)}
    assert found == set(kinds)  # the seed covers every kind of bad [supports]
    for case in cases:
        directory = shared_dir(tmp_path_factory, case.name[:30])
        argv = MPI.COMM_WORLD.bcast(case.materialize(directory) if RANK0 else None, root=0)
        before = mi.snapshot(directory)
        code, out, err = call(argv, capsys)
        if MPI.COMM_WORLD.rank == 0:
            found = mi.problems(case, directory, code, out, err, before)
            assert not found, f"{case.name}: {found}"


@pytest.mark.mpi
def test_a_clamp_holds_the_pull_on_the_growing_edge():
    """The example scene, 4 steps: the clamp's x1 force balances the loads' x1 resultant on the
    grown right edge at every step (the symmetry plane holds no x1), which grows with the
    tissue; its x2 force holds the tissue's growth along x2 back (negative)."""
    scene = load_scene(EXAMPLE).replace(**{"time.t_max": 4.0})
    model = macro_model(scene, MPI.COMM_WORLD)
    Fg, pulls = model.initial_growth(), []
    for _ in range(scene.time.n_steps):
        result = model.step(Fg)
        pull = model.problem.loads.balance().net
        F1, F2 = result.held_force
        assert abs(F1 + pull) <= ROUND_OFF * abs(pull) and F2 < 0.0
        pulls.append(pull)
        Fg = growth.advance(Fg, result.G, scene.time.dt, scene.time.integrator)
    assert pulls[0] == pytest.approx(2e-5 * 2.0, rel=1e-12) and np.all(np.diff(pulls) > 0.0)


def test_a_sweep_varies_a_held_edge(tmp_path):
    """``supports.<edge>`` is a sweep key like ``loads.<edge>``, even where the base holds none."""
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "{EXAMPLE}"\n[vary]\n"supports.left" = ["clamped", "roller"]\n'
                     '"supports.top" = ["roller"]\n')  # fmt: skip
    runs = load_sweep(sweep).runs
    assert [r.scene.held_components() for r in runs] == [
        {"left": (0, 1), "top": (1,)}, {"left": (0,), "top": (1,)}
    ]  # fmt: skip


# --- the example scene --------------------------------------------------------------------------


def summary(directory: Path) -> dict[str, np.ndarray]:
    with open(directory / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.mpi
def test_the_held_and_pulled_example_runs(tmp_path_factory, capsys):
    """scenes/examples/held_and_pulled.toml: held on the left, pulled on the right; it runs,
    grows faster along the pull, and writes no load_imbalance (the held edge carries the load)."""
    scene = load_scene(EXAMPLE)
    assert not scene.pinned and scene.loads and scene.supports
    directory = shared_dir(tmp_path_factory, "example")
    code, _, err = call(["run", EXAMPLE, "-o", directory / "run"], capsys)
    assert code == 0, err
    table = summary(directory / "run")
    assert "load_imbalance" not in table
    np.testing.assert_allclose(table["held_force_1"][0], -2e-5 * 2.0, rtol=ROUND_OFF)
    assert len(table["t"]) == scene.time.n_steps + 1
    assert np.all(table["growth_rate_11"] > table["growth_rate_22"])


@pytest.mark.skip_in_parallel
def test_mpirun_reproduces_the_serial_example(tmp_path_factory, capsys):
    """``mpirun -n 2 plantgrowth run`` of the example against the serial run, 1e-8 relative as
    tests/test_tissue_shapes.py (only the LU and the reductions' order differ)."""
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    directory = shared_dir(tmp_path_factory, "example_mpirun")
    code, _, err = call(["run", EXAMPLE, "-o", directory / "serial"], capsys)
    assert code == 0, err
    command = [mpirun, "-n", "2", PLANTGROWTH, "run", str(EXAMPLE), "-o", str(directory / "mpi")]
    done = subprocess.run(command, capture_output=True, text=True, env=ENV, timeout=300)
    assert done.returncode == 0, done.stderr
    serial, parallel = summary(directory / "serial"), summary(directory / "mpi")
    for column in (
        "area",
        "growth_rate_11",
        "growth_rate_22",
        "u1_max",
        "u2_max",
        "held_force_1",
        "held_force_2",
    ):
        np.testing.assert_allclose(parallel[column], serial[column], rtol=1e-8, err_msg=column)
