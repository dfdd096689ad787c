"""The accuracy-cost map (issue 9): error against a converged reference versus run time.

For each scene (default: ``gradient_E_strain``, ``gradient_P1_stress`` and the hard case
``E_contrast_100``) it runs, with ``plantgrowth run`` in a subprocess and the on-disk cell
cache off (every run pays for its own cell solves):

- the scene as shipped (its preset: ``balanced``) and each numerical knob varied alone from
  it: ``tissue.h``, ``tissue.H``, ``accuracy.cell_resolution``, ``accuracy.cell_tolerance``,
  ``time.dt`` and ``time.integrator``;
- the three presets (``accuracy.preset``, the scene's own explicit keys kept);
- a reference with every knob refined at once: two runs at H and H/2 extrapolated in H
  (Richardson: H is the knob that converges slowest, at first order), the others at or beyond
  the finest level of their sequences. The reference's own error is estimated knob by knob
  from the sequences: with d1, d2 the changes over the last two refinements of a knob, the
  error left beyond its finest level is about d1 rho / (1 - rho), rho = d1 / d2 (a geometric
  tail; successive refinement), or d1 where the changes do not contract; for H, half the
  extrapolation's correction (an order between 0.7 and 1.6), all summed.

Errors, relative to the reference: the final area, the final mean tr G and the L2 norm of
u - u_ref at t_max (both fields sampled on one uniform grid of the reference rectangle, P1
interpolation; u1 in the zero-mean gauge, as in the micro-macro comparison: the rigid x1
translation fixed by the pinned origin is not part of the tissue's shape). Cost: the CPU
seconds of the whole process (imports and set-up included; robust to other load on the
machine), and its wall seconds. Writes
``benchmarks/results/accuracy_cost.json`` after every run (a rerun reuses the runs already
there with the same scene text and resolved knobs; ``--redo NAME`` repeats some); the sampled
u fields are kept in ``results/accuracy_cost/`` (not committed), which a rerun needs.

    python scripts/studies/accuracy_cost.py [--scenes S ...] [--redo preset:balanced ...]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
from matplotlib.tri import LinearTriInterpolator, Triangulation

import plantgrowth as pg
from plantgrowth.base.machine import machine_description
from plantgrowth.scene.presets import PRESETS
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
SCENES = ("gradient_E_strain.toml", "gradient_P1_stress.toml", "hard/E_contrast_100.toml")
OUT = ROOT / "benchmarks/results/accuracy_cost.json"
SAMPLES_DIR = ROOT / "results/accuracy_cost"
KNOBS: dict[str, list[dict]] = {
    "h": [{"tissue.h": h} for h in (0.4, 0.2, 0.05, 0.025)],
    "H": [{"tissue.H": H} for H in (4.0, 2.0, 1.0, 0.25, 0.125)],
    "cell_resolution": [{"accuracy.cell_resolution": r} for r in (1, 3, 4, 6)],
    "cell_tolerance": [{"accuracy.cell_tolerance": c} for c in (3e-2, 1e-2, 3e-3, 1e-4, 0.0)],
    "dt": [{"time.dt": dt} for dt in (4.0, 2.0, 0.5, 0.25)],
    "integrator": [{"time.integrator": name} for name in ("euler", "exp", "adaptive")],
}
REFERENCE = {
    "tissue.h": 0.025,
    "accuracy.cell_resolution": 6,
    "accuracy.cell_tolerance": 1e-4,
    "time.dt": 0.25,
}
REFERENCE_H = (0.125, 0.0625)
"""The reference is extrapolated in H (Richardson, order 1: the observed ratio of successive
changes under halving H is about 0.5 for u, below for area and tr G) from two runs at these H;
h, dt, the cell resolution and tolerance are at or beyond the finest level of their sequences."""
FINER = {"h": -1, "H": -1, "cell_resolution": 1, "cell_tolerance": -1, "dt": -1}
"""Direction in which each refinement knob refines (-1: smaller is finer); 0 tolerance last."""
SAMPLES = (140, 60)  # sample grid of u over the reference rectangle


def with_overrides(scene: dict, overrides: dict) -> dict:
    """A copy of the scene's TOML data with dotted keys set (outputs reduced to u)."""
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in scene.items()}
    for dotted, value in overrides.items():
        section, key = dotted.split(".")
        out.setdefault(section, {})[key] = value
    out["output"] = {"fields": ["u"]}
    return out


