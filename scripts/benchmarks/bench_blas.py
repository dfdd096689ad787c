"""Whole runs on the reference BLAS against OpenBLAS (scripts/install.sh installs
``libopenblas0-serial``; docs/large_tissues.md, "An optimized BLAS").

Debian links numpy, scipy and PETSc against ``libblas.so.3`` / ``liblapack.so.3``, which its
alternatives resolve to the reference (netlib) build unless an optimized one is installed.
This script runs each scene as a whole ``plantgrowth run`` process (one rank, cell cache off)
alternately with the reference BLAS, forced by putting its directories first on
``LD_LIBRARY_PATH``, and with the system's choice, ``--repeats`` times: median CPU seconds
(user + sys of the child), the median of the pairs' ratios, and the largest relative
difference of the runs' t_max measures (:data:`MEASURES`; round-off: the two libraries sum in
other orders).
Scenes: the reference scene, gradient_E_strain at ``balanced`` and the same with fibres
and stress feedback (scripts/benchmarks/bench_feedback_cost.py's scene). Writes
``benchmarks/results/blas.json`` with the machine (whose ``blas`` names the system's choice).

    python scripts/benchmarks/bench_blas.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from pathlib import Path

from bench_feedback_cost import feedback_text
from bench_feedback_cost import run as whole_run
from bench_fibre_cost import scene_text

from plantgrowth.base.machine import machine_description

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/blas.json"
REFERENCE_BLAS = "/usr/lib/x86_64-linux-gnu/blas:/usr/lib/x86_64-linux-gnu/lapack"
"""Debian's directories of the reference libblas.so.3 and liblapack.so.3."""
MEASURES = ("area", "u1_max", "u2_max", "growth_rate_area", "elastic_strain_max", "fibre_order")
"""The summary's physical measures compared (not its solver residual, a round-off itself)."""


def run(exe: str, text: str, reference_blas: bool) -> dict:
    """One whole run of the scene text (cache off): CPU seconds and the last row's measures."""
    env = dict(os.environ)
    env.pop("LD_LIBRARY_PATH", None)
    if reference_blas:
        env["LD_LIBRARY_PATH"] = REFERENCE_BLAS
    whole = whole_run(exe, text, env=env, measures=MEASURES)
    return {"cpu": whole["cpu"], "last": {k: whole[k] for k in MEASURES if k in whole}}


def largest_difference(a: dict, b: dict) -> float:
    """Largest relative difference of two runs' measures (those not zero in both)."""
    return max((abs(a[k] - b[k]) / max(abs(a[k]), abs(b[k])) for k in a if a[k] or b[k]),
               default=0.0)  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    exe = str(Path(sys.executable).with_name("plantgrowth"))
    scenes = {
        "reference_stress": (ROOT / "scenes/reference_stress.toml").read_text(),
        "gradient_E_strain": scene_text(False),
        "gradient_E_strain_feedback": feedback_text(),
    }
    result: dict = {"machine": machine_description(), "load_before": os.getloadavg(),
                    "reference_blas": REFERENCE_BLAS, "repeats": args.repeats}  # fmt: skip
    runs: dict = {name: {"reference": [], "system": []} for name in scenes}
    for _ in range(args.repeats):
        for name, text in scenes.items():
            for kind in ("reference", "system"):
                runs[name][kind].append(run(exe, text, kind == "reference"))
            print(name, [runs[name][k][-1]["cpu"] for k in ("reference", "system")], flush=True)
    result["scenes"] = {
        name: {
            "cpu_reference": [r["cpu"] for r in pair["reference"]],
            "cpu_system": [r["cpu"] for r in pair["system"]],
            "median_reference": statistics.median(r["cpu"] for r in pair["reference"]),
            "median_system": statistics.median(r["cpu"] for r in pair["system"]),
            "median_ratio_system_over_reference": statistics.median(
                s["cpu"] / r["cpu"] for r, s in zip(pair["reference"], pair["system"], strict=True)
            ),
            "largest_relative_difference": largest_difference(
                pair["reference"][-1]["last"], pair["system"][-1]["last"]
            ),
        }
        for name, pair in runs.items()
    }  # fmt: skip
    result["load_after"] = os.getloadavg()
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps({n: {k: v for k, v in s.items() if k.startswith(("median", "largest"))}
                      for n, s in result["scenes"].items()}, indent=1))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
