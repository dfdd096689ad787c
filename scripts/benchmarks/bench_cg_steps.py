"""CG iterations per step of the macro solve, and what in the surrogate moves them (issue 33).

Runs a scene with the macro solve forced to CG (``solver.macro = "iterative"``), the cell cache
off unless ``--cache`` (every lattice solve shows) and PETSc's true-residual monitor on the macro
CG. Per step: CG iterations, the initial relative residual ``r0 = |b - A x0| / |b|`` of the
solution history's guess x0 (CG's iterations are about ``log(r0 / rtol) / log(1 / rho)``, rho
about 0.5 here), and the cell solves. Variants, each run in its own process:

- ``bilinear`` and ``c1``: the scene with ``accuracy.cell_interpolant`` set to that value (the
  surrogate as the run has it; c1 is docs/surrogate_c1.md's, refinements blended in);

and diagnostics that this script applies by patching the bilinear surrogate before the run:

- ``prebuilt``: every square of a finished run's lattice (``--squares-from``: its state.h5, last
  step; default: the ``bilinear`` variant's run) built before step 0, so nothing is refined during
  the run: the jumps of refinement are gone, the interpolant's kinks (C0, piecewise bilinear)
  stay;
- ``smooth``: the surrogate's answer at s = 0 scaled by ``1 + 3 s1 + 2 s2 + 30 s1^2``, a smooth
  stand-in with no lattice (not the physics): what CG needs when every tensor moves smoothly;
- ``cubic``: the values at the points of a finished run's lattice (as ``prebuilt``) fitted by one
  cubic polynomial in (s1, s2) per table (least squares; its largest misfit at the points is
  logged): smooth, with the real tensors' dependence on s;
- ``lookahead``: a prototype of look-ahead refinement (issue 33's idea (a)): each query also
  asks at ``s_n + K (s_n - s_{n-1})`` (K = ``--ahead``), and the points only these extrapolated
  queries asked for are blended in over K steps (smoothstep weight); no resume state and no
  accuracy guard for a query that reaches a square before its blend ends.

``--log`` parses a finished run's log instead (CG iterations and cell solves; no r0). Writes
``--out`` (JSON) with the machine and the load average.

    python scripts/benchmarks/bench_cg_steps.py --variants bilinear c1 prebuilt smooth lookahead \\
        --squares-from /tmp/run/state.h5 [--scene scenes/gradient_E_strain.toml] [--ranks 1]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "scenes" / "gradient_E_strain.toml"
MONITOR = "-plantgrowth_macro_ksp_monitor_true_residual"
MPI_ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_rmaps_base_oversubscribe": "1", "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
}  # fmt: skip
FROM_STEP = 16
"""Issue 33: at most 6 CG iterations per step from step 16 on."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", type=Path, default=SCENE)
    variants = ["bilinear", "c1", "prebuilt", "smooth", "cubic", "lookahead"]
    parser.add_argument("--variants", nargs="+", default=["bilinear", "c1"], choices=variants)
    parser.add_argument("--squares-from", type=Path, help="state.h5 of a finished run (prebuilt)")
    parser.add_argument("--ahead", type=int, default=12, help="look-ahead and blend steps K")
    parser.add_argument("--ranks", type=int, default=1)
    parser.add_argument("--t-max", type=float, help="time.t_max (default: the scene's)")
    parser.add_argument("--log", type=Path, help="parse this run log instead of running")
    parser.add_argument("--cache", action="store_true", help="keep the cell cache on")
    parser.add_argument("--keep", type=Path, help="keep the runs' directories under this one")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results/cg_steps.json")
    parser.add_argument("--child", help=argparse.SUPPRESS)  # inside the run's process
    parser.add_argument("-o", dest="outdir", type=Path, help=argparse.SUPPRESS)
    return parser.parse_args(argv)


