"""What ``plantgrowth run`` writes (fields.xdmf/.h5, coarse.xdmf, state.h5, summary.csv,
scene.toml, run.log), and what a bad scene or an unwritable output path does not write.

In-process calls go through ``plantgrowth.cli.main(argv) -> int`` on COMM_WORLD (valid under
mpirun: rank 0 prints and writes the CSV and the log, the XDMF/HDF5 files are written
collectively); the subprocess calls are ``skip_in_parallel``. Files are read with xml.etree and
h5py (serial h5py, read-only, after the run has finished on every rank).
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.cli import main
from plantgrowth.scene import load_scene
from plantgrowth.scene.limits import OUTPUT_FIELDS, WATER_FIELDS

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

BIN = Path(sys.executable).parent
PLANTGROWTH = str(BIN / "plantgrowth")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
RANK0 = MPI.COMM_WORLD.rank == 0

REQUIRED_COLUMNS = [
    "t", "area", "growth_rate_11", "growth_rate_22", "growth_rate_area",
    "u1_max", "u2_max", "n_cell_solves", "seconds",
]  # fmt: skip
SMALL = """\
[tissue]
h = 0.5
H = 1.0
[growth]
law = "stress"
[time]
t_max = 2
dt = 1
[accuracy]
cell_resolution = 1
"""
# Every field a scene without water can ask for (a JSON array is TOML); the water fields need a
# hydraulic macro scene and are tested there (tests/test_macro_water_scene.py).
DRY_FIELDS = [name for name in OUTPUT_FIELDS if name not in WATER_FIELDS]
ALL_FIELDS = f"[output]\nfields = {json.dumps(DRY_FIELDS)}\n"
E_NAMES = ["E1111", "E2222", "E1122", "E1212", "E1112", "E2212"]  # coarse-node fields
ULP32 = 2.0**-23  # one float32 unit in the last place (relative): a stored value is off by half
STATIC = '[growth]\nlaw = "none"\n[tissue]\nh = 0.5\n[accuracy]\ncell_resolution = 1\n'


def shared_dir(factory, name: str) -> Path:
    comm = MPI.COMM_WORLD
    return comm.bcast(factory.mktemp(name) if comm.rank == 0 else None, root=0)


def write(path: Path, content: str | bytes) -> None:
    """Write on rank 0, then let every rank see it."""
    if RANK0:
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
    MPI.COMM_WORLD.Barrier()


def run(scene: Path, outdir: Path) -> int:
    code = main(["run", str(scene), "-o", str(outdir)])
    MPI.COMM_WORLD.Barrier()  # rank 0 writes the last CSV row and log line after the collectives
    return code


@pytest.fixture(scope="module")
def good_run(tmp_path_factory):
    """One small run with every output field (E_hom as six coarse-node fields, eps_hom too,
    fibre_direction: the walls are fibred, and cue_anisotropy: with stress feedback)."""
    directory = shared_dir(tmp_path_factory, "output_files")
    scene, outdir = directory / "small.toml", directory / "run"
    walls = "[walls]\nfibre_stiffness = 1.0\nfibre_angle = 30.0\n"
    write(scene, SMALL + walls + '[feedback]\ncue = "stress"\nrate = 0.5\n' + ALL_FIELDS)
    assert run(scene, outdir) == 0
    return scene, outdir


def read_summary(path: Path) -> tuple[list[str], list[dict[str, float]]]:
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        rows = [{k: float(v) for k, v in row.items()} for row in reader]
        return list(reader.fieldnames), rows


# --- a good run ---------------------------------------------------------------------------------


def test_output_directory_holds_the_run_files(good_run):
    _, outdir = good_run
    names = {p.name for p in outdir.iterdir()}
    assert names == {"fields.xdmf", "coarse.xdmf", "fields.h5", "fields", "state.h5",
                     "state_previous.h5", "summary.csv", "scene.toml", "run.log"}  # fmt: skip
    assert not [n for n in names if n.startswith(".")]  # the write probe is gone


def test_summary_has_the_columns_and_one_row_per_step(good_run):
    scene_path, outdir = good_run
    scene = load_scene(scene_path)
    columns, rows = read_summary(outdir / "summary.csv")
    assert set(REQUIRED_COLUMNS) <= set(columns)
    assert len(rows) == scene.time.n_steps + 1  # steps 0..n: t = 0 is written too
    for k, row in enumerate(rows):
        assert row["step"] == k
        assert row["t"] == pytest.approx(k * scene.time.dt, rel=1e-15, abs=0)
        assert row["n_cell_solves"] == int(row["n_cell_solves"]) >= 0
        assert row["seconds"] >= 0.0 and row["area"] > 0.0
        assert all(np.isfinite(v) for v in row.values())


def _xdmf(outdir: Path, name: str = "fields.xdmf") -> ET.Element:
    return ET.parse(outdir / name).getroot()


@pytest.mark.parametrize("name", ["fields.xdmf", "coarse.xdmf"])
def test_xdmf_has_a_mesh_and_one_time_series_per_field(good_run, name):
    """fields.xdmf: the fine mesh, u at its nodes, the other fields on its cells; coarse.xdmf:
    the coarse grid, E_hom's six components at its nodes."""
    scene_path, outdir = good_run
    scene = load_scene(scene_path)
    _, rows = read_summary(outdir / "summary.csv")
    times = [row["t"] for row in rows]
    root = _xdmf(outdir, name)
    assert root.tag == "Xdmf"
    domain = root.find("Domain")
    assert domain is not None
    grids = domain.findall("Grid")
    meshes = [g for g in grids if g.get("GridType") == "Uniform"]
    assert len(meshes) == 1
    topology, geometry = meshes[0].find("Topology"), meshes[0].find("Geometry")
    assert topology is not None and geometry is not None
    assert topology.get("TopologyType") == "Triangle"
    assert topology.find("DataItem") is not None and geometry.find("DataItem") is not None

    # one temporal collection; each step is a grid holding every written field
    collections = [g for g in grids if g.get("GridType") == "Collection"]
    assert len(collections) == 1 and collections[0].get("CollectionType") == "Temporal"
    steps = collections[0].findall("Grid")
    assert len(steps) == len(rows)
    values = [float(step.find("Time").get("Value")) for step in steps]
    assert values == pytest.approx(times, rel=1e-12, abs=1e-12)
    assert all(a < b for a, b in zip(values, values[1:], strict=False))
    fine = [f for f in scene.output.fields if f != "E_hom"]
    expected = fine if name == "fields.xdmf" else E_NAMES
    for step in steps:
        attributes = {a.get("Name"): a for a in step.findall("Attribute")}
        assert sorted(attributes) == sorted(expected)
        for field, attribute in attributes.items():
            on_nodes = field == "u" or name == "coarse.xdmf"
            assert attribute.get("Center") == ("Node" if on_nodes else "Cell")


