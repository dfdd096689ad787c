"""Base: what every part of plantgrowth shares, with no model in it: user-facing errors, 2D
tensor storage and principal values, MPI gathers of distributed data, sampling of UFL expressions
on mesh cells, the machine description recorded with benchmarks, ufl's and ffcx's versions read
without pkg_resources.

May import: ``plantgrowth.forms``, ``plantgrowth.meshes`` and third-party packages only.
"""
