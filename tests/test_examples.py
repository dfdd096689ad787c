"""The scripts in examples/ (docs/api.md), run as a user runs them: ``python examples/NAME.py``
in a fresh process (serial; ``skip_in_parallel``), into a temporary directory. What they print
must be what the runs wrote: the numbers are printed with Python's repr (shortest round trip)
and summary.csv holds 17 significant digits, so the two agree exactly.
"""

from __future__ import annotations

import csv
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import ENV

import plantgrowth as pg

pytestmark = pytest.mark.skip_in_parallel

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
PNG = b"\x89PNG\r\n\x1a\n"  # the signature every PNG file starts with
NUMBER = r"([-+0-9.e]+)"


def run_example(name: str, *args: object, cwd: Path) -> str:
    """``python examples/name args`` in ``cwd``; its stdout (it must succeed)."""
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / name), *map(str, args)],
        cwd=cwd, capture_output=True, text=True, env=ENV, timeout=180,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    return done.stdout


def last_row(run: Path) -> dict[str, float]:
    with open(run / "summary.csv", newline="") as f:
        return {key: float(value) for key, value in list(csv.DictReader(f))[-1].items()}


def printed(pattern: str, out: str) -> float:
    found = re.search(pattern, out)
    assert found, f"{pattern!r} not in the output:\n{out}"
    return float(found.group(1))


def is_png(path: Path) -> bool:
    data = path.read_bytes()
    return data.startswith(PNG) and len(data) > 1000


def listing(directory: Path) -> list[str]:
    return sorted(str(p.relative_to(directory)) for p in directory.rglob("*"))


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> tuple[Path, str]:
    """examples/build_and_run.py into a fresh directory: (its run directory, its stdout)."""
    cwd = tmp_path_factory.mktemp("build_and_run")
    out = run_example("build_and_run.py", cwd / "run", cwd=cwd)
    assert [p.name for p in cwd.iterdir()] == ["run"]  # written only where told
    return cwd / "run", out


def test_build_and_run_prints_the_final_area_and_growth_rate(built):
    run, out = built
    assert {"summary.csv", "fields.xdmf", "fields.h5", "scene.toml"} <= set(listing(run))
    row = last_row(run)
    assert row["t"] == 10.0
    assert printed(rf"final area at t = 10: {NUMBER}", out) == row["area"]
    rate = printed(rf"mean growth rate \(growth_rate_area\) at t = 10: {NUMBER}", out)
    assert rate == row["growth_rate_area"] > 0.0
    scene = pg.load_scene(run / "scene.toml")  # the scene built in Python, as resolved
    assert (scene.tissue.width, scene.accuracy.preset, scene.growth.law) == (4.0, "draft", "stress")


def test_parameter_loop_prints_each_runs_rate_and_draws_them(tmp_path):
    out = run_example("parameter_loop.py", tmp_path / "loop", cwd=tmp_path)
    rates = []
    for E in ("0.5", "1", "2", "4"):
        rate = printed(rf"E = {E}: growth_rate_area at t = 5: {NUMBER}", out)
        assert rate == last_row(tmp_path / "loop" / f"E_{E}")["growth_rate_area"], E
        rates.append(rate)
    assert rates == sorted(rates, reverse=True)  # strain law: the softer, the faster
    assert is_png(tmp_path / "loop" / "growth_rate_vs_E.png")  # the default figure path
    assert [p.name for p in tmp_path.iterdir()] == ["loop"]  # written only where told

    figure = tmp_path / "figures" / "loop.png"  # a path given; the runs replaced
    again = run_example("parameter_loop.py", tmp_path / "loop", "--figure", figure,
                        "--overwrite", cwd=tmp_path)  # fmt: skip
    assert is_png(figure) and f"wrote {figure}" in again
    assert again.splitlines()[:4] == out.splitlines()[:4]


def test_plot_field_draws_a_field_of_the_run(built, tmp_path):
    run, _ = built
    before = {name: (run / name).stat().st_mtime_ns for name in listing(run)}
    out = run_example("plot_field.py", run, tmp_path / "pictures", cwd=tmp_path)
    assert is_png(tmp_path / "pictures" / "G_tr_t10.png")
    G = pg.read_results(run).field("G")
    trG = G[:, 0, 0] + G[:, 1, 1]
    assert printed(rf"tr G at t = 10: min {NUMBER}", out) == trG.min()
    assert printed(rf"max {NUMBER}", out) == trG.max() > trG.min()  # eta varies along x1

    out = run_example("plot_field.py", run, tmp_path / "pictures", "--field", "sigma_hom",
                      "--component", "11", "--time", "3", cwd=tmp_path)  # fmt: skip
    assert is_png(tmp_path / "pictures" / "sigma_hom_11_t3.png")
    sigma11 = pg.read_results(run).field("sigma_hom", t=3)[:, 0, 0]
    assert printed(rf"sigma_hom_11 at t = 3: min {NUMBER}", out) == np.min(sigma11)
    assert sorted(p.name for p in (tmp_path / "pictures").iterdir()) == [
        "G_tr_t10.png",
        "sigma_hom_11_t3.png",
    ]
    assert {name: (run / name).stat().st_mtime_ns for name in listing(run)} == before  # read only
