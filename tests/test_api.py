"""The Python API (docs/api.md): ``pg.load_scene``, ``pg.Scene.from_dict``, ``scene.replace``,
``pg.run``, ``pg.read_results`` and ``pg.cell``, against what the ``plantgrowth`` command does.

Every test is valid in serial and under ``mpirun -n 2``: directories are made on rank 0 and
shared, runs are collective on COMM_WORLD, the in-process CLI runs through ``main`` on every
rank. The runs are a draft scene of three steps (h = 0.5, under a second each).

Tolerances: ``pg.run`` and ``plantgrowth run`` do the same arithmetic in the same process, and
summary.csv holds 17 significant digits, so they agree to round-off (1e-12). A resumed run
repeats the uninterrupted run's arithmetic (1e-10, as tests/test_interruptions.py). A run on two
ranks differs from the serial one by the parallel LU (~1e-14 measured): 1e-10, on fields written
as float64 (``output.precision``: float32 would round a 1e-14 difference up to one float32 unit,
2**-23). The summary's ``residual`` is itself round-off (~3e-15, and MUMPS under mpirun varies
from run to run by 10%): compared absolutely, to 1e-10. The mean of G11 over the cells of a
uniform mesh is the summary's growth_rate_11 to the float32 rounding of the stored values
(2**-23, as tests/test_output_files.py).
"""

from __future__ import annotations

import csv
import json
import logging
import re
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import call, shared_dir, write
from mpi4py import MPI

import plantgrowth as pg
from plantgrowth.cli import main
from plantgrowth.models.linear import SolveReport
from plantgrowth.models.macro import problem as macro_problem
from plantgrowth.scene.presets import PRESETS