def parse_log(text: str) -> list[dict]:
    """Per step: CG iterations, r0 (None without the monitor's lines), cell solves and the
    largest relative difference so far of the run's exact checks of the interpolated tensors
    (from the run's output, or its run.log)."""
    steps, first, check = [], None, None
    for line in text.splitlines():
        line = re.sub(r"^\d{4}-\d\d-\d\d [\d:,]+ ", "", line)  # run.log's time stamps
        monitor = re.search(r"^\s*0 KSP .*\|\|r\(i\)\|\|/\|\|b\|\| (\S+)", line)
        if monitor and first is None:
            first = float(monitor[1])  # a repeated solve (rebuilt preconditioner): the first
        cg = re.match(r"macro solve: (\d+) CG iterations", line)
        if cg:
            iterations = int(cg[1])
        checked = re.search(r"largest so far (\S+),", line)
        if checked:
            check = float(checked[1])
        step = re.match(r"step (\d+)/\d+ .*cell solves (\d+)", line)
        if step:
            steps.append({"step": int(step[1]), "cg": iterations, "r0": first,
                          "cell_solves": int(step[2]), "largest_check": check})  # fmt: skip
            first = None
    return steps


def digest(steps: list[dict]) -> dict:
    """The issue's test (CG <= 6 from step 16 on) and the totals."""
    late = [s for s in steps if s["step"] >= FROM_STEP]
    return {
        "cg_per_step": [s["cg"] for s in steps],
        "max_cg_from_step_16": max((s["cg"] for s in late), default=None),
        "steps_over_6_from_step_16": [s["step"] for s in late if s["cg"] > 6],
        "total_cg": sum(s["cg"] for s in steps),
        "total_cell_solves": sum(s["cell_solves"] for s in steps),
        "refining_steps": [s["step"] for s in steps if s["cell_solves"]],
        "largest_check": steps[-1]["largest_check"] if steps else None,
    }


def with_interpolant(text: str, interpolant: str) -> str:
    """A scene's text with ``accuracy.cell_interpolant`` set (the scene has an [accuracy])."""
    line = f'cell_interpolant = "{interpolant}"'
    text, n = re.subn(r"(?m)^cell_interpolant = .*$", line, text)
    if not n:
        text, n = re.subn(r"(?m)^\[accuracy\]\n", f"[accuracy]\n{line}\n", text, count=1)
    assert n == 1, "no [accuracy] table"
    return text


def forced_cg(scene: Path, t_max: float | None) -> str:
    """The scene's text with ``solver.macro = "iterative"`` (and ``time.t_max``)."""
    text = scene.read_text()
    if t_max is not None:
        text, n = re.subn(r"(?m)^t_max = .*$", f"t_max = {t_max!r}", text)
        assert n == 1, f"{scene}: no single t_max line"
    if re.search(r"(?m)^\[solver\]", text):
        return re.sub(r"(?m)^\[solver\]\n", '[solver]\nmacro = "iterative"\n', text, count=1)
    return text + '\n[solver]\nmacro = "iterative"\n'


def final_area(outdir: Path) -> float:
    lines = (outdir / "summary.csv").read_text().splitlines()
    header = lines[0].split(",")
    return float(lines[-1].split(",")[header.index("area")])


