"""The paper's studies as sweeps (Fig. 2c, Fig. 3): run them, then write their numbers as JSON.

The sweep files are ``scenes/sweeps/paper/*.toml``, run in this order (the longest first):

- ``fig3_micro_<p>_<law>``: micro Nx = 16 against the macro model (model = "both") on the
  gradient scenes of p = E, nu, P1, tau, eta, to t = 60 (Fig. 3, columns 2-3);
- ``fig2c_<law>``, ``fig2c_l_<law>``: +/- 5% around the reference (Fig. 2c);
- ``fig3_scan_<law>``, ``fig3_scan_l_<law>``: homogeneous scans over the docs/model.md section 9
  intervals (Fig. 3, first column).

Each is ``nice -n 10 plantgrowth sweep FILE -o RESULTS/<name>`` in a subprocess, one at a time; a
sweep whose sweep.csv says every run is done is skipped (an unfinished one resumes natively).
Then the numbers go to ``--json`` (default ``benchmarks/results/paper_studies.json``):

- sensitivities phi = (x0 / X(x0)) dX/dx [sensitivity] of X = the mean of tr G (sweep.csv's
  ``growth_rate_area``) at t_max, by central differences, next to the same central difference of
  the exact homogeneous rate;
- the scans: X at t_max against the exact homogeneous rate, and their largest relative difference;
- micro against macro per gradient scene: mean tr G, area and area growth area(t_max) / area(0)
  at t_max, their relative differences, and the time series of mean tr G of both (for the plots).
  The two areas differ at t = 0 already (the micro area encloses the outer walls' bulges under
  turgor), so the area growth is the fairer comparison.

Exact homogeneous rate (docs/model.md section 4; tests/test_macro_exact_solutions.py): homogeneous
parameters, constant P1 and no loads give ``sigma_hom = (1 - phi_w) P1 I`` for any cell and any Fg,
and the wall-averaged strain is the wall compliance times the wall-averaged stress, so G is
isotropic and constant in time: tr G = 2 eta [c (1 - phi_w) / phi_w P1 - tau]_+ (clipped to M per
component), c = 1 (stress law), (1 - nu) / E (strain law); phi_w is the cell's exact wall fraction.

    python scripts/studies/paper_studies.py [--results results/paper_studies] [--only NAME ...]
        [--analyse-only]
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import plantgrowth as pg
from plantgrowth.base.machine import machine_description
from plantgrowth.studies.sweep_file import Run, Sweep, load_sweep

ROOT = Path(__file__).resolve().parents[2]
SWEEPS_DIR = ROOT / "scenes" / "sweeps" / "paper"
LAWS = ("strain", "stress")
GRADIENTS = ("E", "nu", "P1", "tau", "eta")
L_KEYS = ("cell.l1", "cell.l2")
EXACT_TOLERANCE = 1e-9
"""Largest accepted relative difference of a homogeneous run's rate from the exact one: the
run's rate is exact up to the LU round-off of the macro and cell solves (1e-9 is the bound of
tests/test_macro_exact_solutions.py; measured there ~1e-11)."""


def sweep_names() -> list[str]:
    """The sweep files' stems in run order: the long micro-macro runs first."""
    micro = [f"fig3_micro_{p}_{law}" for p in GRADIENTS for law in LAWS]
    macro = [f"{kind}_{law}" for kind in ("fig2c", "fig2c_l", "fig3_scan", "fig3_scan_l")
             for law in LAWS]  # fmt: skip
    return micro + macro


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--results", type=Path, default=ROOT / "results" / "paper_studies", help="sweep outputs")
    add("--json", type=Path, default=ROOT / "benchmarks" / "results" / "paper_studies.json")
    add("--only", nargs="+", choices=sweep_names(), default=None, help="run these sweeps only")
    add("--analyse-only", action="store_true", help="run nothing; write the JSON from results")
    add("--nice", type=int, default=10, help="niceness of the sweeps (default 10)")
    add("--plantgrowth", default=str(Path(sys.executable).with_name("plantgrowth")))
    return parser.parse_args(argv)


# --- running --------------------------------------------------------------------------------------


def read_table(outdir: Path) -> list[dict[str, str]]:
    """The rows of ``outdir/sweep.csv`` ([] if there is none)."""
    try:
        with open(outdir / "sweep.csv", newline="") as f:
            return list(csv.DictReader(f))
    except FileNotFoundError:
        return []


