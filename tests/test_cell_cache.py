"""The on-disk cache of the surrogate's lattice (plantgrowth/unitcell/cache.py, issue 9).

Runs are real ``plantgrowth run`` subprocesses sharing one cache directory (so
``skip_in_parallel``): two at once, and one killed with SIGKILL; later runs must start from
what they left. A small E-gradient strain scene (h = 0.35, cell resolution 1, tolerance
1e-3) keeps each run at a few seconds.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.unitcell.homogenization import CHECK_EVERY, CHECK_LINE

pytestmark = pytest.mark.skip_in_parallel

PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")
SCENE = {
    "tissue": {"h": 0.35},
    "material": {"E": {"from": 0.5, "to": 2.0}},
    "growth": {"law": "strain"},
    "accuracy": {"cell_resolution": 1, "cell_tolerance": 1e-3},
}


def write_scene(path: Path, t_max: float) -> Path:
    path.write_text(dict_to_toml(SCENE | {"time": {"t_max": t_max, "dt": 1.0}}))
    return path


def start(scene: Path, outdir: Path, cache: Path) -> subprocess.Popen:
    env = dict(os.environ, PLANTGROWTH_CACHE_DIR=str(cache))
    return subprocess.Popen(
        [PLANTGROWTH, "run", str(scene), "-o", str(outdir)],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def lattice_solves(outdir: Path) -> list[int]:
    """Cell solves per step, less the surrogate's self-checks: the first call of a run checks
    (when it interpolates), then every CHECK_EVERY-th; each check is logged in run.log."""
    with open(outdir / "summary.csv", newline="") as f:
        solves = [int(float(row["n_cell_solves"])) for row in csv.DictReader(f)]
    log = (outdir / "run.log").read_text()
    for step in range(0, len(solves), CHECK_EVERY):  # exp integrator: one call per step
        solves[step] -= f"{CHECK_LINE} {step // CHECK_EVERY + 1}:" in log
    return solves


def cache_files(cache: Path) -> list[Path]:
    return sorted(cache.glob("cells/*/*.npz"))


def test_two_concurrent_runs_fill_one_cache_that_a_third_run_reuses(tmp_path):
    """Both concurrent runs finish; every file in the cache is complete; a third run finds
    every lattice point it needs there (where the first two solved some)."""
    scene, cache = write_scene(tmp_path / "scene.toml", 6.0), tmp_path / "cache"
    runs = [start(scene, tmp_path / f"run{k}", cache) for k in (1, 2)]
    for proc in runs:
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err
    files = cache_files(cache)
    assert files and not list(cache.glob("cells/*/.*.tmp"))
    for path in files:
        with np.load(path) as data:
            assert len(data["points"]) == len(data["values"]) > 0
    third = start(scene, tmp_path / "run3", cache)
    _, err = third.communicate(timeout=300)
    assert third.returncode == 0, err
    assert sum(lattice_solves(tmp_path / "run3")) == 0  # steps 0..6 all from the cache
    # the cache is read as geometries appear, so one concurrent run may find the other's
    # files and solve nothing; between them they solved
    assert sum(lattice_solves(tmp_path / "run1")) + sum(lattice_solves(tmp_path / "run2")) > 0


def test_a_killed_run_leaves_a_cache_the_next_run_starts_from(tmp_path):
    """SIGKILL in the middle of a run: whatever files it wrote are complete, and the next run
    needs no lattice point at its first step (those of the killed run's first step)."""
    scene, cache = write_scene(tmp_path / "scene.toml", 200.0), tmp_path / "cache"
    proc = start(scene, tmp_path / "killed", cache)
    deadline, summary = time.monotonic() + 120, tmp_path / "killed" / "summary.csv"
    while time.monotonic() < deadline and not (
        summary.is_file() and len(summary.read_text().splitlines()) > 3  # header + 3 steps
    ):
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    assert proc.returncode == -signal.SIGKILL
    files = cache_files(cache)
    assert files
    for path in files:
        with np.load(path) as data:
            assert len(data["points"]) == len(data["values"]) > 0
    after = start(write_scene(tmp_path / "short.toml", 2.0), tmp_path / "after", cache)
    _, err = after.communicate(timeout=300)
    assert after.returncode == 0, err
    assert lattice_solves(tmp_path / "after")[0] == 0
