"""The presets' time targets (issue 9): each preset on ``gradient_E_strain`` against the
shipped reference scene, measured in the same session.

Runs ``plantgrowth run`` as a whole process (imports included), the cell cache off, in turn
A B A B ... (reference_stress, then the E-gradient scene under each preset) so a drift of the
machine's speed hits both alike; records the median wall and CPU seconds and the ratio to the
reference scene pair by pair, with the load average before and after. The errors of the
presets are those of ``benchmarks/results/accuracy_cost.json``
(``scripts/studies/accuracy_cost.py``). Writes ``benchmarks/results/presets.json``.

    python scripts/benchmarks/bench_presets.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.presets import PRESETS
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/presets.json"
REFERENCE = ROOT / "scenes/reference_stress.toml"
SCENE = ROOT / "scenes/gradient_E_strain.toml"
TARGETS = {"draft": (0.03, 1.0), "balanced": (0.01, 1.5), "fine": (0.001, None)}
"""Issue 9: (largest error against the converged reference, largest time ratio to the
reference scene) per preset; None: time reported only."""


def timed_run(scene_text: str) -> tuple[float, float]:
    """Wall and CPU seconds of one ``plantgrowth run`` of the scene text (cache off)."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene.toml"
        scene.write_text(scene_text)
        command = [Path(sys.executable).with_name("plantgrowth"), "run", scene, "-o", f"{tmp}/o"]
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, env=env)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def preset_text(preset: str) -> str:
    """The E-gradient scene as shipped, with ``accuracy.preset`` set."""
    data = tomllib.loads(SCENE.read_text())
    data.setdefault("accuracy", {})["preset"] = preset
    return dict_to_toml(data)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    errors = json.loads((ROOT / "benchmarks/results/accuracy_cost.json").read_text())
    errors = errors["scenes"]["gradient_E_strain"]["errors"]
    load_before = os.getloadavg()
    reference_text = REFERENCE.read_text()
    timed_run(reference_text)  # warm-up: JIT cache and file cache
    samples: dict[str, list[tuple[float, float]]] = {"reference_stress": []}
    ratios: dict[str, list[float]] = {name: [] for name in PRESETS}
    for _ in range(args.repeats):
        for name in PRESETS:
            ref = timed_run(reference_text)
            run = timed_run(preset_text(name))
            samples["reference_stress"].append(ref)
            samples.setdefault(name, []).append(run)
            ratios[name].append(run[0] / ref[0])
    result = {"machine": machine_description(), "load_before": load_before,
              "load_after": os.getloadavg(), "repeats": args.repeats, "cache": "off",
              "reference_stress": _medians(samples["reference_stress"]), "presets": {}}  # fmt: skip
    for name in PRESETS:
        error_limit, ratio_limit = TARGETS[name]
        ratio = statistics.median(ratios[name])
        err = errors[f"preset:{name}"]["err_max"]
        result["presets"][name] = _medians(samples[name]) | {
            "wall_ratio_to_reference_stress": ratio,
            "err_max": err,
            "error_target": error_limit,
            "ratio_target": ratio_limit,
            "meets_targets": err <= error_limit and (ratio_limit is None or ratio <= ratio_limit),
        }
        print(name, json.dumps(result["presets"][name]))
    OUT.write_text(json.dumps(result, indent=1))
    return 0


def _medians(pairs: list[tuple[float, float]]) -> dict[str, float]:
    return {
        "wall_seconds": statistics.median(p[0] for p in pairs),
        "cpu_seconds": statistics.median(p[1] for p in pairs),
    }


if __name__ == "__main__":
    sys.exit(main())