COMM = MPI.COMM_WORLD
RANK0 = COMM.rank == 0
SCENE = """\
[tissue]
h = 0.5
[growth]
law = "stress"
[time]
t_max = 2
[accuracy]
preset = "draft"
cell_resolution = 1
"""
ULP32 = 2.0**-23
E_NAMES = ("E1111", "E2222", "E1122", "E1212", "E1112", "E2212")
NOT_COMPARED = ("n_cell_solves",)  # a resumed run's cell cache restarts empty


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """summary.csv by column, read with the csv module alone (not with pg.Results)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {key: np.array([float(row[key]) for row in rows]) for key in rows[0]}


def timings(name: str) -> bool:
    return name.startswith("seconds")


def files(directory: Path) -> list[str]:
    return sorted(str(p.relative_to(directory)) for p in directory.rglob("*"))


def assert_same_summary(got: dict, expected: dict, rtol: float, skip: tuple = ()) -> None:
    """Every column but the timings (and ``skip``) to ``rtol``; ``residual`` to 1e-10 absolute
    (round-off, see above)."""
    assert list(got) == list(expected)
    for key, values in expected.items():
        if key == "residual" and key not in skip:
            np.testing.assert_allclose(got[key], values, rtol=0, atol=1e-10, err_msg=key)
        elif not timings(key) and key not in skip:
            np.testing.assert_allclose(got[key], values, rtol=rtol, atol=0, err_msg=key)


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory) -> Path:
    path = shared_dir(tmp_path_factory, "api") / "draft.toml"
    write(path, SCENE)
    return path


@pytest.fixture(scope="module")
def runs(scene_file) -> tuple[pg.Results, Path]:
    """The scene run by ``pg.run`` (its Results) and by ``plantgrowth run`` (its directory)."""
    results = pg.run(pg.load_scene(scene_file), scene_file.parent / "api_run")
    cli_dir = scene_file.parent / "cli_run"
    assert main(["run", str(scene_file), "-o", str(cli_dir)]) == 0
    COMM.Barrier()  # rank 0 writes the last row after the collectives
    return results, cli_dir


# --- scenes -------------------------------------------------------------------------------------


def test_load_scene_reads_the_file_and_fills_the_preset(scene_file):
    scene = pg.load_scene(scene_file)
    assert isinstance(scene, pg.Scene)
    assert (scene.tissue.h, scene.time.t_max, scene.growth.law) == (0.5, 2.0, "stress")
    assert scene.accuracy.preset == "draft"
    assert scene.tissue.H == PRESETS["draft"]["tissue"]["H"]  # left to the preset
    assert scene.accuracy.cell_tolerance == PRESETS["draft"]["accuracy"]["cell_tolerance"]
    missing = scene_file.parent / "no_such_scene.toml"
    with pytest.raises(pg.SceneError, match=re.escape(str(missing))):
        pg.load_scene(missing)


def test_scene_from_dict_equals_the_loaded_file(scene_file):
    data = tomllib.loads(SCENE)
    assert pg.Scene.from_dict(data, directory=scene_file.parent) == pg.load_scene(scene_file)
    data["material"] = {"E": 2.0}
    assert pg.Scene.from_dict(data) != pg.load_scene(scene_file)
    with pytest.raises(pg.SceneError, match="growth.law"):
        pg.Scene.from_dict({"tissue": {"h": 0.5}})


def test_replace_changes_only_the_key(scene_file):
    scene = pg.load_scene(scene_file)
    stiffer = scene.replace(**{"material.E": 2.0})
    before, after = scene.dotted(), stiffer.dotted()
    assert after["material.E"] == 2.0 and before["material.E"] == 1.0  # scene is unchanged
    assert sorted(k for k in before if before[k] != after[k]) == ["material.E"]


def test_replace_unknown_key_raises_naming_it(scene_file):
    scene = pg.load_scene(scene_file)
    with pytest.raises(pg.SceneError, match=re.escape("material.Young")):
        scene.replace(**{"material.Young": 2.0})


def test_replace_out_of_range_raises_naming_key_and_range(scene_file):
    scene = pg.load_scene(scene_file)
    with pytest.raises(pg.SceneError) as error:
        scene.replace(**{"material.nu": 0.5})
    assert "material.nu" in str(error.value) and "(-1, 0.5)" in str(error.value)


def test_replace_preset_moves_the_keys_left_to_it(scene_file):
    """The file gives tissue.h and accuracy.cell_resolution; dt, H and cell_tolerance are the
    preset's and follow it (H clipped to h <= H)."""
    scene = pg.load_scene(scene_file)
    fine = scene.replace(**{"accuracy.preset": "fine"})
    preset = PRESETS["fine"]
    assert fine.time.dt == preset["time"]["dt"] != scene.time.dt
    assert fine.accuracy.cell_tolerance == preset["accuracy"]["cell_tolerance"]
    assert fine.tissue.H == max(0.5, preset["tissue"]["H"])
    assert (fine.tissue.h, fine.accuracy.cell_resolution) == (0.5, 1)  # given: kept
    assert fine.replace(**{"accuracy.preset": "draft"}) == scene


# --- pg.run -------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_run_returns_the_summary_plantgrowth_run_writes(runs):
    results, cli_dir = runs
    assert isinstance(results, pg.Results)
    summary, written = results.summary, read_csv(cli_dir / "summary.csv")
    assert len(summary["t"]) == 3
    assert_same_summary(summary, written, rtol=1e-12)
    assert files(results.directory) == files(cli_dir)
    assert "fields.xdmf" in files(cli_dir) and "fields/step_000002.h5" in files(cli_dir)


@pytest.mark.mpi
def test_run_of_a_bad_scene_raises_and_writes_nothing(mpi_tmp_path):
    """nu out of range on part of the tissue: only the run's own places find it."""
    bad = pg.Scene.from_dict(
        tomllib.loads(SCENE) | {"material": {"nu": {"expr": "where(x1 > 3, 0.6, 0.3)"}}}
    )
    with pytest.raises(pg.InputError, match="material.nu"):
        pg.run(bad, mpi_tmp_path / "bad")
    assert files(mpi_tmp_path) == []


