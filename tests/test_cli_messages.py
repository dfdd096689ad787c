"""What the command line says (issue 21, item 8): ``--version``, ``--quiet``, the final line
with the area and the mean growth rate, a named error for tissue.width / tissue.height where the
tissue is cellular (micro, both, compare: the cells set its size), and failure hints that name
time.dt and the adaptive integrator when growth contrast is the cause.

In-process through ``main`` on every rank (valid under mpirun; rank 0 alone prints).
"""

from __future__ import annotations

from importlib.metadata import version

import numpy as np
import pytest
from cli_helpers import RANK0, call, shared_dir, write

from plantgrowth.models import diagnostics
from plantgrowth.results.run_results import read_results
from plantgrowth.scene import Scene, parse_scene
from plantgrowth.scene.toml_text import dict_to_toml

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

SMALL = {
    "tissue": {"h": 0.5},
    "growth": {"law": "stress"},
    "time": {"t_max": 2},
    "accuracy": {"cell_resolution": 1},
}
CONTRAST = SMALL | {
    "growth": {"law": "stress", "eta": {"from": 1.0, "to": 100.0}},
    "time": {"t_max": 4, "dt": 1},
    "numerics": {"on_instability": "warn"},
}
"""A 100x eta contrast: elements invert at step 3 (t = 3) with dt = 1 and the exp integrator."""
MICRO = 'model = "{model}"\n[tissue]\n{key} = {value}\n[growth]\nlaw = "stress"\n[micro]\nnx = 4\n'


def test_version_prints_the_installed_version(capsys):
    with pytest.raises(SystemExit) as stop:
        call(["--version"], capsys)
    out = capsys.readouterr().out
    assert stop.value.code == 0
    assert out == f"plantgrowth {version('plantgrowth')}\n"


def _run(factory, capsys, name: str, scene: dict | str, before=(), after=()) -> tuple:
    """``plantgrowth *before run SCENE -o DIR *after``, the scene a dict or TOML text, in a
    fresh directory: (exit code, stdout, stderr, DIR)."""
    directory = shared_dir(factory, name)
    path, outdir = directory / "scene.toml", directory / "out"
    write(path, scene if isinstance(scene, str) else dict_to_toml(scene))
    return (*call([*before, "run", path, "-o", outdir, *after], capsys), outdir)


def _result_line(out: str) -> list[str]:
    return [line for line in out.splitlines() if line.startswith("result: ")]


@pytest.mark.parametrize("where", ["after", "before", "none"])
def test_quiet_keeps_only_the_final_line_which_names_area_and_growth_rate(
    where, tmp_path_factory, capsys
):
    flags = {"after": {"after": ["--quiet"]}, "before": {"before": ["-q"]}, "none": {}}[where]
    code, out, err, outdir = _run(tmp_path_factory, capsys, f"quiet_{where}", SMALL, **flags)
    assert code == 0, err
    if not RANK0:
        return
    summary = read_results(outdir).summary
    lines = out.splitlines()
    assert _result_line(out) == [lines[-1]]  # one result line, the last
    if where == "none":
        assert any(line.startswith("plantgrowth run") for line in lines) and len(lines) > 3
    else:
        assert len(lines) == 1, out
    words = lines[-1].replace(",", "").replace(":", "").split()
    area = float(words[words.index("area") + 1])
    rate = float(words[words.index("G") + 1])
    # printed with 6 significant digits
    assert area == pytest.approx(summary["area"][-1], rel=1e-5)
    assert rate == pytest.approx(summary["growth_rate_area"][-1], rel=1e-5)
    assert f"t = {summary['t'][-1]:g}" in lines[-1]
    ratio = summary["area"][-1] / summary["area"][0]
    assert f"({ratio:.4g} times its value at t = 0)" in lines[-1]
    log = (outdir / "run.log").read_text()  # run.log keeps the progress either way
    assert "step 2/2" in log and lines[-1] in log


def test_a_run_of_both_models_ends_with_one_result_line_per_model(tmp_path_factory, capsys):
    both = SMALL | {"model": "both", "time": {"t_max": 1}, "micro": {"nx": 4, "resolution": 1}}
    code, out, err, outdir = _run(tmp_path_factory, capsys, "both", both, after=["-q"])
    assert code == 0, err
    if RANK0:
        lines = out.splitlines()
        assert [line.split(":")[0] for line in lines] == ["macro result", "micro result"], out
        for side, line in zip(("macro", "micro"), lines, strict=True):
            area = read_results(outdir / side).summary["area"][-1]
            assert f"area {area:.6g} (" in line


