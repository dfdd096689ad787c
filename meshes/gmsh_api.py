"""gmsh, imported when the first mesh is built and initialized once per process.

Importing gmsh costs 0.35-0.45 s (``python -X importtime``), which a run whose cell values are
cached never pays. gmsh 4.8 sets SIGINT to its default action when it is imported; imported late,
it would replace the handler then in place (the time loop's, which stops a run at the end of a
step), so :func:`gmsh_api` puts that handler back.
"""

from __future__ import annotations

import signal
import sys
import threading
from types import ModuleType

_state = {"initialized": False}


def gmsh_api() -> ModuleType:
    """The gmsh module, initialized quietly (gmsh 4.8 has no ``isInitialized``), with the SIGINT
    handler of the moment kept."""
    if "gmsh" not in sys.modules:
        previous = signal.getsignal(signal.SIGINT)
        import gmsh

        if previous is not None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, previous)
    import gmsh

    if not _state["initialized"]:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        _state["initialized"] = True
    return gmsh
