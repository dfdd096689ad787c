"""ParaView's own XDMF3 reader opens a run's fields.xdmf and coarse.xdmf and renders them
headless (skipped where ParaView is absent), and the optional install provides what that needs.

ParaView is not part of the default install (it is large); `PLANTGROWTH_WITH_PARAVIEW=1 bash
scripts/install.sh` provides `pvbatch`, which runs scripts/figures/check_paraview.py, and
`xvfb-run`: pvbatch aborts without an X server when it renders ("bad X server connection").
"""

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import h5py
import pytest

from plantgrowth.base.tensors import VOIGT_NAMES
from plantgrowth.cli import main

REPO = Path(__file__).resolve().parents[1]
CHECK_PARAVIEW = REPO / "scripts" / "figures" / "check_paraview.py"
SCENE = """
[tissue]
h = 0.5
[growth]
law = "{law}"
[time]
t_max = 3
[accuracy]
cell_resolution = 1
"""
HEADLESS = ["xvfb-run", "-a", "pvbatch"]


def pvbatch() -> list[str]:
    """pvbatch, under a virtual X server when there is no display."""
    return ["pvbatch"] if os.environ.get("DISPLAY") else HEADLESS


needs_paraview = pytest.mark.skipif(
    shutil.which("pvbatch") is None, reason="ParaView (pvbatch) not installed"
)


def run(directory: Path, law: str) -> Path:
    """A run of SCENE with the growth law; its output directory."""
    scene, outdir = directory / "scene.toml", directory / "out"
    scene.write_text(SCENE.format(law=law))
    assert main(["run", str(scene), "-o", str(outdir)]) == 0
    return outdir


def check(outdir: Path, *extra: str, xdmf: str = "fields.xdmf") -> dict:
    if pvbatch() == HEADLESS and shutil.which("xvfb-run") is None:
        pytest.fail(
            "no display and no xvfb-run: PLANTGROWTH_WITH_PARAVIEW=1 bash scripts/install.sh"
        )
    done = subprocess.run(
        [*pvbatch(), str(CHECK_PARAVIEW), str(outdir / xdmf), *extra],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.skip_in_parallel
@needs_paraview
def test_paraview_reads_every_step_and_field_and_renders_headless(tmp_path):
    outdir = run(tmp_path, "strain")
    picture = tmp_path / "last.png"
    seen = check(outdir, "--png", str(picture))
    assert seen["times"] == [0.0, 1.0, 2.0, 3.0]
    with h5py.File(outdir / "fields.h5") as f:
        n_points, n_cells = len(f["Mesh/geometry"]), len(f["Mesh/topology"])
    assert (seen["n_points"], seen["n_cells"]) == (n_points, n_cells)
    assert seen["point_arrays"] == ["u"]
    assert {"Fg", "G", "sigma_hom"} <= set(seen["cell_arrays"])
    with h5py.File(outdir / "fields" / "step_000003.h5") as f:
        u_max = abs(f["u"][:, 0]).max()
    assert seen["u_max_abs_x"] == pytest.approx(u_max, rel=1e-6)  # float32 in VTK arrays
    header = picture.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n"
    assert struct.unpack(">II", header[16:24]) == (640, 360)  # IHDR width, height


@pytest.mark.skip_in_parallel
@needs_paraview
def test_paraview_reads_the_coarse_grid_series(tmp_path):
    """coarse.xdmf: the coarse grid with E_hom's six components at its nodes, at every time."""
    outdir = run(tmp_path, "strain")
    seen = check(outdir, xdmf="coarse.xdmf")
    assert seen["times"] == [0.0, 1.0, 2.0, 3.0]
    with h5py.File(outdir / "fields.h5") as f:
        coarse = len(f["CoarseMesh/geometry"]), len(f["CoarseMesh/topology"])
    assert (seen["n_points"], seen["n_cells"]) == coarse
    assert sorted(seen["point_arrays"]) == sorted(VOIGT_NAMES)
    assert seen["cell_arrays"] == []


@pytest.mark.skip_in_parallel
@needs_paraview
def test_paraview_reads_a_single_time(tmp_path):
    """A static run (law none) has one time, which ParaView reports as a bare float."""
    assert check(run(tmp_path, "none"))["times"] == [0.0]


def test_the_paraview_install_brings_a_virtual_x_server():
    """`PLANTGROWTH_WITH_PARAVIEW=1` adds ParaView, xvfb (for `xvfb-run -a pvbatch`) and xauth
    (which xvfb-run needs; only a recommendation of xvfb) to the Debian packages."""
    script = REPO / "scripts" / "install.sh"
    section = f"sed -n '/^APT_PACKAGES=(/,/^fi$/p' {script}"  # the list and its options
    listing = f'eval "$({section})"; printf "%s\\n" "${{APT_PACKAGES[@]}}"'

    def packages(flag: str) -> set[str]:
        env = dict(os.environ, PLANTGROWTH_WITH_PARAVIEW=flag)
        done = subprocess.run(["bash", "-c", listing], env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return set(done.stdout.split())

    optional = {"paraview", "python3-paraview", "xvfb", "xauth"}
    assert optional <= packages("1")
    assert not optional & packages("0")
    assert "python3-dolfinx" in packages("0")
    readme = (REPO / "README.md").read_text()
    assert "xvfb-run -a pvbatch scripts/figures/check_paraview.py" in readme
