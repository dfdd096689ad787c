"""Hard-case stability suite: every scene of ``scenes/hard`` at full resolution and refined once.

Runs each scene (and the refinement: tissue.h halved, accuracy.cell_resolution + 1) through
:func:`plantgrowth.studies.hard_cases.evaluate` with the scenes' integrator ('adaptive'), once
more with ``kinematics = "finite"`` (base resolution), plus at full resolution: the large-step
study (final area versus a dt = 0.25 'adaptive' run for dt in {1, 10, 30} with the three
integrators, on the scenes of ``DT_SCENES``), the long run at dt = 10 with each integrator
(``EXTRA``), and the limit scenes (``LIMIT_SCENES``) with other steps and integrators
(``LIMIT_RUNS``). The base, refined and finite runs stop where the law loses strong ellipticity
(``numerics.on_instability = "stop"``, the default); the runs of the integrator studies measure
the time stepping and go on (``"warn"``), recording where the law was first not elliptic. Each
stop is recorded with its cause class ("loss of ellipticity", "element inverted", other), step,
time and place. Writes the criterion values, the refinement changes, the limits, the
step-size errors, the cost of 'adaptive' and the machine description to
``benchmarks/results/hard_cases.json``; the tables and text of docs/stability.md are made from
that file by ``scripts/figures/hard_cases_tables.py``. Each run is a serial subprocess
(``--jobs 2`` runs two at a time); run directories go to ``results/hard_cases/``.

    python scripts/studies/hard_cases.py [--jobs 2] [--only reference,gradient_E] [--force]
        [--variants base,refined,finite,checks]
"""

from __future__ import annotations

import argparse
import json
import logging
import math
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
LIMIT_SCENES = (
    "E_contrast_100", "E_contrast_100_strain", "clamp_shear", "P1_steep", "long_run_gradient_E",
    "anisotropic_Fg0_x1",
)  # fmt: skip
"""Scenes that reach a limit of the model on the cheap meshes (tests/test_hard_cases.py): the
law loses strong ellipticity (all but the last), or the linear model inverts an element
(anisotropic_Fg0_x1). Which cases stop at full resolution is read from the runs (``collect``)."""
WARN = {"on_instability": "warn"}
"""The numerics of the integrator studies: they go on past a loss of ellipticity."""
VARIANTS = ("base", "refined", "finite", "checks")
"""Groups of runs (``--variants``): the scenes as shipped, refined once, with finite
kinematics, and the integrator studies (large steps, long runs, limit checks)."""
LIMIT_RUNS = [{"dt": 0.25, "integrator": "adaptive"}, {"dt": 1.0, "integrator": "euler"}]
"""Integrator checks of the limit scenes (base resolution, ``WARN``): a small adaptive step and the
paper's explicit Euler; the law losing ellipticity (or an element inverting) at the same place
and about the same time shows that the limit is not an integrator effect."""
LIMIT_DTS = (LIMIT_RUNS[0]["dt"], LIMIT_RUNS[1]["dt"])
"""The steps of the limit checks (a limit scene of ``DT_SCENES`` has more runs: its limit rows
show these)."""
LIMIT_RUNS_LONG = {
    "long_run_gradient_E": [
        {"dt": 2.5, "integrator": "adaptive"},
        {"dt": 5.0, "integrator": "euler"},
    ]
}
"""long_run_gradient_E runs to t ~ 280: dt = 0.25 would be 1120 coupled steps (each with at
least two solves of the E-gradient cell problems), so its checks halve the scene's own dt = 5
(adaptive) and use Euler at the scene's dt."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=Path, default=Path("scenes/hard"), help="scene directory")
    parser.add_argument("--out", type=Path, default=Path("results/hard_cases"), help="run dirs")
    parser.add_argument("--json", type=Path, default=Path("benchmarks/results/hard_cases.json"))
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time (default 1)")
    parser.add_argument("--only", type=lambda s: s.split(","), default=None, help="scene names")
    parser.add_argument("--force", action="store_true", help="rerun runs that have a result")
    parser.add_argument(
        "--variants", type=lambda s: s.split(","), default=list(VARIANTS),
        help="groups of runs to run (the others' existing results are used): " + ",".join(VARIANTS),
    )  # fmt: skip
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)  # one run (internal)
    return parser.parse_args(argv)


# --- runs -----------------------------------------------------------------------------------------


def jobs(scene_dir: Path, names: list[str]) -> list[dict]:
    """Every run: (scene, variant, time overrides); variant 'base', 'refined' or 'finite' (the
    runs with time overrides: 'base' variant, group 'checks', numerics ``WARN``)."""
    out = []
    for name in names:
        path = str(scene_dir / f"{name}.toml")
        scene_time = hc.to_scene(hc.read_scene_data(path)).time
        own = (scene_time.dt, scene_time.integrator)
        out += [
            {"case": name, "scene": path, "variant": v, "time": {}}
            for v in ("base", "refined", "finite")
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
            if (t["dt"], t["integrator"]) == own and name not in LIMIT_SCENES:
                continue  # the base run itself (a limit scene's stops: run it with WARN)
            out.append({"case": name, "scene": path, "variant": "base", "time": t})
    seen, unique = set(), []
    for job in out:
        t = job["time"]
        suffix = f"_dt{t['dt']:g}_{t['integrator']}" if t else ""
        job["label"] = f"{job['case']}_{job['variant']}{suffix}"
        job["group"] = "checks" if t else job["variant"]
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
    cost *= {"refined": 5.0, "finite": 2.0}.get(job["variant"], 1.0)
    cost *= 1.0 if constant else 15.0
    if job["case"] in LIMIT_SCENES and not job["time"]:  # they stop early
        cost *= 0.3
    return cost


def worker(spec: dict) -> None:
    """Run one job in this (serial) process and write its result JSON."""
    from mpi4py import MPI

    data = hc.read_scene_data(spec["scene"])
    if spec["variant"] == "refined":
        data = hc.refined(data)
    if spec["variant"] == "finite":
        data = hc.with_overrides(data, {"kinematics": "finite"})
    if spec["time"]:
        data = hc.with_overrides(data, {"time": spec["time"], "numerics": WARN})
    scene = hc.to_scene(data, spec["scene"])
    warnings = _InstabilityWarning()
    logging.getLogger("plantgrowth").addHandler(warnings)
    result = hc.evaluate(scene, Path(spec["outdir"]), MPI.COMM_WORLD)
    result.update(
        job=spec["label"], case=spec["case"], variant=spec["variant"],
        dt=scene.time.dt, integrator=scene.time.integrator, t_max=scene.time.t_max,
        h=scene.tissue.h, cell_resolution=scene.accuracy.cell_resolution,
        kinematics=scene.kinematics, on_instability=scene.numerics.on_instability,
        instability=hc.parse_stop(warnings.first),
    )  # fmt: skip
    result.update(_summary_totals(Path(spec["outdir"]) / "summary.csv"))
    Path(spec["result"]).write_text(json.dumps(result, indent=1))


class _InstabilityWarning(logging.Handler):
    """Keeps the run's loss-of-ellipticity warning (``"warn"``: the first step where the law is
    not strongly elliptic, with its place)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.first = None

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        if "loss of ellipticity" in text and self.first is None:
            self.first = text.split("warning: ", 1)[-1]


