"""Hard-case stability suite: every scene of ``scenes/hard`` at full resolution and refined once.

Runs each scene (and the refinement: tissue.h halved, accuracy.cell_resolution + 1) through
:func:`plantgrowth.studies.hard_cases.evaluate` with the scenes' integrator ('adaptive'), plus at
full resolution: the large-step study (final area versus a dt = 0.25 'adaptive' run for dt in
{1, 10, 30} with the three integrators, on the scenes of ``DT_SCENES``), the long run at dt = 10
with each integrator (``EXTRA``), and the limit scenes (``LIMIT_SCENES``: they stop with
"element inverted") with other steps and integrators (``LIMIT_RUNS``). Writes the criterion
values, the refinement changes, the limits, the step-size errors, the cost of 'adaptive' and the
machine description to ``benchmarks/results/hard_cases.json`` and the section
"Numerical stability" to ``docs_snippets/hard_cases_readme.md``. Each run is a serial
subprocess (``--jobs 2`` runs two at a time); run directories go to ``results/hard_cases/``.

    python scripts/hard_cases.py [--jobs 2] [--only reference,gradient_E] [--render-only]
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from plantgrowth.base.machine import machine_description
from plantgrowth.studies import hard_cases as hc

DT_SCENES = ("reference", "gradient_E", "E_contrast_100")
"""Scenes of the large-step study: the homogeneous reference (Euler's error has a closed form),
the E-gradient scene of the paper, and the 100x stiffness contrast under the stress law."""
INTEGRATORS = ("euler", "exp", "adaptive")
EXTRA = {
    "long_run": [{"dt": 10.0, "integrator": i} for i in INTEGRATORS]
    + [{"dt": 5.0, "integrator": "exp"}]
}
"""Further full-resolution runs: the long run at dt = 10, where the lagged coupling of euler and
exp oscillates, and exp at the scene's dt = 5."""
LIMIT_SCENES = ("E_contrast_100_strain", "clamp_shear", "anisotropic_Fg0_x1", "long_run_gradient_E")
"""Limits of the geometrically linear macro model: they stop with "element inverted" at h = 0.1
(the first two only on fine meshes), whatever the integrator and step."""
LIMIT_RUNS = [{"dt": 0.25, "integrator": "adaptive"}, {"dt": 1.0, "integrator": "euler"}]
"""Integrator checks of the limit scenes (base resolution): a small adaptive step and the paper's
explicit Euler; failing at the same place and about the same time shows that the stop is not
an integrator effect."""
LIMIT_RUNS_LONG = {
    "long_run_gradient_E": [
        {"dt": 2.5, "integrator": "adaptive"},
        {"dt": 5.0, "integrator": "euler"},
    ]
}
"""long_run_gradient_E stops at t ~ 280: dt = 0.25 would be 1120 coupled steps (each with at
least two solves of the E-gradient cell problems), so its checks halve the scene's own dt = 5
(adaptive) and use Euler at the scene's dt."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=Path, default=Path("scenes/hard"), help="scene directory")
    parser.add_argument("--out", type=Path, default=Path("results/hard_cases"), help="run dirs")
    parser.add_argument("--json", type=Path, default=Path("benchmarks/results/hard_cases.json"))
    parser.add_argument("--readme", type=Path, default=Path("docs_snippets/hard_cases_readme.md"))
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time (default 1)")
    parser.add_argument("--only", type=lambda s: s.split(","), default=None, help="scene names")
    parser.add_argument("--render-only", action="store_true", help="rewrite the docs from JSON")
    parser.add_argument("--force", action="store_true", help="rerun runs that have a result")
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)  # one run (internal)
    return parser.parse_args(argv)


# --- runs -----------------------------------------------------------------------------------------


def jobs(scene_dir: Path, names: list[str]) -> list[dict]:
    """Every run: (scene, variant, time overrides); variant 'base' or 'refined'."""
    out = []
    for name in names:
        path = str(scene_dir / f"{name}.toml")
        scene_time = hc.to_scene(hc.read_scene_data(path)).time
        own = (scene_time.dt, scene_time.integrator)
        out += [
            {"case": name, "scene": path, "variant": v, "time": {}} for v in ("base", "refined")
        ]
        times = list(EXTRA.get(name, []))
        if name in LIMIT_SCENES:
            times += LIMIT_RUNS_LONG.get(name, LIMIT_RUNS)
        if name in DT_SCENES:
            times.append(
                {
                    "dt": hc.DT_STUDY["reference_dt"],
                    "integrator": hc.DT_STUDY["reference_integrator"],
                }
            )
            times += [{"dt": dt, "integrator": i} for dt in hc.DT_STUDY["dts"] for i in INTEGRATORS]
        for t in times:
            if (t["dt"], t["integrator"]) == own:
                continue  # the base run itself
            out.append({"case": name, "scene": path, "variant": "base", "time": t})
    seen, unique = set(), []
    for job in out:
        t = job["time"]
        suffix = f"_dt{t['dt']:g}_{t['integrator']}" if t else ""
        job["label"] = f"{job['case']}_{job['variant']}{suffix}"
        if job["label"] not in seen:
            seen.add(job["label"])
            unique.append(job)
    return unique


def _cost(job: dict) -> float:
    """A rough relative cost (steps x solves per step x mesh x cell problems), to start the
    slowest runs first so that the two workers finish together."""
    data = hc.read_scene_data(job["scene"])
    scene = hc.to_scene(data)
    dt = job["time"].get("dt", scene.time.dt)
    integrator = job["time"].get("integrator", scene.time.integrator)
    constant = all(f.is_constant for f in scene.parameter_fields().values())
    cost = scene.time.t_max / dt * (2.5 if integrator == "adaptive" else 1.0)
    cost *= 5.0 if job["variant"] == "refined" else 1.0
    cost *= 1.0 if constant else 15.0
    if job["case"] in LIMIT_SCENES:  # they stop early
        cost *= 0.3
    return cost


def worker(spec: dict) -> None:
    """Run one job in this (serial) process and write its result JSON."""
    from mpi4py import MPI

    data = hc.read_scene_data(spec["scene"])
    if spec["variant"] == "refined":
        data = hc.refined(data)
    if spec["time"]:
        data = hc.with_overrides(data, {"time": spec["time"]})
    scene = hc.to_scene(data, spec["scene"])
    result = hc.evaluate(scene, Path(spec["outdir"]), MPI.COMM_WORLD)
    result.update(
        job=spec["label"], case=spec["case"], variant=spec["variant"],
        dt=scene.time.dt, integrator=scene.time.integrator, t_max=scene.time.t_max,
        h=scene.tissue.h, cell_resolution=scene.accuracy.cell_resolution,
    )  # fmt: skip
    result.update(_summary_totals(Path(spec["outdir"]) / "summary.csv"))
    Path(spec["result"]).write_text(json.dumps(result, indent=1))


def _summary_totals(path: Path) -> dict:
    """Totals over the steps of a run's summary.csv: growth sub-steps (adaptive: accepted
    sub-steps; euler/exp: 1 per step), cell solves, solve and cell-problem seconds."""
    import csv

    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))

    def total(key: str) -> float:
        return sum(float(r[key]) for r in rows if r.get(key) not in (None, ""))

    return {
        "substeps_total": total("substeps"),
        "advances": max(len(rows) - 1, 0),
        "n_cell_solves_total": total("n_cell_solves"),
        "seconds_solve_total": total("seconds_solve"),
        "seconds_cells_total": total("seconds_cells"),
    }


def run_job(job: dict, out: Path, force: bool = False) -> dict:
    """One job as a subprocess; its log goes to ``out/<label>/stdout.txt``. A job whose
    ``result.json`` exists is not rerun unless ``force``."""
    outdir = out / job["label"]
    if not force and (outdir / "result.json").is_file():
        print(f"{job['label']:44s} (result exists, reused; --force reruns it)", flush=True)
        return json.loads((outdir / "result.json").read_text())
    outdir.mkdir(parents=True, exist_ok=True)
    spec = dict(job, outdir=str(outdir), result=str(outdir / "result.json"))
    (outdir / "result.json").unlink(missing_ok=True)
    start = time.perf_counter()
    with open(outdir / "stdout.txt", "w") as log:
        rc = subprocess.call(
            [sys.executable, __file__, "--worker", json.dumps(spec)],
            stdout=log, stderr=subprocess.STDOUT,
        )  # fmt: skip
    seconds = time.perf_counter() - start
    if rc != 0 or not (outdir / "result.json").is_file():
        result = dict(job=job["label"], case=job["case"], variant=job["variant"], passed=False,
                      dt=job["time"].get("dt"), integrator=job["time"].get("integrator"),
                      error=f"worker exited with {rc}; see {outdir / 'stdout.txt'}")  # fmt: skip
    else:
        result = json.loads((outdir / "result.json").read_text())
    status = "pass" if result.get("passed") else "FAIL"
    print(f"{job['label']:44s} {status:5s} {seconds:7.1f} s", flush=True)
    return result


# --- results --------------------------------------------------------------------------------------

RUN_KEYS = (
    "job", "case", "variant", "dt", "integrator", "h", "cell_resolution", "passed", "error",
    "steps", "n_steps", "t_reached", "t_max", "area_final", "growth_rate_final",
    "anisotropy_max", "det_deformation_min", "det_Fg_min_ratio", "G_abs_max", "G_lambda_max",
    "G_lambda_min", "growth_log_rate_max", "growth_excess_max", "criteria", "seconds",
    "substeps_total", "advances", "n_cell_solves_total", "clamp",
)  # fmt: skip
"""The values kept for the runs of the large-step study, the long runs and the limit checks."""


def _brief(r: dict) -> dict:
    out = {k: r.get(k) for k in RUN_KEYS}
    out["stop"] = parse_stop(r.get("error"))
    return out


def parse_stop(error: str | None) -> dict | None:
    """Where and why a run stopped, from the RunError message: ``"step N, t = T: what at x =
    (x1, x2) (n place(s) on this rank); likely cause: ..."`` (``after step N``: while advancing
    the growth from t = T, i.e. in (T, T + dt], inside the sub-steps for 'adaptive')."""
    if not error:
        return None
    m = re.match(r"(after )?step (\d+), t = ([^:]+): (.*)", error, re.S)
    if m is None:
        return {"message": error, "cause": error[:80]}
    rest = m.group(4)
    x = re.search(r" at x = \(([^)]*)\)", rest)
    places = re.search(r"\((\d+) place\(s\)", rest)
    likely = rest.split("likely cause: ", 1)[1] if "likely cause: " in rest else None
    return {
        "step": int(m.group(2)),
        "t": float(m.group(3)),
        "during_advance": bool(m.group(1)),
        "cause": rest.split(" at x = ")[0].split(";")[0],
        "x": [float(v) for v in x.group(1).split(",")] if x else None,
        "places": int(places.group(1)) if places else None,
        "likely_cause": likely,
    }


def _at_corner(error: str | None, scene_path: str) -> bool | None:
    """Whether the first place named in the RunError is within 2 h of a tissue corner."""
    stop = parse_stop(error)
    if not stop or not stop.get("x"):
        return None
    tissue = hc.to_scene(hc.read_scene_data(scene_path)).tissue
    x, y = stop["x"]
    dx, dy = min(x, tissue.width - x), min(y, tissue.height - y)
    return max(dx, dy) <= 2 * tissue.h


def _fg0_ratio(scene_path: str) -> float:
    s = np.linalg.svd(np.array(hc.to_scene(hc.read_scene_data(scene_path)).growth.Fg0, float))
    return float(s[1][0] / s[1][1])


def collect(results: list[dict], scene_dir: Path) -> dict:
    """Passing cases (base, refined, refinement changes), limits of the model, the step-size
    study, the long runs, the cost of the adaptive integrator and the unexpected failures."""
    by_job = {r["job"]: r for r in results}
    cases, limits, unexpected = {}, {}, []
    for r in results:
        if r["job"] != f"{r['case']}_base":
            continue
        name, fine = r["case"], by_job.get(f"{r['case']}_refined")
        if name in LIMIT_SCENES:
            checks = [_brief(c) for c in results if c["case"] == name and c["variant"] == "base"
                      and c["job"] != r["job"]]  # fmt: skip
            path = str(scene_dir / f"{name}.toml")
            for run in [r, fine, *[by_job[c["job"]] for c in checks]]:
                if run is not None:
                    run["stop_at_corner"] = _at_corner(run.get("error"), path)
            checks = [dict(c, stop_at_corner=by_job[c["job"]]["stop_at_corner"]) for c in checks]
            limits[name] = {
                "base": dict(_brief(r), stop_at_corner=r["stop_at_corner"]),
                "refined": dict(_brief(fine), stop_at_corner=fine["stop_at_corner"])
                if fine else None,
                "checks": sorted(checks, key=lambda c: (c["dt"], c["integrator"])),
                "Fg0_ratio": _fg0_ratio(path),
            }  # fmt: skip
            continue
        comparable = fine and r["error"] is None and fine.get("error") is None
        changes = hc.refinement_changes(r, fine) if comparable else None  # same t_max only
        cases[name] = {"base": r, "refined": fine, "refinement": changes}
        for variant, run in (("base", r), ("refined", fine)):
            if run is None or not run.get("passed"):
                unexpected.append(f"{name} ({variant}): {_status(run)}")
        if not (changes and changes["passed"]):
            unexpected.append(f"{name}: refinement change {changes}")
    study = {}
    ref_dt, ref_int = hc.DT_STUDY["reference_dt"], hc.DT_STUDY["reference_integrator"]
    for name in DT_SCENES:
        if name not in cases:
            continue
        runs = [r for r in results if r["case"] == name and r["variant"] == "base"]
        ref = [r for r in runs if (r["dt"], r["integrator"]) == (ref_dt, ref_int)]
        ref = ref[0] if ref else None
        ref_area = ref["area_final"] if ref and ref["error"] is None else math.nan
        rows = []
        for r in sorted(runs, key=lambda r: (r["dt"], r["integrator"])):
            if r is ref or r["dt"] not in hc.DT_STUDY["dts"]:
                continue
            row = _brief(r)
            row["area_error"] = (
                hc.relative_change(ref_area, r["area_final"]) if r["error"] is None else math.nan
            )
            rows.append(row)
            if r["integrator"] == "adaptive" and not r["passed"]:
                unexpected.append(f"{name} at dt = {r['dt']:g} adaptive: {_status(r)}")
        study[name] = {"reference": _brief(ref) if ref else None, "runs": rows}
    if "reference" in study and study["reference"]["reference"]:
        study["reference"]["euler_formula"] = _euler_formula(study["reference"])
    extra = [
        _brief(r) for r in results
        if r["case"] in EXTRA and r["variant"] == "base"
    ]  # fmt: skip
    long_run = hc.to_scene(hc.read_scene_data(scene_dir / "long_run.toml"))
    phi_w = long_run.cell.at(0.0, 0.0).phi_w
    exact = 2 * (1 - long_run.material.nu.start) * (1 - phi_w) / phi_w * long_run.P1.start
    return {
        "cases": cases,
        "limits": limits,
        "dt_study": study,
        "long_run": {
            "runs": sorted(extra, key=lambda r: (r["dt"], r["integrator"])),
            "exact_rate": exact,
            "exact_rate_formula": "2 (1 - nu) (1 - phi_w) / phi_w P1 (strain law, uniform)",
        },
        "integrator_cost": _integrator_cost(study, extra),
        "unexpected": unexpected,
    }


def _euler_formula(s: dict) -> list[dict]:
    """Euler's area error on the homogeneous reference, predicted from the uniform rate
    g = tr G / 2 of the dt = 0.25 run: ``1 - ((1 + g dt)^(t/dt) / e^(g t))^2``."""
    rate = s["reference"].get("growth_rate_final")
    if s["reference"]["error"] is not None or rate is None or not math.isfinite(rate):
        return []
    g, out = rate / 2, []
    for r in s["runs"]:
        if r["integrator"] == "euler" and r["error"] is None:
            n = r["t_reached"] / r["dt"]
            predicted = 1 - ((1 + g * r["dt"]) ** n / math.exp(g * r["t_reached"])) ** 2
            out.append({"dt": r["dt"], "measured": r["area_error"], "predicted": predicted})
    return out


def _integrator_cost(study: dict, extra: list[dict]) -> list[dict]:
    """'adaptive' against 'exp' at the same scene and dt: wall time ratio and the accepted
    sub-steps per step (each needs one extra macro solve and its cell problems)."""
    pairs = [(n, r) for n, s in study.items() for r in s["runs"]]
    pairs += [(r["case"], r) for r in extra]
    runs = {(n, r["dt"], r["integrator"]): r for n, r in pairs}
    out = []
    for (name, dt, integrator), r in sorted(runs.items()):
        exp = runs.get((name, dt, "exp"))
        if integrator != "adaptive" or exp is None:
            continue
        steps = max(r.get("advances") or 0, 1)
        out.append({
            "case": name, "dt": dt, "seconds_adaptive": r["seconds"],
            "seconds_exp": exp["seconds"], "ratio": r["seconds"] / exp["seconds"],
            "substeps_per_step": (r.get("substeps_total") or 0) / steps,
            "steps": r.get("advances"), "exp_stopped": exp["error"] is not None,
            "adaptive_stopped": r["error"] is not None,
        })  # fmt: skip
    return out


def _finite_or_none(x):
    """JSON-safe: NaN and Inf (unreached values) become null."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _finite_or_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite_or_none(v) for v in x]
    return x


