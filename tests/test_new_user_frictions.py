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

import re
import tomllib
from pathlib import Path

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



def test_micro_cue_anisotropy_is_each_cells_cue_anisotropy():
    """A micro feedback scene writes cue_anisotropy per cell: on every wall triangle of a cell,
    (q1 - q2) / (|q1| + |q2|) of the cell's cue, here from numpy's eigenvalues (the code uses
    closed forms). Tolerance 1e-12: both are round-off apart on |q| ~ 1e-3 (2 x 2 eigenvalues)."""
    from plantgrowth.models.micro.model import MicroModel

    text = 'model = "micro"\n[micro]\nnx = 2\nresolution = 1\n[growth]\nlaw = "strain"\n'
    model = MicroModel(_scene(text + WALLS + FEEDBACK), COMM)
    model.step(model.initial_growth())
    assert "cue_anisotropy" in [f.name for f in model.outputs]
    q = np.linalg.eigvalsh(model._cue)  # ascending: q2, q1
    A = (q[:, 1] - q[:, 0]) / (np.abs(q[:, 0]) + np.abs(q[:, 1]))
    dofs = model.cue_out.function_space.dofmap.list.array[: model.n_owned]
    assert np.abs(model.cue_out.x.array[dofs] - A[model.cell_id]).max() <= 1e-12
    assert A.max() > 0.0  # the cells' own-wall stress is anisotropic: a real check

# --- 8. unknown field names: "did you mean"; render checks the field before the file -----------


@pytest.mark.parametrize(
    "name, meant",
    [("stress", "'sigma_hom'"), ("strain", "'eps_hom' or 'elastic_strain'"), ("growth", "'G'"),
     ("displacement", "'u'"), ("trg", "'trG'"), ("fibres", "'fibre_direction'")],
)  # fmt: skip
def test_an_unknown_output_field_gets_did_you_mean(name, meant):
    with pytest.raises(SceneError) as caught:
        _scene(f'[growth]\nlaw = "stress"\n[output]\nfields = ["u", "{name}"]\n')
    message = str(caught.value)
    assert message.startswith(f"output.fields[1] = {name!r} is invalid: it must be one of")
    assert message.endswith(f"; did you mean {meant}?"), message


@pytest.fixture(scope="module")
def plain_run(tmp_path_factory):
    """A one-step macro run that wrote the default fields (u, Fg, G, sigma_hom, E_hom)."""
    directory = shared_dir(tmp_path_factory, "plain_run")
    scene = directory / "plain.toml"
    write(scene, SMALL + '[growth]\nlaw = "stress"\n[time]\nt_max = 1\n')
    from plantgrowth.cli import main

    assert main(["run", str(scene), "-o", str(directory / "run")]) == 0
    COMM.Barrier()
    return directory


def test_render_names_a_wrong_field_before_an_existing_file(plain_run, capsys):
    picture = plain_run / "exists.png"
    write(picture, "a picture the user keeps")
    code, _, err = call(["render", plain_run / "run", "--field", "stress", "-o", picture], capsys)
    assert code == 2
    if RANK0:
        assert "--field = 'stress' is not written" in err and "exists" not in err, err
        assert "did you mean sigma_hom?" in err, err
    assert picture.read_text() == "a picture the user keeps"


def test_render_suggests_a_field_the_run_did_not_write(plain_run, capsys):
    code, _, err = call(
        ["render", plain_run / "run", "--field", "strain", "-o", plain_run / "s.png"], capsys
    )
    assert code == 2
    if RANK0:
        assert "(did you mean eps_hom or elastic_strain?)" in err, err
        assert "add it there and run the scene again" in err, err


# --- 4. every angle key warns when it looks like radians ----------------------------------------


