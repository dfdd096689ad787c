"""Output economy (issue 10, item 4): ``output.every``, E_hom on the coarse grid, compressed
fields in ``output.precision`` and the float64 resume state.

In-process runs through ``main`` (serial and under mpirun: rank 0 writes, every rank reads after
a barrier). A kill that must land at one exact point (after a step's summary row, before its
state) is simulated in-process: the state write raises RunError at that step, which leaves on
disk what SIGKILL would there (SIGKILL itself, with ``output.every``: test_interruptions.py).

Tolerances: runs compared here repeat the same arithmetic on the same ranks (the cell problems
are solved at their rounded keys, so a fresh cell cache after a restart changes nothing), so
RTOL = 1e-10 leaves room for round-off only (measured: bitwise in serial, ~1e-14 under mpirun,
whose solves are not bitwise repeatable from run to run). A float32 field is the float64
value rounded once, so two runs whose float64 values agree to RTOL may still differ by one
float32 unit in the last place, 2**-23 relative.
"""

from __future__ import annotations

import csv
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest
from cli_helpers import RANK0, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.base.errors import RunError
from plantgrowth.base.tensors import VOIGT_NAMES
from plantgrowth.cli import main
from plantgrowth.models.macro.coarse import CoarseGrid
from plantgrowth.results.reader import read_series
from plantgrowth.runner import output
from plantgrowth.runner.output import Schedule
from plantgrowth.scene import SceneError, parse_scene

RTOL = 1e-10
ULP32 = 2.0**-23
NOT_COMPARED = ("n_cell_solves", "residual")  # the cache restarts empty; round-off
SCENE = """\
[tissue]
h = 0.5
H = 1.0
[growth]
law = "stress"
eta = {{from = 0.5, to = 2.0}}
[time]
t_max = {t_max}
dt = 1
[accuracy]
cell_resolution = 1
[output]
every = {every}
precision = "{precision}"
"""


def scene_text(t_max: int = 10, every: int = 4, precision: str = "float32") -> str:
    """A small macro scene whose Fg varies in space (an eta gradient), so every step differs."""
    return SCENE.format(t_max=t_max, every=every, precision=precision)


def run(directory: Path, name: str, text: str) -> Path:
    """Write the scene ``name.toml`` and run it into ``directory/name`` (on every rank)."""
    scene, outdir = directory / f"{name}.toml", directory / name
    write(scene, text)
    assert main(["run", str(scene), "-o", str(outdir)]) == 0
    MPI.COMM_WORLD.Barrier()  # rank 0 writes the last row and state after the collectives
    return outdir


def step_files(outdir: Path) -> list[int]:
    return sorted(int(p.stem.split("_")[1]) for p in (outdir / "fields").glob("step_*.h5"))


def indexed_times(xdmf: Path) -> list[float]:
    root = ET.parse(xdmf).getroot()
    times = [grid.find("Time") for grid in root.iter("Grid")]
    return [float(time.get("Value")) for time in times if time is not None]


