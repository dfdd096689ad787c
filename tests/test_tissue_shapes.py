"""Tissue shapes (issue 11, item 2): ``tissue.outline`` polygons and ``tissue.mesh`` files.

Runs are tiny (draft preset, 2 steps). The comparisons use homogeneous scenes, whose solution
(uniform growth, uniform stress under a balanced pull) is linear in x and so exact in P1 on any
mesh: two meshes of the same tissue then agree to round-off, not to a discretisation error.
"""

from __future__ import annotations

import shutil
import subprocess
import tomllib
from pathlib import Path

import malformed_inputs as mi
import numpy as np
import pytest
from cli_helpers import ENV, PLANTGROWTH, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.meshes.polygon import first_crossing, write_polygon_msh
from plantgrowth.models.macro.coarse import CoarseGrid, active_nodes
from plantgrowth.models.macro.model import macro_model
from plantgrowth.results.reader import read_series
from plantgrowth.scene import SceneError, load_scene, parse_scene

LAW = '[growth]\nlaw = "stress"\n'
RUN = '[time]\nt_max = 2\n[accuracy]\npreset = "draft"\ncell_tolerance = 0\n'
RECTANGLE = [[0, 0], [4, 0], [4, 2], [0, 2]]
L_SHAPE = [[0, 0], [4, 0], [4, 1], [2, 1], [2, 3], [0, 3]]
TRAPEZOID = [[0, 0], [6, 0], [4, 3], [0, 3]]
GROUPS = {"symmetry": [0], "slope": [1], "top": [2], "left": [3]}
COMPARED = ("area", "growth_rate_11", "growth_rate_22", "u1_max", "u2_max", "det_Fg_min")
ROUND_OFF = 1e-9
"""Relative agreement of two runs whose solution P1 represents exactly (LU on a few hundred
dofs: ~1e-13; margin for the different meshes' sums)."""


def outline(points) -> str:
    return f"[tissue]\noutline = {points}\n"


def scene(text: str):
    return parse_scene(tomllib.loads(text if "[growth]" in text else text + LAW))


def summary(outdir: Path) -> np.ndarray:
    return np.genfromtxt(outdir / "summary.csv", delimiter=",", names=True)


def run(directory: Path, name: str, text: str, capsys) -> np.ndarray:
    """Run a scene in-process on every rank; its summary rows."""
    path = directory / f"{name}.toml"
    write(path, text + RUN + ("" if "[growth]" in text else LAW))
    code, _, err = call(["run", path, "-o", directory / name], capsys)
    assert code == 0, err
    return summary(directory / name)


def assert_same_run(a: np.ndarray, b: np.ndarray) -> None:
    assert len(a) == len(b) == 3  # t = 0, 1, 2
    for column in COMPARED:
        np.testing.assert_allclose(b[column], a[column], rtol=ROUND_OFF, err_msg=column)


# --- geometry and scene checks ------------------------------------------------------------------


@pytest.mark.parametrize(
    "points, crossing",
    [(RECTANGLE, None), (L_SHAPE, None), (TRAPEZOID[::-1], None),  # clockwise is fine
     ([[0, 0], [4, 0], [0, 3], [4, 3]], (1, 3)),  # a bow tie
     ([[0, 0], [4, 0], [2, 0]], (0, 1)),  # folds back onto itself
     ([[1, 0], [4, 0], [4, 2], [2, 2], [2, 0], [1, 1]], (0, 3))],  # touches edge 0 at (2, 0)
)  # fmt: skip
def test_first_crossing(points, crossing):
    assert first_crossing(np.array(points, dtype=float)) == crossing


