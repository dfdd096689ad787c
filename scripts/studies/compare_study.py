"""Micro-macro comparison study (docs/model.md sections 7-8, the paper's Fig. 2 d-j).

Two kinds of runs of ``plantgrowth compare``, each on a scene derived from
``scenes/reference_<law>.toml`` with ``[cell] w`` and ``[micro] resolution`` set:

- error study (Fig. 2 g-h): every w/l2 in ``--widths`` and law in ``--laws``, first step only,
  ``--nx`` (default 4 8 12 16) at ``--resolution`` (default 2);
- full-time runs (Fig. 2 d-f, i-j): w/l2 = ``--full-width`` (0.05, the reference), both laws,
  ``--full-nx`` (default 4 8 16) up to the scene's t_max (60) at ``--full-resolution``;
- with ``--gradient SCENE`` (a file in ``--scenes``, e.g. gradient_P1_strain), one more full
  run of that scene at ``--gradient-nx`` (default 8) up to ``--gradient-t-max`` (default 200).

``--kinematics finite`` (docs/model.md section 10) sets the scenes' kinematics; its default roots
are then ``results/compare_study_finite`` and ``benchmarks/results/compare_finite``.

Raw runs (fields.h5/.xdmf, large) go to ``--raw`` (default ``results/compare_study/<case>``,
git-ignored); ``compare.csv`` and every ``summary.csv`` are copied to
``--bench`` (default ``benchmarks/results/compare/<case>/``) with ``index.json``: the machine
description, the cases, their command lines and wall times.

    python scripts/studies/compare_study.py [--jobs 2] [--skip-existing] [--only error|full]
        [--kinematics finite] [--gradient gradient_P1_strain]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import plantgrowth as pg
from plantgrowth.base.machine import machine_description

LAWS = ("strain", "stress")
WIDTHS = (0.05, 0.1, 0.2)


@dataclass(frozen=True)
class Case:
    """One ``plantgrowth compare`` run of ``<source>.toml`` (``reference_<law>`` unless a
    gradient scene), t_max None: the scene's."""

    name: str
    kind: str  # "error" (first step only) or "full" (up to t_max)
    law: str
    w: float
    nx: tuple[int, ...]
    resolution: int
    kinematics: str = "linear"
    source: str = ""
    t_max: float | None = None

    @property
    def first_step_only(self) -> bool:
        return self.kind == "error"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--scenes", type=Path, default=Path("scenes"), help="directory of reference_<law>.toml")
    add("--raw", type=Path, default=None, help="raw run root (default: results/compare_study)")
    add("--bench", type=Path, default=None, help="CSV/JSON root (benchmarks/results/compare)")
    add("--kinematics", choices=("linear", "finite"), default="linear",
        help="the scenes' kinematics (docs/model.md section 10)")  # fmt: skip
    add("--gradient", default=None, help="a gradient scene's name in --scenes (full run)")
    add("--gradient-nx", type=int, default=8, help="Nx of the gradient run")
    add("--gradient-t-max", type=float, default=200.0, help="t_max of the gradient run")
    add("--widths", type=float, nargs="+", default=list(WIDTHS), help="w/l2 of the error study")
    add("--laws", nargs="+", choices=LAWS, default=list(LAWS), help="growth laws")
    add("--nx", type=int, nargs="+", default=[4, 8, 12, 16], help="Nx of the error study")
    add("--resolution", type=int, default=2, help="micro resolution of the error study")
    add("--full-width", type=float, default=0.05, help="w/l2 of the full-time runs")
    add("--full-nx", type=int, nargs="+", default=[4, 8, 16], help="Nx of the full-time runs")
    add(
        "--full-resolution",
        type=int,
        default=2,
        help="micro resolution of the full-time runs (1 cuts the Nx = 16 cost about threefold "
        "but is stiffer in bending than 2, itself ~2%% too stiff: STYLE.md)",
    )
    add("--only", choices=("error", "full"), default=None, help="run one kind of case only")
    add("--jobs", type=int, default=1, help="compares at a time (default 1; 2 cores here)")
    add("--skip-existing", action="store_true", help="do not rerun complete raw results")
    add("--plantgrowth", default=None, help="the command (default: next to this python)")
    args = parser.parse_args(argv)
    suffix = "" if args.kinematics == "linear" else f"_{args.kinematics}"
    args.raw = args.raw or Path(f"results/compare_study{suffix}")
    args.bench = args.bench or Path(f"benchmarks/results/compare{suffix}")
    return args