def test_run_refuses_an_earlier_run_unless_overwrite(runs, mpi_tmp_path):
    results, _ = runs
    outdir = mpi_tmp_path / "earlier"
    if RANK0:
        shutil.copytree(results.directory, outdir)
    COMM.Barrier()
    listing = files(outdir)
    before = {name: (outdir / name).read_bytes() for name in listing if (outdir / name).is_file()}
    scene = pg.load_scene(outdir / "scene.toml")
    with pytest.raises(pg.InputError, match="holds an earlier run"):
        pg.run(scene, outdir)
    assert files(outdir) == listing
    assert {name: (outdir / name).read_bytes() for name in before} == before
    again = pg.run(scene, outdir, overwrite=True)
    assert_same_summary(again.summary, results.summary, rtol=1e-12)


@pytest.mark.mpi
def test_run_logs_into_run_log_and_shows_only_warnings(mpi_tmp_path, capsys):
    """In a script that never called the CLI (the ``plantgrowth`` logger left unset): run.log
    records the run as under the CLI, the console shows only its warnings (cell.theta = 3 and
    the strain it causes), and the logger is left as it was."""
    logger = logging.getLogger("plantgrowth")
    saved = (logger.level, list(logger.handlers), logger.propagate)
    for handler in saved[1]:  # an earlier in-process CLI call configured it
        logger.removeHandler(handler)
    logger.setLevel(logging.NOTSET)
    logger.propagate = True
    outdir = mpi_tmp_path / "run"
    try:
        scene = pg.Scene.from_dict(tomllib.loads(SCENE)).replace(**{"cell.theta": 3.0})
        capsys.readouterr()
        pg.run(scene, outdir, label="api test")
        out, err = capsys.readouterr()
        after = (logger.level, list(logger.handlers), logger.propagate)
    finally:
        logger.setLevel(saved[0])
        logger.propagate = saved[2]
        for handler in saved[1]:
            logger.addHandler(handler)
    assert after == (logging.NOTSET, [], True)
    assert out == ""
    if not RANK0:
        assert err == ""
        return
    text = (outdir / "run.log").read_text()
    assert f"api test -> {outdir} on {COMM.size} rank(s)" in text
    assert "step 2/2" in text and f"done: {outdir}" in text
    assert "warning: cell.theta = 3 degrees" in text
    lines = err.splitlines()
    assert lines and all(line.startswith("plantgrowth: warning: ") for line in lines), err
    assert "cell.theta = 3 degrees" in lines[0]


@pytest.mark.mpi
def test_run_of_model_both_returns_macro_and_micro(mpi_tmp_path):
    scene = pg.Scene.from_dict(
        tomllib.loads(SCENE) | {"model": "both", "micro": {"nx": 2, "resolution": 1}}
    )
    results = pg.run(scene, mpi_tmp_path / "both")
    assert sorted(results) == ["macro", "micro"]
    for side, result in results.items():
        assert result.directory == mpi_tmp_path / "both" / side
        np.testing.assert_array_equal(result.summary["t"], [0.0, 1.0, 2.0])
    assert "cell_id" in results["micro"].fields and "E1111" in results["macro"].fields
    with pytest.raises(pg.InputError, match="model = 'both'"):
        pg.read_results(mpi_tmp_path / "both")


# --- pg.read_results ----------------------------------------------------------------------------


