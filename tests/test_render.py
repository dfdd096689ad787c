"""``plantgrowth render`` (issue 11, item 4): PNGs of a macro and a micro run, headless, and
its named errors; it never writes into the run directory nor over a file without --force.

In-process through ``main`` (serial and under mpirun: rank 0 draws, every rank returns the same
code). Runs: macro h = 0.5, micro Nx = 4 with one element across a wall, two steps.
"""

from __future__ import annotations

import numpy as np
import pytest
from cli_helpers import RANK0, call, shared_dir, write
from matplotlib.image import imread
from mpi4py import MPI

from plantgrowth.results.reader import read_series
from plantgrowth.results.render import pick_time

FIELDS = '["u", "G", "E_hom", "trG", "growth_anisotropy", "growth_direction", "stress_direction"]'
MACRO = f"""\
[tissue]
h = 0.5
H = 1.0
[growth]
law = "stress"
eta = {{from = 0.5, to = 2.0}}
[time]
t_max = 2
[accuracy]
cell_resolution = 1
[output]
fields = {FIELDS}
"""
MICRO = MACRO.replace("[tissue]\nh = 0.5\nH = 1.0\n", 'model = "micro"\n') + (
    "[micro]\nnx = 4\nresolution = 1\n"
)


def snapshot(directory) -> dict:
    return {str(p): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{"macro": DIR, "micro": DIR} and a directory for pictures."""
    directory = shared_dir(tmp_path_factory, "render")
    out = {}
    for name, text in (("macro", MACRO), ("micro", MICRO)):
        write(directory / f"{name}.toml", text)
        from plantgrowth.cli import main

        assert main(["run", str(directory / f"{name}.toml"), "-o", str(directory / name)]) == 0
        MPI.COMM_WORLD.Barrier()
        out[name] = directory / name
    pictures = directory / "pictures"
    if RANK0:
        pictures.mkdir()
    MPI.COMM_WORLD.Barrier()
    return out, pictures


@pytest.mark.parametrize(
    "model, field",
    [("macro", ["trG"]), ("macro", ["G", "--component", "tr"]), ("macro", ["growth_direction"]),
     ("macro", ["u"]), ("micro", ["trG"]), ("micro", ["stress_direction"]),
     ("micro", ["u", "--component", "norm"]), ("macro", ["E1111"])],
)  # fmt: skip
def test_render_writes_a_png_and_leaves_the_run_alone(runs, model, field, capsys):
    dirs, pictures = runs
    picture = pictures / f"{model}_{'_'.join(field)}.png"
    before = snapshot(dirs[model]) if RANK0 else None
    code, out, err = call(["render", dirs[model], "--field", *field, "-o", picture], capsys)
    assert code == 0, err
    if RANK0:
        assert f"wrote {picture}" in out
        assert picture.stat().st_size > 0
        image = imread(picture)  # a valid PNG: matplotlib decodes it
        assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
        assert np.ptp(image[..., :3]) > 0  # not a blank canvas
        assert snapshot(dirs[model]) == before
        assert not list(pictures.glob(".*"))  # no temporary file left


def test_existing_picture_is_refused_unless_force(runs, capsys):
    dirs, pictures = runs
    picture = pictures / "mine.png"
    write(picture, "a user's file\n")
    code, _, err = call(["render", dirs["macro"], "--field", "trG", "-o", picture], capsys)
    assert code == 2
    if RANK0:
        assert "--force" in err and picture.read_text() == "a user's file\n"
    code, _, _ = call(["render", dirs["macro"], "--field", "trG", "-o", picture, "--force"],
                      capsys)  # fmt: skip
    assert code == 0
    if RANK0:
        assert imread(picture).ndim == 3


ERRORS = {  # name -> (argv after "render", with {dir} the run and {pic} a new picture; text)
    "unknown_field": (["{dir}", "--field", "sigma", "-o", "{pic}"],
                      "--field = 'sigma' is not written in"),
    "no_such_dir": (["{dir}/nothing", "--field", "trG", "-o", "{pic}"], "no such directory"),
    "not_a_run": (["{dir}/fields", "--field", "trG", "-o", "{pic}"], "not a run directory"),
    "time_after": (["{dir}", "--field", "trG", "--time", "3", "-o", "{pic}"],
                   "--time = 3.0 is out of range: the run wrote t in [0, 2]"),
    "time_before": (["{dir}", "--field", "trG", "--time", "-1", "-o", "{pic}"], "--time"),
    "tensor_needs_component": (["{dir}", "--field", "G", "-o", "{pic}"],
                               "--component = None is invalid for the tensor field G"),
    "scalar_has_none": (["{dir}", "--field", "trG", "--component", "11", "-o", "{pic}"],
                        "is a scalar field"),
    "vector_component": (["{dir}", "--field", "u", "--component", "3", "-o", "{pic}"],
                         "1, 2, norm"),
    "inside_the_run": (["{dir}", "--field", "trG", "-o", "{dir}/pic.png"],
                       "inside the run directory"),
    "not_png": (["{dir}", "--field", "trG", "-o", "{pic}.jpg"], "must be a .png"),
    "no_field": (["{dir}", "-o", "{pic}"], "--field"),
    "dpi": (["{dir}", "--field", "trG", "--dpi", "0", "-o", "{pic}"], "--dpi = 0"),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(ERRORS))
def test_bad_render_requests_name_the_option_and_write_nothing(runs, name, capsys):
    dirs, pictures = runs
    argv, text = ERRORS[name]
    picture = pictures / f"error_{name}.png"
    argv = [a.replace("{dir}", str(dirs["macro"])).replace("{pic}", str(picture)) for a in argv]
    before = snapshot(dirs["macro"].parent) if RANK0 else None
    code, _, err = call(["render", *argv], capsys)
    assert code == 2
    if RANK0:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("plantgrowth: error: "), err
        assert text in lines[0], lines[0]
        if name == "unknown_field":
            assert "trG, u" in lines[0]  # the written fields are listed
        assert snapshot(dirs["macro"].parent) == before


def test_time_picks_the_nearest_written_time(runs):
    dirs, _ = runs
    series = read_series(dirs["macro"])
    assert series.times == [0.0, 1.0, 2.0]
    assert pick_time(series, None) == 2.0
    assert pick_time(series, 1.4) == 1.0
    assert pick_time(series, 1.6) == 2.0
    assert pick_time(series, 2.0 + 1e-12) == 2.0
