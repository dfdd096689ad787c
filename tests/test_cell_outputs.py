"""Micro runs' per-cell outputs (issue 11, item 3): ``cells.csv`` (one row per biological cell
and written step) and ``cells.xdmf`` (the cells' outlines), and the growth fields per cell.

One tiny micro run (Nx = 4: 8 cells, one P2 element across a wall, strain law with an eta
gradient, t = 0..2, every other step written) through ``main`` in process (serial and under
mpirun); the serial-vs-``mpirun -n 2`` comparison is a subprocess (``skip_in_parallel``).
"""

from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest
from cli_helpers import ENV, PLANTGROWTH, shared_dir, write
from mpi4py import MPI

from plantgrowth.base import principal
from plantgrowth.cli import main
from plantgrowth.meshes.honeycomb import HoneycombCell, polygon_area
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models.micro.outlines import CELL_COLUMNS
from plantgrowth.results.reader import read_series
from plantgrowth.scene.limits import GROWTH_FIELDS

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

NX = 4
N_CELLS = NX * NX // 2
WRITTEN = [0, 2, 3]  # every = 2, t_max = 3
SCENE = f"""\
model = "micro"
[growth]
law = "strain"
eta = {{from = 0.5, to = 2.0}}
[time]
t_max = 3
dt = 1
[micro]
nx = {NX}
resolution = 1
[output]
every = 2
precision = "float64"
fields = {str(["u", *GROWTH_FIELDS]).replace("'", '"')}
"""


def read_csv(path) -> list[dict[str, float]]:
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The micro run's output directory (the scene beside it, micro.toml)."""
    directory = shared_dir(tmp_path_factory, "cell_outputs")
    scene, outdir = directory / "micro.toml", directory / "out"
    write(scene, SCENE)
    assert main(["run", str(scene), "-o", str(outdir)]) == 0
    MPI.COMM_WORLD.Barrier()  # rank 0 writes the last rows after the collectives
    return outdir


def assert_same_cells(
    expected: Path, actual: Path, rel: float, growth_abs: float, other_abs: float
) -> None:
    """The two runs' cells.csv have the same rows, every column within ``rel`` (absolute
    floors: ``growth_abs`` for the anisotropy and direction columns, ``other_abs`` else)."""
    a_rows, b_rows = read_csv(expected / "cells.csv"), read_csv(actual / "cells.csv")
    assert len(b_rows) == len(a_rows)
    for a, b in zip(a_rows, b_rows, strict=True):
        for key in CELL_COLUMNS:
            absolute = growth_abs if key.startswith("growth_") else other_abs
            assert b[key] == pytest.approx(a[key], rel=rel, abs=absolute), key


def test_one_row_per_cell_and_written_step(finished):
    with open(finished / "cells.csv", newline="") as f:
        assert next(csv.reader(f)) == CELL_COLUMNS
    rows = read_csv(finished / "cells.csv")
    assert len(rows) == N_CELLS * len(WRITTEN)
    assert [r["step"] for r in rows] == [s for s in WRITTEN for _ in range(N_CELLS)]
    assert [r["cell"] for r in rows] == list(range(N_CELLS)) * len(WRITTEN)
    assert all(np.isfinite(v) for r in rows for v in r.values())


def test_cell_areas_add_up_to_the_tissue_area(finished):
    """Deformed: walls (det F) and voids (Green's theorem on the membrane) of all cells make
    the area enclosed by the deformed outer boundary, summary.csv's area: an identity of the
    discrete solution, exact to round-off (1e-10; measured 2e-16). Reference: the mid-line
    hexagons (cut at x2 = 0) tile the tissue exactly."""
    rows = read_csv(finished / "cells.csv")
    summary = {int(r["step"]): r for r in read_csv(finished / "summary.csv")}
    layout = TissueLayout(HoneycombCell(1.0, 1.0, 30.0, 0.05), NX)
    hexagons = np.array([polygon_area(layout.hexagon(i)) for i in range(N_CELLS)])
    for step in WRITTEN:
        cells = [r for r in rows if r["step"] == step]
        assert sum(r["area"] for r in cells) == pytest.approx(summary[step]["area"], rel=1e-10)
        assert [r["area_ref"] for r in cells] == pytest.approx(hexagons, rel=1e-12)
        assert all(r["area"] > r["area_ref"] for r in cells)  # turgor and growth inflate
    full = [r for r in rows if r["step"] == 0][NX:]  # rows above the cut bottom one
    centres = layout.centres[NX:]
    assert np.array([(r["x1_ref"], r["x2_ref"]) for r in full]) == pytest.approx(centres, abs=1e-12)