def test_read_results_times_shapes_and_values(runs):
    results, cli_dir = runs
    read = pg.read_results(cli_dir)
    summary = read_csv(cli_dir / "summary.csv")
    np.testing.assert_array_equal(read.times, summary["t"])  # output.every = 1
    assert {"u", "Fg", "G", "sigma_hom", *E_NAMES} <= set(read.fields)
    points, triangles = read.points, read.triangles
    n, m = len(points), len(triangles)
    assert points.shape == (n, 2) and triangles.shape == (m, 3) and triangles.max() == n - 1
    assert read.field("u").shape == (n, 2) and np.abs(read.field("u")).max() > 0.0
    assert read.field("G").shape == read.field("sigma_hom").shape == (m, 2, 2)
    assert read.field("G").dtype == np.float64  # stored as float32 (output.precision)
    assert read.field("E1111").shape == (m,)
    for name in ("u", "G", "E1111"):  # t = None: the last written time
        np.testing.assert_array_equal(read.field(name), read.field(name, t=read.times[-1]))
    assert not np.array_equal(read.field("u", t=0.0), read.field("u"))
    np.testing.assert_array_equal(read.field("Fg", t=0), np.broadcast_to(np.eye(2), (m, 2, 2)))
    for t, rate in zip(summary["t"], summary["growth_rate_11"], strict=True):
        assert read.field("G", t=t)[:, 0, 0].mean() == pytest.approx(rate, rel=ULP32)


def test_read_results_names_what_exists(runs, mpi_tmp_path):
    results, _ = runs
    read = pg.read_results(results.directory)
    with pytest.raises(pg.InputError) as error:
        read.field("trG")
    assert "'trG'" in str(error.value) and "sigma_hom" in str(error.value)
    with pytest.raises(pg.InputError) as error:
        read.field("u", t=1.5)
    assert "t = 1.5" in str(error.value) and "written times: 0, 1, 2" in str(error.value)
    with pytest.raises(pg.InputError, match="not a plantgrowth run directory"):
        pg.read_results(mpi_tmp_path)


def read_now(outdir: Path) -> tuple | Exception:
    """What a reader sees of the run in ``outdir`` now: completed steps, written times and the
    last u, or the error (returned, not raised: the other ranks are inside the run)."""
    try:
        going = pg.read_results(outdir)
        return going.summary["step"], going.times, going.field("u")
    except Exception as err:
        return err


@pytest.mark.mpi
def test_read_results_of_a_run_going_on_and_of_a_failed_run(runs, mpi_tmp_path, monkeypatch):
    """Read in the middle of a run (rank 0, from inside the solves of steps 0 and 2), then
    after step 2's solve failed (RunError): steps 0 and 1. A row being appended (no end of line
    yet) is left out. Resumed, the run ends as the uninterrupted one."""
    results, _ = runs
    outdir = mpi_tmp_path / "failed"
    calls, during = [], {}
    solve = macro_problem.assemble_and_solve

    def failing_at_step_2(*args):
        calls.append(1)
        if RANK0 and len(calls) in (1, 3):  # step 0: nothing written yet; 2: steps 0, 1 done
            during[len(calls) - 1] = read_now(outdir)
        report = solve(*args)
        return SolveReport(reason=-3, residual=float("nan")) if len(calls) == 3 else report

    monkeypatch.setattr(macro_problem, "assemble_and_solve", failing_at_step_2)
    scene = pg.load_scene(results.directory / "scene.toml")
    with pytest.raises(pg.RunError, match="step 2"):
        pg.run(scene, outdir)
    monkeypatch.undo()
    read = pg.read_results(outdir)
    np.testing.assert_array_equal(read.summary["step"], [0, 1])
    np.testing.assert_array_equal(read.times, [0.0, 1.0])
    np.testing.assert_array_equal(read.field("u"), read.field("u", t=1))
    if RANK0:  # a row being appended: all its columns, the last one cut short
        text = (outdir / "summary.csv").read_text()
        try:
            (outdir / "summary.csv").write_text(text + text.splitlines()[-1][:-2])
            during["cut"] = read.summary["step"]
        finally:
            (outdir / "summary.csv").write_text(text)
    COMM.Barrier()
    resumed = pg.run(scene, outdir, resume=True)
    assert_same_summary(resumed.summary, results.summary, rtol=1e-10, skip=NOT_COMPARED)
    if RANK0:  # after the last collective call: a failure here cannot hang the other ranks
        np.testing.assert_array_equal(during["cut"], [0, 1])
        assert isinstance(during[0], pg.InputError), during[0]  # the mesh, but no step yet
        assert "no fields written yet" in str(during[0])
        steps, times, u = during[2]
        np.testing.assert_array_equal(steps, [0, 1])
        np.testing.assert_array_equal(times, [0.0, 1.0])
        np.testing.assert_array_equal(u, pg.read_results(outdir).field("u", t=1))


