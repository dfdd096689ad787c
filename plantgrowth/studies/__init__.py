"""Studies made of many runs: micro against macro (``compare``), parameter sweeps and the
hard-case stability criteria.

May import: ``plantgrowth.runner`` and everything below it.
"""