@pytest.mark.parametrize(
    "tables, key, value",
    [("[walls]\nfibre_stiffness = 5.0\nfibre_angle = 1.5708\n", "walls.fibre_angle", "1.5708"),
     ("[walls]\nfibre_stiffness = 5.0\nfibre_angle = {from = -0.7854, to = 90.0}\n",
      "walls.fibre_angle", "-0.7854"),
     ("[cell]\ntheta = 0.5236\n", "cell.theta", "0.5236")],
    ids=["fibre_angle", "fibre_angle_field", "theta"],
)  # fmt: skip
def test_an_angle_that_looks_like_radians_warns(tables, key, value):
    from plantgrowth.scene.plausibility import ANGLES, scene_warnings

    assert set(ANGLES) == {"cell.theta", "walls.fibre_angle"}  # every angle key of a scene
    found = scene_warnings(_scene('[growth]\nlaw = "stress"\n' + tables))
    assert len(found) == 1, found
    assert found[0].startswith(f"{key} = {value} degrees is below 5 in magnitude"), found
    assert f"radians? {value} rad = " in found[0]


@pytest.mark.parametrize("angle", ["0.0", "90.0", "-30.0", "{from = 0.0, to = 90.0}"])
def test_angles_in_degrees_do_not_warn(angle):
    from plantgrowth.scene.plausibility import scene_warnings

    walls = f"[walls]\nfibre_stiffness = 5.0\nfibre_angle = {angle}\n"
    assert scene_warnings(_scene('[growth]\nlaw = "stress"\n' + walls)) == []


# --- 3. one step growing the area beyond plausibility names the units of eta -------------------


def test_step_growth_warns_once_above_its_bound():
    from plantgrowth.runner.step_warnings import MAX_STEP_GROWTH, StepWarnings

    warnings = StepWarnings()
    below = np.log(MAX_STEP_GROWTH) * 0.999  # rate x dt just below and above the bound
    assert warnings.growth(0, 0.0, below, 1.0, "stress") == []
    assert warnings.growth(0, 0.0, below / 2.0, 2.0 * 1.002, "stress") != []
    assert warnings.growth(1, 1.0, 10.0, 1.0, "stress") == []  # once per run


@pytest.mark.parametrize(
    "law, tables, phrases",
    [("stress", '[material]\nE = 300.0\n[pressure]\nP1 = 0.3\n[growth]\nlaw = "stress"\n',
      ["per unit stress per unit time", "scale as 1/E"]),
     ("strain", '[growth]\nlaw = "strain"\neta = 100.0\n',
      ["per unit strain per unit time", "lower eta"])],
)  # fmt: skip
def test_a_run_growing_implausibly_fast_names_the_units_of_eta(
    law, tables, phrases, tmp_path_factory, capsys
):
    """The user's scene (E = 300, P1 = 0.3 in MPa, eta = 1) and a strain-law eta 100 times the
    reference: the first step's growth factor is the clamp's exp(2 M dt) = 7.4 or more."""
    directory = shared_dir(tmp_path_factory, f"fast_{law}")
    scene = directory / "fast.toml"
    write(scene, SMALL + '[time]\nt_max = 1\n[numerics]\non_instability = "warn"\n' + tables)
    code, _, err = call(["run", scene, "-o", directory / "run"], capsys)
    assert code == 0, err
    if RANK0:
        found = [line for line in err.splitlines() if "grows the tissue's area" in line]
        assert len(found) == 1, err
        assert found[0].startswith("plantgrowth: warning: step 0, t = 0: the mean growth rate")
        assert all(phrase in found[0] for phrase in phrases), found[0]


def test_no_shipped_scene_reaches_the_step_growth_bound():
    """The measurement behind MAX_STEP_GROWTH (scripts/studies/area_growth.py): every shipped
    scene and hard case grows less per step, the measured area ratios too."""
    import json

    from plantgrowth.runner.step_warnings import MAX_STEP_GROWTH

    measured = json.loads((REPO / "benchmarks" / "results" / "area_growth.json").read_text())
    scenes = REPO / "scenes"
    files = [p for p in scenes.glob("*.toml") if p.stem != "organ_E_gradient"]  # 1e6 dofs
    files += [*scenes.glob("biology/*.toml"), *scenes.glob("shapes/*.toml")]
    keys = {p.stem for p in files} | {f"hard/{p.stem}" for p in scenes.glob("hard/*.toml")}
    assert keys <= set(measured), keys - set(measured)  # every shipped scene was measured
    factors = [row.get("growth_factor_max", 1.0) for row in measured.values()]
    ratios = [row.get("area_ratio_max", 1.0) for row in measured.values()]
    assert max(factors + ratios) < MAX_STEP_GROWTH


