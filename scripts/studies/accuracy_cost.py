"""The accuracy-cost map (issue 9; re-run for issue 20 with per-cell tensors): error against a
converged reference versus run time.

For each scene (default: ``gradient_E_strain``, ``gradient_P1_stress``, the hard case
``E_contrast_100`` and the small feature ``examples/soft_disc``) it runs, with ``plantgrowth
run`` in a subprocess and the on-disk cell cache off (every run pays for its own cell solves):

- the scene as shipped (its preset: ``balanced``) and each numerical knob varied alone from
  it, at the levels around the presets (``tissue.h``, ``tissue.H``,
  ``accuracy.cell_resolution``, ``accuracy.cell_tolerance``, ``time.dt``,
  ``time.integrator``); a level that resolves to the shipped scene's knobs is not run again;
- the three presets (``accuracy.preset``, the scene's own explicit keys kept);
- candidate presets (``CANDIDATES``);
- a reference run: the ``fine`` preset with h halved (``REFERENCE``).

Per-scene overrides (``SCENE_OVERRIDES``) apply to every run of a scene: E_contrast_100 goes
on where its soft end loses strong ellipticity (``numerics.on_instability = "warn"``: the map
measures discretization error, not the model's validity), the soft disc runs to t = 20.

The converged reference: the reference run extrapolated knob by knob (errors taken as additive
over the knobs): for h against the ``fine`` preset run (h twice the reference's; rho from
that change and the h sequence's last, h = 0.1 to 0.05), for dt and
the cell resolution and tolerance (whose finest levels the reference shares) with the last
step of their own sequences; each correction is that last change times rho / (1 - rho), rho
the ratio of the knob's successive changes on its sequence (``extrapolated_reference``). The
reference's own error is estimated as half of each correction (the whole last change where the
changes do not contract) plus the geometric tail of the H sequence, summed. For the three
smooth scenes the final area and mean tr G are instead the extrapolated references of the map
before per-cell tensors (``MAIN_REFERENCES``, with their estimated errors): converged values
are properties of the model, not of the code path, and the new extrapolation checks them; their
u fields were not kept, so u is always the new extrapolation.

Errors, relative to the reference: the final area, the final mean tr G and the L2 norm of
u - u_ref at t_max (both fields sampled on one uniform grid of the reference rectangle, P1
interpolation; u1 in the zero-mean gauge, as in the micro-macro comparison: the rigid x1
translation fixed by the pinned origin is not part of the tissue's shape). Cost: the CPU
seconds of the whole process (imports and set-up included; robust to other load on the
machine), and its wall seconds. Writes
``benchmarks/results/accuracy_cost.json`` after every run (a rerun reuses the runs already
there with the same scene text and resolved knobs; ``--redo NAME`` repeats some, ``--redo``
alone all; two processes may share the file: each merges its runs in under a lock); the
sampled u fields are kept in ``results/accuracy_cost/`` (not committed): a scene's errors are
summarized once every run of it has its fields there (a new machine: ``--redo``).

    python scripts/studies/accuracy_cost.py [--scenes S ...] [--only NAME ...] [--redo NAME ...]
    python scripts/studies/accuracy_cost.py --summarize   # errors again from the stored runs
"""

from __future__ import annotations

