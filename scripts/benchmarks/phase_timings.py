"""Time per phase of the coupled macro run (cell problems, macro solve, growth, I/O).

Runs each scene (default: the reference stress scene and the E-gradient strain scene) into
results/phase_timings/<name> and writes the totals of summary.csv's seconds_* columns, the set-up
time and the number of cell solves to benchmarks/results/phase_timings.json with the machine.

    python scripts/benchmarks/phase_timings.py [SCENE.toml ...]
"""

import argparse
import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from plantgrowth.base.machine import machine_description

PHASES = ("seconds_cells", "seconds_solve", "seconds_growth", "seconds_io")
DEFAULT = ["scenes/reference_stress.toml", "scenes/gradient_E_strain.toml"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", default=DEFAULT)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/phase_timings.json"))
    args = parser.parse_args(argv)
    results = {}
    for scene in map(Path, args.scenes):
        outdir = Path("results/phase_timings") / scene.stem
        start = time.perf_counter()
        plantgrowth = Path(sys.executable).with_name("plantgrowth")
        command = [plantgrowth, "run", scene, "-o", outdir, "--overwrite"]
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}  # every run pays its cell solves
        subprocess.run(command, check=True, capture_output=True, env=env)
        wall = time.perf_counter() - start
        with open(outdir / "summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        totals = {p: sum(float(r[p]) for r in rows) for p in PHASES}
        steps = sum(float(r["seconds"]) for r in rows)
        results[scene.stem] = {
            "wall_seconds": wall,
            "steps_seconds": steps,
            "startup_seconds": wall - steps,  # imports, JIT cache look-up, meshes, first forms
            **totals,
            "cell_solves": sum(int(float(r["n_cell_solves"])) for r in rows),
            "steps": len(rows),
        }
        print(scene.stem, json.dumps(results[scene.stem]))
    args.out.write_text(json.dumps({"machine": machine_description(), "runs": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
