"""The elastic strain a biologist reads (issue 21, item 3): the fields ``elastic_strain`` and
``elastic_strain_tensor``, summary.csv's ``elastic_strain_max`` and its place, and the warnings
once per strain band (plantgrowth/models/elastic_strain.py, plantgrowth/runner/step_warnings.py).

Macro: a pulled homogeneous tissue (the pull of docs/usage.md, 3.5 times harder, so that the
strain starts in the first band), linear and finite kinematics; the written tensor is checked
against the strain computed here from the written u and Fg alone (P1 gradients per triangle).
Micro (linear and finite): under the strain law with tau = 0 and eta = 1 the growth rate G is
each cell's wall-averaged elastic strain (eps_el or Ee; its positive part, positive definite
here), computed by the growth law's own assembly: the written tensor must equal it.
In-process runs through ``main`` (serial and under mpirun: the same values and places), and
serial against ``mpirun -n 2`` as processes. Runs: h = 0.5, H = 1, cell_resolution 1.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from cli_helpers import ENV, PLANTGROWTH, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.models.elastic_strain import (
    PLACE_ROUNDING,
    TIE,
    StrainPeak,
    principal_magnitude,
    strain_peak,
)
from plantgrowth.models.step import StepResult
from plantgrowth.results.run_results import read_results
from plantgrowth.runner.step_warnings import STRAIN_BANDS, StepWarnings

ROUND_OFF = 1e-12  # closed-form 2x2 algebra on O(1) numbers: a few ulps
SOLVE = 1e-9
"""The written fields (float64) against the strain recomputed from the written u: both come from
the same LU solution, so they differ by the round-off of two gradient evaluations (measured
~1e-15 relative); 1e-9 of the strain fails on any real difference (a missing term is >= 1e-3)."""
STRAIN_MESSAGE = "the largest elastic strain reached"
MACRO = """\
kinematics = "{kinematics}"
[tissue]
width = 4.0
height = 2.0
h = 0.5
H = 1.0
[growth]
law = "stress"
[time]
t_max = {t_max}
dt = 1
[loads]
left = [-0.0007, 0]
right = [0.0007, 0]
[accuracy]
cell_resolution = 1
[output]
fields = ["u", "Fg", "elastic_strain", "elastic_strain_tensor"]
precision = "float64"
"""
MICRO = """\
model = "micro"
kinematics = "{kinematics}"
[growth]
law = "strain"
tau = 0.0
[time]
t_max = 1
dt = 1
[micro]
nx = 4
resolution = 1
[output]
fields = ["u", "G", "elastic_strain", "elastic_strain_tensor"]
precision = "float64"
"""


# --- the helpers ---------------------------------------------------------------------------------


def test_principal_magnitude_is_the_largest_absolute_eigenvalue():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(400, 2, 2))
    eps = 0.5 * (A + np.swapaxes(A, 1, 2))
    expected = np.abs(np.linalg.eigvalsh(eps)).max(axis=1)
    assert principal_magnitude(eps) == pytest.approx(expected, rel=0, abs=ROUND_OFF)
    # the symmetric part is used: a rotation-like skew part adds nothing
    skew = np.array([[0.0, 1.0], [-1.0, 0.0]])
    assert principal_magnitude(eps + skew) == pytest.approx(expected, rel=0, abs=ROUND_OFF)


@pytest.mark.mpi
def test_the_peak_place_is_the_same_however_the_units_are_shared_out():
    """Every rank holds a share of the same units; a tie (a uniform tissue, values equal to
    round-off) goes to the smallest (x1, x2), so serial and mpirun report the same place."""
    comm = MPI.COMM_WORLD
    rng = np.random.default_rng(5)
    points = rng.uniform(0.0, 4.0, size=(60, 2))
    values = np.full(60, 0.3) * (1.0 + 1e-14 * rng.normal(size=60))  # uniform up to round-off
    values[:7] = 0.1
    mine = slice(comm.rank, None, comm.size)
    peak = strain_peak(values[mine], points[mine], comm)
    tied = points[7:]
    first = tied[np.lexsort((tied[:, 1], tied[:, 0]))[0]]
    assert peak.value == values.max()
    assert peak.place == tuple(first)
    values[40] = 0.31  # a clear peak wins wherever it is
    assert strain_peak(values[mine], points[mine], comm) == StrainPeak(0.31, tuple(points[40]))


# --- the warnings --------------------------------------------------------------------------------


def _result(strain: float) -> StepResult:
    return StepResult(np.zeros((1, 2, 2)), 1, 0.0, elastic_strain=StrainPeak(strain, (1.5, 0.5)))


def _warned(warnings: StepWarnings, strains: list[float]) -> list[int]:
    """The steps at which a strain warning is given."""
    return [k for k, s in enumerate(strains) if warnings.check(k, float(k), _result(s))]


def test_a_strain_warning_comes_each_time_a_higher_band_is_first_entered():
    low, mid, high = STRAIN_BANDS
    strains = [0.5 * low, 1.1 * low, 1.2 * low, 1.1 * low, 1.1 * mid, 0.9 * mid, 1.5 * high]
    assert _warned(StepWarnings(), strains) == [1, 4, 6]
    # a jump over two bands warns once, naming the higher band
    warnings = StepWarnings()
    text = warnings.check(0, 0.0, _result(1.1 * mid))
    assert len(text) == 1 and f"above {mid:.0%}" in text[0]
    assert warnings.check(1, 1.0, _result(1.2 * low)) == []


def test_a_resumed_run_warns_only_for_bands_its_earlier_steps_had_not_reached():
    low, mid, _ = STRAIN_BANDS
    assert _warned(StepWarnings(strain_reached=1.1 * low), [1.2 * low, 1.3 * low]) == []
    assert _warned(StepWarnings(strain_reached=1.1 * low), [1.2 * low, 1.1 * mid]) == [1]


def test_the_strain_warning_says_what_it_means_and_what_to_do():
    low, mid, _ = STRAIN_BANDS
    linear = StepWarnings("linear").check(3, 3.0, _result(1.1 * low))[0]
    assert "step 3, t = 3" in linear and "x1 = 1.5, x2 = 0.5" in linear
    assert f"{1.1 * low:.3g}" in linear and 'kinematics = "finite"' in linear
    finite = StepWarnings("finite").check(3, 3.0, _result(1.1 * low))[0]
    assert "kinematics are exact" in finite and "wall law" in finite
    large = StepWarnings("linear").check(3, 3.0, _result(1.1 * mid))[0]
    assert "qualitative" in large and "P1" in large


# --- macro runs ----------------------------------------------------------------------------------


def _macro_run(factory, capsys, kinematics: str):
    directory = shared_dir(factory, f"macro_{kinematics}")
    scene = directory / "scene.toml"
    write(scene, MACRO.format(kinematics=kinematics, t_max=2))
    code, _, err = call(["run", scene, "-o", directory / "out"], capsys)
    assert code == 0, err
    return directory, err


def _strain_from_u(results, t: float, finite: bool) -> np.ndarray:
    """(n_triangles, 2, 2) eps_el or Ee from the written P1 u and per-triangle Fg."""
    X, tri = results.points, results.triangles
    u = results.field("u", t)
    edges = np.stack([X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]], axis=1)
    du = np.stack([u[tri[:, 1]] - u[tri[:, 0]], u[tri[:, 2]] - u[tri[:, 0]]], axis=1)
    grad_u = np.swapaxes(np.linalg.solve(edges, du), 1, 2)  # du_i/dX_j
    Finv = np.linalg.inv(results.field("Fg", t))
    if finite:
        Fe = (np.eye(2) + grad_u) @ Finv
        return 0.5 * (np.swapaxes(Fe, 1, 2) @ Fe - np.eye(2))
    A = grad_u @ Finv + Finv
    return 0.5 * (A + np.swapaxes(A, 1, 2)) - np.eye(2)


def _expected_place(points: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """The documented rule: among the units within TIE of the peak, the smallest (x1, x2)."""
    tied = points[values >= values.max() * (1.0 - TIE)]
    key = np.round(tied / PLACE_ROUNDING)
    return tuple(tied[np.lexsort((key[:, 1], key[:, 0]))[0]])


@pytest.mark.mpi
@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_macro_fields_and_columns_are_the_strain_of_the_written_displacement(
    tmp_path_factory, capsys, kinematics
):
    directory, err = _macro_run(tmp_path_factory, capsys, kinematics)
    results = read_results(directory / "out")
    summary = results.summary
    midpoints = results.points[results.triangles].mean(axis=1)
    for t in results.times:
        expected = _strain_from_u(results, t, kinematics == "finite")
        scale = np.abs(expected).max()
        tensor = results.field("elastic_strain_tensor", t)
        assert tensor == pytest.approx(expected, rel=0, abs=SOLVE * scale)
        largest = results.field("elastic_strain", t)
        assert largest == pytest.approx(
            np.abs(np.linalg.eigvalsh(expected)).max(axis=1), rel=0, abs=SOLVE * scale
        )
        row = int(np.flatnonzero(summary["t"] == t)[0])
        assert summary["elastic_strain_max"][row] == pytest.approx(largest.max(), rel=ROUND_OFF)
        place = (summary["elastic_strain_max_x1"][row], summary["elastic_strain_max_x2"][row])
        assert place == pytest.approx(_expected_place(midpoints, largest), abs=1e-12)
    # linear: the pull starts the run in the first band (0.31 measured): one warning, at step 0,
    # naming the place. finite: the same pull stretches the tissue by 0.12 (the lumens' water a
    # follower pressure, issue 36; 0.22 with the former dead load), below the first band: none
    if kinematics == "linear":
        assert STRAIN_BANDS[0] < summary["elastic_strain_max"].max() < STRAIN_BANDS[1]
    else:
        assert 0.0 < summary["elastic_strain_max"].max() < STRAIN_BANDS[0]
    if MPI.COMM_WORLD.rank == 0:
        assert err.count(STRAIN_MESSAGE) == (1 if kinematics == "linear" else 0)
        assert kinematics == "finite" or "step 0, t = 0" in err


@pytest.mark.mpi
def test_a_resumed_run_does_not_repeat_the_warning_of_a_band_already_reached(
    tmp_path_factory, capsys
):
    directory, _ = _macro_run(tmp_path_factory, capsys, "linear")
    longer = directory / "longer.toml"
    write(longer, MACRO.format(kinematics="linear", t_max=3))
    code, _, err = call(["run", longer, "--resume", directory / "out"], capsys)
    assert code == 0, err
    assert STRAIN_MESSAGE not in err
    assert len(read_results(directory / "out").summary["t"]) == 4
    if MPI.COMM_WORLD.rank == 0:  # the first run's warning is in run.log, once
        log = (directory / "out" / "run.log").read_text()
        assert log.count(STRAIN_MESSAGE) == 1


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("material", ["", "[material]\nE = {from = 0.5, to = 2.0}\n"])
def test_mpirun_reports_the_serial_peak_at_the_same_place(tmp_path_factory, capsys, material):
    """The pulled homogeneous tissue's strain is uniform up to round-off (every cell tied) and
    the E gradient's peaks at the soft end: on 2 ranks the places equal the serial ones exactly
    and the values to 1e-8 relative (the solves' round-off, ~1e-13)."""
    directory = shared_dir(tmp_path_factory, "mpirun")
    scene = directory / "scene.toml"
    write(scene, MACRO.format(kinematics="linear", t_max=2) + material)
    code, _, err = call(["run", scene, "-o", directory / "serial"], capsys)
    assert code == 0, err
    done = subprocess.run(
        ["mpirun", "-n", "2", PLANTGROWTH, "run", str(scene), "-o", str(directory / "mpi")],
        env=ENV, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    serial, parallel = (read_results(directory / d).summary for d in ("serial", "mpi"))
    assert parallel["elastic_strain_max"] == pytest.approx(serial["elastic_strain_max"], rel=1e-8)
    for column in ("elastic_strain_max_x1", "elastic_strain_max_x2"):
        assert np.array_equal(parallel[column], serial[column]), column


# --- micro run -----------------------------------------------------------------------------------


@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_micro_fields_and_columns_are_the_wall_averaged_strain_of_each_cell(
    tmp_path_factory, capsys, kinematics
):
    directory = shared_dir(tmp_path_factory, f"micro_{kinematics}")
    scene = directory / "scene.toml"
    write(scene, MICRO.format(kinematics=kinematics))
    code, _, err = call(["run", scene, "-o", directory / "out"], capsys)
    assert code == 0, err
    results = read_results(directory / "out")
    summary = results.summary
    cells = results.field("cell_id").astype(int)
    tensor = results.field("elastic_strain_tensor")
    G = results.field("G")
    # one value per cell, on all its wall triangles
    for cell in np.unique(cells):
        assert np.all(tensor[cells == cell] == tensor[cells == cell][0])
    # G = eta [mean strain]_+ = the mean strain (eta = 1, positive definite); cut bottom cells
    # drop the shear in G only (docs/model.md section 7)
    assert np.linalg.eigvalsh(G).min() > 0.0
    scale = np.abs(G).max()
    diagonal = [0, 1], [0, 1]
    assert tensor[:, *diagonal] == pytest.approx(G[:, *diagonal], rel=0, abs=ROUND_OFF * scale)
    whole = G[:, 0, 1] != 0.0
    assert whole.sum() > len(G) / 2
    assert tensor[whole] == pytest.approx(G[whole], rel=0, abs=ROUND_OFF * scale)
    largest = results.field("elastic_strain")
    assert largest == pytest.approx(principal_magnitude(tensor), rel=0, abs=ROUND_OFF * scale)
    assert summary["elastic_strain_max"][-1] == pytest.approx(largest.max(), rel=ROUND_OFF)
    # the place is the cell's reference centroid, cells.csv's x1_ref, x2_ref
    rows = np.genfromtxt(directory / "out" / "cells.csv", delimiter=",", names=True)
    last = rows[rows["t"] == rows["t"].max()]
    per_cell = np.array([largest[cells == int(c)][0] for c in last["cell"]])
    refs = np.column_stack([last["x1_ref"], last["x2_ref"]])
    place = (summary["elastic_strain_max_x1"][-1], summary["elastic_strain_max_x2"][-1])
    assert place == pytest.approx(_expected_place(refs, per_cell), abs=1e-12)
