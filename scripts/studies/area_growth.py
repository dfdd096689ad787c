"""The largest area growth of one step in each shipped scene (issue 32): the measurement behind
the plausibility warning of plantgrowth/runner/step_warnings.py (MAX_STEP_AREA_GROWTH).

Runs every example of scripts/studies/strain_bands.py and the hard cases (``scenes/hard``) with
``accuracy.preset = "draft"`` for the meshes and cell accuracy (the scene's own h and H dropped;
its own dt kept, since the warning is per step), in this process, one after the other, and
records from each run's summary.csv the largest ratio of one row's area to the row before,
``area(t + dt) / area(t)``, and its time, and the largest growth factor of one step,
``exp(growth_rate_area dt)`` (what the advance does to the tissue's reference-area mean of
det Fg; the warning's measure, known before the step is taken). Results:
``benchmarks/results/area_growth.json`` (written after each scene); runs under
``results/area_growth/``.

    python scripts/studies/area_growth.py [--only reference_stress,...]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tomllib
from pathlib import Path

from mpi4py import MPI

import plantgrowth as pg

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strain_bands import example_scenes, run_measured  # noqa: E402  (a sibling script)


def draft(path: Path, extra: dict) -> pg.Scene:
    """The scene of ``path`` on the draft preset's meshes and cell accuracy, its own dt kept."""
    data = tomllib.loads(path.read_text(encoding="utf-8")) | extra
    data.setdefault("accuracy", {})["preset"] = "draft"
    for key in ("h", "H"):
        data.get("tissue", {}).pop(key, None)
    return pg.Scene.from_dict(data, directory=path.parent)


def largest_step(summary: Path) -> dict:
    """The largest area(t + dt) / area(t) of a summary.csv, its t + dt, and the last t (empty
    for a run that stopped before its first row)."""
    with open(summary, newline="") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    if not rows:
        return {}
    pairs = zip(rows, rows[1:], strict=False)
    ratios = [(b["area"] / a["area"], b["t"], b["t"] - a["t"]) for a, b in pairs]
    ratio, t, dt = max(ratios, default=(1.0, 0.0, 0.0))
    dt = dt or 1.0
    top = max(rows, key=lambda r: r["growth_rate_area"])
    return {
        "area_ratio_max": ratio, "t": t, "dt": dt, "t_reached": rows[-1]["t"],
        "growth_factor_max": math.exp(top["growth_rate_area"] * dt), "growth_factor_t": top["t"],
    }  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", type=lambda s: s.split(","), default=None, help="scene names")
    parser.add_argument("--out", type=Path, default=Path("results/area_growth"))
    parser.add_argument("--json", type=Path, default=Path("benchmarks/results/area_growth.json"))
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    scenes = example_scenes()
    scenes |= {f"hard/{p.stem}": (p, {}) for p in sorted(Path("scenes/hard").glob("*.toml"))}
    found = json.loads(args.json.read_text()) if args.json.exists() else {}
    for name, (path, extra) in scenes.items():
        if args.only is not None and name not in args.only:
            continue
        rows = run_measured(draft(path, extra), args.out / name, name, largest_step, comm)
        for key, row in rows.items():
            found[key] = row | {"stop": row["stop"][:200]}
            if comm.rank == 0:
                print(key, json.dumps(found[key]), flush=True)
                args.json.parent.mkdir(parents=True, exist_ok=True)
                args.json.write_text(json.dumps(found, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
