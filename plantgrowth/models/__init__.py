"""The tissue models (docs/model.md sections 4-7, 10): the macroscopic model (``models.macro``:
fine-mesh elasticity with homogenized tensors from a coarse grid of cell problems), the
microscopic model (``models.micro``: every cell wall resolved), and what both share: the growth
law and integrators, linear and Newton solvers, the checks that stop a step, and the step
protocol the time loop drives (:mod:`plantgrowth.models.step`).

May import: ``plantgrowth.unitcell``, ``plantgrowth.scene``, ``plantgrowth.base``,
``plantgrowth.forms``, ``plantgrowth.meshes``.
"""
