"""The paper-study sweeps (scripts/studies/paper_studies.py): every sweep file and every run's
scene is valid, the script knows every file, and its sensitivity and exact-rate formulas are
right. Runs nothing."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from plantgrowth.scene import load_scene
from plantgrowth.studies.sweep_file import load_sweep

ROOT = Path(__file__).resolve().parents[1]
ROUND_OFF = 1e-12  # a few float64 operations on numbers of order 1


def _load_script():
    spec = importlib.util.spec_from_file_location(
        "paper_studies", ROOT / "scripts" / "studies" / "paper_studies.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


studies = _load_script()


def test_every_sweep_file_is_a_study_and_valid():
    """load_sweep checks the base scene and every run's scene (the CLI's validation)."""
    files = sorted(studies.SWEEPS_DIR.glob("*.toml"))
    assert sorted(f.stem for f in files) == sorted(studies.sweep_names())
    counts = {f.stem: len(load_sweep(f).runs) for f in files}
    assert counts["fig2c_stress"] == 21 and counts["fig2c_l_strain"] == 9
    assert all(counts[f"fig3_micro_{p}_stress"] == 1 for p in studies.GRADIENTS)


def test_micro_sweeps_are_the_gradient_scenes_with_the_micro_side():
    for name in studies.sweep_names()[: 2 * len(studies.GRADIENTS)]:
        (run,) = load_sweep(studies.SWEEPS_DIR / f"{name}.toml").runs
        p, law = name.removeprefix("fig3_micro_").rsplit("_", 1)
        gradient = load_scene(ROOT / "scenes" / f"gradient_{p}_{law}.toml")
        assert run.scene.model == "both" and run.scene.micro_nx == 16
        assert run.scene.growth.law == law and run.scene.time.t_max == 60.0
        assert gradient.dotted() | {"model": "both"} == run.scene.dotted()


@pytest.mark.parametrize("h", [0.05, 0.2])
def test_sensitivity_of_power_laws(h):
    """X = x^p: central differences are exact for p = 0, 1, 2 (the truncation error is
    p (p - 1) (p - 2) h^2 / 6); for p = -1 the central difference is -1 / (1 - h^2) exactly."""
    x0 = 0.7
    x = (x0 * (1 - h), x0, x0 * (1 + h))
    for p in (0.0, 1.0, 2.0):
        X = tuple(v**p for v in x)
        assert abs(studies.sensitivity(x, X) - p) < ROUND_OFF
    X = tuple(1.0 / v for v in x)
    assert abs(studies.sensitivity(x, X) + 1.0 / (1.0 - h**2)) < ROUND_OFF
    assert abs(studies.sensitivity(x, (3.0, 3.0, 3.0))) == 0.0  # a flat rate: insensitive


def test_exact_rate_of_the_reference_scenes():
    """Stress law: tr G = 2 eta (1 - phi_w) P1 / phi_w (0.01584 at phi_w = 0.11214);
    strain law: the same times (1 - nu) / E; equal at nu = 0 (paper section 5)."""
    stress = load_scene(ROOT / "scenes" / "reference_stress.toml")
    strain = load_scene(ROOT / "scenes" / "reference_strain.toml")
    phi_w = stress.cell.at(0.0, 0.0).phi_w
    assert abs(phi_w - 0.11214) < 1e-5  # docs/unit_cell.md's value, rounded to 5 digits
    assert studies.exact_rate(stress) == pytest.approx(2 * (1 - phi_w) / phi_w * 1e-3, rel=1e-14)
    assert studies.exact_rate(strain) == pytest.approx(0.7 * studies.exact_rate(stress), rel=1e-14)
    rows = {run.values["material.nu"]: run.scene for run in
            load_sweep(studies.SWEEPS_DIR / "fig3_scan_strain.toml").runs
            if "material.nu" in run.values}  # fmt: skip
    assert studies.exact_rate(rows[0.0]) == pytest.approx(studies.exact_rate(stress), rel=1e-14)
    taus = [run.scene for run in load_sweep(studies.SWEEPS_DIR / "fig3_scan_strain.toml").runs
            if run.values.get("growth.tau", 0.0) > 0.006]  # fmt: skip
    assert taus and all(studies.exact_rate(s) == 0.0 for s in taus)  # above the yield: no growth


def table_row(run) -> dict[str, str]:
    """A finished run's sweep.csv row (the columns the analysis reads), mean tr G = 1."""
    return {"run": run.name, "status": "done", "t": "60", "growth_rate_area": "1.0"}


def test_points_and_sensitivity_from_a_synthetic_table():
    """The analysis path on a fabricated sweep.csv: a one-at-a-time P1 triple whose rates follow
    X = P1^2 gives phi = 2; the l1 x l2 grid's diagonal is picked as the parameter l."""
    sweep = load_sweep(studies.SWEEPS_DIR / "fig2c_stress.toml")
    rows = [table_row(run) for run in sweep.runs]
    for run, row in zip(sweep.runs, rows, strict=True):
        if "pressure.P1" in run.values:
            row["growth_rate_area"] = repr(run.values["pressure.P1"] ** 2)
    values = studies.points(sweep, rows)["pressure.P1"]
    x, X = (tuple(v[k] for v in values) for k in (0, 1))
    assert abs(studies.sensitivity(x, X) - 2.0) < ROUND_OFF  # central differences: exact on x^2
    rows[-1]["status"] = "pending"  # cell.theta's last run: unfinished runs are left out
    assert [v[0] for v in studies.points(sweep, rows)["cell.theta"]] == [28.5, 30.0]
    grid = load_sweep(studies.SWEEPS_DIR / "fig2c_l_stress.toml")
    rows = [table_row(run) for run in grid.runs[::-1]]  # matched by name, not by order
    diagonal = studies.points(grid, rows)["l"]
    assert [v[0] for v in diagonal] == [0.95, 1.0, 1.05]
    assert np.allclose([v[2] for v in diagonal][1], studies.exact_rate(load_scene(
        ROOT / "scenes" / "reference_stress.toml")), rtol=1e-14)  # fmt: skip
