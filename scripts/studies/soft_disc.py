"""The soft disc's growth rate at t = 0 (issue 20, item 4): the small-feature accuracy check.

``scenes/examples/soft_disc.toml`` (8 x 4 tissue, E = 0.3 within a radius 1 of its centre, 1
outside, strain law) run for one step by ``plantgrowth run`` (the cell cache off) under each
preset and on a sequence of fine meshes; the quantity is the mean tr G at t = 0 inside the
disc, area-weighted over the fine cells whose midpoint is inside. The converged value is the
finest run of the h sequence (every other knob at the ``fine`` preset's values or beyond),
extrapolated in h from its last two runs when their changes contract (Richardson with the
observed order). ``--exe`` runs another checkout's ``plantgrowth`` (the comparison with main).
Writes ``benchmarks/results/soft_disc.json``.

    python scripts/studies/soft_disc.py [--exe PATH] [--label NAME]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from plantgrowth.base.machine import machine_description
from plantgrowth.results.reader import read_series
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes/examples/soft_disc.toml"
OUT = ROOT / "benchmarks/results/soft_disc.json"
CENTRE, RADIUS = (4.0, 2.0), 1.0
FINE_KNOBS = {"accuracy": {"cell_resolution": 3, "cell_tolerance": 1e-4}}
H_SEQUENCE = (0.1, 0.05, 0.025)
"""Fine meshes of the convergence sequence (coarse grid H = h: on the exact path and on the
surrogate path alike every field is then sampled at spacing h)."""


def disc_mean_trG(outdir: Path) -> float:
    """Area-weighted mean tr G at t = 0 over the cells whose midpoint is inside the disc."""
    series = read_series(outdir)
    corners = series.points[series.triangles]
    mid = corners.mean(axis=1)
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    inside = np.hypot(mid[:, 0] - CENTRE[0], mid[:, 1] - CENTRE[1]) < RADIUS
    trG = series.cell_field("G", series.times[0], "tr")
    return float(np.sum(area[inside] * trG[inside]) / np.sum(area[inside]))


def run(exe: str, overrides: dict) -> dict:
    """One step of the disc scene with the overrides (nested dict) merged in."""
    data = tomllib.loads(SCENE.read_text())
    data["time"] = {"t_max": 1.0, "dt": 1.0}
    data["output"] = {"fields": ["u", "G"]}
    for section, values in overrides.items():
        data.setdefault(section, {}).update(values)
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene.toml"
        scene.write_text(dict_to_toml(data))
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
        start = time.perf_counter()
        subprocess.run([exe, "run", str(scene), "-o", f"{tmp}/o"], check=True,
                       capture_output=True, env=env)  # fmt: skip
        wall = time.perf_counter() - start
        return {"overrides": overrides, "mean_trG": disc_mean_trG(Path(tmp) / "o"), "wall": wall}


def converged(values: list[float]) -> float:
    """Richardson from the last three of a halving sequence (observed order), else the last."""
    a, b, c = values[-3:]
    d1, d2 = c - b, b - a
    if d2 == 0.0 or not 0.0 < d1 / d2 < 1.0:
        return c
    rho = d1 / d2
    return c + d1 * rho / (1.0 - rho)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--exe", default=str(Path(sys.executable).with_name("plantgrowth")))
    parser.add_argument("--label", default="this checkout")
    args = parser.parse_args(argv)
    results = json.loads(OUT.read_text()) if OUT.is_file() else {}
    runs = {f"preset:{p}": run(args.exe, {"accuracy": {"preset": p}})
            for p in ("draft", "balanced", "fine")}  # fmt: skip
    for h in H_SEQUENCE:
        overrides = {"tissue": {"h": h, "H": h}} | FINE_KNOBS
        runs[f"h:{h}"] = run(args.exe, overrides)
        print(f"h = {h}: {runs[f'h:{h}']['mean_trG']:.6g}", flush=True)
    sequence = [runs[f"h:{h}"]["mean_trG"] for h in H_SEQUENCE]
    value = converged(sequence)
    for record in runs.values():
        record["error"] = record["mean_trG"] / value - 1.0
    results[args.label] = {"runs": runs, "converged": value, "machine": machine_description()}
    OUT.write_text(json.dumps(results, indent=1) + "\n")
    for name, record in runs.items():
        print(f"{name:16s} {record['mean_trG']:.6g}  error {record['error']:+.2%}")
    print(f"converged {value:.6g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