@pytest.mark.parametrize("name", ["fields.xdmf", "coarse.xdmf"])
def test_every_dataitem_exists_in_the_h5_file_with_its_dimensions(good_run, name):
    """Each DataItem names an existing dataset of its dimensions and type (readers load the
    values with the declared type: ParaView's default is float32)."""
    _, outdir = good_run
    items = list(_xdmf(outdir, name).iter("DataItem"))
    assert len(items) > 10
    opened: dict[str, h5py.File] = {}
    try:
        for item in items:
            assert item.get("Format") == "HDF"
            filename, _, path = item.text.strip().partition(":")
            # relative to the .xdmf: the mesh in fields.h5, each step in fields/step_NNNNNN.h5
            assert filename == "fields.h5" or filename.startswith("fields/step_"), filename
            assert path.startswith("/")
            if filename not in opened:
                opened[filename] = h5py.File(outdir / filename, "r")
            f = opened[filename]
            assert path in f, path
            dimensions = tuple(int(d) for d in item.get("Dimensions").split())
            assert f[path].shape == dimensions, path
            declared = (item.get("NumberType"), int(item.get("Precision")))
            kind = "Int" if f[path].dtype.kind == "i" else "Float"
            assert declared == (kind, f[path].dtype.itemsize), path
    finally:
        for f in opened.values():
            f.close()


