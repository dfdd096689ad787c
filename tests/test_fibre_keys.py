"""The fibre keys of a scene (``[walls] fibre_stiffness, fibre_angle``, ``[feedback] cue,
rate``): parsed and checked in plantgrowth/scene/, round-tripped through the resolved
scene.toml, varied by sweeps, and accepted for every model (the runs with fibres:
test_macro_fibres.py, test_micro_fibres.py).

In-process CLI calls run ``main`` on every rank (valid under mpirun: every rank must fail the
same way). The one run here (``fibre_stiffness = 0``, the paper's walls) is tiny:
h = 0.5, cell_resolution 1, one step.
"""

from __future__ import annotations

import math
import tomllib

import pytest
from cli_helpers import RANK0, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.base.errors import SceneError
from plantgrowth.runner.scene_run import check_used_values
from plantgrowth.scene import parse_scene
from plantgrowth.studies.sweep_file import load_sweep

BASE = {"growth": {"law": "stress"}}
FIBRES = {"fibre_stiffness": 2.0, "fibre_angle": 30.0}
TINY = """\
[growth]
law = "stress"
[tissue]
h = 0.5
[time]
t_max = 1
[accuracy]
cell_resolution = 1
[output]
fields = ["u"]
"""


def _scene(**tables):
    return parse_scene(BASE | tables)


# --- parsing and the resolved scene ----------------------------------------------------------


@pytest.mark.parametrize(
    "walls",
    [
        FIBRES,
        {"fibre_stiffness": {"from": 0.0, "to": 3.0}, "fibre_angle": {"expr": "30 * x1 - 90"}},
        {"fibre_stiffness": {"expr": "where(x2 < 1, k_f, 0)"}, "fibre_angle": -45},
        {"fibre_stiffness": 0.0},  # the paper's walls: no direction needed
        {"fibre_stiffness": 0, "fibre_angle": {"from": 0, "to": 90, "along": "x2"}},
    ],
)
def test_fibre_keys_round_trip_through_the_resolved_scene(walls):
    data = BASE | {"parameters": {"k_f": 1.5}, "walls": walls}
    data |= {"feedback": {"cue": "strain", "rate": 0.25}} if "fibre_angle" in walls else {}
    scene = parse_scene(data)
    again = parse_scene(tomllib.loads(scene.to_toml()))
    assert again == scene
    assert again.to_toml() == scene.to_toml()
    dotted = scene.dotted()
    assert "walls.fibre_stiffness" in dotted
    assert ("walls.fibre_angle" in dotted) == ("fibre_angle" in walls)
    assert ("feedback.cue" in dotted) == ("feedback" in data)


def test_a_scene_without_fibres_writes_no_fibre_tables():
    """Older runs' scene.toml (resume compares it) stays the same: the tables are written only
    when given."""
    assert not {"walls", "feedback"} & set(_scene().to_dict())


def test_the_fibre_values_are_read_as_given():
    scene = _scene(
        walls={"fibre_stiffness": {"from": 1.0, "to": 3.0}, "fibre_angle": 60},
        feedback={"cue": "stress", "rate": 2},
    )
    stiffness, angle = scene.walls.fibre_stiffness, scene.walls.fibre_angle
    assert stiffness(scene.tissue.width / 2, 0.0) == pytest.approx(2.0, rel=1e-15)
    assert angle(1.0, 2.0) == 60.0
    assert (scene.feedback.cue, scene.feedback.rate) == ("stress", 2.0)
    assert isinstance(scene.feedback.rate, float)
    # a micro tissue's own extent: the linear field runs over it, never extrapolated
    micro = scene.over_extent(5.0, 2.0).walls.fibre_stiffness
    assert (micro(0.0, 0.0), micro(5.0, 0.0)) == (1.0, 3.0)
    assert not _scene(walls={"fibre_stiffness": 0.0}).walls.fibred
    assert _scene(walls={"fibre_stiffness": {"expr": "0 * x1"}, "fibre_angle": 0}).walls.fibred


# --- bad input: named errors ------------------------------------------------------------------

BAD = [
    ({"walls": {"fibre_stiffness": -0.5, "fibre_angle": 0}}, "walls.fibre_stiffness = -0.5"),
    ({"walls": {"fibre_stiffness": math.nan, "fibre_angle": 0}}, "walls.fibre_stiffness = nan"),
    ({"walls": {"fibre_stiffness": {"from": 1, "to": -1}, "fibre_angle": 0}},
     "walls.fibre_stiffness.to = -1"),
    ({"walls": {"fibre_stiffness": 1, "fibre_angle": math.inf}}, "walls.fibre_angle = inf"),
    ({"walls": {"fibre_stiffness": 1, "fibre_angle": 2e6}}, "walls.fibre_angle = 2000000.0"),
    ({"walls": {"fibre_stiffness": "1", "fibre_angle": 0}}, "walls.fibre_stiffness: expected"),
    ({"walls": {"fibre_stiffness": 1}}, "walls.fibre_angle is required"),
    ({"walls": {"fibre_angle": 30}}, "walls.fibre_stiffness is required"),
    ({"walls": {"fiber_angle": 30}}, "did you mean 'fibre_angle'"),
    ({"material": {"fibre_stiffness": 1}}, "did you mean 'walls.fibre_stiffness'"),
    ({"walls": 1.0}, "walls: expected a table"),
    ({"feedback": {"cue": "stress", "rate": 1}}, "feedback: [feedback] turns the fibre director"),
    ({"walls": {"fibre_stiffness": 0}, "feedback": {"cue": "stress", "rate": 1}},
     "scene has no fibres"),
    ({"walls": FIBRES, "feedback": {"cue": "curvature", "rate": 1}},
     "feedback.cue = 'curvature' is invalid"),
    ({"walls": FIBRES, "feedback": {"cue": "stress", "rate": -1}}, "feedback.rate = -1"),
    ({"walls": FIBRES, "feedback": {"cue": "stress", "rate": math.nan}}, "feedback.rate = nan"),
    ({"walls": FIBRES, "feedback": {"cue": "stress", "rate": {"from": 0, "to": 1}}},
     "feedback.rate: expected a number"),
    ({"walls": FIBRES, "feedback": {"rate": 1}}, "feedback.cue is required"),
    ({"walls": FIBRES, "feedback": {}}, "feedback.cue is required"),
    ({"walls": FIBRES, "feedback": {"cue": "strain"}}, "feedback.rate is required"),
    ({"walls": FIBRES, "feedback": {"cue": "strain", "rate": 1, "k": 1}},
     "unknown key 'feedback.k'"),
]  # fmt: skip