def _g(x, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{digits}g}"


def _pct(x, digits: int = 2) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.{digits}g}%"


def _status(r: dict | None) -> str:
    if r is None:
        return "-"
    if r["passed"]:
        return "pass"
    failed = [k for k, ok in (r.get("criteria") or {}).items() if not ok]
    if r.get("error"):
        stop = r.get("stop") or parse_stop(r["error"])
        if stop and "step" in stop:
            cause = "inverted element" if "inverted" in stop["cause"] else stop["cause"][:40]
            return f"FAIL ({_stop_at(stop)}: {cause})"
        return f"FAIL ({r['error'][:60]})"
    return f"FAIL ({', '.join(failed)})"


def _stop_at(stop: dict | None) -> str:
    """Where a run stopped: ``step 13, t = 13``, or ``after step 10, t = 10`` for a failure
    inside the growth advance from t = 10."""
    if not stop or "step" not in stop:
        return "-"
    if stop["during_advance"]:
        return f"after step {stop['step']}, t = {stop['t']:g}"
    return f"step {stop['step']}, t = {stop['t']:g}"


def _t_stop(r: dict | None) -> str:
    """The time at which a run stopped ("t = 13", "t = 10+" inside the advance from 10)."""
    stop = (r or {}).get("stop")
    if not r or not stop or "t" not in stop:
        return "-" if not r else "none"
    return f"t = {stop['t']:g}{'+' if stop['during_advance'] else ''}"