# --- 6. pg.Interrupted is a KeyboardInterrupt; the API names its arguments ---------------------


def test_interrupted_is_a_keyboard_interrupt_exported_as_pg_interrupted():
    import plantgrowth as pg
    from plantgrowth.runner import timeloop

    assert pg.Interrupted is timeloop.Interrupted
    assert issubclass(pg.Interrupted, KeyboardInterrupt)
    assert not issubclass(pg.Interrupted, Exception)
    assert "Interrupted" in pg.__all__


def test_ctrl_c_stops_a_parameter_loop_that_catches_exception(tmp_path_factory, monkeypatch):
    """``except Exception: continue`` over pg.run calls (the user's parameter loop) stops at
    Ctrl-C: SIGINT's flag is set before the first step ends, so the run stops after it."""
    from contextlib import nullcontext

    import plantgrowth as pg
    from plantgrowth.runner import timeloop

    monkeypatch.setattr(timeloop, "interrupt_at_step_end", lambda: nullcontext({"set": True}))
    directory = shared_dir(tmp_path_factory, "loop")
    scene = _scene(SMALL + '[growth]\nlaw = "stress"\n[time]\nt_max = 2\n')
    started = []
    with pytest.raises(pg.Interrupted, match="interrupted after step 0"):
        for E in (1.0, 2.0):
            started.append(E)
            try:
                pg.run(scene.replace(**{"material.E": E}), directory / f"E{E:g}")
            except Exception:  # noqa: BLE001  (what the user wrote: a failed run is skipped)
                continue
    assert started == [1.0]


def test_ctrl_c_in_compare_exits_130_with_one_line(tmp_path_factory, monkeypatch, capsys):
    """compare has no handler of its own: main turns pg.Interrupted into exit code 130 and one
    line (before, the exception escaped main with a traceback)."""
    from contextlib import nullcontext

    from plantgrowth.runner import timeloop

    monkeypatch.setattr(timeloop, "interrupt_at_step_end", lambda: nullcontext({"set": True}))
    directory = shared_dir(tmp_path_factory, "compare_stop")
    scene = directory / "compare.toml"
    write(scene, '[growth]\nlaw = "stress"\n[time]\nt_max = 2\n[tissue]\nh = 0.5\n'
                 "[accuracy]\ncell_resolution = 1\n[micro]\nresolution = 1\n")  # fmt: skip
    code, _, err = call(["compare", scene, "--nx", "2", "-o", directory / "out"], capsys)
    assert code == 130
    if RANK0:
        assert err.splitlines() == ["plantgrowth: interrupted after step 0 (t = 0); every "
                                    "completed step is saved"], err  # fmt: skip

def test_api_messages_name_the_api_arguments(tmp_path_factory):
    import plantgrowth as pg

    directory = shared_dir(tmp_path_factory, "api_words")
    write(directory / "run" / "fields" / "step_000000.h5", "")  # an earlier run's file
    scene = _scene(SMALL + '[growth]\nlaw = "stress"\n[time]\nt_max = 1\n')
    with pytest.raises(pg.InputError) as caught:
        pg.run(scene, directory / "run")
    assert "use overwrite=True to replace it" in str(caught.value)
    assert f"resume=True (outdir {directory / 'run'}) to continue it" in str(caught.value)
    assert "--" not in str(caught.value).replace(str(directory), "")
    with pytest.raises(pg.InputError, match=r"^resume=True \(outdir .*\): no scene.toml there"):
        pg.run(scene, directory / "run", resume=True)
    with pytest.raises(pg.InputError, match=r"^give either overwrite=True or resume=True"):
        pg.run(scene, directory / "run", resume=True, overwrite=True)


