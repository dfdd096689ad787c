"""The step files' compressor: libdeflate's levels against zlib's (the choice of
``plantgrowth.base.deflate.LEVEL`` and of libdeflate over zlib).

Runs two scenes to t = 2 on 1 rank (cell cache off): the scaling study's 1e5-dof tissue
(scripts/benchmarks/scaling.py, gradient_E_strain scaled) and scenes/reference_stress.toml.
Takes the datasets of each one's last step file as the runs write them (float32 fields after
HDF5's byte shuffle, one chunk each: a 1-rank run) and compresses their bytes with every level
of ``LIBDEFLATE_LEVELS`` and ``ZLIB_LEVELS``, ``--repeats`` times in turn. Records per scene,
compressor and level the bytes out and the median seconds over the repeats (the file's datasets
together), every stream inflated back to its input (checked). Writes
``benchmarks/results/deflate.json`` (about a minute).

    python scripts/benchmarks/bench_deflate.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
import zlib
from pathlib import Path

import h5py
import numpy as np
from scaling import scaled_scene

from plantgrowth.base.deflate import Deflater
from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/deflate.json"
EXE = str(Path(sys.executable).with_name("plantgrowth"))
LIBDEFLATE_LEVELS = (1, 2, 3, 4, 6, 9)
ZLIB_LEVELS = (1, 2, 6)


def scenes() -> dict[str, str]:
    """name -> the TOML text of each scene whose step file is compressed."""
    tissue = scaled_scene(1e5, 2.0, {"macro": "iterative"})
    reference = tomllib.loads((ROOT / "scenes/reference_stress.toml").read_text())
    reference.setdefault("time", {})["t_max"] = 2.0
    return {"tissue_1e5": dict_to_toml(tissue), "reference_stress": dict_to_toml(reference)}


def step_chunks(text: str) -> list[np.ndarray]:
    """The shuffled bytes of every dataset of the scene's last step file (one chunk each)."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene.toml"
        scene.write_text(text)
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
        subprocess.run([EXE, "run", str(scene), "-o", f"{tmp}/o"], check=True,
                       capture_output=True, env=env)  # fmt: skip
        last = sorted(Path(tmp, "o/fields").glob("step_*.h5"))[-1]
        chunks = []
        with h5py.File(last, "r") as f:

            def take(_: str, item: object) -> None:
                if isinstance(item, h5py.Dataset):
                    values = np.ascontiguousarray(item[...])
                    shuffled = values.view(np.uint8).reshape(-1, values.dtype.itemsize).T
                    chunks.append(np.ascontiguousarray(shuffled))

            f.visititems(take)
    return chunks


def compressors() -> dict[str, Deflater]:
    """name -> a compressor of contiguous byte arrays to zlib streams."""
    found = {f"libdeflate {level}": Deflater(level) for level in LIBDEFLATE_LEVELS}
    if any(f.library != "libdeflate" for f in found.values()):
        raise SystemExit("libdeflate is not installed (Debian: libdeflate0)")
    return found | {f"zlib {level}": Deflater(level, use_libdeflate=False) for level in ZLIB_LEVELS}


def measure(chunks: list[np.ndarray], functions: dict[str, Deflater], repeats: int) -> dict:
    """Per compressor: the bytes out and the median seconds of the datasets together."""
    seconds: dict[str, list[float]] = {name: [] for name in functions}
    sizes: dict[str, int] = {}
    for _ in range(repeats):
        for name, function in functions.items():
            start = time.perf_counter()
            streams = [function(c) for c in chunks]
            seconds[name].append(time.perf_counter() - start)
            sizes[name] = sum(len(s) for s in streams)
            for stream, chunk in zip(streams, chunks, strict=True):
                assert zlib.decompress(stream) == chunk.tobytes(), name
    return {name: {"bytes": sizes[name], "seconds": statistics.median(seconds[name])}
            for name in functions}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    functions = compressors()
    record: dict = {
        "machine": machine_description(),
        "command": "scripts/benchmarks/bench_deflate.py " + " ".join(argv or sys.argv[1:]),
        "repeats": args.repeats,
        "scenes": {},
    }
    for scene, text in scenes().items():
        chunks = step_chunks(text)
        results = measure(chunks, functions, args.repeats)
        record["scenes"][scene] = {"input_bytes": int(sum(c.nbytes for c in chunks)),
                                   "datasets": len(chunks), "compressors": results}  # fmt: skip
        for name, values in results.items():
            print(f"{scene:16s} {name:14s} {values['bytes']:>10d} B  {values['seconds']:.5f} s")
    OUT.write_text(json.dumps(record, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