def _summary_totals(path: Path) -> dict:
    """Totals over the steps of a run's summary.csv: growth sub-steps (adaptive: accepted
    sub-steps; euler/exp: 1 per step), cell solves, solve and cell-problem seconds, Newton
    iterations, the largest non-elliptic area fraction and the first step with one > 0, the
    steps with singular points (non-elliptic sets within a cell) and the first of them."""
    import csv

    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))

    def total(key: str) -> float:
        return sum(float(r[key]) for r in rows if r.get(key) not in (None, ""))

    fractions = [(int(float(r["step"])), float(r.get("nonelliptic_area_fraction") or 0.0))
                 for r in rows]  # fmt: skip
    singular = [int(float(r["step"])) for r in rows if float(r.get("singular_points") or 0) > 0]
    return {
        "singular_steps": len(singular),
        "first_singular_step": singular[0] if singular else None,
        "nonelliptic_area_fraction_max": max((f for _, f in fractions), default=0.0),
        "first_nonelliptic_step": next((k for k, f in fractions if f > 0.0), None),
        "newton_iterations_total": total("newton_iterations"),
        "substeps_total": total("substeps"),
        "advances": max(len(rows) - 1, 0),
        "n_cell_solves_total": total("n_cell_solves"),
        "seconds_solve_total": total("seconds_solve"),
        "seconds_cells_total": total("seconds_cells"),
    }


