"""ParaView's own XDMF3 reader opens a run's fields.xdmf (skipped where ParaView is absent).

ParaView is not part of the default install (it is large); `apt-get install paraview
python3-paraview` provides `pvbatch`, which runs scripts/check_paraview.py.
"""

import json
import shutil
import subprocess
from pathlib import Path

import h5py
import pytest

from plantgrowth.cli import main

REPO = Path(__file__).resolve().parents[1]
SCENE = """
[tissue]
h = 0.5
[growth]
law = "strain"
[time]
t_max = 3
[accuracy]
cell_resolution = 1
"""


@pytest.mark.skip_in_parallel
@pytest.mark.skipif(shutil.which("pvbatch") is None, reason="ParaView (pvbatch) not installed")
def test_paraview_reads_every_step_and_field(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    outdir = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(outdir)]) == 0
    done = subprocess.run(
        ["pvbatch", str(REPO / "scripts" / "check_paraview.py"), str(outdir / "fields.xdmf")],
        capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["times"] == [0.0, 1.0, 2.0, 3.0]
    with h5py.File(outdir / "fields.h5") as f:
        n_points, n_cells = len(f["Mesh/geometry"]), len(f["Mesh/topology"])
    assert (seen["n_points"], seen["n_cells"]) == (n_points, n_cells)
    assert seen["point_arrays"] == ["u"]
    assert {"Fg", "G", "sigma_hom", "E1111"} <= set(seen["cell_arrays"])
    with h5py.File(outdir / "fields" / "step_000003.h5") as f:
        u_max = abs(f["u"][:, 0]).max()
    assert seen["u_max_abs_x"] == pytest.approx(u_max, rel=1e-6)  # float32 in VTK arrays
