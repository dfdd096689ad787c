"""The macroscopic model: the fine-mesh elasticity problem, its boundary, the coarse grid of cell
problems, the domain a run solves on, and the coupled step (paper Algorithm 1)."""