@pytest.mark.mpi
def test_read_results_of_an_mpi_run_equals_the_serial_run(scene_file, mpi_tmp_path):
    """pg.run on COMM_WORLD (two ranks under mpirun) against pg.run on COMM_SELF (rank 0)."""
    scene = pg.load_scene(scene_file).replace(**{"output.precision": "float64"})
    parallel = pg.run(scene, mpi_tmp_path / "parallel", comm=COMM)
    failure = None
    if RANK0:
        try:
            serial = pg.run(scene, mpi_tmp_path / "serial", comm=MPI.COMM_SELF)
        except Exception as err:  # the other ranks must not wait for rank 0 forever
            failure = repr(err)
    assert COMM.bcast(failure, root=0) is None
    if not RANK0:
        return
    got, expected = pg.read_results(parallel.directory), pg.read_results(serial.directory)
    assert_same_summary(got.summary, expected.summary, rtol=1e-10)
    np.testing.assert_array_equal(got.triangles, expected.triangles)
    np.testing.assert_allclose(got.points, expected.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got.times, expected.times)
    assert got.fields == expected.fields
    for t in expected.times:
        # E1112 and E2212 are zero up to round-off: E_hom's components share E1111's scale
        e_scale = max(np.abs(expected.field(name, t)).max() for name in E_NAMES)
        for name in expected.fields:
            want = expected.field(name, t)
            scale = e_scale if name in E_NAMES else np.abs(want).max()
            error = np.abs(got.field(name, t) - want).max()
            assert error <= 1e-10 * scale, (name, t, error, scale)


# --- pg.cell ------------------------------------------------------------------------------------

CELL = {"l1": 1.2, "l2": 1.0, "theta": 35.0, "w": 0.06, "E": 2.0, "nu": 0.25}
FG = [[1.1, 0.05], [0.0, 1.0]]


def test_cell_equals_plantgrowth_cell_json(capsys):
    argv = ["cell", "--json", "--resolution", "1", "--Fg", "1.1,0.05,0.0,1.0"]
    argv += [f"--{key}={value}" for key, value in CELL.items()]
    code, out, _ = call(argv, capsys)
    assert code == 0
    printed = json.loads(COMM.bcast((out.splitlines() or [""])[-1] if RANK0 else None))
    got = pg.cell(**CELL, Fg=FG, resolution=1, comm=COMM)
    assert list(got) == list(printed)
    assert {"b", "inv_M", "kappa"} <= set(got)  # docs/model.md "Water fluxes"
    assert got["ndofs"] == printed["ndofs"] and isinstance(got["ndofs"], int)

    def numbers(value) -> np.ndarray:  # dbar_w is a table of lists: compare its numbers
        return np.asarray(list(value.values()) if isinstance(value, dict) else value, float)

    for key, value in printed.items():
        if key != "seconds":
            np.testing.assert_allclose(numbers(got[key]), numbers(value), rtol=1e-12,
                                       atol=1e-12 * got["E1111"], err_msg=key)  # fmt: skip
    reference = pg.cell(resolution=1)
    assert abs(got["E1111"] - reference["E1111"]) > 1e-3 * reference["E1111"]  # inputs used


@pytest.mark.parametrize(
    ("change", "named"), [({"nu": 0.5}, "nu = 0.5"), ({"w": 0.9}, "w = 0.9")], ids=["nu", "w"]
)
def test_cell_bad_input_raises_naming_it(change, named):
    with pytest.raises(pg.InputError, match=re.escape(named)):
        pg.cell(**(CELL | change), resolution=1)