def test_cli_messages_keep_the_flags(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "cli_words")
    write(directory / "run" / "fields" / "step_000000.h5", "")
    scene = directory / "scene.toml"
    write(scene, SMALL + '[growth]\nlaw = "stress"\n[time]\nt_max = 1\n')
    code, _, err = call(["run", scene, "-o", directory / "run"], capsys)
    assert code == 2
    if RANK0:
        assert "use --overwrite to replace it" in err and f"--resume {directory / 'run'}" in err
    code, _, err = call(["run", scene, "--resume", directory / "run", "--overwrite"], capsys)
    assert code == 2
    if RANK0:
        assert "give either --overwrite or --resume, not both" in err, err


# --- 7. check_paraview.py names a missing file --------------------------------------------------


@pytest.mark.parametrize("name", ["coarse.xdmf", "fields.xdmf"])
def test_check_paraview_names_a_missing_file(name, tmp_path):
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[1] / "scripts" / "figures" / "check_paraview.py"
    done = subprocess.run(
        [sys.executable, str(script), str(tmp_path / name)], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.startswith(f"check_paraview.py: error: {tmp_path / name}: no such file")
    assert ("lists E_hom" in done.stderr) == (name == "coarse.xdmf"), done.stderr


# --- 5 and 2. the docs: the strain bands' numbers, the mirror plane -----------------------------

REPO = Path(__file__).resolve().parents[1]
BAND_DOCS = ("README.md", "docs/usage.md", "docs/finite_kinematics.md",
             "scenes/examples/held_and_pulled.toml")  # fmt: skip
"""The texts that speak of the strain warnings' thresholds."""


def warning_percentages(text: str) -> list[float]:
    """Every percentage a text gives a warning: "the 5% warning", "5% of the small-strain
    warning", "warnings at 20%", "the plausibility warning at 5% elastic strain"."""
    patterns = (r"(\d+(?:\.\d+)?)%[\w\s-]{0,30}warning",
                r"warnings?[\w\s]{0,20}?(?:at|above) (\d+(?:\.\d+)?)%")  # fmt: skip
    return [float(m.group(1)) for p in patterns for m in re.finditer(p, text)]


def test_the_warning_check_finds_the_old_five_percent():
    assert warning_percentages("here: 4.5% at t = 10, below the 5% of the small-strain warning")
    assert warning_percentages("stays below the 5% warning") == [5.0]
    assert warning_percentages("(the plausibility warning at 5% elastic strain") == [5.0]


@pytest.mark.parametrize("name", BAND_DOCS)
def test_the_docs_give_the_strain_bands_of_the_code(name):
    from plantgrowth.runner.step_warnings import STRAIN_BANDS

    text = (REPO / name).read_text(encoding="utf-8")
    bands = [100.0 * b for b in STRAIN_BANDS]
    assert all(p in bands for p in warning_percentages(text)), warning_percentages(text)
    listed = ", ".join(f"{b:g}%" for b in bands[:-1]) + f" and {bands[-1]:g}%"  # 20%, 50% and 100%
    assert listed in " ".join(text.split()), f"{name} does not list the bands {listed}"


@pytest.mark.parametrize("name, link", [("README.md", "docs/figures/mirror_plane.png"),
                                        ("docs/usage.md", "figures/mirror_plane.png")])  # fmt: skip
def test_the_scenes_sections_explain_the_mirror_plane(name, link):
    text = (REPO / name).read_text(encoding="utf-8")
    scenes = text.split("\n## Scenes\n", 1)[1].split("\n## ", 1)[0]
    assert "**The mirror plane x2 = 0.**" in scenes
    assert f"]({link})" in scenes
    assert (REPO / "docs" / "figures" / "mirror_plane.png").is_file()
    assert (REPO / "scripts" / "figures" / "plot_mirror_plane.py").is_file()