import argparse
import csv
import fcntl
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
SCENES = (
    "gradient_E_strain.toml",
    "gradient_P1_stress.toml",
    "hard/E_contrast_100.toml",
    "examples/soft_disc.toml",
)
SCENE_OVERRIDES = {
    "E_contrast_100": {"numerics.on_instability": "warn"},
    "soft_disc": {"time.t_max": 20.0, "numerics.on_instability": "warn"},
}
"""Applied to every run of the scene (reference included)."""
OUT = ROOT / "benchmarks/results/accuracy_cost.json"
SAMPLES_DIR = ROOT / "results/accuracy_cost"
KNOBS: dict[str, list[dict]] = {
    "h": [{"tissue.h": h} for h in (0.2, 0.05)],
    "H": [{"tissue.H": H} for H in (2.0, 0.125)],
    "cell_resolution": [{"accuracy.cell_resolution": r} for r in (1, 3)],
    "cell_tolerance": [{"accuracy.cell_tolerance": c} for c in (1e-2, 1e-4)],
    "dt": [{"time.dt": dt} for dt in (2.0, 0.5)],
    "integrator": [{"time.integrator": name} for name in ("euler", "exp")],
}
"""Around the presets: h and dt at draft's and fine's levels beside balanced's (the shipped
scene), the cell knobs at draft's and fine's, H at two points only (with per-cell tensors H
samples just the cell geometry and nu, constant in these scenes)."""
REFERENCE = {
    "tissue.h": 0.025,
    "tissue.H": 0.0625,
    "accuracy.cell_resolution": 3,
    "accuracy.cell_tolerance": 1e-4,
    "time.dt": 0.5,
}
"""The ``fine`` preset with h halved: h, the one knob whose refinement still moves the fine
preset's result, beyond its sequence; dt, the cell resolution and tolerance at the finest
level of theirs (their tails beyond it are in the reference's error estimate)."""
MAIN_REFERENCES = {
    "gradient_E_strain": {"area": 41.840810975960295, "mean_trG": 0.010238230866627791},
    "gradient_P1_stress": {"area": 80.05706117592464, "mean_trG": 0.019792531077876787},
    "E_contrast_100": {"area": 58.01059298678424, "mean_trG": 0.015835350715252845},
}
"""The converged area and mean tr G at t = 60 of the map before per-cell tensors (commit
2c36810, benchmarks/results/accuracy_cost.json there: 2 Q(H = 0.0625) - Q(H = 0.125), h =
0.025, cell resolution 6, tolerance 1e-4, dt = 0.25; estimated errors 0.0062% / 0.0011%,
0.0022% / 0.000095%, 0.013% / 0.00021%). Their u fields were not kept."""
MAIN_ESTIMATES = {
    "gradient_E_strain": {"err_area": 6.2e-5, "err_trG": 1.1e-5},
    "gradient_P1_stress": {"err_area": 2.2e-5, "err_trG": 9.5e-7},
    "E_contrast_100": {"err_area": 1.3e-4, "err_trG": 2.1e-6},
}
"""Those estimated errors of MAIN_REFERENCES (area, mean tr G)."""
CANDIDATES = {"fine+dt:0.25": {"accuracy.preset": "fine", "time.dt": 0.25}}
"""Candidate presets beside the three. fine+dt:0.25 was run on soft_disc and gradient_E_strain
only (``--only``): it left the soft disc's error where fine's is (h dominates there); on
E_contrast_100 it would change the scene's own dt, which a preset keeps."""
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
    return runs | CANDIDATES | {"reference": REFERENCE}


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
    warned = [line for line in proc.stderr.splitlines() if "ellipticity" in line]
    if warned:
        record["ellipticity_warnings"] = warned[:3]
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


def changes_along(runs: dict[str, dict], names: list[str], fields: dict) -> dict[str, list]:
    """The relative changes of area, mean tr G and u between successive runs of names."""
    pairs = list(zip(names[:-1], names[1:], strict=True))
    out: dict[str, list] = {"err_area": [], "err_trG": [], "err_u": []}
    for a, b in pairs:
        for k, v in errors(runs[a], runs[b], fields[a], fields[b]).items():
            out[k].append(v)
    return out


def extrapolated_reference(
    runs: dict[str, dict], fields: dict
) -> tuple[dict, np.ndarray, dict] | None:
    """The reference run extrapolated knob by knob (errors additive over the knobs): for each
    refinement knob, the change over its last refinement times rho / (1 - rho), rho the ratio
    of its successive changes on its sequence around the shipped scene, where the changes
    contract (rho < 0.9; else no extrapolation). For h the last refinement is the ``fine``
    preset run (h twice the reference's, every other refinement knob alike but H) to the
    reference run, the one before it the h sequence's last (h = 0.1 to 0.05); for dt, the
    cell resolution and tolerance, whose finest levels the reference shares, the sequence's
    own last step (shipped to finest). Returns the values, the u samples and, per knob and
    quantity, rho and the relative correction made."""
    ref, fine = runs.get("reference"), runs.get("preset:fine")
    if not (ref and fine and ref["exit"] == fine["exit"] == 0):
        return None
    values = {k: ref[k] for k in ("area", "mean_trG")}
    u = fields["reference"].copy()
    info: dict[str, dict] = {}
    for knob in ("h", "dt", "cell_resolution", "cell_tolerance"):
        sequence = knob_sequence(runs, knob)
        observed = changes_along(runs, sequence, fields)
        a, b = ("preset:fine", "reference") if knob == "h" else sequence[-2:]
        last = errors(runs[b], runs[a], fields[b], fields[a])
        info[knob] = {}
        for name, changes in observed.items():
            if knob == "h":  # the fine preset to the reference: one more halving of h
                changes = [*changes, last[name]]
            rho = changes[-1] / changes[-2] if len(changes) > 1 and changes[-2] > 0 else 1.0
            factor = rho / (1.0 - rho) if rho < 0.9 else 0.0
            info[knob][name] = {"rho": rho, "correction": factor * last[name],
                                "last_change": last[name]}  # fmt: skip
            if name == "err_u":
                u += (fields[b] - fields[a]) * factor
            else:
                key = {"err_area": "area", "err_trG": "mean_trG"}[name]
                values[key] += (runs[b][key] - runs[a][key]) * factor
    return values, u, info


