"""Run every input of the malformed-input generator through the CLI; write a JSON report.

    python scripts/studies/fuzz_inputs.py [--seed 20240611] [--n 1200]
        -> benchmarks/results/bad_inputs.json

Each case runs in-process (``plantgrowth.cli.main``) in a fresh directory that is also the working
directory, with stdout/stderr captured; cases marked ``isolate`` (sizes that could take minutes if
accepted) run as subprocesses with a time limit. A case passes when it exits with code 2, prints
one ``plantgrowth: error:`` line naming the field, no traceback, and writes nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import json
import os
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

from plantgrowth.base.machine import machine_description
from plantgrowth.cli import main

REPO = Path(__file__).resolve().parents[2]
OUTPUT = REPO / "benchmarks" / "results" / "bad_inputs.json"
ISOLATED_TIMEOUT = 30.0  # seconds; a refused input takes ~1 s (interpreter and import)


def _load_generator():
    """tests/malformed_inputs.py by path (tests/ is not a package; sys.path stays as it is)."""
    spec = importlib.util.spec_from_file_location(
        "malformed_inputs", REPO / "tests" / "malformed_inputs.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["malformed_inputs"] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


def run_in_process(argv: list[str]) -> tuple[int | None, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except Exception as exc:  # a bug: recorded, the fuzzing goes on
            code = None
            print(f"Traceback (in-process): {type(exc).__name__}: {exc}", file=sys.stderr)
    return code, out.getvalue(), err.getvalue()


def main_fuzz(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=20240611)
    parser.add_argument("--n", type=int, default=1200)
    parser.add_argument("--output", type=Path, default=OUTPUT)
    args = parser.parse_args(argv)

    generator = _load_generator()
    cases = generator.generate(args.seed, args.n)
    by_class: dict[str, Counter] = defaultdict(Counter)
    by_code: Counter = Counter()
    failures = []
    start = time.perf_counter()
    home = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="plantgrowth_fuzz_") as tmp:
        for case in cases:
            directory = Path(tmp) / case.name
            directory.mkdir()
            call = case.materialize(directory)
            before = generator.snapshot(directory)
            t0 = time.perf_counter()
            os.chdir(directory)  # a default output directory would land here and be seen
            try:
                if case.isolate:
                    code, out, err = generator.run_cli(call, directory, ISOLATED_TIMEOUT)
                else:
                    code, out, err = run_in_process(call)
            finally:
                os.chdir(home)
            seconds = time.perf_counter() - t0
            found = generator.problems(case, directory, code, out, err, before)
            by_code[str(code)] += 1
            by_class[case.cls]["cases"] += 1
            by_class[case.cls]["ok" if not found else "failed"] += 1
            if found:
                failures.append({
                    "name": case.name, "class": case.cls, "argv": list(case.argv),
                    "files": {rel: (c if isinstance(c, str) else c.hex())[:2000]
                              for rel, c in case.files},
                    "expect": list(case.expect), "exit_code": code,
                    "stderr": err[-1500:], "problems": found, "seconds": round(seconds, 3),
                })  # fmt: skip
    total = time.perf_counter() - start
    report = {
        "seed": args.seed,
        "n": args.n,
        "passed": args.n - len(failures),
        "failed": len(failures),
        "seconds": round(total, 1),
        "exit_codes": dict(sorted(by_code.items())),
        "classes": {c: dict(v) for c, v in sorted(by_class.items())},
        "failures": failures,
        "machine": machine_description(),
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(report, indent=1) + "\n")
    print(f"{args.n} inputs, seed {args.seed}: {report['passed']} passed, {len(failures)} failed "
          f"in {total:.1f} s; exit codes {report['exit_codes']} -> {args.output}")  # fmt: skip
    for c, v in report["classes"].items():
        print(f"  {c:<18} {v.get('cases', 0):4d} cases  {v.get('failed', 0):3d} failed")
    return 0


if __name__ == "__main__":
    sys.exit(main_fuzz())
