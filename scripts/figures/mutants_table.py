"""Print benchmarks/results/mutants.json (written by scripts/studies/mutation_study.py) as Markdown.

python scripts/figures/mutants_table.py [path/to/mutants.json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

DEFAULT = Path(__file__).resolve().parents[2] / "benchmarks" / "results" / "mutants.json"


def table(data: dict) -> str:
    lines = [
        "| mutant | file | kind | killed by (first failing test of the default serial suite) |",
        "|---|---|---|---|",
    ]
    for m in data["mutants"]:
        killer = m["killed_by"].removeprefix("tests/") if m["killed"] else "**survived**"
        killer = f"`{killer}`" if m["killed"] else killer
        lines.append(f"| `{m['name']}` | {m['file']} | {m['category']} | {killer} |")
    baseline = data.get("baseline") or {}
    lines += [
        "",
        f"{data['n_killed']} of {data['n_mutants']} killed; commit {data['commit'][:10]}; "
        f"baseline {baseline.get('outcome', '-')} in {baseline.get('seconds', '-')} s; "
        f"mutant runs {data['mutant_seconds']:.0f} s, whole study "
        f"{data['wall_seconds_last_invocation']:.0f} s.",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "json", nargs="?", type=Path, default=DEFAULT, help="(default: %(default)s)"
    )
    args = parser.parse_args(argv)
    print(table(json.loads(args.json.read_text())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