def summarize(stem: str, runs: dict[str, dict], samples: Path) -> dict:
    """Errors of every run against the reference; the reference's estimated error; the knob
    whose refinement removes most of the shipped scene's error; the check of main's
    reference values."""
    done = [n for n, r in runs.items() if r["exit"] == 0]
    if not all((samples / f"{n}.npy").is_file() for n in done):
        return {}  # a map being re-run on a new machine: summarized once every field is there
    fields = {n: np.load(samples / f"{n}.npy") for n in done}
    extrapolated = extrapolated_reference(runs, fields)
    if extrapolated is None:
        return {}
    ref, u_ref, corrections = extrapolated
    out: dict = {"extrapolation": corrections, "reference_values": dict(ref)}
    main_ref = MAIN_REFERENCES.get(stem)
    if main_ref:
        out["check_of_main_reference"] = {
            k: (ref[k] - main_ref[k]) / abs(main_ref[k]) for k in main_ref
        } | {"reference_run_" + k: (runs["reference"][k] - main_ref[k]) / abs(main_ref[k])
             for k in main_ref}  # fmt: skip
        ref = dict(main_ref)
        out["reference_values"] = ref | {"source": "MAIN_REFERENCES (area, mean_trG)"}
    table = {}
    for name, record in runs.items():
        if record["exit"] == 0:
            e = errors(record, ref, fields[name], u_ref)
            table[name] = e | {"err_max": max(e.values())}
    estimate = {"err_area": 0.0, "err_trG": 0.0, "err_u": 0.0}
    for per_quantity in corrections.values():  # half of each correction, or the last change
        for k, v in per_quantity.items():
            estimate[k] += 0.5 * abs(v["correction"]) if v["rho"] < 0.9 else v["last_change"]
    observed = changes_along(runs, knob_sequence(runs, "H"), fields)
    for name in estimate:
        estimate[name] += tail_estimate(observed[name])
    if main_ref:  # main's estimated errors (docs/accuracy_cost.md) for area and tr G
        estimate |= MAIN_ESTIMATES[stem]
    out |= {"errors": table, "reference_error_estimate": estimate}
    shipped = table.get("shipped")
    if shipped:
        finest = {knob: min((table[n]["err_max"] for n in table if n.startswith(knob + ":")),
                            default=np.inf) for knob in KNOBS}  # fmt: skip
        out["dominant_knob"] = min(finest, key=finest.get)
        out["error_left_when_refining"] = finest
    return out


def save_run(out: Path, stem: str, scene: str, run_name: str, record: dict | None) -> None:
    """Merge one run (None: none) into the JSON under a lock (two processes may share the
    file) and re-summarize its scene."""
    SAMPLES_DIR.mkdir(parents=True, exist_ok=True)
    with open(SAMPLES_DIR / "accuracy_cost.lock", "w") as lock:  # not committed
        fcntl.flock(lock, fcntl.LOCK_EX)
        data = json.loads(out.read_text()) if out.exists() else {"scenes": {}}
        data["machine"] = machine_description()
        data["command"] = "python scripts/studies/accuracy_cost.py"
        data["cost"] = "CPU seconds of the whole plantgrowth process (user + system), cache off"
        entry = data["scenes"].setdefault(stem, {"scene": scene, "runs": {}})
        if record is not None:
            entry["runs"][run_name] = record
        entry["overrides"] = SCENE_OVERRIDES.get(stem, {})
        for key in (
            "check_of_main_reference",
            "extrapolation",
            "h_extrapolation",
            "reference_values",
        ):
            entry.pop(key, None)
        entry |= summarize(stem, entry["runs"], SAMPLES_DIR / stem)
        out.write_text(json.dumps(data, indent=1))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--redo", nargs="*", default=None,
                        help="run names to repeat (none given: every run)")
    parser.add_argument("--only", nargs="*", default=None, help="run only these names")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--summarize", action="store_true", help="re-summarize only, no runs")
    args = parser.parse_args(argv)
    if args.summarize:
        for name in args.scenes:
            save_run(args.out, Path(name).stem, f"scenes/{name}", "", None)
        return 0
    for name in args.scenes:
        path = ROOT / "scenes" / name
        base = tomllib.loads(path.read_text())
        samples = SAMPLES_DIR / path.stem
        scene_overrides = SCENE_OVERRIDES.get(path.stem, {})
        shipped = knobs_of(dict_to_toml(with_overrides(base, scene_overrides)))
        for run_name, overrides in runs_of(base).items():
            if args.only is not None and run_name not in args.only:
                continue
            text = dict_to_toml(with_overrides(base, scene_overrides | overrides))
            knobs = knobs_of(text)
            if ":" in run_name and not run_name.startswith("preset:") and knobs == shipped:
                continue  # this level is the shipped scene's
            data = json.loads(args.out.read_text()) if args.out.exists() else {"scenes": {}}
            old = data["scenes"].get(path.stem, {}).get("runs", {}).get(run_name)
            same = old and old["scene_text"] == text and old.get("resolved") == knobs
            redo = args.redo is not None and (not args.redo or run_name in args.redo)
            if same and not redo:
                continue
            with tempfile.TemporaryDirectory() as tmp:
                load = os.getloadavg()[0]
                record = run(text, Path(tmp), samples / f"{run_name}.npy")
            record |= {"scene_text": text, "load_before": load}
            save_run(args.out, path.stem, f"scenes/{name}", run_name, record)
            shown = {k: v for k, v in record.items() if k not in ("resolved", "scene_text")}
            print(path.stem, run_name, json.dumps(shown), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
