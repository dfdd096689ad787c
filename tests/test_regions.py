"""Named regions and named parameters (issue 21, items 4-5): the regions' columns of summary.csv
and sweep.csv, parameters used by name, ``mode = "zip"`` sweeps, and their bad inputs.

Runs are tiny (h = 0.35, cell_resolution 1, two steps; micro: Nx = 4). In-process tests call
``main`` on every rank, so under mpirun they check the regions' sums across ranks; the
subprocess test (``skip_in_parallel``) compares a serial run with ``mpirun -n 2``.

Tolerances: a region covering the whole tissue sums the same per-unit numbers as the global
columns in another order (macro; micro areas: cells.csv's per-cell areas against the tissue's
Green's-theorem area, measured 2e-16 apart), so 1e-12 relative is round-off with room; a
parameter is replaced by its number when parsed, so its run is the literal's (1e-12, the issue's
bound; measured bitwise); a sweep's run is ``plantgrowth run``'s code (1e-10 as
tests/test_sweep.py; measured bitwise); serial against 2 ranks: a distributed LU's round-off
(1e-8 relative, as every serial/parallel test).
"""

from __future__ import annotations

import csv
import subprocess
import tomllib
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import ENV, PLANTGROWTH, RANK0, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.base.errors import SceneError
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models.regions import STATISTICS
from plantgrowth.results.reader import boundary_outline, read_series
from plantgrowth.results.region_outlines import region_outlines
from plantgrowth.scene import parse_scene
from plantgrowth.studies.sweep_file import NUMBERS, load_sweep

DISC = "(x1 - 3.5)**2 + (x2 - 1.5)**2 < 1"
SCENE = """\
model = "{model}"
[tissue]
h = 0.35
[parameters]
E_in = 0.5
pull = 0.0002
[material]
E = {{expr = "{E}"}}
[growth]
law = "strain"
[time]
t_max = 2
[output]
precision = "float64"
fields = ["u", "G", "elastic_strain"]
[accuracy]
cell_resolution = 1
[micro]
nx = 4
resolution = 1
[numerics]
on_instability = "warn"
{extra}[regions]
disc = {{expr = "{disc}"}}
everything = {{expr = "x1 > -1"}}
"""
LOADS = '[loads]\nleft = [{{expr = "-{0}"}}, 0]\nright = [{{expr = "{0}"}}, 0]\n'
GLOBAL = {"area": "area", "trG": "growth_rate_area", "growth_rate_11": "growth_rate_11",
          "growth_rate_22": "growth_rate_22",
          "elastic_strain_max": "elastic_strain_max"}  # fmt: skip


def scene_text(model="macro", E=f"where({DISC}, E_in, 1)", disc=DISC, loads="pull") -> str:
    extra = LOADS.format(loads) if model == "macro" else ""
    return SCENE.format(model=model, E=E, disc=disc, extra=extra)


def summary(path: Path) -> list[dict[str, float]]:
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def run(factory, name: str, text: str, capsys) -> Path:
    directory = shared_dir(factory, name)
    write(directory / "scene.toml", text)
    code, _, err = call(["run", directory / "scene.toml", "-o", directory / "out"], capsys)
    assert code == 0, err
    return directory / "out"


@pytest.mark.mpi
@pytest.mark.parametrize("model", ["macro", "micro"])
def test_a_region_of_the_whole_tissue_gives_the_global_columns(tmp_path_factory, capsys, model):
    out = run(tmp_path_factory, f"whole_{model}", scene_text(model), capsys)
    rows = summary(out / "summary.csv")
    assert len(rows) == 3
    for row in rows:
        for statistic, column in GLOBAL.items():
            assert row[f"everything.{statistic}"] == pytest.approx(row[column], rel=1e-12)
        # the soft disc grows faster than the tissue: its own columns are not the global ones
        assert row["disc.trG"] > 1.05 * row["growth_rate_area"]
        assert 0.0 < row["disc.area"] < 0.5 * row["area"]