def make_cases(args: argparse.Namespace) -> list[Case]:
    """Full-time runs first: they are the longest, so they start at once under --jobs 2."""
    cases, kin = [], args.kinematics
    if args.only in (None, "full"):
        if args.gradient is not None:
            text = (args.scenes / f"{args.gradient}.toml").read_text()
            scene = tomllib.loads(text)
            t = args.gradient_t_max
            cases.append(Case(
                f"{args.gradient}_t{t:g}_nx{args.gradient_nx}", "full", scene["growth"]["law"],
                scene["cell"]["w"], (args.gradient_nx,), args.full_resolution, kin,
                args.gradient, t,
            ))  # fmt: skip
        for law in args.laws:
            w = args.full_width
            cases.append(Case(
                f"full_w{w:g}_{law}", "full", law, w, tuple(args.full_nx), args.full_resolution,
                kin, f"reference_{law}",
            ))  # fmt: skip
    if args.only in (None, "error"):
        for w in args.widths:
            for law in args.laws:
                cases.append(Case(
                    f"error_w{w:g}_{law}", "error", law, w, tuple(args.nx), args.resolution, kin,
                    f"reference_{law}",
                ))  # fmt: skip
    return cases


def _set_key(text: str, table: str, key: str, value: str) -> str:
    """Set ``key = value`` in ``[table]`` of a TOML text (comments kept); add what is missing."""
    lines = text.splitlines()
    header = re.compile(r"^\s*\[([^\]]+)\]")
    start = next((i for i, s in enumerate(lines) if (m := header.match(s)) and m[1] == table), None)
    if start is None:
        return text.rstrip("\n") + f"\n\n[{table}]\n{key} = {value}\n"
    end = next((i for i in range(start + 1, len(lines)) if header.match(lines[i])), len(lines))
    assignment = re.compile(rf"^(\s*{re.escape(key)}\s*=\s*)([^#]*?)(\s*(#.*)?)$")
    for i in range(start + 1, end):
        if m := assignment.match(lines[i]):
            lines[i] = f"{m[1]}{value}{m[3]}"
            return "\n".join(lines) + "\n"
    lines.insert(start + 1, f"{key} = {value}")
    return "\n".join(lines) + "\n"


def write_scene(case: Case, scenes: Path, path: Path) -> Path:
    """``scenes/<case.source>.toml`` with ``cell.w``, ``micro.resolution``, the kinematics and
    (if given) ``time.t_max`` set; checked by loading it back."""
    text = (scenes / f"{case.source}.toml").read_text()
    text = _set_key(text, "cell", "w", repr(case.w))
    text = _set_key(text, "micro", "resolution", str(case.resolution))
    if case.t_max is not None:
        text = _set_key(text, "time", "t_max", repr(case.t_max))
    if case.kinematics != "linear":  # a top-level key: before the first table
        text = f'kinematics = "{case.kinematics}"\n' + text
    data = tomllib.loads(text)
    assert data["cell"]["w"] == case.w and data["micro"]["resolution"] == case.resolution
    assert data.get("kinematics", "linear") == case.kinematics
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    pg.load_scene(path).check_micro()  # bad input fails here, before any run
    return path


def command_line(command: str, case: Case, scene: Path, out: Path) -> list[str]:
    cmd = [command, "compare", str(scene), "--nx", *map(str, case.nx), "-o", str(out)]
    return cmd + ["--overwrite"] + (["--first-step-only"] if case.first_step_only else [])


def is_complete(case: Case, scene: Path, out: Path) -> bool:
    """True if ``out`` ran this case (its resolved ``scene.toml`` has the same law, w and micro
    resolution), ``out/compare.csv`` has every Nx and, for full runs, each micro summary reaches
    the scene's last step."""
    table, resolved = out / "compare.csv", out / "scene.toml"
    if not (table.is_file() and resolved.is_file()):
        return False
    ran = tomllib.loads(resolved.read_text())
    same = (ran["growth"]["law"], ran["cell"]["w"], ran["micro"]["resolution"],
            ran.get("kinematics", "linear"))  # fmt: skip
    if same != (case.law, case.w, case.resolution, case.kinematics):
        return False
    with open(table, newline="") as f:
        done = {int(float(row["nx"])) for row in csv.DictReader(f)}
    if not set(case.nx) <= done:
        return False
    if case.first_step_only:
        return True
    last = pg.load_scene(scene).time.n_steps
    for nx in case.nx:
        summary = out / f"nx{nx}" / "micro" / "summary.csv"
        if not summary.is_file():
            return False
        with open(summary, newline="") as f:
            steps = [int(row["step"]) for row in csv.DictReader(f)]
        if not steps or max(steps) < last:
            return False
    return True