def run_variant(args: argparse.Namespace, variant: str, scene: Path, outdir: Path) -> dict:
    if variant in ("bilinear", "c1"):
        own = scene.with_name(f"scene_{variant}.toml")
        own.write_text(with_interpolant(scene.read_text(), variant))
        scene = own
    else:  # the diagnostics patch the bilinear surrogate
        own = scene.with_name("scene_patched.toml")
        own.write_text(with_interpolant(scene.read_text(), "bilinear"))
        scene = own
    command = [sys.executable, __file__, "--child", variant, "--ahead", str(args.ahead),
               "--scene", str(scene), "-o", str(outdir)]  # fmt: skip
    if variant in ("prebuilt", "cubic"):  # default: the bilinear variant's lattice at its end
        squares = args.squares_from or outdir.parent / "bilinear" / "state.h5"
        command += ["--squares-from", str(squares)]
    if args.ranks > 1:
        command = ["/usr/bin/mpirun", "-n", str(args.ranks), *command]
    env = dict(os.environ, PETSC_OPTIONS=MONITOR, **MPI_ENV)
    if not args.cache:
        env["PLANTGROWTH_CACHE_DIR"] = "off"
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    steps = parse_log(done.stdout + done.stderr)
    return {"steps": steps, "final_area": final_area(outdir)} | digest(steps)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.child:
        return child(args)
    from plantgrowth.base.machine import machine_description

    result = {
        "description": __doc__.split("\n\n")[0],
        "command": "python scripts/benchmarks/bench_cg_steps.py " + " ".join(sys.argv[1:]),
        "scene": str(args.scene),
        "ranks": args.ranks,
        "machine": machine_description(),
        "load_average_before": os.getloadavg(),
        "variants": {},
    }
    if args.log:
        result["log"] = str(args.log)
        steps = parse_log(args.log.read_text())
        result["variants"]["log"] = {"steps": steps} | digest(steps)
    else:
        result["ahead"] = args.ahead
        result["t_max"] = args.t_max
        result["squares_from"] = str(args.squares_from)
        with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-cg-") as tmp:
            root = args.keep or Path(tmp)
            scene = Path(tmp) / "scene.toml"
            scene.write_text(forced_cg(args.scene, args.t_max))
            for variant in args.variants:
                record = run_variant(args, variant, scene, root / variant)
                result["variants"][variant] = record
                print(variant, {k: v for k, v in record.items() if k != "steps"}, flush=True)
    result["load_average_after"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


def child(args: argparse.Namespace) -> int:
    """Inside the run's process: patch the surrogate for a diagnostic variant, then run the
    scene."""
    import plantgrowth.unitcell.surrogate as sg

    original = sg.LatticeSurrogate._refine
    if args.child in ("prebuilt", "cubic"):
        import h5py

        with h5py.File(args.squares_from, "r") as f:
            rows = f[sorted(f)[-1]]["surrogate_squares"][...]
    if args.child == "cubic":
        sg.LatticeSurrogate._refine = _cubic(original, rows)
    elif args.child == "prebuilt":

        def prebuilt(self, *a, **k):
            if not getattr(self, "_prebuilt", False):
                self._prebuilt = True
                self.restore(rows)
            return original(self, *a, **k)

        sg.LatticeSurrogate._refine = prebuilt
    elif args.child == "smooth":

        def smooth(self, tables, which, s, tolerance):
            s = np.asarray(s, dtype=float).reshape(len(which), 2)
            answer = original(self, tables, which, np.zeros_like(s), tolerance)
            scale = 1 + 3 * s[:, 0] + 2 * s[:, 1] + 30 * s[:, 0] ** 2
            return sg.Answer(answer.values * scale[:, None], answer.estimates,
                             answer.interpolated, answer.solves)  # fmt: skip

        sg.LatticeSurrogate._refine = smooth
    elif args.child == "lookahead":
        sg.LatticeSurrogate._refine = _lookahead(original, args.ahead)
    from plantgrowth.cli import main as cli

    sys.argv = ["plantgrowth", "run", str(args.scene), "-o", str(args.outdir)]
    return cli()


def _cubic_terms(s: np.ndarray) -> np.ndarray:
    a, b = s[:, 0], s[:, 1]
    return np.column_stack([a**0, a, b, a * a, a * b, b * b, a**3, a * a * b, a * b * b, b**3])


def _cubic(original, rows: np.ndarray):
    """The ``cubic`` variant's ``_refine`` (module docstring)."""
    import logging

    import plantgrowth.unitcell.lattice as lat
    import plantgrowth.unitcell.surrogate as sg

    def refine(self, tables, which, s, tolerance):
        if not hasattr(self, "_cubic"):
            self.restore(rows)
            self._cubic = {}
            names = {v: k for k, v in self._table_ids.items()}
            for table_id, table in names.items():
                keys = [k for k in self._surplus if k >> 42 == table_id]
                points = np.array(
                    [[((k >> 21) & lat.LOW) - lat.OFFSET, (k & lat.LOW) - lat.OFFSET] for k in keys]
                )  # fmt: skip
                exact = np.array([self.values[table, tuple(p)] for p in points.tolist()])
                terms = _cubic_terms(points * (sg.H0 / sg.STEP))
                self._cubic[table] = np.linalg.lstsq(terms, exact, rcond=None)[0]
                misfit = self.relative_difference(terms @ self._cubic[table], exact).max()
                logging.getLogger("plantgrowth").info(
                    "cubic fit of table %s: %d points, largest misfit %.2g", table, len(keys),
                    misfit,
                )  # fmt: skip
        which = np.asarray(which, dtype=np.int64)
        s = np.asarray(s, dtype=float).reshape(len(which), 2)
        answer = original(self, tables, which, np.zeros_like(s), tolerance)
        values = np.empty_like(answer.values)
        for k, table in enumerate(tables):
            asked = which == k
            values[asked] = _cubic_terms(s[asked]) @ self._cubic[tuple(table)]
        return sg.Answer(values, answer.estimates, answer.interpolated, answer.solves)

    return refine


def _lookahead(original, ahead: int):
    """The ``lookahead`` variant's ``_refine`` (module docstring)."""
    import plantgrowth.unitcell.lattice as lat
    import plantgrowth.unitcell.surrogate as sg

    def refine(self, tables, which, s, tolerance):
        if not hasattr(self, "_ahead"):
            self._ahead = {"last": {}, "blend": {}, "calls": 0}
        memory = self._ahead
        memory["calls"] += 1
        which = np.asarray(which, dtype=np.int64)
        s = np.asarray(s, dtype=float).reshape(len(which), 2)
        answer = original(self, tables, which, s, tolerance)  # the asked queries: no blend
        name = (tuple(tables), which.tobytes())
        previous = memory["last"].get(name)
        memory["last"][name] = s.copy()
        values, solves = answer.values, answer.solves
        if previous is not None:
            moved = np.flatnonzero((s != previous).any(axis=1))
            tol = np.full(len(which), self.tolerance) if tolerance is None else tolerance
            before = set(self._surplus)
            more = original(
                self, tables, np.concatenate([which, which[moved]]),
                np.concatenate([s, s[moved] + ahead * (s[moved] - previous[moved])]),
                np.concatenate([tol, np.asarray(tol)[moved]]),
            )  # fmt: skip
            for key in set(self._surplus) - before:
                memory["blend"][key] = memory["calls"]
            values, solves = more.values[: len(which)].copy(), solves + more.solves
        ids = self._numbers(tables)[which]
        for key, start in list(memory["blend"].items()):
            x = (memory["calls"] - start + 1) / (ahead + 1)
            if x >= 1.0:
                del memory["blend"][key]
                continue
            point = np.array([((key >> 21) & lat.LOW) - lat.OFFSET, (key & lat.LOW) - lat.OFFSET])
            level = next(k for k in range(sg.MAX_LEVEL + 1) if not (point % (sg.STEP >> k)).any())
            d = np.abs(s - point * (sg.H0 / sg.STEP)) / (sg.H0 / 2.0**level)
            hat = np.clip(1 - d[:, 0], 0, None) * np.clip(1 - d[:, 1], 0, None)
            hat[ids != key >> 42] = 0.0
            hit = hat > 0
            weight = x * x * (3 - 2 * x)
            values[hit] -= (1 - weight) * hat[hit, None] * self._surplus[key][None, :]
        return sg.Answer(values, answer.estimates, answer.interpolated, solves)

    return refine


if __name__ == "__main__":
    raise SystemExit(main())