@pytest.mark.parametrize(
    "model, key, value", [("micro", "width", 8.0), ("micro", "height", 4.0), ("both", "width", 8.0)]
)
def test_width_or_height_of_a_cellular_tissue_is_a_named_error(
    model, key, value, tmp_path_factory, capsys
):
    """The micro tissue is micro.nx cells per row: at Nx = 4, 7.79 x 2.5, whatever
    tissue.width says (the issue: a disc meant for 8 x 4 stuck out of it)."""
    scene = MICRO.format(model=model, key=key, value=value)
    code, _, err, outdir = _run(tmp_path_factory, capsys, f"{model}_{key}", scene)
    assert code == 2
    assert not outdir.exists()
    if RANK0:
        assert len(err.splitlines()) == 1, err
        assert f"tissue.{key} = {value:g} is not used by model = '{model}'" in err
        assert "micro.nx = 4 cells per row, here 7.794 x 2.5" in err


def test_compare_refuses_a_width_it_would_ignore(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "compare_width")
    scene = directory / "scene.toml"
    write(scene, dict_to_toml(SMALL | {"tissue": {"width": 8.0, "h": 0.5}}))
    code, _, err = call(["compare", scene, "--nx", "4", "-o", directory / "c"], capsys)
    assert code == 2
    assert not (directory / "c").exists()
    if RANK0:
        assert "tissue.width = 8 is not used by plantgrowth compare" in err, err
        assert "--nx 4 cells per row" in err


def test_the_resolved_scene_of_a_micro_run_loads_again():
    """scene.toml writes the default width and height: they are no error."""
    scene = parse_scene({"model": "micro", "growth": {"law": "stress"}, "micro": {"nx": 4}})
    again = Scene.from_dict(scene.to_dict())
    assert (again.tissue.width, again.tissue.height) == (scene.tissue.width, 3.0)


def test_an_inverted_element_names_the_time_step_and_the_adaptive_integrator():
    message = diagnostics.inversion_problems(np.array([1.0, -0.1]), np.zeros((2, 2)))[0]
    assert "time.dt" in message and 'time.integrator = "adaptive"' in message


def test_the_stiffness_check_flags_exactly_the_nodes_whose_e_hom_is_not_spd():
    """Sylvester's criterion (diagnostics.stiffness_problems) against numpy's eigenvalues, on
    symmetric matrices whose smallest eigenvalue is +-1e-3 of the largest (a honeycomb's shear
    modulus is about 1e-2 of its stiffness: far from round-off, so the two must agree), with
    positive diagonals (no minor of order 1 gives the indefinite ones away), and one SPD matrix
    made asymmetric by 1e-6 of its largest entry (the check allows 1e-8)."""
    rng = np.random.default_rng(5)
    Q = np.linalg.qr(rng.normal(size=(300, 3, 3)))[0]
    sign = np.where(rng.random(300) < 0.5, -1.0, 1.0)
    eigen = np.column_stack([sign * 1e-3, rng.uniform(0.1, 1, 300), np.ones(300)])
    C = Q @ (eigen[:, :, None] * np.swapaxes(Q, 1, 2))
    C = C[(np.diagonal(C, axis1=1, axis2=2) > 0).all(axis=1)]
    C[0] = np.diag([1.0, 0.5, 0.1])
    C[0, 0, 1] += 1e-6
    n = len(C)
    expected = (np.linalg.eigvalsh(0.5 * (C + np.swapaxes(C, 1, 2)))[:, 0] <= 0) | (
        np.arange(n) == 0
    )
    assert 100 < expected.sum() < n - 100
    points = np.column_stack([np.arange(float(n)), np.zeros(n)])
    assert not diagnostics.stiffness_problems(C[~expected], points[~expected])
    message = diagnostics.stiffness_problems(C, points)[0]
    assert "not symmetric positive definite" in message
    assert f"at x = (0, 0) ({int(expected.sum())} place(s)" in message


def test_a_run_that_fails_on_a_growth_contrast_names_dt_and_adaptive(tmp_path_factory, capsys):
    code, _, err, _ = _run(tmp_path_factory, capsys, "contrast", CONTRAST)
    assert code == 3
    failure = [line for line in err.splitlines() if "run failed" in line]
    assert len(failure) == RANK0, err
    for line in failure:
        assert "element inverted" in line and "time.dt" in line and "adaptive" in line
