"""Hard-case stability suite: every scene of ``scenes/hard`` at full resolution and refined once.

Runs each scene (and the refinement: tissue.h halved, accuracy.cell_resolution + 1) through
:func:`plantgrowth.studies.hard_cases.evaluate` with the scenes' integrator ('adaptive'), plus at
full resolution: the large-step study (final area versus a dt = 0.25 'adaptive' run for dt in
{1, 10, 30} with the three integrators, on the scenes of ``DT_SCENES``), the long run at dt = 10
with each integrator (``EXTRA``), and the limit scenes (``LIMIT_SCENES``: they stop with
"element inverted") with other steps and integrators (``LIMIT_RUNS``). Writes the criterion
values, the refinement changes, the limits, the step-size errors, the cost of 'adaptive' and the
machine description to ``benchmarks/results/hard_cases.json``; the tables and text of
docs/stability.md are made from that file by ``scripts/figures/hard_cases_tables.py``. Each run
is a serial subprocess (``--jobs 2`` runs two at a time); run directories go to
``results/hard_cases/``.

    python scripts/studies/hard_cases.py [--jobs 2] [--only reference,gradient_E] [--force]
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
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time (default 1)")
    parser.add_argument("--only", type=lambda s: s.split(","), default=None, help="scene names")
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
                unexpected.append(f"{name} ({variant}): {run_status(run)}")
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
                unexpected.append(f"{name} at dt = {r['dt']:g} adaptive: {run_status(r)}")
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


def run_status(r: dict | None) -> str:
    """A run's outcome in a few words: ``pass``, or ``FAIL (...)`` with where and why it stopped
    or which criteria failed (docs/stability.md's tables, the ``unexpected`` list)."""
    if r is None:
        return "-"
    if r["passed"]:
        return "pass"
    failed = [k for k, ok in (r.get("criteria") or {}).items() if not ok]
    if r.get("error"):
        stop = r.get("stop") or parse_stop(r["error"])
        if stop and "step" in stop:
            cause = "inverted element" if "inverted" in stop["cause"] else stop["cause"][:40]
            return f"FAIL ({stop_at(stop)}: {cause})"
        return f"FAIL ({r['error'][:60]})"
    return f"FAIL ({', '.join(failed)})"


def stop_at(stop: dict | None) -> str:
    """Where a run stopped: ``step 13, t = 13``, or ``after step 10, t = 10`` for a failure
    inside the growth advance from t = 10."""
    if not stop or "step" not in stop:
        return "-"
    if stop["during_advance"]:
        return f"after step {stop['step']}, t = {stop['t']:g}"
    return f"step {stop['step']}, t = {stop['t']:g}"


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.worker is not None:
        worker(json.loads(args.worker))
        return 0
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
    print(f"tables: python scripts/figures/hard_cases_tables.py --json {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