@pytest.mark.mpi
def test_region_columns_equal_the_written_fields_of_their_fine_cells(tmp_path_factory, capsys):
    """Membership by reference midpoint, means weighted by reference area, area in the current
    configuration: recomputed from fields.xdmf (float64) with numpy (the deformed triangles'
    areas; u is P1, so det(I + grad u) times the reference area is the deformed area)."""
    out = run(tmp_path_factory, "fields", scene_text(), capsys)
    if not RANK0:
        return
    rows = summary(out / "summary.csv")
    series = read_series(out)
    x, tri = series.points, series.triangles
    mid = x[tri].mean(axis=1)
    inside = (mid[:, 0] - 3.5) ** 2 + (mid[:, 1] - 1.5) ** 2 < 1

    def areas(p):
        a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
        return 0.5 * np.abs(np.cross(b - a, c - a))

    ref = areas(x)[inside]
    for step, t in enumerate(series.times):
        G = series.cell_field("G", t)[inside]
        current = areas(x + series.displacement(t))[inside].sum()
        means = [(ref * G[:, k]).sum() / ref.sum() for k in (0, 4, 1)]  # 11, 22, 12
        peak = series.cell_field("elastic_strain", t)[inside].max()
        values = [current, means[0] + means[1], *means, peak]
        expected = dict(zip(STATISTICS, values, strict=True))
        for statistic, value in expected.items():
            assert rows[step][f"disc.{statistic}"] == pytest.approx(value, rel=1e-10, abs=1e-15)


def test_a_named_parameter_gives_the_run_of_its_literal(tmp_path_factory, capsys):
    named = run(tmp_path_factory, "named", scene_text(), capsys)
    literal = scene_text(E=f"where({DISC}, 0.5, 1)", loads="0.0002")
    assert "E_in" not in literal.split("[parameters]")[1].split("[material]")[1]
    alone = run(tmp_path_factory, "literal", literal, capsys)
    if not RANK0:
        return
    a, b = summary(named / "summary.csv"), summary(alone / "summary.csv")
    assert len(a) == len(b) == 3
    for x, y in zip(a, b, strict=True):
        # serial: bitwise; 2 ranks: the distributed LU is not bitwise reproducible from run to
        # run (measured: disc.growth_rate_12 = 2.2e-5 differing in its 12th digit), so small
        # columns (G12, the residual) are compared to 1e-12 of the scale tr G
        scale = 1e-12 * y["growth_rate_area"]
        for key in x:
            if not key.startswith("seconds"):
                assert x[key] == pytest.approx(y[key], rel=1e-12, abs=scale), key
    # the parameter is used: another E_in is another run
    scene = parse_scene({"growth": {"law": "strain"}, "parameters": {"E_in": 0.5},
                         "material": {"E": {"expr": f"where({DISC}, E_in, 1)"}}})  # fmt: skip
    assert scene.material.E(3.5, 1.5) == 0.5
    assert scene.replace(**{"parameters.E_in": 0.7}).material.E(3.5, 1.5) == 0.7


ZIP = """\
base = "base.toml"
mode = "{mode}"
[vary]
"parameters.E_in" = [0.5, 0.7]
"loads.left" = [[-0.0001, 0], [-0.0003, 0]]
"loads.right" = [[0.0001, 0], [0.0003, 0]]
"""


