"""Markdown tables of the accuracy-cost map (``benchmarks/results/accuracy_cost.json``).

Prints, per scene, every run's relative errors (final area, final mean tr G, u at t_max) and
cost, then one table of the presets over all scenes; the docs and README tables are pasted
from it. Never solves.

    python scripts/figures/accuracy_cost_table.py
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "benchmarks/results/accuracy_cost.json"


def _pct(x: float) -> str:
    return f"{100 * x:.2g}%"


def scene_table(stem: str, entry: dict) -> list[str]:
    """One row per run of one scene."""
    lines = [f"#### {stem}", "", "| run | err area | err mean tr G | err u | err max | CPU s | "
             "wall s | cell solves |", "|---|---:|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    for name, run in entry["runs"].items():
        if run["exit"] == 0 and name not in entry.get("errors", {}):
            continue
        if run["exit"] != 0:
            lines.append(f"| {name} | stopped: {run['error'][:60]} | | | | | | |")
            continue
        e = entry["errors"][name]
        errors = " | ".join(_pct(e[k]) for k in ("err_area", "err_trG", "err_u", "err_max"))
        cost = f"{run['cpu_seconds']:.3g} | {run['wall_seconds']:.3g} | {run['cell_solves']}"
        lines.append(f"| {name} | {errors} | {cost} |")
    if entry.get("overrides"):
        shown = ", ".join(f"`{k} = {v!r}`" for k, v in entry["overrides"].items())
        lines += ["", f"Every run of this scene with {shown}."]
    if "check_of_main_reference" in entry:
        check = entry["check_of_main_reference"]
        lines += ["", "Area and mean tr G against main's extrapolated reference (MAIN_REFERENCES); "
                  "main's reference against this one's: the reference run differs by "
                  f"{_pct(check['reference_run_area'])} (area), "
                  f"{_pct(check['reference_run_mean_trG'])} (tr G); extrapolated, by "
                  f"{_pct(check['area'])}, {_pct(check['mean_trG'])}."]  # fmt: skip
    for knob, per_quantity in entry.get("extrapolation", {}).items():
        shown = ", ".join(f"{k[4:]} rho {v['rho']:.2g}, {_pct(v['correction'])}"
                          for k, v in per_quantity.items())  # fmt: skip
        lines += [f"Reference extrapolated in {knob}: {shown}."]
    estimate = entry.get("reference_error_estimate", {})
    if estimate:
        shown = ", ".join(f"{k[4:]} {_pct(v)}" for k, v in estimate.items() if k != "err_max")
        lines += ["", f"Estimated error of the reference itself: {shown}."]
    if "dominant_knob" in entry:
        left = entry["error_left_when_refining"]
        shown = ", ".join(f"{k} {_pct(v)}" for k, v in left.items())
        lines += [f"Dominant knob of the shipped scene: **{entry['dominant_knob']}** (largest "
                  f"error left when only that knob is refined: {shown})."]  # fmt: skip
    return lines + [""]


def preset_table(scenes: dict) -> list[str]:
    """The presets' largest error and CPU seconds on every scene."""
    names = [n for n in next(iter(scenes.values()))["runs"] if n.startswith("preset:")]
    header = "| preset | " + " | ".join(f"{stem}: err max / CPU s" for stem in scenes) + " |"
    lines = [header, "|---|" + "---:|" * len(scenes)]
    for name in names:
        cells = []
        for entry in scenes.values():
            run, e = entry["runs"].get(name), entry.get("errors", {}).get(name)
            cells.append(f"{_pct(e['err_max'])} / {run['cpu_seconds']:.3g}" if e else "-")
        lines.append(f"| {name.split(':')[1]} | " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA, help="(default: %(default)s)")
    args = parser.parse_args(argv)
    scenes = json.loads(args.data.read_text())["scenes"]
    for stem, entry in scenes.items():
        print("\n".join(scene_table(stem, entry)))
    print("\n".join(preset_table(scenes)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
