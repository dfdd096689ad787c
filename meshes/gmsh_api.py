"""gmsh, imported when the first mesh is built and initialized once per process.

Importing gmsh costs 0.35-0.45 s (``python -X importtime``; 0.07-0.09 s loaded as below), which
a run whose cell values are cached never pays. gmsh 4.8 sets SIGINT to its default action when
it is imported; imported late, it would replace the handler then in place (the time loop's,
which stops a run at the end of a step), so :func:`gmsh_api` puts that handler back.

Imported after dolfinx, PETSc and MPI, loading libgmsh and its 70 libraries (OpenCASCADE, FLTK,
...) resolves their symbols through every library loaded before (ctypes binds at load time):
0.36-0.48 s of CPU against 0.13-0.16 s with the library loaded ``RTLD_DEEPBIND`` first (its own
dependencies searched before the process's global scope), which :func:`_load_deep_bound` does
where the platform has it and no ``LD_PRELOAD`` library (an interposed malloc, a sanitizer) must
come first. The same code runs, bound to the same libraries: the unit-cell meshes are equal.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from types import ModuleType

_state = {"initialized": False}


def _load_deep_bound() -> None:
    """Load libgmsh (found as gmsh.py finds it) with ``RTLD_DEEPBIND``; gmsh.py's own ``CDLL``
    then gets the loaded library. Nothing where that cannot be done."""
    deepbind = getattr(os, "RTLD_DEEPBIND", None)
    if deepbind is None or sys.platform != "linux" or os.environ.get("LD_PRELOAD"):
        return
    import ctypes
    from ctypes.util import find_library

    name = find_library("gmsh")
    if name is not None:
        try:
            ctypes.CDLL(name, mode=ctypes.RTLD_LOCAL | deepbind)
        except OSError:  # gmsh.py's own load will say why
            pass


def gmsh_api() -> ModuleType:
    """The gmsh module, initialized quietly (gmsh 4.8 has no ``isInitialized``), with the SIGINT
    handler of the moment kept."""
    if "gmsh" not in sys.modules:
        previous = signal.getsignal(signal.SIGINT)
        _load_deep_bound()
        import gmsh

        if previous is not None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, previous)
    import gmsh

    if not _state["initialized"]:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        _state["initialized"] = True
    return gmsh