def test_a_zip_sweep_equals_the_stand_alone_runs(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "zip")
    write(directory / "base.toml", scene_text())
    write(directory / "sweep.toml", ZIP.format(mode="zip"))
    code, _, err = call(["sweep", directory / "sweep.toml", "-o", directory / "out"], capsys)
    assert code == 0, err
    rows = None
    if RANK0:
        with open(directory / "out" / "sweep.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    rows = MPI.COMM_WORLD.bcast(rows, root=0)
    assert [(r["parameters.E_in"], r["loads.left"]) for r in rows] == [
        ("0.5", "[-0.0001, 0]"), ("0.7", "[-0.0003, 0]")
    ]  # fmt: skip
    for row in rows:
        alone = directory / f"alone_{row['run']}"
        scene = directory / "out" / row["run"] / "scene.toml"
        code, _, err = call(["run", scene, "-o", alone], capsys)
        assert code == 0, err
        if RANK0:
            last = summary(alone / "summary.csv")[-1]
            for key in ("area", "growth_rate_area", *(f"disc.{s}" for s in STATISTICS)):
                assert float(row[key]) == pytest.approx(last[key], rel=1e-10), (row["run"], key)
    assert rows[0]["disc.trG"] != rows[1]["disc.trG"]
    # the same lists as a grid pair unbalanced loads: refused before anything runs
    write(directory / "grid.toml", ZIP.format(mode="grid"))
    code, _, err = call(["sweep", directory / "grid.toml", "-o", directory / "grid"], capsys)
    assert code == 2
    assert not (directory / "grid").exists()


@pytest.mark.skip_in_parallel
def test_mpirun_2_gives_the_serial_region_columns(tmp_path_factory, capsys):
    serial = run(tmp_path_factory, "serial", scene_text(), capsys)
    parallel = serial.parent / "mpi"
    done = subprocess.run(
        ["mpirun", "-n", "2", PLANTGROWTH, "run", str(serial.parent / "scene.toml"), "-o",
         str(parallel)], env=ENV, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    for a, b in zip(
        summary(serial / "summary.csv"), summary(parallel / "summary.csv"), strict=True
    ):
        for key in (f"{r}.{s}" for r in ("disc", "everything") for s in STATISTICS):
            assert a[key] == pytest.approx(b[key], rel=1e-8, abs=1e-15), key


# --- bad input ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "fragments"),
    [
        ({"material": {"E": {"expr": "1 + E_out"}}}, ("material.E.expr", "unknown name 'E_out'")),
        ({"parameters": {"x1": 2.0}}, ("parameters.x1", "reserved")),
        ({"parameters": {"sqrt": 2.0}}, ("parameters.sqrt", "reserved")),
        ({"parameters": {"E_in": "0.3"}}, ("parameters.E_in", "expected a number")),
        ({"parameters": {"E_in": float("inf")}}, ("parameters.E_in", "finite")),
        ({"parameters": {"2x": 1.0}}, ("parameters.2x", "not a valid name")),
        ({"regions": {"disc": {"expr": "x1 <"}}}, ("regions.disc.expr",)),
        ({"regions": {"disc": {"expr": "x3 < 1"}}}, ("regions.disc.expr", "unknown name 'x3'")),
        ({"regions": {"disc": "x1 < 1"}}, ("regions.disc", 'expr = "..."')),
        ({"regions": {"disc": {"expr": "x1 < 1", "to": 2}}}, ("unknown key 'regions.disc.to'",)),
        ({"regions": {"disc": {"expr": "2 < 1"}}}, ("regions.disc", "0 everywhere")),
        ({"regions": {"a.b": {"expr": "1"}}}, ("regions.a.b", "not a valid name")),
        ({"regions": []}, ("regions: expected a table",)),
    ],
)  # fmt: skip
def test_bad_parameters_and_regions_are_named_errors(data, fragments):
    with pytest.raises(SceneError) as caught:
        parse_scene({"growth": {"law": "stress"}, **data})
    for fragment in fragments:
        assert fragment in str(caught.value)


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("model", "disc", "fragments"),
    [
        ("macro", "x1 > 100", ("regions.disc: the region is empty", "fine cell midpoints")),
        ("micro", "x1 > 100", ("regions.disc: the region is empty", "cell centres")),
        ("macro", "log(x1 - 3)", ("regions.disc.expr = nan at x1 =", "finite")),
    ],
)  # fmt: skip
def test_a_region_empty_or_undefined_on_the_mesh_is_refused(
    tmp_path_factory, capsys, model, disc, fragments
):
    directory = shared_dir(tmp_path_factory, "empty")
    write(directory / "scene.toml", scene_text(model, disc=disc))
    code, _, err = call(["run", directory / "scene.toml", "-o", directory / "out"], capsys)
    assert code == 2
    if RANK0:
        assert all(f in err for f in fragments), err
    assert not (directory / "out").exists()


# --- render --regions -----------------------------------------------------------------------------