def is_done(sweep: Sweep, outdir: Path) -> bool:
    rows = read_table(outdir)
    return len(rows) == len(sweep.runs) and all(row["status"] == "done" for row in rows)


def run_sweeps(args: argparse.Namespace) -> int:
    """Each sweep of ``--only`` (default all) in turn; 0 if every one ended with exit code 0."""
    failed = []
    for name in args.only or sweep_names():
        path, outdir = SWEEPS_DIR / f"{name}.toml", args.results / name
        if is_done(load_sweep(path), outdir):
            print(f"{name:24s} done earlier, skipped", flush=True)
            continue
        cmd = [
            "nice",
            "-n",
            str(args.nice),
            args.plantgrowth,
            "sweep",
            str(path),
            "-o",
            str(outdir),
        ]
        print(f"{name:24s} {shlex.join(cmd)}", flush=True)
        start = time.perf_counter()
        rc = subprocess.call(cmd, stdout=subprocess.DEVNULL)
        print(f"{name:24s} exit code {rc}, {time.perf_counter() - start:.0f} s", flush=True)
        if rc:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)} (see their sweep.csv); run again to retry")
    return 1 if failed else 0


# --- the numbers ----------------------------------------------------------------------------------


def exact_rate(scene: pg.Scene) -> float:
    """Exact mean tr G of a homogeneous scene (module docstring; docs/model.md section 4)."""
    g, m = scene.growth, scene.material
    phi_w = scene.cell.at(0.0, 0.0).phi_w
    c = 1.0 if g.law == "stress" else (1.0 - m.nu.start) / m.E.start
    driving = c * (1.0 - phi_w) / phi_w * scene.P1.start - g.tau.start
    return 2.0 * min(g.clamp, g.eta.start * max(driving, 0.0))


def sensitivity(x: tuple[float, float, float], X: tuple[float, float, float]) -> float:
    """[sensitivity] phi = (x0 / X(x0)) dX/dx at the middle point x0 of (x-, x0, x+), dX/dx by
    the central difference (X+ - X-) / (x+ - x-)."""
    return x[1] / X[1] * (X[2] - X[0]) / (x[2] - x[0])


def relative(a: float, b: float) -> float:
    return abs(a - b) / abs(b) if b else abs(a - b)


def finished(sweep: Sweep, rows: list[dict[str, str]]) -> Iterator[tuple[Run, dict[str, str]]]:
    """(run, its sweep.csv row) of every done run."""
    by_name = {row["run"]: row for row in rows}
    for run in sweep.runs:
        row = by_name.get(run.name)
        if row is not None and row["status"] == "done":
            yield run, row


def points(sweep: Sweep, rows: list[dict[str, str]]) -> dict[str, list[tuple]]:
    """``{parameter: [(x, X at t_max, exact X, row), ...]}`` sorted by x, from the finished runs:
    one-at-a-time keys by their key, and ``l`` from a l1 x l2 grid's diagonal."""
    out: dict[str, list[tuple]] = {}
    for run, row in finished(sweep, rows):
        if set(run.values) == set(L_KEYS):
            if run.values[L_KEYS[0]] != run.values[L_KEYS[1]]:
                continue
            key, x = "l", run.values[L_KEYS[0]]
        else:
            (key, x), = run.values.items()  # fmt: skip
        rate = float(row["growth_rate_area"])
        out.setdefault(key, []).append((float(x), rate, exact_rate(run.scene), row))
    return {key: sorted(values, key=lambda p: p[0]) for key, values in out.items()}


def grid_offdiagonal(sweep: Sweep, rows: list[dict[str, str]]) -> float | None:
    """Largest relative difference from the exact rate over the elongated cells (l1 != l2)."""
    diffs = [
        relative(float(row["growth_rate_area"]), exact_rate(run.scene))
        for run, row in finished(sweep, rows)
        if len(set(run.values.values())) > 1
    ]
    return max(diffs) if diffs else None