def test_cell_growth_columns_are_those_of_the_cells_growth_rate(finished):
    """tr G, anisotropy and direction per cell match the written G field (float64) of the
    cell's walls, through the same helpers (round-off)."""
    rows = read_csv(finished / "cells.csv")
    series = read_series(finished)
    for step, t in zip(WRITTEN, series.times, strict=True):
        ids = series.cell_field("cell_id", t).astype(int)
        first = np.unique(ids, return_index=True)[1]
        G = series.cell_field("G", t)[first][:, [0, 1, 3, 4]].reshape(-1, 2, 2)
        cells = [r for r in rows if r["step"] == step]
        assert [r["trG"] for r in cells] == pytest.approx(principal.trace(G), rel=1e-12)
        assert [r["growth_anisotropy"] for r in cells] == pytest.approx(
            principal.anisotropy(G), abs=1e-12
        )
        direction = [(r["growth_direction_1"], r["growth_direction_2"]) for r in cells]
        assert np.array(direction) == pytest.approx(principal.principal_direction(G), abs=1e-12)
        for name in ("trG", "growth_anisotropy"):
            assert series.cell_field(name, t)[first] == pytest.approx(
                [r[name] for r in cells], rel=1e-12, abs=1e-15
            )
        # strain law: the stress direction comes from the cells' mean wall stress
        stress = series.cell_field("stress_direction", t)[first][:, :2]
        assert np.allclose(np.linalg.norm(stress, axis=1), 1.0, atol=1e-12)
        assert np.max([r["growth_anisotropy"] for r in cells]) > 1e-3  # measured 0.05


def test_outlines_are_a_line_mesh_meshio_and_h5py_read(finished):
    meshio = pytest.importorskip("meshio")
    with meshio.xdmf.TimeSeriesReader(str(finished / "cells.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        assert cells[0].type == "line"
        assert reader.num_steps == len(WRITTEN)
        t, point_data, cell_data = reader.read_data(reader.num_steps - 1)
        assert t == 3.0
        assert point_data["u"].shape == (len(points), 3)
        ids = cell_data["cell_id"][0][:, 0]
    # one closed polygon per cell: 6 edges for a full hexagon, 5 for a cut bottom one
    counts = np.bincount(ids.astype(int))
    assert list(counts) == [5] * NX + [6] * (N_CELLS - NX)
    with h5py.File(finished / "fields.h5", "r") as f:
        assert f["Outlines/geometry"].shape == (len(points), 2)
        assert f["Outlines/topology"].shape == (int(counts.sum()), 2)
    series = read_series(finished)
    deformed = series.outlines.deformed(3.0)
    assert np.all(np.abs(deformed[:, 1][series.outlines.points[:, 1] == 0.0]) < 1e-12)  # u2 = 0


@pytest.mark.skip_in_parallel
def test_mpirun_writes_the_serial_cell_table_and_outlines(finished):
    """Same tissue on 2 ranks: the vertex displacements and per-cell integrals match the serial
    run's to the distributed solve's round-off (1e-8 relative; measured 4e-11). Anisotropy and
    direction divide G's round-off by g1 - g2 (here down to 2e-3 of tr G): 1e-8 absolute
    (measured 7e-10)."""
    parallel = finished.parent / "mpi"
    done = subprocess.run(
        ["mpirun", "-n", "2", PLANTGROWTH, "run", str(finished.parent / "micro.toml"),
         "-o", str(parallel)], env=ENV, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert_same_cells(finished, parallel, rel=1e-8, growth_abs=1e-8, other_abs=1e-12)
    a, b = read_series(finished), read_series(parallel)
    assert np.array_equal(a.outlines.points, b.outlines.points)
    for t in a.times:
        assert b.outlines.deformed(t) == pytest.approx(a.outlines.deformed(t), rel=1e-8)


def test_an_extended_run_writes_the_rows_of_a_straight_run(finished):
    """t_max = 1 (rows of steps 0 and 1), then --resume to t_max = 3: step 1 is not on the new
    schedule (every = 2), so its rows go; the table equals the straight run's. Serial: 1e-10, the
    same arithmetic repeated, as tests/test_interruptions.py. Under mpirun the resumed run's mesh
    may be partitioned anew, so its distributed LU is another partition's round-off: the 1e-8
    relative of the serial = mpirun comparison above (measured 1.1e-10 relative in x1 after
    three steps). Anisotropy and direction divide u's round-off by g1 - g2, here down to 2e-3 of
    tr G: 1e-9 absolute for those (measured 1.5e-12 serial, 1.8e-10 under mpirun)."""
    directory = finished.parent
    short, extended = directory / "short.toml", directory / "extended"
    write(short, SCENE.replace("t_max = 3", "t_max = 1"))
    assert main(["run", str(short), "-o", str(extended)]) == 0
    MPI.COMM_WORLD.Barrier()
    assert [r["step"] for r in read_csv(extended / "cells.csv")] == [0] * N_CELLS + [1] * N_CELLS
    assert main(["run", str(directory / "micro.toml"), "--resume", str(extended)]) == 0
    MPI.COMM_WORLD.Barrier()
    rel = 1e-10 if MPI.COMM_WORLD.size == 1 else 1e-8
    assert_same_cells(finished, extended, rel=rel, growth_abs=1e-9, other_abs=1e-14)
