"""ufl's and ffcx's versions read without ``pkg_resources`` (issue 33, item 3: start-up).

Both packages' ``__init__`` (Debian's ufl 2022.2, ffcx 0.5) do ``import pkg_resources`` only for
``__version__ = pkg_resources.get_distribution(name).version``; importing ``pkg_resources`` scans
every installed distribution and costs a run 0.07-0.13 s. While either ``__init__`` runs, a
stand-in module answers ``get_distribution(name).version`` from ``importlib.metadata`` (the same
``Version`` field of the same metadata; ffcx's version is part of its forms' cache signature, so
it must be the same string) and fetches the real ``pkg_resources`` for any other name. Outside
those two imports nothing changes: ``import pkg_resources`` gets the real module.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import sys
import types
from typing import Any

PACKAGES = frozenset({"ufl", "ffcx"})
"""The top-level packages whose ``__init__`` runs with the stand-in."""


class _Distribution:
    """What ``get_distribution(name)`` returns to ufl and ffcx: the version only."""

    def __init__(self, name: str) -> None:
        from importlib.metadata import version

        self.version = version(name)


class _StandIn(types.ModuleType):
    """``pkg_resources`` during ufl's and ffcx's ``__init__``: ``get_distribution`` answered
    here, every other attribute from the real module (imported then)."""

    get_distribution = staticmethod(_Distribution)

    def __getattr__(self, name: str) -> Any:
        if sys.modules.get("pkg_resources") is self:
            del sys.modules["pkg_resources"]
        return getattr(importlib.import_module("pkg_resources"), name)


class _Loader:
    """The package's own loader, executing its ``__init__`` with the stand-in in place (unless
    the real ``pkg_resources`` is loaded already)."""

    def __init__(self, loader: Any) -> None:
        self.loader = loader

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType | None:
        return self.loader.create_module(spec)

    def exec_module(self, module: types.ModuleType) -> None:
        if "pkg_resources" in sys.modules:
            self.loader.exec_module(module)
            return
        stand_in = _StandIn("pkg_resources")
        sys.modules["pkg_resources"] = stand_in
        try:
            self.loader.exec_module(module)
        finally:
            if sys.modules.get("pkg_resources") is stand_in:
                del sys.modules["pkg_resources"]

    def __getattr__(self, name: str) -> Any:  # get_resource_reader, is_package, ...
        return getattr(self.loader, name)


class _Finder:
    """A ``sys.meta_path`` entry that finds ufl and ffcx as the path finder does and wraps the
    loader; None (the next finder's turn) for every other name."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name not in PACKAGES or "pkg_resources" in sys.modules:
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is not None and spec.loader is not None:
            spec.loader = _Loader(spec.loader)
        return spec


def install() -> None:
    """Put the finder first on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())