def fig2c_numbers(results: Path) -> dict:
    out: dict = {}
    for law in LAWS:
        entries = {}
        for name in (f"fig2c_{law}", f"fig2c_l_{law}"):
            sweep = load_sweep(SWEEPS_DIR / f"{name}.toml")
            for key, values in points(sweep, read_table(results / name)).items():
                if len(values) != 3:
                    continue  # unfinished
                x, X, exact, _ = zip(*values, strict=True)
                entries[key] = {
                    "x": list(x), "rate": list(X), "phi": sensitivity(x, X),
                    "phi_exact": sensitivity(x, exact),
                }  # fmt: skip
        out[law] = entries
    return out


def scan_numbers(results: Path) -> dict:
    out: dict = {}
    for law in LAWS:
        entries = {}
        for name in (f"fig3_scan_{law}", f"fig3_scan_l_{law}"):
            sweep, rows = load_sweep(SWEEPS_DIR / f"{name}.toml"), read_table(results / name)
            for key, values in points(sweep, rows).items():
                x, X, exact, table = zip(*values, strict=True)
                entries[key] = {
                    "x": list(x), "rate": list(X), "exact": list(exact),
                    "t": [float(r["t"]) for r in table],
                    "max_relative_difference": max(map(relative, X, exact)),
                }  # fmt: skip
            if rows and (off := grid_offdiagonal(sweep, rows)) is not None:
                entries["l1_ne_l2_max_relative_difference"] = off
        out[law] = entries
    return out


def summary_series(path: Path) -> dict[str, list[float]]:
    with open(path, newline="") as f:
        rows = [row for row in csv.DictReader(f) if row.get("step")]
    return {k: [float(row[k]) for row in rows] for k in ("t", "area", "growth_rate_area")}


def micro_numbers(results: Path) -> dict:
    """Per gradient scene (finished runs only): both sides at their last common time."""
    out: dict = {}
    for p in GRADIENTS:
        for law in LAWS:
            name = f"fig3_micro_{p}_{law}"
            rows = read_table(results / name)
            if not rows or rows[0]["status"] != "done":
                continue
            run_dir = results / name / "run_0000"
            macro = summary_series(run_dir / "macro" / "summary.csv")
            micro = summary_series(run_dir / "micro" / "summary.csv")
            growth = {side: series["area"][-1] / series["area"][0]
                      for side, series in (("macro", macro), ("micro", micro))}  # fmt: skip
            out[name] = {
                "parameter": p, "law": law, "t": macro["t"][-1],
                "rate_macro": macro["growth_rate_area"][-1],
                "rate_micro": micro["growth_rate_area"][-1],
                "rate_relative_difference": relative(micro["growth_rate_area"][-1],
                                                     macro["growth_rate_area"][-1]),
                "area_macro": macro["area"][-1], "area_micro": micro["area"][-1],
                "area_relative_difference": relative(micro["area"][-1], macro["area"][-1]),
                "area_growth_macro": growth["macro"], "area_growth_micro": growth["micro"],
                "area_growth_relative_difference": relative(growth["micro"], growth["macro"]),
                "seconds": float(rows[0]["seconds"]),
                "series": {"t": macro["t"], "rate_macro": macro["growth_rate_area"],
                           "rate_micro": micro["growth_rate_area"]},
            }  # fmt: skip
    return out


def sweep_seconds(results: Path) -> dict[str, float]:
    """Seconds per sweep: the sum of its runs' ``seconds`` (sweep.csv)."""
    return {name: round(sum(float(r["seconds"] or 0) for r in rows), 1)
            for name in sweep_names() if (rows := read_table(results / name))}  # fmt: skip


def write_json(results: Path, path: Path) -> dict:
    scans = scan_numbers(results)
    worst = [v["max_relative_difference"] for law in scans.values() for v in law.values()
             if isinstance(v, dict)]  # fmt: skip
    data = {
        "command": "python scripts/studies/paper_studies.py",
        "machine": machine_description(),
        "measure": "X = mean tr G over the tissue (reference-area weights), sweep.csv's "
        "growth_rate_area, at t_max",
        "exact_tolerance": EXACT_TOLERANCE,
        "scans_max_relative_difference": max(worst) if worst else None,
        "fig2c": fig2c_numbers(results),
        "fig3_scans": scans,
        "fig3_micro_macro": micro_numbers(results),
        "sweep_seconds": sweep_seconds(results),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {path}")
    return data


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    code = 0 if args.analyse_only else run_sweeps(args)
    write_json(args.results, args.json)
    return code


if __name__ == "__main__":
    sys.exit(main())
