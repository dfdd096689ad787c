"""Where convergence tests write their JSON results: the test's temporary directory, and
``benchmarks/results/`` when the environment sets PLANTGROWTH_WRITE_RESULTS (figure scripts
read them there)."""

from __future__ import annotations

import json
import os
from pathlib import Path

RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results"


def write_results(name: str, data: dict, tmp_dir: str | Path) -> None:
    """Write ``data`` as ``name`` (call on one rank)."""
    targets = [Path(tmp_dir) / name]
    if os.environ.get("PLANTGROWTH_WRITE_RESULTS"):
        RESULTS.mkdir(parents=True, exist_ok=True)
        targets.append(RESULTS / name)
    for path in targets:
        path.write_text(json.dumps(data, indent=2))
