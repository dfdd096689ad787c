"""Run the 14 gradient scenes of the paper's Fig. 3 (columns 2-3) into ``results/gradients/``.

One run per parameter (E, nu, P1, tau, eta, w, l) and growth law (strain, stress):

    plantgrowth run scenes/gradient_<param>_<law>.toml -o results/gradients/gradient_<param>_<law>

A run whose ``summary.csv`` already reaches the scene's last step is skipped unless ``--force``.
``--jobs 2`` runs two scenes at a time (each a serial ``plantgrowth`` process). Prints the wall
time of each run; exits non-zero if any run failed.

    python scripts/studies/run_gradient_scenes.py [--jobs 2] [--force] [--only E,nu]
"""

from __future__ import annotations

import argparse
import csv
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import plantgrowth as pg
from plantgrowth.scene.toml_text import dict_to_toml

PARAMS = ("E", "nu", "P1", "tau", "eta", "w", "l")
LAWS = ("strain", "stress")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=Path, default=Path("scenes"), help="scene directory")
    parser.add_argument("--out", type=Path, default=Path("results/gradients"), help="result root")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time (default 1)")
    parser.add_argument("--force", action="store_true", help="rerun complete results too")
    parser.add_argument(
        "--only", type=lambda s: s.split(","), default=None, help="comma-separated params"
    )
    parser.add_argument("--plantgrowth", default=None, help="the command (default: on PATH)")
    return parser.parse_args(argv)


def is_complete(scene_path: Path, result_dir: Path) -> bool:
    """True if ``result_dir/summary.csv`` has the row of the scene's last step."""
    summary = result_dir / "summary.csv"
    if not summary.is_file():
        return False
    with open(summary, newline="") as f:
        steps = [int(row["step"]) for row in csv.DictReader(f) if row.get("step")]
    return bool(steps) and max(steps) >= pg.load_scene(scene_path).time.n_steps


def run_one(command: str, scene: Path, out: Path) -> tuple[str, int, float]:
    """Run one scene; its output goes to ``out/stdout.txt``. Returns (stem, exit code, seconds)."""
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with open(out / "stdout.txt", "w") as log:
        rc = subprocess.call(
            [command, "run", str(scene), "-o", str(out), "--overwrite"],
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    seconds = time.perf_counter() - start
    print(f"{scene.stem:24s} {'ok' if rc == 0 else f'FAILED ({rc})':10s} {seconds:7.1f} s")
    sys.stdout.flush()
    return scene.stem, rc, seconds


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    command = args.plantgrowth or shutil.which("plantgrowth")
    if command is None:
        print("plantgrowth is not on PATH; pass --plantgrowth", file=sys.stderr)
        return 2
    params = args.only or PARAMS
    jobs = [(args.scenes / f"gradient_{p}_{law}.toml", args.out) for p in params for law in LAWS]
    return run_all(command, jobs, args.jobs, args.force)


def run_all(command: str, jobs: list[tuple[Path, Path]], workers: int, force: bool) -> int:
    """Run each (scene, result root) into ``root/<scene stem>``, ``workers`` at a time, skipping
    complete results unless ``force``; prints the wall time; 1 if any run failed, else 0."""
    todo = []
    for scene, root in jobs:
        out = root / scene.stem
        if not force and is_complete(scene, out):
            print(f"{scene.stem:24s} complete, skipped (--force reruns it)")
            continue
        todo.append((scene, out))
    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        results = list(pool.map(lambda job: run_one(command, *job), todo))
    failed = [stem for stem, rc, _ in results if rc != 0]
    print(f"{len(results)} runs in {time.perf_counter() - start:.1f} s wall; failed: {failed or 0}")
    return 1 if failed else 0


def run_scene_data(data: dict, name: str, results: Path, force: bool) -> Path:
    """Runs scene data (a variant of a shipped scene) as ``name`` into ``results/<name>``, unless
    complete (``force`` reruns it), with this interpreter's ``plantgrowth``; returns that
    directory. Exits with a message naming the run if it fails."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / f"{name}.toml"
        scene.write_text(dict_to_toml(data))
        command = str(Path(sys.executable).with_name("plantgrowth"))
        if run_all(command, [(scene, results)], 1, force):
            raise SystemExit(f"the run {name} failed")
    return results / name


if __name__ == "__main__":
    sys.exit(main())
