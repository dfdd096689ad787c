"""The frictions a new user met (issue 32, item 3), each fixed: a fibred scene writes its director
and its feedback cue's anisotropy by default; unknown field names get "did you mean"; render
checks the field before the output file; every angle key warns about radians; ``pg.Interrupted``
is a KeyboardInterrupt and the API's messages name its arguments; a one-step area growth beyond
plausibility names the units of eta; check_paraview.py names a missing coarse.xdmf.

Runs are in process through ``main`` or the models on every rank (valid under mpirun). Small
scenes: h = 0.5, H = 1 or 2, one P2 element across a wall, one or two steps. Tolerances are
stated where a number is compared.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from cli_helpers import RANK0, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.base.errors import SceneError
from plantgrowth.models.macro.model import macro_model
from plantgrowth.scene import parse_scene
from plantgrowth.scene.limits import DEFAULT_OUTPUT

COMM = MPI.COMM_WORLD
SMALL = "[tissue]\nh = 0.5\nH = 1.0\n[accuracy]\ncell_resolution = 1\n"
WALLS = "[walls]\nfibre_stiffness = 5.0\nfibre_angle = 60.0\n"
FEEDBACK = '[feedback]\ncue = "stress"\nrate = 0.5\n'


def _scene(text: str):
    return parse_scene(tomllib.loads(text))


# --- 1. a fibred scene writes its director (and a feedback scene its cue's anisotropy) ----------


@pytest.mark.parametrize(
    "extra, added",
    [
        ("", ()),
        (WALLS, ("fibre_direction",)),
        (WALLS.replace("5.0", "0.0") + FEEDBACK, ("fibre_direction", "cue_anisotropy")),
        (WALLS + FEEDBACK, ("fibre_direction", "cue_anisotropy")),
    ],
    ids=["isotropic", "fibred", "feedback_unfibred", "feedback"],
)
def test_a_scene_with_a_director_writes_it_by_default(extra, added):
    scene = _scene('[growth]\nlaw = "stress"\n' + extra)
    assert scene.output.fields == DEFAULT_OUTPUT + added


def test_fields_the_user_lists_are_kept_and_cue_anisotropy_needs_feedback():
    listed = _scene('[growth]\nlaw = "stress"\n[output]\nfields = ["u"]\n' + WALLS + FEEDBACK)
    assert listed.output.fields == ("u",)
    with pytest.raises(SceneError, match=r"^output\.fields: cue_anisotropy .* no \[feedback\]"):
        _scene('[growth]\nlaw = "stress"\n[output]\nfields = ["cue_anisotropy"]\n' + WALLS)


def test_render_fibres_draws_a_fibred_run_that_listed_no_fields(tmp_path_factory, capsys):
    """The user's path: a fibred scene run as written, then ``render --fibres`` (refused before:
    "add fibre_direction to [output] fields and run again")."""
    directory = shared_dir(tmp_path_factory, "fibred_defaults")
    scene = directory / "fibred.toml"
    write(scene, SMALL + WALLS + '[growth]\nlaw = "strain"\n[time]\nt_max = 1\n')
    code, _, err = call(["run", scene, "-o", directory / "run"], capsys)
    assert code == 0, err
    picture = directory / "u.png"
    code, _, err = call(
        ["render", directory / "run", "--field", "u", "--fibres", "-o", picture], capsys
    )
    assert code == 0, err
    assert picture.is_file()


def _one_step_anisotropy(text: str) -> tuple[float, float]:
    """(min, max) over all ranks of the written cue_anisotropy after the first step."""
    model = macro_model(_scene(text), COMM)
    model.step(model.initial_growth())
    A = model.problem.cell_values(model.director.anisotropy)
    return (
        COMM.allreduce(float(A.min()), op=MPI.MIN),
        COMM.allreduce(float(A.max()), op=MPI.MAX),
    )


def test_cue_anisotropy_is_one_under_a_uniaxial_pull_and_zero_under_turgor():
    """A homogeneous tissue pulled along x1 without turgor has a uniaxial sigma_hom (q2 = 0):
    A = (q1 - q2) / (|q1| + |q2|) = 1; turgor alone gives sigma_hom = (1 - phi_w) P1 I
    (docs/fibres.md): A = 0. Tolerance 1e-9: q2 and q1 - q2 are the LU's round-off relative to
    the stress (measured 6e-12 in tests/test_macro_fibres.py)."""
    base = SMALL + WALLS + FEEDBACK + '[growth]\nlaw = "stress"\n'
    pull = base + "[pressure]\nP1 = 0.0\n[loads]\nleft = [-0.001, 0.0]\nright = [0.001, 0.0]\n"
    low, high = _one_step_anisotropy(pull)
    assert 1.0 - low <= 1e-9 and high <= 1.0 + 1e-12
    low, high = _one_step_anisotropy(base)
    assert low >= 0.0 and high <= 1e-9
