"""The unit cell (docs/model.md sections 2-3): the periodic cell problems and their solver, the
homogenized tensors, the surrogate that interpolates them, their cache and the sharing of cell
problems among ranks.

May import: ``plantgrowth.scene``, ``plantgrowth.base``, ``plantgrowth.forms``,
``plantgrowth.meshes``.
"""