def test_an_outline_sets_the_bounding_box_and_its_edges():
    s = scene(outline(L_SHAPE) + "[loads]\nedge1 = [3e-5, 0.0]\nedge5 = [-1e-5, 0.0]\n")
    assert (s.tissue.width, s.tissue.height) == (4.0, 3.0)
    assert s.tissue.shape.symmetry == ("edge0",)
    assert s.tissue.shape.edges == {"edge1": 1.0, "edge2": 2.0, "edge3": 2.0, "edge4": 2.0,
                                    "edge5": 3.0}  # fmt: skip
    assert s.tissue.pin == (0.0, 0.0)
    assert s.tissue.h == 0.1 and s.tissue.H == 0.5  # the balanced preset's
    small = scene(outline([[0, 0], [0.1, 0], [0, 0.15]])).tissue
    assert small.h == 0.05 and small.H == 0.15  # the preset's h and H clipped to the box
    assert parse_scene(tomllib.loads(s.to_toml())) == s  # the resolved scene loads back
    clockwise = scene(outline([[1, 3], [4, 0], [1, 0]]))
    assert clockwise.tissue.pin == (1.0, 0.0)  # the bottom-left-most vertex on x2 = 0
    assert clockwise.tissue.shape.symmetry == ("edge1",)


LOADED = outline(RECTANGLE) + "[loads]\n"
BAD = {  # name -> (scene text, the start of the error message)
    "self-intersecting": (
        outline([[0, 0], [4, 0], [0, 3], [4, 3]]),
        "tissue.outline: edges 1 and 3 intersect",
    ),
    "no bottom edge": (outline([[0, 1], [4, 1], [2, 3]]), "tissue.outline: no edge lies on x2 = 0"),
    "point below x2 = 0": (
        outline([[0, 0], [4, 0], [4, -1], [0, 3]]),
        "tissue.outline[2][1] = -1 is out of range",
    ),
    "too few points": (outline([[0, 0], [4, 0]]), "tissue.outline: expected an array of 3 to"),
    "repeated point": (
        outline([[0, 0], [4, 0], [4, 0], [0, 3]]),
        "tissue.outline[1] and tissue.outline[2] are",
    ),
    "not a point": (outline([[0, 0], [4, 0], 3]), "tissue.outline[2]: expected a point"),
    "with width": (outline(RECTANGLE) + "width = 4\n", "tissue.width: not with tissue.outline"),
    "symmetry edge loaded": (
        LOADED + "edge0 = [0, 1e-5]\n",
        "loads.edge0: edge 'edge0' lies on the symmetry plane",
    ),
    "rectangle edge name": (LOADED + "top = [0, 1e-5]\n", "unknown key 'loads.top'"),
    "unbalanced": (LOADED + "edge1 = [1e-5, 0]\n", "loads: net x1 force f_edge1[0] * 2 ="),
    "micro model": (
        'model = "micro"\n' + outline(RECTANGLE),
        "tissue.outline: the micro model builds its own",
    ),
    "both models": (
        'model = "both"\n' + outline(RECTANGLE),
        "tissue.outline: the micro model builds its own",
    ),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_outlines_are_named_errors(name):
    text, message = BAD[name]
    with pytest.raises(SceneError) as caught:
        scene(text)
    assert str(caught.value).startswith(message), str(caught.value)


MSH = {  # name -> curve groups of the trapezoid's edges, the error (None: valid)
    "valid": (GROUPS, None),
    "no symmetry group": ({"top": [2]}, "no curve group 'symmetry'"),
    "symmetry off the axis": ({"symmetry": [2]}, "the curve group 'symmetry' is not on x2 = 0"),
}


@pytest.fixture(scope="module")
def msh_files(tmp_path_factory) -> Path:
    """The trapezoid as .msh files with the groups of MSH, and two broken files (rank 0)."""
    directory = shared_dir(tmp_path_factory, "msh")
    if MPI.COMM_WORLD.rank == 0:
        for name, (groups, _) in MSH.items():
            write_polygon_msh(TRAPEZOID, 0.6, groups, directory / f"{name}.msh")
        (directory / "garbage.msh").write_text("$MeshFormat\nnot a mesh\n")
        (directory / "mesh.stl").write_text("solid\n")
    MPI.COMM_WORLD.Barrier()
    return directory


def mesh_scene(directory: Path, file: str, rest: str = "") -> str:
    return f'[tissue]\nmesh = "{directory / file}"\n{rest}'


@pytest.mark.parametrize(
    "file, message",
    [(f"{name}.msh", error) for name, (_, error) in MSH.items() if error]
    + [("missing.msh", "file not found"), ("garbage.msh", "not a readable gmsh mesh"),
       ("mesh.stl", "not a .msh file")],
)  # fmt: skip
def test_bad_mesh_files_are_named_errors(msh_files, file, message):
    with pytest.raises(SceneError) as caught:
        scene(mesh_scene(msh_files, file))
    text = str(caught.value)
    assert text.startswith(f"tissue.mesh = '{msh_files / file}': ") and message in text, text


@pytest.mark.parametrize(
    "groups, message",
    [({"symmetry": (1, 2), "top": (3, 4)}, "no point group 'pinned'"),
     ({"pinned": (1,), "symmetry": (1, 2)}, None), ({"pinned": (1,)}, "no curve group 'symmetry'"),
     ({"pinned": (1,), "symmetry": (3, 4)}, "'symmetry' is not on x2 = 0")],
)  # fmt: skip
def test_a_hand_written_msh_file_needs_its_groups(tmp_path, groups, message):
    path = tmp_path / "square.msh"
    path.write_text(mi.square_msh(groups))
    text = f'[tissue]\nmesh = "{path}"\nh = 0.5\n'
    if message is None:
        assert scene(text).tissue.shape.edges == {}
        return
    with pytest.raises(SceneError, match=message):
        scene(text)


def test_a_mesh_file_names_its_loadable_edges_and_is_relative_to_the_scene(msh_files):
    path = msh_files / "scene.toml"
    write(path, '[tissue]\nmesh = "valid.msh"\n[loads]\ntop = [0, 1e-5]\n' + LAW)
    s = load_scene(path)
    assert s.tissue.mesh == str(msh_files / "valid.msh")
    assert sorted(s.tissue.shape.edges) == ["left", "slope", "top"]
    assert (s.tissue.width, s.tissue.height, s.tissue.pin) == (6.0, 3.0, (0.0, 0.0))
    with pytest.raises(SceneError, match="loads.symmetry: edge 'symmetry' lies on the symmetry"):
        scene(mesh_scene(msh_files, "valid.msh", "[loads]\nsymmetry = [0, 1e-5]\n"))


# --- the coarse grid ----------------------------------------------------------------------------


@pytest.mark.mpi
def test_coarse_nodes_outside_the_tissue_take_no_part():
    """The L's coarse grid (H = 1) covers [0, 4] x [0, 3]; the four nodes of the empty corner
    x1 > 2, x2 > 1 weigh no fine cell and get no cell problem."""
    s = scene(outline(L_SHAPE) + "h = 0.25\nH = 1\n")
    model = macro_model(s, MPI.COMM_WORLD)
    nodes = model.grid.nodes
    assert len(nodes) == 20
    outside = {tuple(p) for p in nodes[~model.active]}
    assert outside == {(3.0, 2.0), (4.0, 2.0), (3.0, 3.0), (4.0, 3.0)}
    calls = []
    homogenize = model.homogenizer.homogenize
    model.homogenizer.homogenize = lambda *a: calls.append(len(a[0])) or homogenize(*a)
    model.step(model.initial_growth())
    assert calls == [16]


def test_active_nodes_of_a_full_rectangle_are_all_nodes():
    grid = CoarseGrid(4.0, 2.0, 4, 2)
    x, y = np.meshgrid(np.linspace(0.05, 3.95, 40), np.linspace(0.05, 1.95, 20))
    W = grid.interpolation_matrix(np.column_stack([x.ravel(), y.ravel()]))
    assert active_nodes(W, MPI.COMM_SELF).all()


# --- runs ---------------------------------------------------------------------------------------


def test_an_outline_equal_to_the_rectangle_gives_the_rectangle_run(tmp_path_factory, capsys):
    """Same tissue, coarse grid and balanced pull (loads by edge index on the outline): the
    runs agree to round-off although gmsh's mesh is not the structured rectangle's."""
    directory = shared_dir(tmp_path_factory, "same")
    pull = "[loads]\n{} = [2e-5, 0.0]\n{} = [-2e-5, 0.0]\n"
    box = run(directory, "box", "[tissue]\nwidth = 4\nheight = 2\n" + pull.format("right", "left"),
              capsys)  # fmt: skip
    polygon = run(directory, "polygon", outline(RECTANGLE) + pull.format("edge1", "edge3"), capsys)
    assert_same_run(box, polygon)
    assert polygon["u1_max"][0] > 0.0 and box["area"][-1] > box["area"][0]


@pytest.mark.mpi
def test_a_mesh_file_gives_the_run_of_the_same_outline(msh_files, tmp_path_factory, capsys):
    """write_polygon_msh and the outline mesher build the same gmsh mesh: loads by group name
    on the file and by edge index on the outline agree to round-off."""
    directory = shared_dir(tmp_path_factory, "file")
    f = 1e-5 * np.sqrt(13.0) / 3.0  # balances f_slope = 1e-5 on |slope| = sqrt(13) with left
    loads = "[loads]\n{} = [1e-5, 0.0]\n{} = [" + repr(-f) + ", 0.0]\n"
    h = "h = 0.6\n"
    from_file = run(directory, "file", mesh_scene(msh_files, "valid.msh", h)
                    + loads.format("slope", "left"), capsys)  # fmt: skip
    polygon = run(directory, "polygon", outline(TRAPEZOID) + h + loads.format("edge1", "edge3"),
                  capsys)  # fmt: skip
    assert_same_run(from_file, polygon)


@pytest.mark.mpi
def test_an_l_shape_runs_grows_and_writes_readable_fields(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "L")
    rows = run(directory, "L", outline(L_SHAPE) + "[loads]\nedge1 = [3e-5, 0.0]\n"
               "edge5 = [-1e-5, 0.0]\n", capsys)  # fmt: skip
    assert np.all(np.diff(rows["area"]) > 0.0) and np.all(rows["growth_rate_area"] > 0.0)
    if MPI.COMM_WORLD.rank == 0:
        series = read_series(directory / "L")
        area = 0.5 * np.abs(np.cross(*np.swapaxes(
            series.points[series.triangles[:, 1:]] - series.points[series.triangles[:, :1]], 0, 1
        ))).sum()  # fmt: skip
        assert area == pytest.approx(8.0, rel=1e-12)  # 4 x 1 + 2 x 2: the mesh is the L
        # E_hom lives on the coarse nodes (the empty corner's show their nearest active node's
        # value); read back at the cells; at t = 0 (Fg = I) every node has the same cell
        E = series.cell_field("E1111", 0.0)
        assert np.all(np.isfinite(E)) and np.ptp(E) == 0.0 and E.min() > 0.0


@pytest.mark.skip_in_parallel
def test_mpirun_reproduces_the_serial_l_shape(tmp_path_factory, capsys):
    """``mpirun -n 2 plantgrowth run`` of the loaded L against the serial run; 1e-8 relative
    as tests/test_macro_run.py (only the macro LU and the reductions' order differ)."""
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    directory = shared_dir(tmp_path_factory, "mpirun")
    text = outline(L_SHAPE) + "[loads]\nedge1 = [3e-5, 0.0]\nedge5 = [-1e-5, 0.0]\n"
    text += "[material]\nE = {from = 1.0, to = 0.5}\n"  # heterogeneous: several cell problems
    serial = run(directory, "serial", text, capsys)
    command = [mpirun, "-n", "2", PLANTGROWTH, "run", str(directory / "serial.toml"), "-o",
               str(directory / "parallel")]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, env=ENV, timeout=300)
    assert done.returncode == 0, done.stderr
    parallel = summary(directory / "parallel")
    for column in COMPARED:
        np.testing.assert_allclose(parallel[column], serial[column], rtol=1e-8, err_msg=column)