def test_h5_fields_hold_the_run(good_run):
    """Fg(0) = I in every cell; u(0) != 0 (turgor); the G field's mean is the summary's (to the
    float32 rounding of the stored values)."""
    _, outdir = good_run
    _, rows = read_summary(outdir / "summary.csv")
    with h5py.File(outdir / "fields.h5", "r") as f:
        n_cells = f["Mesh/topology"].shape[0]
    with h5py.File(outdir / "fields" / "step_000000.h5", "r") as f:
        Fg0 = f["Fg"][...]
        assert Fg0.shape == (n_cells, 9)  # 2x2 tensors padded to 3x3 for XDMF
        assert np.allclose(Fg0[:, [0, 4]], 1.0, rtol=0, atol=0)
        assert np.all(Fg0[:, [1, 2, 3, 5, 6, 7, 8]] == 0.0)
        assert np.abs(f["u"][...]).max() > 0.0
    for step, row in enumerate(rows):
        with h5py.File(outdir / "fields" / f"step_{step:06d}.h5", "r") as f:
            G = f["G"][...].astype(float)
        # uniform structured mesh: cell mean = area mean; G11 > 0 in every cell, so the mean of
        # the rounded values is within 2**-24 relative of the float64 mean
        assert G[:, 0].mean() == pytest.approx(row["growth_rate_11"], rel=ULP32)


def test_scene_toml_loads_back_to_the_run_scene(good_run):
    scene_path, outdir = good_run
    written = load_scene(outdir / "scene.toml")
    assert written == load_scene(scene_path)
    assert written.output.fields == tuple(DRY_FIELDS)  # the resolved scene, not a copy of the file
    assert "[material]" in (outdir / "scene.toml").read_text()  # defaults are filled in


def test_run_log_exists_and_records_the_run(good_run):
    scene_path, outdir = good_run
    text = (outdir / "run.log").read_text()
    assert f"{scene_path} -> {outdir}" in text
    assert f"on {MPI.COMM_WORLD.size} rank(s)" in text
    assert "done:" in text


def test_run_log_holds_only_its_own_run(tmp_path_factory):
    """Two runs in one process (scripts and tests call main() in process): the first run's log
    must not receive the second run's lines."""
    directory = shared_dir(tmp_path_factory, "two_runs")
    scene = directory / "static.toml"
    write(scene, STATIC)
    first, second = directory / "first", directory / "second"
    assert run(scene, first) == 0
    assert run(scene, second) == 0
    text = (first / "run.log").read_text()
    assert f"-> {first}" in text
    assert f"-> {second}" not in text, "run.log of the first run also logs the second run"


def test_progress_goes_to_the_current_stdout(good_run, mpi_tmp_path, capsys):
    """In-process runs print their progress to the sys.stdout of the moment, like print().

    ``good_run`` made an earlier main() call in this process, under a different sys.stdout (a
    stream that pytest has since replaced, and for a capsys test, closed): a console handler
    bound once to that stream loses this run's progress or writes to a closed file.
    """
    scene = mpi_tmp_path / "static.toml"
    write(scene, STATIC)
    assert run(scene, mpi_tmp_path / "out") == 0
    captured = capsys.readouterr()
    if RANK0:
        assert f"done: {mpi_tmp_path / 'out'}" in captured.out
        assert "Logging error" not in captured.err