def run_case(cmd: list[str], out: Path, env: dict[str, str]) -> tuple[int, float]:
    """Run one compare, its output into ``out/stdout.txt``. Returns (exit code, seconds)."""
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with open(out / "stdout.txt", "w") as log:
        rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    return rc, time.perf_counter() - start


def copy_results(case: Case, raw: Path, bench: Path) -> list[str]:
    """compare.csv and the summary.csv files (small) into ``bench``; returns what was copied."""
    copied = []
    for source in [raw / "compare.csv", raw / "scene.toml"] + sorted(raw.glob("nx*/*/summary.csv")):
        if source.is_file():
            target = bench / source.relative_to(raw)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)
            copied.append(str(source.relative_to(raw)))
    return copied


def _error_line(stdout: Path) -> str:
    """The ``plantgrowth: ...`` error line of a failed compare (its last such line)."""
    lines = [s for s in stdout.read_text().splitlines() if s.startswith("plantgrowth:")]
    return lines[-1] if lines else "no error line in stdout.txt"


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    command = args.plantgrowth or str(Path(sys.executable).with_name("plantgrowth"))
    if shutil.which(command) is None:
        print(f"{command} is not an executable; pass --plantgrowth", file=sys.stderr)
        return 2
    env = dict(os.environ)
    if args.jobs > 1:  # two serial processes on two cores: no threaded BLAS on top
        env.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    index_path = args.bench / "index.json"
    index = json.loads(index_path.read_text()) if index_path.is_file() else {"cases": {}}
    jobs = []
    for case in make_cases(args):
        scene = write_scene(case, args.scenes, args.raw / "scenes" / f"{case.name}.toml")
        out = args.raw / case.name
        cmd = command_line(command, case, scene, out)
        if args.skip_existing and is_complete(case, scene, out):
            print(f"{case.name:22s} complete, skipped")
            jobs.append((case, cmd, out, None))
        else:
            jobs.append((case, cmd, out, "run"))

    def work(job):
        case, cmd, out, todo = job
        if todo is None:
            return case, cmd, out, 0, None
        print(f"{case.name:22s} started: {' '.join(cmd)}", flush=True)
        rc, seconds = run_case(cmd, out, env)
        state = "ok" if rc == 0 else f"FAILED ({rc}), see {out / 'stdout.txt'}"
        print(f"{case.name:22s} {state} {seconds:7.1f} s", flush=True)
        return case, cmd, out, rc, seconds

    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = list(pool.map(work, jobs))
    wall = time.perf_counter() - start

    failed = []
    for case, cmd, out, rc, seconds in results:
        if rc != 0:  # recorded too: the summaries of the steps completed, and the error
            failed.append(case.name)
        bench = args.bench / case.name
        entry = index["cases"].get(case.name, {}) if seconds is None else {}
        entry.update(asdict(case))
        entry.update(
            command=shlex.join([Path(cmd[0]).name, *cmd[1:]]),
            scene=(bench / "scene.toml").as_posix(),
            raw=out.as_posix(),
            files=copy_results(case, out, bench),
        )
        if seconds is not None:
            entry["wall_seconds"] = round(seconds, 1)
            entry["jobs"] = args.jobs
        entry["error"] = _error_line(out / "stdout.txt") if rc != 0 else None
        index["cases"][case.name] = entry
    index["machine"] = machine_description()
    index["study_command"] = shlex.join(
        ["python", "scripts/studies/compare_study.py", *(sys.argv[1:] if argv is None else argv)]
    )
    index["notes"] = (
        "Error cases: first step only (the errors are measured at t = 0, where Fg = I, so the "
        "displacement errors do not depend on the law). Full cases: up to t_max. `resolution` is "
        "the micro model's number of P2 elements across one cell's own wall. wall_seconds is the "
        "wall time of the whole compare (all Nx, macro and micro, set-up included) with `jobs` "
        "compares running at a time on this machine; seconds_macro/seconds_micro per Nx are in "
        "each compare.csv."
    )
    index["cases"] = dict(sorted(index["cases"].items()))
    args.bench.mkdir(parents=True, exist_ok=True)
    index_path.write_text(json.dumps(index, indent=2) + "\n")
    print(f"{len(results)} cases in {wall:.1f} s wall; failed: {failed or 0}; index: {index_path}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