def summary(outdir: Path) -> list[dict[str, float]]:
    with open(outdir / "summary.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def datasets(path: Path) -> dict[str, np.ndarray]:
    """Every dataset of an HDF5 file by its path."""
    found = {}

    def visit(name: str, item: h5py.HLObject) -> None:
        if isinstance(item, h5py.Dataset):
            found[name] = item[...]

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return found


def assert_close(got: np.ndarray, expected: np.ndarray, rtol: float, what: str) -> None:
    scale = max(float(np.abs(expected).max()), 1e-300)
    error = float(np.abs(got.astype(float) - expected.astype(float)).max()) / scale
    assert error <= rtol, f"{what}: relative difference {error:.3g} > {rtol:.3g}"


def assert_same_datasets(got: Path, expected: Path, rtol: float) -> None:
    """The same datasets in two HDF5 files, equal to rtol (relative to each dataset's max)."""
    found, wanted = datasets(got), datasets(expected)
    assert found.keys() == wanted.keys()
    for name, value in wanted.items():
        if name.endswith("lu_floor"):  # the residual a fresh LU left: round-off, not a result
            # (two 2-rank runs' differ by about 1 %), so each must be round-off
            assert found[name].max() < 1e-12 and value.max() < 1e-12, name
            continue
        assert_close(found[name], value, rtol, f"{expected.name}:{name}")


def assert_same_fields_and_state(outdir: Path, reference: Path, steps: list[int]) -> None:
    """The fields of ``steps`` (float32: one ulp) and the float64 state equal the reference's."""
    for step in steps:
        path = Path("fields") / f"step_{step:06d}.h5"
        assert_same_datasets(outdir / path, reference / path, ULP32 + RTOL)
    for name in ("state.h5", "state_previous.h5"):
        assert_same_datasets(outdir / name, reference / name, RTOL)


def assert_same_outputs(outdir: Path, reference: Path) -> None:
    """The same written steps, summary rows, state and fields (RTOL; float32 fields one ulp)."""
    assert step_files(outdir) == step_files(reference)
    for name in ("fields.xdmf", "coarse.xdmf"):
        assert indexed_times(outdir / name) == indexed_times(reference / name), name
    rows, ref_rows = summary(outdir), summary(reference)
    assert [r["step"] for r in rows] == [r["step"] for r in ref_rows]
    for row, ref in zip(rows, ref_rows, strict=True):
        for key, value in ref.items():
            if not key.startswith("seconds") and key not in NOT_COMPARED:
                assert row[key] == pytest.approx(value, rel=RTOL, abs=1e-300), (row["step"], key)
    assert_same_fields_and_state(outdir, reference, step_files(reference))


# --- which steps are written --------------------------------------------------------------------


@pytest.mark.parametrize(
    "every, n_steps, written",
    [(1, 3, [0, 1, 2, 3]), (4, 10, [0, 4, 8, 10]), (5, 10, [0, 5, 10]), (20, 10, [0, 10]),
     (3, 0, [0])],
)  # fmt: skip
def test_the_schedule_is_t0_every_kth_step_and_the_last(every, n_steps, written):
    schedule = Schedule(every, n_steps)
    assert [s for s in range(n_steps + 1) if s in schedule] == written


@pytest.mark.parametrize(
    "table, message",
    [({"every": 0}, "output.every = 0 is out of range"),
     ({"every": 10**6 + 1}, "output.every = 1000001 is out of range"),
     ({"every": 2.0}, "output.every: expected an integer"),
     ({"every": True}, "output.every: expected an integer"),
     ({"every": "2"}, "output.every: expected an integer"),
     ({"precision": "double"}, "output.precision = 'double' is invalid"),
     ({"precision": 64}, "output.precision: expected a string")],
)  # fmt: skip
def test_bad_output_keys_are_named(table, message):
    with pytest.raises(SceneError, match="^" + message):
        parse_scene({"growth": {"law": "stress"}, "output": table})


def test_output_keys_default_and_round_trip():
    scene = parse_scene({"growth": {"law": "stress"}})
    assert (scene.output.every, scene.output.precision) == (1, "float32")
    table = {"every": 7, "precision": "float64"}
    chosen = parse_scene({"growth": {"law": "stress"}, "output": table})
    assert chosen.to_dict()["output"]["every"] == 7
    assert parse_scene(chosen.to_dict()) == chosen


# --- coarse grid --------------------------------------------------------------------------------


def test_coarse_grid_triangles_split_the_rectangles_as_the_interpolation_does():
    """Each triangle's centroid is interpolated from exactly its three nodes (weights 1/3), the
    triangles are counter-clockwise and tile the rectangle."""
    grid = CoarseGrid(3.0, 2.0, 3, 2)
    triangles = grid.triangles
    x = grid.nodes[triangles]
    d1, d2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    signed = 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    assert np.all(signed > 0) and signed.sum() == pytest.approx(6.0, rel=1e-14)
    W = grid.interpolation_matrix(x.mean(axis=1)).toarray()
    for row, nodes in zip(W, triangles, strict=True):
        assert sorted(np.flatnonzero(row > 1e-12)) == sorted(nodes)
        assert row[nodes] == pytest.approx(1.0 / 3.0, rel=1e-12)


# --- a run with output.every --------------------------------------------------------------------


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """t_max = 10 with every = 4 and every = 1 (float32), and every = 4 in float64."""
    directory = shared_dir(tmp_path_factory, "economy")
    return {
        "every4": run(directory, "every4", scene_text()),
        "every1": run(directory, "every1", scene_text(every=1)),
        "float64": run(directory, "float64", scene_text(precision="float64")),
    }


@pytest.mark.mpi
def test_every_writes_t0_each_kth_and_the_last_step_and_every_row(runs):
    outdir = runs["every4"]
    assert step_files(outdir) == [0, 4, 8, 10]
    assert indexed_times(outdir / "fields.xdmf") == [0.0, 4.0, 8.0, 10.0]
    assert indexed_times(outdir / "coarse.xdmf") == [0.0, 4.0, 8.0, 10.0]
    assert [r["step"] for r in summary(outdir)] == list(range(11))
    for name, step in (("state.h5", 10), ("state_previous.h5", 9)):  # each step's state once
        with h5py.File(outdir / name, "r") as f:
            assert sorted(f) == [f"step_{step:06d}"]


@pytest.mark.mpi
def test_every_changes_what_is_written_not_the_numbers(runs):
    """The written steps of every = 4 equal those steps of every = 1 (bitwise in serial; under
    mpirun the parallel solves' round-off, ~1e-14, can move a float32 rounding by one ulp)."""
    sparse, dense = runs["every4"], runs["every1"]
    assert step_files(dense) == list(range(11))
    assert_same_fields_and_state(sparse, dense, step_files(sparse))


@pytest.mark.mpi
def test_e_hom_lives_on_the_coarse_grid_only(runs):
    outdir = runs["every4"]
    fine = {a.get("Name") for a in ET.parse(outdir / "fields.xdmf").getroot().iter("Attribute")}
    assert fine == {"u", "Fg", "G", "sigma_hom"}
    root = ET.parse(outdir / "coarse.xdmf").getroot()
    assert {a.get("Name") for a in root.iter("Attribute")} == set(VOIGT_NAMES)
    assert {a.get("Center") for a in root.iter("Attribute")} == {"Node"}
    with h5py.File(outdir / "fields.h5", "r") as f:
        nodes, triangles = f["CoarseMesh/geometry"][...], f["CoarseMesh/topology"][...]
    grid = CoarseGrid.with_edge(6.928203230275509, 3.0, 1.0)  # the scene's tissue and H
    assert np.array_equal(nodes, grid.nodes)
    assert np.array_equal(triangles, grid.triangles)
    with h5py.File(outdir / "fields" / "step_000010.h5", "r") as f:
        assert f["coarse/E1111"].shape == (len(nodes), 1)
        assert "E1111" not in f


def test_the_reader_gives_e_hom_on_the_fine_cells_as_the_model_interpolates_it(runs):
    """cell_field("E1111") (matplotlib's P1 interpolation on the coarse triangles) equals the
    model's own weights W at the cell midpoints: two float64 evaluations of one interpolant."""
    series = read_series(runs["every4"])
    assert set(VOIGT_NAMES) <= set(series.names)
    centroids = series.points[series.triangles].mean(axis=1)
    W = CoarseGrid.with_edge(6.928203230275509, 3.0, 1.0).interpolation_matrix(centroids)
    for name in VOIGT_NAMES:
        nodes = series.coarse.node_field(name, 10.0).astype(float)
        assert_close(series.cell_field(name, 10.0), W @ nodes, 1e-12, name)
    E1111 = series.coarse.node_field("E1111", 10.0)
    assert np.ptp(E1111) > 1e-3 * E1111.max()  # the eta gradient makes E_hom vary


@pytest.mark.mpi
def test_fields_are_compressed_in_their_precision_and_the_state_is_float64(runs):
    """float32 fields are the float64 state rounded once; float64 fields equal it; every
    DataItem declares the precision of its dataset."""
    for name, dtype in (("every4", np.float32), ("float64", np.float64)):
        outdir = runs[name]
        with h5py.File(outdir / "fields" / "step_000010.h5", "r") as f:
            for dataset in ("u", "Fg", "G", "sigma_hom", "coarse/E1111"):
                assert f[dataset].dtype == dtype and f[dataset].compression == "gzip", dataset
            Fg = f["Fg"][...][:, [0, 1, 3, 4]]
        with h5py.File(outdir / "state.h5", "r") as f:
            state_Fg = f["step_000010/Fg"][...]
            assert state_Fg.dtype == np.float64 and f["step_000010/G"].dtype == np.float64
        assert np.array_equal(Fg, state_Fg.astype(dtype))
        for xdmf in ("fields.xdmf", "coarse.xdmf"):
            for item in ET.parse(outdir / xdmf).getroot().iter("DataItem"):
                filename, _, path = item.text.strip().partition(":")
                with h5py.File(outdir / filename, "r") as f:
                    assert int(item.get("Precision")) == f[path].dtype.itemsize, item.text


def test_meshio_reads_both_series(runs):
    meshio = pytest.importorskip("meshio")
    outdir = runs["every4"]
    with meshio.xdmf.TimeSeriesReader(str(outdir / "coarse.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        assert reader.num_steps == 4 and cells[0].type == "triangle"
        t, point_data, _ = reader.read_data(3)
        assert t == 10.0 and point_data["E1111"].shape == (len(points), 1)
    with meshio.xdmf.TimeSeriesReader(str(outdir / "fields.xdmf")) as reader:
        points, _ = reader.read_points_cells()
        t, point_data, cell_data = reader.read_data(3)
        assert t == 10.0 and point_data["u"].shape == (len(points), 3)
        assert "E1111" not in cell_data


# --- resume stays exact -------------------------------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("kill", [6, 8], ids=["off_schedule", "written_step"])
def test_a_run_stopped_before_a_state_resumes_to_the_same_outputs(
    runs, tmp_path_factory, capsys, monkeypatch, kill
):
    """Stopped after step ``kill``'s fields and summary row, before its state: on disk the
    summary is one row ahead of the state (and for a written step, a field file too); --resume
    redoes that step and ends with the uninterrupted run's written steps, rows and state."""
    directory = shared_dir(tmp_path_factory, f"stopped_{kill}")
    write_state = output.StateFile.write

    def stopping(self, step, t, state):
        if step == kill:
            raise RunError("simulated kill")
        write_state(self, step, t, state)

    monkeypatch.setattr(output.StateFile, "write", stopping)
    scene = directory / "stopped.toml"
    write(scene, scene_text())
    outdir = directory / "stopped"
    assert call(["run", scene, "-o", outdir], capsys)[0] == 3
    if RANK0:
        assert [r["step"] for r in summary(outdir)] == list(range(kill + 1))
        assert step_files(outdir) == [s for s in (0, 4, 8) if s <= kill]
    monkeypatch.setattr(output.StateFile, "write", write_state)
    code, _, err = call(["run", scene, "--resume", outdir], capsys)
    assert code == 0, err
    if RANK0:
        assert f"resuming after step {kill - 1} " in (outdir / "run.log").read_text()
        assert_same_outputs(outdir, runs["every4"])


def test_extending_a_run_writes_the_steps_of_an_uninterrupted_one(runs, tmp_path_factory, capsys):
    """every = 4, t_max = 10 extended to 13: step 10 is no longer the last, so its fields go;
    12 and 13 are written, exactly as a run straight to t_max = 13 writes them."""
    directory = shared_dir(tmp_path_factory, "extend")
    extended = run(directory, "extended", scene_text())
    longer = directory / "longer.toml"
    write(longer, scene_text(t_max=13))
    code, _, err = call(["run", longer, "--resume", extended], capsys)
    assert code == 0, err
    whole = run(directory, "whole", scene_text(t_max=13))
    if RANK0:
        assert step_files(extended) == [0, 4, 8, 12, 13]
        assert_same_outputs(extended, whole)


def test_resume_without_a_state_starts_again_at_t0(runs, tmp_path_factory, capsys):
    """A directory with no state (e.g. written before it existed) is rerun from t = 0."""
    directory = shared_dir(tmp_path_factory, "no_state")
    outdir = run(directory, "rerun", scene_text())
    if RANK0:
        (outdir / "state.h5").unlink()
        (outdir / "state_previous.h5").unlink()
    MPI.COMM_WORLD.Barrier()
    code, _, err = call(["run", directory / "rerun.toml", "--resume", outdir], capsys)
    assert code == 0, err
    if RANK0:
        assert "the run starts again at t = 0" in (outdir / "run.log").read_text()
        assert_same_outputs(outdir, runs["every4"])


def test_no_coarse_series_without_a_coarse_field(tmp_path_factory):
    """Without E_hom there is nothing on the coarse grid: no coarse.xdmf, no coarse mesh."""
    directory = shared_dir(tmp_path_factory, "no_coarse")
    outdir = run(directory, "u_only", scene_text(t_max=2) + 'fields = ["u", "G"]\n')
    assert not (outdir / "coarse.xdmf").exists()
    with h5py.File(outdir / "fields.h5", "r") as f:
        assert sorted(f) == ["Mesh"]
    assert read_series(outdir).names == ["G", "u"]