def test_meshio_reads_the_fields(good_run):
    meshio = pytest.importorskip("meshio")
    _, outdir = good_run
    with meshio.xdmf.TimeSeriesReader(str(outdir / "fields.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        assert len(points) > 0 and cells[0].type == "triangle"
        t, point_data, cell_data = reader.read_data(0)
        assert t == 0.0
        assert point_data["u"].shape == (len(points), 3)
        assert cell_data["G"][0].shape == (len(cells[0].data), 9)
    with meshio.xdmf.TimeSeriesReader(str(outdir / "coarse.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        assert cells[0].type == "triangle"
        t, point_data, _ = reader.read_data(reader.num_steps - 1)
        assert t == 2.0
        assert sorted(point_data) == sorted(E_NAMES)
        assert point_data["E1111"].shape == (len(points), 1)


# --- bad scenes and bad output paths ------------------------------------------------------------

BAD_SCENES = {  # name -> (file content, or None for a missing file; text the message must name)
    "unknown_key": (SMALL + "[material]\nyoung = 2.0\n", "material.young"),
    "nu_one_half": (SMALL + "[material]\nnu = 0.5\n", "material.nu"),
    "wall_too_thick": (SMALL + "[cell]\nw = 0.9\n", "cell.w"),
    "t_max_below_dt": (SMALL.replace("t_max = 2", "t_max = 0.5"), "time.t_max"),
    "wrong_type": (SMALL + '[material]\nE = "soft"\n', "material.E"),
    "no_law": (SMALL.replace('law = "stress"', "eta = 1.0"), "growth.law"),
    "invalid_toml": (SMALL + "[time\n", "invalid TOML"),
    "empty": ("", "empty"),
    "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe", "binary"),
    "missing": (None, "not found"),
}


def _bad_scene(directory: Path, name: str) -> Path:
    content, _ = BAD_SCENES[name]
    path = directory / f"{name}.toml"
    if content is not None:
        write(path, content)
    return path


@pytest.mark.parametrize("name", sorted(BAD_SCENES))
def test_bad_scene_returns_2_with_a_message_and_writes_nothing(name, mpi_tmp_path, capsys):
    scene = _bad_scene(mpi_tmp_path, name)
    outdir = mpi_tmp_path / "out"
    code = run(scene, outdir)
    err = capsys.readouterr().err
    assert code == 2
    assert not outdir.exists()
    if RANK0:  # only rank 0 prints
        _, named = BAD_SCENES[name]
        assert err.startswith("plantgrowth: error: "), err
        assert named in err, err
        assert len(err.strip().splitlines()) == 1, err  # one line, no traceback
        if name in ("empty", "binary", "missing"):
            assert str(scene) in err  # a file-level problem names the file


def test_bad_scene_leaves_a_previous_run_untouched(good_run, mpi_tmp_path, capsys):
    _, original = good_run
    outdir = mpi_tmp_path / "previous"
    if RANK0:
        shutil.copytree(original, outdir)
    MPI.COMM_WORLD.Barrier()

    def contents() -> dict[str, bytes]:
        return {
            str(p.relative_to(outdir)): p.read_bytes() for p in outdir.rglob("*") if p.is_file()
        }

    before = contents()
    for name in ("unknown_key", "nu_one_half", "binary", "missing"):
        assert run(_bad_scene(mpi_tmp_path, name), outdir) == 2, name
    after = contents()
    assert after.keys() == before.keys()
    for filename, content in before.items():
        assert after[filename] == content, f"{filename} changed"
    capsys.readouterr()


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("name", ["unknown_key", "binary"])
def test_bad_scene_subprocess_prints_no_traceback(name, tmp_path):
    scene = _bad_scene(tmp_path, name)
    outdir = tmp_path / "out"
    done = subprocess.run(
        [PLANTGROWTH, "run", str(scene), "-o", str(outdir)],
        capture_output=True, text=True, env=ENV, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.startswith("plantgrowth: error: ")
    assert BAD_SCENES[name][1] in done.stderr
    assert not outdir.exists()


@pytest.mark.parametrize("where", ["under_a_file", "is_a_file"])
def test_unwritable_output_path_returns_2_with_a_message(where, mpi_tmp_path, capsys):
    """A path under a regular file (or a regular file itself) cannot be made a directory
    (permissions would not do: the tests may run as root)."""
    scene = mpi_tmp_path / "static.toml"
    write(scene, STATIC)
    blocker = mpi_tmp_path / "blocker"
    write(blocker, "a regular file\n")
    outdir = blocker / "out" if where == "under_a_file" else blocker
    code = run(scene, outdir)
    err = capsys.readouterr().err
    assert code == 2
    if RANK0:
        assert err.startswith("plantgrowth: error: cannot write the output directory"), err
        assert str(outdir) in err
        assert len(err.strip().splitlines()) == 1, err
    assert blocker.read_text() == "a regular file\n"