@pytest.mark.parametrize("tables, fragment", BAD, ids=[f for _, f in BAD])
def test_bad_fibre_keys_are_named_errors(tables, fragment):
    with pytest.raises(SceneError) as error:
        _scene(**tables)
    assert fragment in str(error.value)


@pytest.mark.mpi
def test_an_expression_out_of_range_is_named_where_the_run_uses_it():
    """A fibre field given as an expression is checked at every place of the mesh, like the
    other fields (scene/places.py), before the runner runs (or refuses) the fibres."""
    scene = parse_scene(
        tomllib.loads(TINY) | {"walls": {"fibre_stiffness": {"expr": "x1 - 3"}, "fibre_angle": 0}}
    )
    with pytest.raises(SceneError, match=r"walls\.fibre_stiffness = -\S+ at x1 = 0"):
        check_used_values(scene, MPI.COMM_WORLD)
    scene = parse_scene(
        tomllib.loads(TINY) | {"walls": {"fibre_stiffness": 1, "fibre_angle": {"expr": "1/x1"}}}
    )
    with pytest.raises(SceneError, match=r"walls\.fibre_angle = inf at x1 = 0"):
        check_used_values(scene, MPI.COMM_WORLD)


# --- sweeps -------------------------------------------------------------------------------------


def test_a_sweep_varies_the_fibre_keys(tmp_path):
    (tmp_path / "base.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(
        'base = "base.toml"\n[vary]\n"walls.fibre_stiffness" = [0.0, 1.5]\n'
        '"walls.fibre_angle" = [0.0, 45.0]\n"feedback.cue" = ["stress", "strain"]\n'
        '"feedback.rate" = [0.5]\n'
    )
    sweep = load_sweep(tmp_path / "sweep.toml")
    assert len(sweep.runs) == 8
    last = sweep.runs[-1].scene
    assert last.walls.fibre_stiffness(0.0, 0.0) == 1.5 and last.walls.fibre_angle(0, 0) == 45.0
    assert (last.feedback.cue, last.feedback.rate) == ("strain", 0.5)
    assert sweep.base_cells == dict.fromkeys(sweep.vary, "")  # the base scene has none
    (tmp_path / "bad.toml").write_text(
        'base = "base.toml"\n[vary]\n"walls.fibre_angle" = [0.0, 45.0]\n'
    )
    with pytest.raises(SceneError, match=r"walls\.fibre_stiffness is required.*run_0000"):
        load_sweep(tmp_path / "bad.toml")


# --- every command reads fibres: macro, micro, both --------------------------------------------

MICRO = 'model = "micro"\n'
STEP = '[walls]\nfibre_stiffness = {expr = "where(x1 < 2, 1, 0)"}\nfibre_angle = 0\n'
FEEDBACK = "[walls]\nfibre_stiffness = 0\nfibre_angle = 0\n[feedback]\ncue = 'stress'\nrate = 1\n"
FIBRED = [
    (MICRO, "[walls]\nfibre_stiffness = 0.5\nfibre_angle = 90\n"),
    ('model = "both"\n', STEP),
    (MICRO, FEEDBACK),
]


@pytest.mark.parametrize("top, extra", FIBRED)
def test_validate_accepts_fibred_micro_scenes(top, extra, tmp_path_factory, capsys):
    """The micro model reads fibres and feedback: validate (and run, sweep, compare) accept
    them."""
    directory = shared_dir(tmp_path_factory, "accepted")
    write(directory / "fibres.toml", top + TINY + extra)
    code, _, err = call(["validate", directory / "fibres.toml"], capsys)
    assert code == 0, err


@pytest.mark.mpi
def test_walls_of_zero_fibre_stiffness_run_as_the_paper_s(tmp_path_factory, capsys):
    """fibre_stiffness = 0 is the paper's model: it runs, and it writes the walls into the
    resolved scene.toml it runs."""
    directory = shared_dir(tmp_path_factory, "zero")
    write(directory / "zero.toml", TINY + "[walls]\nfibre_stiffness = 0\nfibre_angle = 15\n")
    code, _, err = call(["run", directory / "zero.toml", "-o", directory / "out"], capsys)
    assert code == 0, err
    if RANK0:
        resolved = tomllib.loads((directory / "out" / "scene.toml").read_text())
        assert resolved["walls"] == {"fibre_stiffness": 0.0, "fibre_angle": 15.0}
        assert (directory / "out" / "summary.csv").is_file()
