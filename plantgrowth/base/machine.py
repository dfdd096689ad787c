"""Description of the machine and software stack, recorded next to benchmark results.

Hostname-free on purpose: result files are committed and shared.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import time
from importlib import import_module, metadata
from pathlib import Path


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _memory_gib() -> float | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 2**20, 1)
    except (OSError, ValueError, IndexError):
        pass
    return None


def _os_release() -> str:
    try:
        with open("/etc/os-release") as f:
            fields = dict(line.rstrip("\n").split("=", 1) for line in f if "=" in line)
        return fields.get("PRETTY_NAME", "").strip('"') or platform.platform()
    except OSError:
        return platform.platform()


def _version(module: str) -> str | None:
    """``module.__version__``, else the distribution's metadata, else None (missing is fine)."""
    try:
        return str(import_module(module).__version__)
    except (ImportError, AttributeError):
        pass
    try:
        return metadata.version(module)
    except metadata.PackageNotFoundError:
        return None


def _petsc_version() -> str | None:
    try:
        from petsc4py import PETSc
    except ImportError:
        return None
    return ".".join(str(v) for v in PETSc.Sys.getVersion())


def _blas() -> str | None:
    """The BLAS/LAPACK files numpy's process has loaded (Debian's alternatives choose them: the
    reference BLAS, or OpenBLAS since scripts/install.sh installs it), or None if unknown."""
    import_module("numpy")
    names = ("libblas", "liblapack", "libopenblas")
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if line.rsplit("/", 1)[-1].startswith(names)}
    except OSError:
        return None
    return ", ".join(sorted(paths)) or None


def machine_description() -> dict:
    """CPU, cores, memory, OS, the versions of the numerical stack and its BLAS, and the date
    (UTC).

    Returns:
        A JSON-serialisable dictionary without the host name.
    """
    try:
        cores_available = len(os.sched_getaffinity(0))
    except AttributeError:
        cores_available = os.cpu_count()
    return {
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "cores_available": cores_available,
        "memory_gib": _memory_gib(),
        "os": _os_release(),
        "kernel": platform.release(),
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "dolfinx": _version("dolfinx"),
        "dolfinx_mpc": _version("dolfinx_mpc"),
        "petsc4py": _version("petsc4py"),
        "petsc": _petsc_version(),
        "gmsh": _version("gmsh"),
        "blas": _blas(),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }


def write_study_json(path: Path, result: dict, start: float) -> None:
    """Write a study's ``result`` as indented JSON to ``path`` (its directory made), with the
    machine description and the seconds since ``start`` (a ``time.perf_counter()`` value)."""
    result = {**result, "machine": machine_description()}
    result["script_seconds"] = time.perf_counter() - start
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {path} in {result['script_seconds']:.1f} s")