def runs_of(scene: dict) -> dict[str, dict]:
    """Name -> overrides of every run of one scene."""
    runs = {"shipped": {}}
    for knob, levels in KNOBS.items():
        for level in levels:
            runs[f"{knob}:{next(iter(level.values()))}"] = level
    runs |= {f"preset:{name}": {"accuracy.preset": name} for name in PRESETS}
    return runs | {f"reference_H{H}": REFERENCE | {"tissue.H": H} for H in REFERENCE_H}


def run(scene_text: str, workdir: Path, samples: Path) -> dict:
    """One ``plantgrowth run`` of the scene text: CPU and wall seconds and what it wrote (the
    sampled u into the file ``samples``)."""
    scene_file, outdir = workdir / "scene.toml", workdir / "out"
    scene_file.write_text(scene_text)
    env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
    command = [Path(sys.executable).with_name("plantgrowth"), "run", scene_file, "-o", outdir]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(command, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    record = {"exit": proc.returncode, "wall_seconds": wall, "cpu_seconds": cpu}
    if proc.returncode != 0:
        return record | {"error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    with open(outdir / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    resolved = tomllib.loads((outdir / "scene.toml").read_text())
    samples.parent.mkdir(parents=True, exist_ok=True)
    np.save(samples, sample_u(outdir, float(rows[-1]["t"]), resolved["tissue"]))
    return record | {
        "t_final": float(rows[-1]["t"]),
        "area": float(rows[-1]["area"]),
        "mean_trG": float(rows[-1]["growth_rate_area"]),
        "cell_solves": sum(int(float(r["n_cell_solves"])) for r in rows),
        "resolved": resolved_knobs(pg.load_scene(outdir / "scene.toml")),
    }


def resolved_knobs(scene: pg.Scene) -> dict:
    """The numerical knobs of a resolved scene (all of [accuracy], h, H, dt, integrator)."""
    knobs = ("tissue.h", "tissue.H", "time.dt", "time.integrator")
    return {k: v for k, v in scene.dotted().items() if k in knobs or k.startswith("accuracy.")}


def knobs_of(text: str) -> dict:
    """The knobs a scene text resolves to (under the current presets)."""
    return resolved_knobs(pg.Scene.from_dict(tomllib.loads(text)))


def sample_u(outdir: Path, t: float, tissue: dict) -> np.ndarray:
    """u at t on the cell centres of a uniform grid of the rectangle (P1 interpolation)."""
    results = pg.read_results(outdir)
    tri = Triangulation(*results.points.T, results.triangles)
    nx, ny = SAMPLES
    x1 = (np.arange(nx) + 0.5) * tissue["width"] / nx
    x2 = (np.arange(ny) + 0.5) * tissue["height"] / ny
    X1, X2 = np.meshgrid(x1, x2)
    u = results.field("u", t)
    return np.stack([LinearTriInterpolator(tri, u[:, i])(X1, X2).filled(np.nan) for i in (0, 1)])


def errors(record: dict, ref: dict, u: np.ndarray, u_ref: np.ndarray) -> dict[str, float]:
    """Relative errors of area, mean tr G and u (L2 over the sample grid, u1 in the zero-mean
    gauge) against ref."""
    u, u_ref = zero_mean_u1(u), zero_mean_u1(u_ref)
    return {
        "err_area": abs(record["area"] - ref["area"]) / abs(ref["area"]),
        "err_trG": abs(record["mean_trG"] - ref["mean_trG"]) / abs(ref["mean_trG"]),
        "err_u": float(np.sqrt(np.mean((u - u_ref) ** 2) / np.mean(u_ref**2))),
    }


def knob_sequence(runs: dict[str, dict], knob: str) -> list[str]:
    """The runs of one knob and the shipped run, coarse to fine by their resolved value."""
    key = next(iter(KNOBS[knob][0]))
    names = [n for n in runs if n.startswith(knob + ":") or n == "shipped"]
    names = [n for n in names if runs[n]["exit"] == 0]
    by_value = {runs[n]["resolved"][key]: n for n in sorted(names, key=lambda n: n != "shipped")}

    def fineness(v: float) -> float:
        return v * FINER[knob] if v != 0 else np.inf  # cell_tolerance 0: exact, the finest

    return [by_value[v] for v in sorted(by_value, key=fineness)]


def tail_estimate(changes: list[float]) -> float:
    """The error left beyond the last of a sequence of changes between successive levels:
    the geometric tail ``d1 rho / (1 - rho)``, or ``d1`` itself where the changes do not
    contract (rho >= 0.9: the knob is at the floor the other knobs leave)."""
    if not changes:
        return np.inf
    rho = changes[-1] / changes[-2] if len(changes) > 1 and changes[-2] > 0.0 else 1.0
    return changes[-1] * rho / (1.0 - rho) if rho < 0.9 else changes[-1]


def zero_mean_u1(u: np.ndarray) -> np.ndarray:
    """u (2, ny, nx samples) with the mean of u1 removed."""
    return np.stack([u[0] - np.nanmean(u[0]), u[1]])


def extrapolated_reference(runs: dict[str, dict], samples: Path) -> tuple[dict, np.ndarray] | None:
    """The reference (area, mean tr G, u samples) extrapolated from the H and H/2 runs."""
    coarse, fine = (runs.get(f"reference_H{H}") for H in REFERENCE_H)
    if not (coarse and fine and coarse["exit"] == fine["exit"] == 0):
        return None
    u = [np.load(samples / f"reference_H{H}.npy") for H in REFERENCE_H]
    ref = {k: 2.0 * fine[k] - coarse[k] for k in ("area", "mean_trG")}
    return ref, 2.0 * u[1] - u[0]


def summarize(runs: dict[str, dict], samples: Path) -> dict:
    """Errors of every run against the reference; the reference's estimated error; the knob
    whose refinement removes most of the shipped scene's error."""
    extrapolated = extrapolated_reference(runs, samples)
    if extrapolated is None:
        return {}
    ref, u_ref = extrapolated
    fields = {n: np.load(samples / f"{n}.npy") for n, r in runs.items() if r["exit"] == 0}
    table = {}
    for name, record in runs.items():
        if record["exit"] == 0:
            e = errors(record, ref, fields[name], u_ref)
            table[name] = e | {"err_max": max(e.values())}
    finest = f"reference_H{REFERENCE_H[1]}"
    estimate = {k: 0.5 * v for k, v in table[finest].items() if k != "err_max"}
    for knob in set(FINER) - {"H"}:
        sequence = knob_sequence(runs, knob)
        pairs = list(zip(sequence[:-1], sequence[1:], strict=True))
        for name in estimate:
            changes = [errors(runs[a], runs[b], fields[a], fields[b])[name] for a, b in pairs]
            estimate[name] += tail_estimate(changes)
    out = {"errors": table, "reference_error_estimate": estimate}
    shipped = table.get("shipped")
    if shipped:
        finest = {knob: min((table[n]["err_max"] for n in table if n.startswith(knob + ":")),
                            default=np.inf) for knob in KNOBS}  # fmt: skip
        out["dominant_knob"] = min(finest, key=finest.get)
        out["error_left_when_refining"] = finest
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--redo", nargs="*", default=[], help="run names to repeat")
    parser.add_argument("--only", nargs="*", default=None, help="run only these names")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    data = json.loads(args.out.read_text()) if args.out.exists() else {"scenes": {}}
    data["machine"] = machine_description()
    data["command"] = "python scripts/studies/accuracy_cost.py"
    data["cost"] = "CPU seconds of the whole plantgrowth process (user + system), cache off"
    for name in args.scenes:
        path = ROOT / "scenes" / name
        base = tomllib.loads(path.read_text())
        entry = data["scenes"].setdefault(path.stem, {"scene": f"scenes/{name}", "runs": {}})
        samples = SAMPLES_DIR / path.stem
        for run_name, overrides in runs_of(base).items():
            if args.only is not None and run_name not in args.only:
                continue
            text = dict_to_toml(with_overrides(base, overrides))
            old = entry["runs"].get(run_name)
            same = old and old["scene_text"] == text and old.get("resolved") == knobs_of(text)
            if same and run_name not in args.redo:
                continue
            with tempfile.TemporaryDirectory() as tmp:
                load = os.getloadavg()[0]
                record = run(text, Path(tmp), samples / f"{run_name}.npy")
            entry["runs"][run_name] = record | {"scene_text": text, "load_before": load}
            entry |= summarize(entry["runs"], samples)
            args.out.write_text(json.dumps(data, indent=1))
            shown = {k: v for k, v in record.items() if k != "resolved"}
            print(path.stem, run_name, json.dumps(shown), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