def run_job(job: dict, out: Path, force: bool = False) -> dict | None:
    """One job as a subprocess; its log goes to ``out/<label>/stdout.txt``. A job whose
    ``result.json`` exists is not rerun unless ``force``; one marked ``skip`` is only read
    (None if it has no result)."""
    outdir = out / job["label"]
    if job.get("skip"):
        path = outdir / "result.json"
        if not path.is_file():
            return None
        return dict(json.loads(path.read_text()), **_summary_totals(outdir / "summary.csv"))
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
    "substeps_total", "advances", "n_cell_solves_total", "clamp", "kinematics", "on_instability",
    "instability", "nonelliptic_area_fraction_max", "first_nonelliptic_step", "max_elastic_strain",
    "newton_iterations_total", "unstable_state", "singular_steps", "first_singular_step",
)  # fmt: skip
"""The values kept for the runs of the large-step study, the long runs, the limits and the
finite-kinematics runs."""


def _brief(r: dict) -> dict:
    out = {k: r.get(k) for k in RUN_KEYS}
    out["stop"] = hc.parse_stop(r.get("error"))
    return out


def _at_corner(error: str | None, scene_path: str) -> bool | None:
    """Whether the first place named in the RunError is within 2 h of a tissue corner."""
    stop = hc.parse_stop(error)
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
    """Passing cases (base, refined, refinement changes), limits of the model (the cases whose
    base run stops), the finite-kinematics runs, the step-size study, the long runs, the cost
    of the adaptive integrator and the unexpected failures."""
    by_job = {r["job"]: r for r in results}
    cases, limits, finite, unexpected = {}, {}, {}, []
    for r in results:
        if r["job"] != f"{r['case']}_base":
            continue
        name, fine = r["case"], by_job.get(f"{r['case']}_refined")
        path = str(scene_dir / f"{name}.toml")
        if f"{name}_finite" in by_job:
            run = by_job[f"{name}_finite"]
            finite[name] = {"linear": _brief(r), "finite": _brief(run),
                            "stop_at_corner": _at_corner(run.get("error"), path)}  # fmt: skip
        if r["error"] is not None:
            checks = [_brief(c) for c in results if c["case"] == name and c["variant"] == "base"
                      and c["job"] != r["job"]]  # fmt: skip
            for run in [r, fine, *[by_job[c["job"]] for c in checks]]:
                if run is not None:
                    run["stop_at_corner"] = _at_corner(run.get("error"), path)
            checks = [dict(c, stop_at_corner=by_job[c["job"]]["stop_at_corner"]) for c in checks]
            checks = [c for c in checks if name not in DT_SCENES or c["dt"] in LIMIT_DTS]
            limits[name] = {
                "base": dict(_brief(r), stop_at_corner=r["stop_at_corner"]),
                "refined": dict(_brief(fine), stop_at_corner=fine["stop_at_corner"])
                if fine else None,
                "checks": sorted(checks, key=lambda c: (c["dt"], c["integrator"])),
                "Fg0_ratio": _fg0_ratio(path),
            }  # fmt: skip
            if name not in LIMIT_SCENES:
                unexpected.append(f"{name} (base): {hc.run_status(r)}")
            continue
        comparable = fine and r["error"] is None and fine.get("error") is None
        changes = hc.refinement_changes(r, fine) if comparable else None  # same t_max only
        cases[name] = {"base": r, "refined": fine, "refinement": changes}
        for variant, run in (("base", r), ("refined", fine)):
            if run is None or not run.get("passed"):
                unexpected.append(f"{name} ({variant}): {hc.run_status(run)}")
        if not (changes and changes["passed"]):
            unexpected.append(f"{name}: refinement change {changes}")
    study = {}
    ref_dt, ref_int = hc.DT_STUDY["reference_dt"], hc.DT_STUDY["reference_integrator"]
    for name in DT_SCENES:
        runs = [r for r in results if r["case"] == name and r["variant"] == "base"]
        warned = {(r["dt"], r["integrator"]) for r in runs if r["job"] != f"{name}_base"}
        runs = [
            r
            for r in runs
            if r["job"] != f"{name}_base" or (r["dt"], r["integrator"]) not in warned
        ]
        if not runs:
            continue
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
                unexpected.append(f"{name} at dt = {r['dt']:g} adaptive: {hc.run_status(r)}")
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
        "finite": finite,
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


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.worker is not None:
        worker(json.loads(args.worker))
        return 0
    names = args.only or sorted(p.stem for p in args.scenes.glob("*.toml"))
    todo = jobs(args.scenes, names)
    for job in todo:
        job["skip"] = job["group"] not in args.variants
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
    results = [r for r in results if r is not None]
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
    print(f"tables: python scripts/figures/hard_cases_tables.py --json {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