def render(summary: dict) -> str:
    """The section "Numerical stability" (docs/stability.md) from the collected results."""
    cases, limits = summary["cases"], summary["limits"]
    lines = [
        "## Numerical stability",
        "",
        "`python scripts/hard_cases.py --jobs 2` runs the hard cases of `scenes/hard/` (h = 0.1,",
        "H = 1, cell_resolution 2, integrator `adaptive`, the scenes' own) and once refined",
        "(h = 0.05, cell_resolution 3), and writes `benchmarks/results/hard_cases.json`;",
        "`tests/test_hard_cases.py` asserts the same criteria on cheap versions (h = 0.35,",
        "cell_resolution 1). Criteria, over all steps and cells (coarse nodes for E_hom): no",
        "NaN/Inf; `min det Fg / det Fg0 >= 1 - 1e-12`; E_hom symmetric positive definite",
        "(smallest eigenvalue of its Voigt matrix); PETSc reason > 0 and true relative residual",
        f"<= {hc.RESIDUAL_BOUND:g} (`diagnostics.RESIDUAL_BOUND`); `det(I + grad u) > 0`;",
        "`|G_ij| <= M`; `ln sigma_max(Fg Fg0^-1) / t <= 2 M`; under refinement, final area and",
        f"final mean growth rate tr G change by < {hc.REFINEMENT_TOLERANCE:.0%}. A case passes",
        "when the base and the refined run pass every criterion and the refinement changes are",
        "within the tolerance.",
        "",
        "| case | status | min det Fg/Fg0 | min eig E_hom | max residual | min det(I+grad u) "
        "| max ln s_max/t (2M) | Fg ratio | d area | d rate | d E1 | s (base/ref.) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, c in cases.items():
        b, f, ch = c["base"], c["refined"], c["refinement"] or {}
        if "criteria" not in b:
            lines.append(f"| {name} | {_status(b)} |" + " - |" * 10)
            continue
        secs = f"{b['seconds']:.0f}/{f['seconds']:.0f}" if f and f.get("seconds") else "-"
        rate = f"{_g(b['growth_log_rate_max'])} ({_g(b['growth_rate_bound'])})"
        status = _status(b)
        if f is None or not f.get("passed"):
            status += f"; refined: {_status(f)}"
        elif ch and not ch.get("passed"):
            status = "FAIL (refinement change)"
        lines.append(
            f"| {name} | {status} | {_g(b['det_Fg_min_ratio'], 6)} "
            f"| {_g(b['E_hom_min_eig'])} | {_g(b['residual_max'], 2)} "
            f"| {_g(b['det_deformation_min'])} | {rate} | {_g(b['anisotropy_max'])} "
            f"| {_pct(ch.get('area'))} | {_pct(ch.get('growth_rate'))} "
            f"| {_pct(ch.get('E1_step0'))} | {secs} |"
        )
    lines += [
        "",
        "`d area`, `d rate`: relative change of the final area and final mean tr G from the",
        "base to the refined run; `d E1`: of the coarse-node mean E1 of E_hom at t = 0 (the",
        "cell-problem discretisation error). `Fg ratio`: largest principal growth ratio",
        "sigma_max/sigma_min of Fg reached. The values are those of the base run.",
    ]
    if summary.get("unexpected"):
        lines += ["", "**Unexpected failures of passing cases (adaptive):**", ""]
        lines += [f"- {u}" for u in summary["unexpected"]]
    lines += _render_limits(limits)
    lines += _render_study(summary)
    return "\n".join(lines) + "\n" + narrative(summary)


def _render_limits(limits: dict) -> list[str]:
    lines = [
        "",
        "### Limits of the model",
        "",
        "Four scenes stop with the model's own RunError (step, time, place, cause) instead of",
        "running to t_max. They are not part of the table above: each stops at every resolution",
        "and with every integrator tried (rows `dt = ...`: base resolution).",
        "",
        "| case | run | status | stops at | where (x) | cause | Fg ratio reached "
        "| min det(I+grad u) before | s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    likely = set()
    for name, L in limits.items():
        rows = [("h = 0.1, dt = {dt:g} {integrator}", L["base"])]
        rows += [("h = 0.05, dt = {dt:g} {integrator}", L["refined"])] if L["refined"] else []
        rows += [("h = 0.1, dt = {dt:g} {integrator}", c) for c in L["checks"]]
        for label, r in rows:
            stop = r.get("stop") or {}
            if stop.get("likely_cause"):
                likely.add(stop["likely_cause"])
            x = stop.get("x")
            where = f"({x[0]:.3g}, {x[1]:.3g}), {stop.get('places')} place(s)" if x else "-"
            ratio = _g(r.get("anisotropy_max"))
            if r.get("anisotropy_max") is None:
                ratio = f"{_g(L['Fg0_ratio'])} (Fg0; no step completed)"
            status = "ran to t_max" if r["error"] is None else "stopped"
            if r["error"] is None and not r["passed"]:
                status = _status(r)
            lines.append(
                f"| {name} | {label.format(**r)} | {status} | {_stop_at(stop)} | {where} "
                f"| {stop.get('cause', '-')} | {ratio} | {_g(r.get('det_deformation_min'))} "
                f"| {_g(r.get('seconds'), 2)} |"
            )
    lines += [
        "",
        "`stops at`: `step N, t = T` failed in the solve of step N; `after step N, t = T` while",
        "advancing the growth from T to T + dt (for `adaptive`: in one of its sub-steps, whose",
        "midpoint solve sees the inversion first). `min det(I+grad u) before`: over the",
        "completed steps. The model's message gives as likely cause: "
        + "; ".join(f'"{c}"' for c in sorted(likely))
        + ".",
    ]
    return lines


def _render_study(summary: dict) -> list[str]:
    study, ref_dt = summary["dt_study"], hc.DT_STUDY["reference_dt"]
    ref_int = hc.DT_STUDY["reference_integrator"]
    lines = [
        "",
        f"### Large steps: final-area error versus dt = {ref_dt:g} (`{ref_int}`)",
        "",
        f"Reference: the same scene at dt = {ref_dt:g} with `{ref_int}` (the recommended",
        "integrator at a step 4x below the scenes' own). Cells: relative error of the final",
        "area, or where the run stopped; in brackets the wall seconds.",
        "",
        "| scene | dt | " + " | ".join(INTEGRATORS) + " |",
        "|---|---|" + "---|" * len(INTEGRATORS),
    ]
    for name, s in study.items():
        ref = s["reference"]
        if ref is None or ref["error"] is not None:
            lines.append(f"| {name} | {ref_dt:g} (reference) | {_status(ref)} |")
        for dt in hc.DT_STUDY["dts"]:
            cell = {}
            for r in s["runs"]:
                if r["dt"] != dt:
                    continue
                if r["error"] is not None:
                    text = f"stopped at {_t_stop(r)}"
                elif not r["passed"]:
                    text = f"{_pct(r['area_error'])}, {_status(r)}"
                else:
                    text = _pct(r["area_error"])
                cell[r["integrator"]] = f"{text} ({_g(r['seconds'], 2)} s)"
            cells = " | ".join(cell.get(i, "-") for i in INTEGRATORS)
            lines.append(f"| {name} | {dt:g} | {cells} |")
    lines += [
        "",
        "Cost of `adaptive` against `exp` at the same dt (wall seconds of the whole run;",
        "sub-steps: accepted sub-steps per step; every sub-step costs one extra macro solve with",
        "its cell problems, every sub-step after the first one more, every rejected one more):",
        "",
        "| scene | dt | s exp | s adaptive | ratio | sub-steps per step |",
        "|---|---|---|---|---|---|",
    ]
    for c in summary["integrator_cost"]:
        note = " (exp stopped early)" if c["exp_stopped"] else ""
        lines.append(
            f"| {c['case']} | {c['dt']:g} | {_g(c['seconds_exp'], 2)}{note} "
            f"| {_g(c['seconds_adaptive'], 2)} | {_g(c['ratio'], 2)} "
            f"| {_g(c['substeps_per_step'], 3)} |"
        )
    lr = summary["long_run"]
    lines += [
        "",
        f"Long run (homogeneous, t_max = 600; exact mean tr G = {_g(lr['exact_rate'], 6)},",
        f"{lr['exact_rate_formula']}):",
        "",
        "| dt | integrator | status | t reached | final mean tr G | Fg ratio | s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in lr["runs"]:
        lines.append(
            f"| {r['dt']:g} | {r['integrator']} | {_status(r)} | {_g(r['t_reached'])} "
            f"| {_g(r['growth_rate_final'], 6)} | {_g(r['anisotropy_max'], 4)} "
            f"| {_g(r['seconds'], 2)} |"
        )
    return lines


def _run(summary: dict, name: str, dt: float, integrator: str) -> dict | None:
    """A run of the step-size study or the long run (None if absent)."""
    s = summary["dt_study"].get(name)
    runs = list(s["runs"]) + [s["reference"]] if s else []
    if name == "long_run":
        runs = summary["long_run"]["runs"]
    for r in runs:
        if r and r["dt"] == dt and r["integrator"] == integrator:
            return r
    return None


def _err(summary: dict, name: str, dt: float, integrator: str) -> str:
    r = _run(summary, name, dt, integrator)
    if r is None:
        return "-"
    return _pct(r["area_error"]) if r["error"] is None else f"stopped at {_t_stop(r)}"


def _errs(summary: dict, name: str, integrator: str) -> str:
    return " / ".join(_err(summary, name, dt, integrator) for dt in hc.DT_STUDY["dts"])


def _range(values: list[float], digits: int = 2) -> str:
    values = [v for v in values if v is not None and math.isfinite(v)]
    if not values:
        return "-"
    lo, hi = min(values), max(values)
    return (
        _g(lo, digits) if _g(lo, digits) == _g(hi, digits) else f"{_g(lo, digits)}-{_g(hi, digits)}"
    )


def _limit_line(L: dict) -> str:
    checks = ", ".join(f"dt = {c['dt']:g} {c['integrator']}: {_t_stop(c)}" for c in L["checks"])
    return (
        f"stops at {_t_stop(L['base'])} at h = 0.1 and {_t_stop(L['refined'])} at h = 0.05 "
        f"({checks}); Fg ratio reached {_g(L['base']['anisotropy_max'])} / "
        f"{_g((L['refined'] or {}).get('anisotropy_max'))}, min det(I + grad u) before the stop "
        f"{_g(L['base']['det_deformation_min'])} / "
        f"{_g((L['refined'] or {}).get('det_deformation_min'))}"
    )


def narrative(summary: dict) -> str:
    """Which integrator, the failure modes of the explicit schemes and the limits of the model,
    with the measured numbers."""
    dts = " / ".join(f"{dt:g}" for dt in hc.DT_STUDY["dts"])
    lr = summary["long_run"]
    exact = lr["exact_rate"]
    long = {(r["dt"], r["integrator"]): r for r in lr["runs"]}
    ad10, exp10, eu10 = (long.get((10.0, i), {}) for i in ("adaptive", "exp", "euler"))
    exp5, ad5 = long.get((5.0, "exp"), {}), long.get((5.0, "adaptive"), {})
    cost = summary["integrator_cost"]
    comparable = [c for c in cost if not (c["exp_stopped"] or c["adaptive_stopped"])]
    ratio = _range([c["ratio"] for c in comparable])
    ratio_dt1 = _range([c["ratio"] for c in comparable if c["dt"] == 1.0])
    subs_dt1 = _range([c["substeps_per_step"] for c in comparable if c["dt"] == 1.0], 3)
    subs = _range([c["substeps_per_step"] for c in cost], 3)
    heavy = max(cost, key=lambda c: c["substeps_per_step"], default=None)
    formula = summary["dt_study"].get("reference", {}).get("euler_formula", [])
    euler_ref = ", ".join(
        f"{_pct(f['measured'], 3)} (formula {_pct(f['predicted'], 3)}) at dt = {f['dt']:g}"
        for f in formula
    )

    def rel(r: dict) -> str:
        return _pct(hc.relative_change(exact, r.get("growth_rate_final") or math.nan), 2)

    limits = summary["limits"]
    shear = limits.get("clamp_shear", {}).get("base", {})
    aniso = limits.get("anisotropic_Fg0_x1", {})
    aniso_stop = (aniso.get("base") or {}).get("stop") or {}
    explicit_stops = [
        f"{name} at dt = {r['dt']:g} `{r['integrator']}` stops at {_t_stop(r)} "
        f"({(r['stop'] or {}).get('cause', r['error'][:60])}; mean tr G at the last completed "
        f"step t = {_g(r['t_reached'])}: {_g(r['growth_rate_final'], 4)}, against "
        f"{_g((_run(summary, name, r['dt'], 'adaptive') or {}).get('growth_rate_final'), 4)} "
        f"at the end with `adaptive` at the same dt, "
        f"{_status(_run(summary, name, r['dt'], 'adaptive'))})"
        for name, s in summary["dt_study"].items() for r in s["runs"]
        if r["integrator"] != "adaptive" and r["error"] is not None
    ]  # fmt: skip
    explicit_stops = "; ".join(explicit_stops) or "none"
    stops = [L[v] for L in limits.values() for v in ("base", "refined") if L.get(v)]
    stops += [c for L in limits.values() for c in L["checks"]]
    located = [r for r in stops if r.get("stop_at_corner") is not None]
    corners = sum(1 for r in located if r["stop_at_corner"])
    earlier = [
        name for name, L in limits.items()
        if L.get("refined") and (L["refined"].get("stop") or {}).get("t", math.inf)
        < (L["base"].get("stop") or {}).get("t", math.inf)
    ]  # fmt: skip
    abrupt = [
        name for name, L in limits.items()
        if all((r or {}).get("det_deformation_min") is not None
               and r["det_deformation_min"] > 1.0
               for r in [L["base"], L["refined"], *L["checks"]])
    ]  # fmt: skip
    M = shear.get("clamp") or math.nan
    lam_min = shear.get("G_lambda_min")
    return f"""
### Which integrator

Use `integrator = "adaptive"` (every scene in `scenes/hard` does). It takes exponential steps
`Fg <- expm(h G) Fg` with step-doubling error control (`time.tolerance`, default 1e-3): each
step is taken once whole and as two halves, the second half with G re-evaluated at the
half-step state. That midpoint solve removes the one-step lag between growth and elasticity
that makes the explicit schemes oscillate: on the homogeneous long run at dt = 10 `adaptive`
ends with mean tr G {_g(ad10.get("growth_rate_final"), 6)} (exact {_g(exact, 6)}, error
{rel(ad10)}) and an Fg ratio of {_g(ad10.get("anisotropy_max"), 6)}, where `exp` stops at
{_t_stop(exp10)} and `euler` ends with tr G {_g(eu10.get("growth_rate_final"), 4)}. Final-area
error against dt = {hc.DT_STUDY["reference_dt"]:g}, dt = {dts}: gradient_E
{_errs(summary, "gradient_E", "adaptive")}, E_contrast_100
{_errs(summary, "E_contrast_100", "adaptive")}, reference {_errs(summary, "reference", "adaptive")}.

Cost: every step solves the macro problem (with its cell problems) at least twice, plus once
more per extra sub-step when the local error exceeds the tolerance. Measured against `exp` at
the same dt: {ratio_dt1}x the wall time at the scenes' dt = 1 ({subs_dt1} accepted sub-step(s)
per step: the second macro solve is the whole extra cost), {ratio}x over all compared runs, with
{subs} accepted sub-steps per step (most: {heavy["case"] if heavy else "-"} at
dt = {_g(heavy["dt"] if heavy else None)}, {_g(heavy["substeps_per_step"] if heavy else None, 3)}:
at large dt the error control splits the step, and adaptive buys its accuracy with time).
Homogeneous scenes cost less than 2x, likely because their cell problems are cached.

`exp` (`Fg <- expm(dt G) Fg` with G from the start of the step) is exact on homogeneous scenes
for any dt (reference: {_errs(summary, "reference", "exp")} at dt = {dts}) and accurate for
dt <= 5: the long run at dt = 5 ends with tr G {_g(exp5.get("growth_rate_final"), 6)}
({_status(exp5) if exp5 else "not run"}; `adaptive` at dt = 5: \
{_g(ad5.get("growth_rate_final"), 6)}); on gradient_E its error is
{_errs(summary, "gradient_E", "exp")} at dt = {dts}. `det Fg = exp(dt tr G) det Fg_old` never
decreases. `euler` is the paper's explicit scheme: use it only to reproduce the paper.

### Failure modes of the explicit schemes

1. **Under-predicted growth (`euler`, every dt).** Euler compounds `(1 + g dt)^(t/dt)` where
   the exact solution has `exp(g t)`, so on the homogeneous reference the final-area error is
   `1 - ((1 + g dt)^(t/dt) / e^(g t))^2` with g = tr G / 2: measured {euler_ref}. On
   gradient_E: {_errs(summary, "gradient_E", "euler")}; on E_contrast_100:
   {_errs(summary, "E_contrast_100", "euler")} (dt = {dts}).
2. **Lagged-coupling oscillation (`euler` and `exp`, dt = 10 on the long run).** G is taken
   from the start of the step, so a round-off perturbation of the uniform state changes sign
   every step and grows. `euler` reaches t = {_g(eu10.get("t_reached"))} with mean tr G
   {_g(eu10.get("growth_rate_final"), 4)} instead of {_g(exact, 4)} ({rel(eu10)} off) and an Fg
   ratio of {_g(eu10.get("anisotropy_max"))} on a scene that should stay isotropic; `exp`
   stops at {_t_stop(exp10)} ({(exp10.get("stop") or {}).get("cause", "-")}; Fg ratio
   {_g(exp10.get("anisotropy_max"))}). At dt = 5 `exp` stays on the exact rate
   ({rel(exp5)} off, Fg ratio {_g(exp5.get("anisotropy_max"), 6)}).
3. **Lagged coupling on the heterogeneous scenes (large dt).** Runs of the explicit schemes
   that stopped in the step-size study: {explicit_stops}. `adaptive` at the same dt keeps
   the constant rate of the dt = {hc.DT_STUDY["reference_dt"]:g} run
   ({_g((summary["dt_study"].get("E_contrast_100", {}).get("reference") or {}).get(
       "growth_rate_final"), 4)} on E_contrast_100), so this is most likely the same
   instability as in (2), with an earlier onset; at dt = 30 the run has only two steps,
   likely too few for it to grow.

### Limits of the model

The four scenes of the limits table stop with "element inverted" at every step size and with
every integrator tried, so the stop is a property of the model, not of the time stepping
(`t = T+`: while advancing from T, in a sub-step of `adaptive`, whose midpoint solve looks
half a step ahead; `euler` stops later because it under-predicts the growth):

- **E_contrast_100_strain** (100x stiffness contrast under the strain law: the soft side grows
  much faster): {_limit_line(limits["E_contrast_100_strain"])}.
- **long_run_gradient_E** (E gradient grown to t = 600):
  {_limit_line(limits["long_run_gradient_E"])}.
- **clamp_shear** (steep turgor gradient, eta = 50, M = {_g(M)}, max |G_ij| reached
  {_g(shear.get("G_abs_max"))}): {_limit_line(limits["clamp_shear"])}.
- **anisotropic_Fg0_x1** (pre-grown 4:1, Fg0 = diag(4, 1)): stops at {_t_stop(aniso.get("base"))}
  ({aniso_stop.get("places")} place(s) inverted at h = 0.1) at every resolution and step; no
  step completes.

Likely causes (not proven): the macro problem is geometrically linear, `eps = sym(grad u)`,
so it cannot represent the large rotations that strong differential growth produces. In
{", ".join(abrupt) or "none of them"} the smallest det(I + grad u) over the completed steps is
still > 1 (its value under the initial turgor) at every resolution and step: the element
inverts within a single step, even at dt = 0.25, rather than by gradual thinning. The first
inverted element is within 2 h of a tissue corner in {corners} of the {len(located)} stopped
runs above; the refined mesh stops earlier in {", ".join(earlier) or "none of them"}.
In clamp_shear the component-wise clamp (`G = clip(G~, -M, M)`, [def_G_11]) saturates G
towards the rank-one shear `[[M, M], [M, M]]` (eigenvalues 2M and 0), which grows along one
diagonal only; measured: largest eigenvalue {_g(shear.get("G_lambda_max"))}
(2M = {_g(2 * M)}), smallest {_g(lam_min, 2)} ({_g((lam_min or math.nan) / M, 2)} M: the
clipped G is slightly indefinite, i.e. shrinks the other diagonal). In anisotropic_Fg0_x1 the
reduced cell diag(2, 1/2) has long, thin inclined walls and is so compliant that the linear
response to the reference turgor inverts every element at t = 0 (the scene file estimates
grad u22 ~ 47); Fg0 = diag(1, 4) (anisotropic_Fg0_x2) passes.
"""


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.worker is not None:
        worker(json.loads(args.worker))
        return 0
    if args.render_only:
        summary = json.loads(args.json.read_text())
    else:
        names = args.only or sorted(p.stem for p in args.scenes.glob("*.toml"))
        todo = jobs(args.scenes, names)
        # slowest first, so that two jobs finish together
        todo.sort(key=lambda j: (-_cost(j), j["label"]))
        reused = (
            0
            if args.force
            else sum((args.out / job["label"] / "result.json").is_file() for job in todo)
        )
        start = time.perf_counter()
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            results = list(pool.map(lambda job: run_job(job, args.out, args.force), todo))
        wall = time.perf_counter() - start
        summary = collect(results, args.scenes)
        summary.update(
            machine=machine_description(),
            jobs=args.jobs,
            wall_seconds_this_invocation=wall,
            runs_reused_this_invocation=reused,
            seconds_all_runs=sum(r.get("seconds") or 0.0 for r in results),
        )
        args.json.parent.mkdir(parents=True, exist_ok=True)
        summary = _finite_or_none(summary)
        args.json.write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
        print(f"{len(results)} runs in {wall:.1f} s wall -> {args.json}")
    args.readme.parent.mkdir(parents=True, exist_ok=True)
    args.readme.write_text(render(summary))
    print(f"docs section -> {args.readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