def test_render_regions_outlines_the_regions_units(tmp_path_factory, capsys):
    """The whole-tissue region's outline is the tissue's boundary (reader.boundary_outline, an
    independent walk); the disc's is closed loops (every vertex on an even number of its edges);
    a run without regions is refused by name."""
    out = run(tmp_path_factory, "render", scene_text(), capsys)
    picture = out.parent / "regions.png"
    argv = ["render", out, "--field", "G", "--component", "tr", "--regions", "-o", picture]
    code, _, err = call(argv, capsys)
    assert code == 0, err
    if RANK0:
        assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        series = read_series(out)
        t = series.times[-1]
        outlines = region_outlines(series, t)
        x = series.points + series.displacement(t)
        loops = boundary_outline(series.points, series.triangles)
        boundary = {frozenset(map(tuple, x[[a, b]])) for p in loops for a, b in
                    zip(p, np.roll(p, -1), strict=True)}  # fmt: skip
        assert {frozenset(map(tuple, s)) for s in outlines["everything"]} == boundary
        ends, counts = np.unique(outlines["disc"].reshape(-1, 2), axis=0, return_counts=True)
        assert len(outlines["disc"]) >= 8 and np.all(counts % 2 == 0)
        # near the disc of radius 1: within a triangle's diameter (h = 0.35) and u of it
        reach = 1.0 + 0.35 * np.sqrt(2.0) + np.linalg.norm(x - series.points, axis=1).max()
        assert np.all(np.hypot(*(ends - [3.5, 1.5]).T) < reach)
    plain = run(tmp_path_factory, "no_regions", scene_text().split("[regions]")[0], capsys)
    argv[1], argv[-1] = plain, plain.parent / "none.png"
    code, _, err = call(argv, capsys)
    assert code == 2
    if RANK0:
        assert "--regions" in err and "no [regions]" in err
    assert not (plain.parent / "none.png").exists()


def test_the_shipped_soft_disc_sweep_varies_the_disc_by_name():
    path = Path(__file__).parents[1] / "scenes" / "examples" / "soft_disc_E.toml"
    sweep = load_sweep(path)
    assert [r.scene.material.E(4.0, 2.0) for r in sweep.runs] == [0.3, 0.5, 0.7, 1.0]
    assert all(r.scene.material.E(0.5, 0.5) == 1.0 for r in sweep.runs)
    assert [f"disc.{s}" for s in STATISTICS] == sweep.numbers()[len(NUMBERS) :]
    assert [sweep.cells(r)["parameters.E_in"] for r in sweep.runs] == ["0.3", "0.5", "0.7", "1.0"]


def test_parameters_and_regions_round_trip_through_the_resolved_scene():
    scene = parse_scene(tomllib.loads(scene_text()))
    again = parse_scene(tomllib.loads(scene.to_toml()))
    assert again == scene
    assert again.parameters == {"E_in": 0.5, "pull": 0.0002}
    assert list(again.regions) == ["disc", "everything"]
    assert "parameters" not in parse_scene({"growth": {"law": "none"}}).to_dict()


@pytest.mark.mpi
def test_micro_region_columns_equal_the_cells_table(tmp_path_factory, capsys):
    """Micro: the cells whose centre (TissueLayout.centres) lies in the region; area: the sum of
    cells.csv's deformed areas; rates: cells.csv's tr G weighted by its reference areas
    (area_ref, the hexagons cut at x2 = 0). Same numbers summed in another order: 1e-12."""
    out = run(tmp_path_factory, "micro_cells", scene_text("micro"), capsys)
    if not RANK0:
        return
    scene = parse_scene(tomllib.loads(scene_text("micro")))
    centres = TissueLayout(scene.cell.at(0.0, 0.0), scene.micro_nx).centres
    inside = np.flatnonzero((centres[:, 0] - 3.5) ** 2 + (centres[:, 1] - 1.5) ** 2 < 1)
    assert 0 < len(inside) < len(centres)
    cells = summary(out / "cells.csv")
    for row in summary(out / "summary.csv"):
        mine = [c for c in cells if c["step"] == row["step"] and int(c["cell"]) in inside]
        assert len(mine) == len(inside)
        weights = np.array([c["area_ref"] for c in mine])
        trG = weights @ [c["trG"] for c in mine] / weights.sum()
        assert row["disc.area"] == pytest.approx(sum(c["area"] for c in mine), rel=1e-12)
        assert row["disc.trG"] == pytest.approx(trG, rel=1e-12)
