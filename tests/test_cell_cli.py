"""``plantgrowth cell``: output formats, bad input, and serial vs mpirun results.

In-process calls go through ``plantgrowth.cli.main(argv) -> int`` (valid under mpirun: the cell
is distributed on COMM_WORLD, rank 0 prints); the few subprocess calls are ``skip_in_parallel``.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.cli import main
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell.hydraulic_coefficients import hydraulic_summary
from plantgrowth.unitcell.solver import CellSolver

KEYS = "E1111 E2222 E1122 E1212 E1112 E2212 K11 K22 K12 E1 E2 nu12 G12 phi_w ndofs seconds".split()
HYDRAULIC_KEYS = ("b", "inv_M", "kappa")
"""docs/model.md "Water fluxes": the Biot tensor and kappa as [11, 22, 12], the storage 1/M."""
BIN = Path(sys.executable).parent
PLANTGROWTH = str(BIN / "plantgrowth")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
RANK0 = MPI.COMM_WORLD.rank == 0


def _last_json(text: str) -> dict:
    return json.loads(text.strip().splitlines()[-1])


# --- output formats ------------------------------------------------------------------------------


@pytest.mark.mpi
def test_json_output(capsys):
    argv = ["cell", "--json", "--resolution", "1", "--l1", "1.5", "--Fg", "1.2,0.1,0,1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    if not RANK0:
        assert out == ""  # logs and results on rank 0 only
        return
    data = _last_json(out)
    assert set(KEYS) <= set(data)
    assert isinstance(data["ndofs"], int)
    # the CLI reports exactly what the solver computes (same mesh, same constants)
    Fg = np.array([[1.2, 0.1], [0.0, 1.0]])
    result = CellSolver(HoneycombCell(l1=1.5), 1, MPI.COMM_SELF).solve(Fg, 1.0, 0.3)
    expected = result.summary() | hydraulic_summary(result, HoneycombCell(l1=1.5), Fg)
    for key in KEYS + list(HYDRAULIC_KEYS):
        if key != "seconds":
            # serial CLI: bitwise equal; under mpirun MUMPS vs PETSc LU differ by round-off
            assert data[key] == pytest.approx(expected[key], rel=1e-8, abs=1e-14), key
    assert len(data["b"]) == len(data["kappa"]) == 3


@pytest.mark.mpi
def test_table_output(capsys):
    assert main(["cell", "--resolution", "1", "--E", "2", "--nu", "0.25"]) == 0
    out = capsys.readouterr().out
    if not RANK0:
        return
    table = dict(line.split() for line in out.strip().splitlines())
    assert set(KEYS) | {"inv_M"} <= set(table)
    assert "b" not in table and "kappa" not in table  # tensors in --json only
    assert int(table["ndofs"]) > 0
    assert float(table["phi_w"]) == pytest.approx(HoneycombCell().phi_w, rel=1e-5)  # 6 digits


# --- bad input -----------------------------------------------------------------------------------

BAD = [
    (["--w", "0"], "w"),
    (["--w", "-0.05"], "w"),
    (["--w", "0.9"], "w"),  # >= w_max = cos 30 deg
    (["--theta", "0"], "theta"),
    (["--theta", "90"], "theta"),
    (["--l1", "0"], "l1"),
    (["--l2", "-1"], "l2"),
    (["--l1", "nan"], "l1"),
    (["--w", "nan"], "w"),
    (["--nu", "0.5"], "nu"),
    (["--nu", "-1"], "nu"),
    (["--E", "0"], "E"),
    (["--E", "-2"], "E"),
    (["--E", "inf"], "E"),
    (["--Fg", "1,0,0,-1"], "Fg"),
    (["--Fg", "1,1,1,1"], "Fg"),  # det = 0
    (["--Fg", "1,0,1"], "Fg"),
    (["--Fg", "1,0,0,nan"], "Fg"),
    (["--Fg", "1,a,0,1"], "Fg"),
    (["--w", "abc"], "w"),
    (["--resolution", "0"], "resolution"),
    (["--resolution", "two"], "resolution"),
]


@pytest.mark.parametrize("args, name", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_input_exits_2_naming_the_parameter(capsys, args, name):
    assert main(["cell", *args]) == 2  # every rank returns 2 (no collective left hanging)
    err = capsys.readouterr().err
    if not RANK0:
        assert err == ""
        return
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("plantgrowth: error:")
    assert re.search(rf"(^|[^A-Za-z0-9_]){name}([^A-Za-z0-9_]|$)", lines[0]), lines[0]


@pytest.mark.parametrize("argv", [[], ["cell", "--bogus", "1"], ["frobnicate"]])
def test_bad_command_line_exits_2(capsys, argv):
    assert main(argv) == 2
    if RANK0:
        assert capsys.readouterr().err.startswith("plantgrowth: error:")


@pytest.mark.skip_in_parallel
def test_bad_input_subprocess_has_no_traceback():
    proc = subprocess.run(
        [PLANTGROWTH, "cell", "--theta", "95"], capture_output=True, text=True, env=ENV, timeout=120
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert proc.stderr.startswith("plantgrowth: error:") and "theta" in proc.stderr
    assert proc.stdout == ""


@pytest.mark.skip_in_parallel
def test_help():
    proc = subprocess.run(
        [PLANTGROWTH, "cell", "--help"], capture_output=True, text=True, env=ENV, timeout=120
    )
    assert proc.returncode == 0
    for option in ("--l1", "--l2", "--theta", "--w", "--E", "--nu", "--Fg", "--json",
                   "--fibre-stiffness", "--fibre-angle", "inv_M", "kappa", "Biot"):  # fmt: skip
        assert option in proc.stdout
    top = subprocess.run(
        [PLANTGROWTH, "--help"], capture_output=True, text=True, env=ENV, timeout=120
    )
    assert top.returncode == 0 and "cell" in top.stdout


# --- serial vs parallel --------------------------------------------------------------------------


@pytest.mark.skip_in_parallel
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not installed")
def test_mpirun_matches_serial():
    """Two ranks (distributed mesh, MUMPS) vs one (PETSc LU): the same discrete problem, so
    only round-off differs; 1e-8 relative leaves room for the ~10x cancellation in E1 (b, 1/M
    and kappa included: b and 1/M from the same solve, kappa a closed form)."""
    proc = subprocess.run(
        ["mpirun", "-n", "2", PLANTGROWTH, "cell", "--json", "--Fg", "1.3,0.1,0,1"],
        capture_output=True,
        text=True,
        env=ENV,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    parallel = _last_json(proc.stdout)
    Fg = np.array([[1.3, 0.1], [0.0, 1.0]])
    result = CellSolver(HoneycombCell(), 3, MPI.COMM_SELF).solve(Fg, 1.0, 0.3)
    serial = result.summary() | hydraulic_summary(result, HoneycombCell(), Fg)
    assert parallel["ndofs"] == serial["ndofs"]
    for key in KEYS + list(HYDRAULIC_KEYS):
        if key not in ("seconds", "ndofs"):
            assert parallel[key] == pytest.approx(serial[key], rel=1e-8, abs=1e-14), key
