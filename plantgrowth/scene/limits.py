"""The limits of a scene's values: ranges, choices and the largest accepted sizes."""

from __future__ import annotations

import math

from plantgrowth.meshes.tissue import MAX_NX as TISSUE_MAX_NX

BIG = 1e12
"""Largest magnitude accepted for a non-dimensional parameter without a natural bound."""
MAX_LENGTH = 1e6  # tissue and cell lengths, |Fg0 entries|
MAX_CELLS = 4e6  # triangles of the fine mesh
MAX_STEPS = 1e6  # t_max / dt
MAX_RESOLUTION = 64  # accuracy.cell_resolution
MAX_ANGLE = 1e6
"""Largest |walls.fibre_angle| (degrees): reduced to (-90, 90] (a ~ a + 180), an angle of 1e6 keeps
1e-10 degrees; beyond it the reduction would lose digits."""
MAX_NX = TISSUE_MAX_NX  # micro.nx
LAWS = ("stress", "strain", "none")
INTEGRATORS = ("euler", "exp", "adaptive")
MODELS = ("macro", "micro", "both")
KINEMATICS = ("linear", "finite")
MACRO_SOLVERS = ("auto", "direct", "iterative")
CELL_INTERPOLANTS = ("bilinear", "c1")
"""The surrogate's interpolants (``accuracy.cell_interpolant``, docs/surrogate_c1.md)."""
MACRO_THRESHOLD = 30_000
"""Fine dofs from which ``solver.macro = "auto"`` solves iteratively. Measured on the scaling
study's tissue, 1 rank, median step of steps 1-10 (scripts/benchmarks/bench_tissue_solver.py,
benchmarks/results/tissue_solver.json): CG + BoomerAMG from the last five solutions is as fast
as LU from about 5e3 fine dofs on and 1.6-3.9 times faster from 2e4 (2.7 at 1e5, 3.9 at 2e5).
So the threshold is the smallest round number above every shipped scene at every preset (the
largest: soft_disc at `fine`, 26,082), whose results LU keeps bit for bit (serial = mpirun to
round-off), not the crossover itself, which lies at the reference scene's size (4,340); docs/
large_tissues.md, "The 1e5-dof tissue's solver"."""
MACRO_RTOL = 1e-8
"""CG's stopping rule ``|b - A u| / |b| <= macro_rtol`` (docs/large_tissues.md, "Macro solve sized
by accuracy"): the algebraic error it leaves is at most 4 macro_rtol in u and up to 100 macro_rtol
in the largest elastic strain (a maximum of grad u; measured 8.7e-6 at 1e-7), so 1e-8 keeps every
summary column within 1e-6: 1% of the `fine` preset's smallest measured discretization error
(0.0095%, docs/accuracy_cost.md) and 1/10 of the 1e-5 the organ scene's summary may move."""
SPARE_ITERATIONS_RANGE = (0, 1000)
"""``solver.macro_spare_iterations``: 0 (off) to 1000 (beyond any solve's count: CG always
goes on to the tighter stop)."""
MACRO_RTOL_RANGE = (1e-14, 1e-4)
"""``solver.macro_rtol``: below 1e-14 double precision cannot reach the residual; above 1e-4 the
algebraic error would reach the `draft` preset's discretization error."""
GROWTH_FIELDS = ("trG", "growth_anisotropy", "growth_direction", "stress_direction")
"""Outputs derived from G and sigma_hom (plantgrowth/models/growth_fields.py, docs/outputs.md)."""
STRAIN_FIELDS = ("elastic_strain", "elastic_strain_tensor")
"""Elastic strain: largest principal magnitude, tensor (plantgrowth/models/elastic_strain.py)."""
WATER_FIELDS = ("P", "psi", "water_flux")
"""The macro model's water fields (scenes with ``[hydraulics]``): turgor, water potential, the
Darcy flux (plantgrowth/models/macro/water_outputs.py, docs/outputs.md)."""
OUTPUT_FIELDS = (
    "u", "Fg", "G", "sigma_hom", "E_hom", "eps_hom", "stability", *GROWTH_FIELDS, *STRAIN_FIELDS,
    "fibre_direction", "cue_anisotropy", *WATER_FIELDS,
)  # fmt: skip
DEFAULT_OUTPUT = ("u", "Fg", "G", "sigma_hom", "E_hom")
DIRECTOR_OUTPUT = ("fibre_direction",)
"""Added to DEFAULT_OUTPUT for a scene with a fibre director (when it does not list fields)."""
FEEDBACK_OUTPUT = ("cue_anisotropy",)
"""Added to DEFAULT_OUTPUT for a scene with ``[feedback]`` (when it does not list fields)."""
EDGES = ("left", "right", "top")
CUES = ("stress", "strain")
"""``feedback.cue``: the tensor whose principal direction the fibre director turns toward."""
FEEDBACK_WALLS = ("around", "own")
"""``feedback.walls``: the micro cue's walls, both halves of every wall around the cell or only
the cell's own halves."""
SUPPORTS = ("clamped", "roller")
"""Kinds of held edge (``[supports]``): u = 0, or the normal component of u = 0."""
RANGES = {
    "cell.l1": (0.0, MAX_LENGTH, True, False),
    "cell.l2": (0.0, MAX_LENGTH, True, False),
    "cell.theta": (0.0, 90.0, True, True),
    "cell.w": (0.0, MAX_LENGTH, True, False),
    "material.E": (0.0, BIG, True, False),
    "material.nu": (-1.0, 0.5, True, True),
    "pressure.P1": (0.0, BIG, False, False),
    "growth.eta": (0.0, BIG, False, False),
    "growth.tau": (0.0, BIG, False, False),
    "walls.fibre_stiffness": (0.0, BIG, False, False),
    "walls.fibre_angle": (-MAX_ANGLE, MAX_ANGLE, False, False),
    "hydraulics.osmotic": (0.0, BIG, False, False),
    "hydraulics.conductivity": (0.0, BIG, False, False),
}
"""Each field's interval (low, high, low end open, high end open), checked wherever it is used."""
FG0_RANGE = (-MAX_LENGTH, MAX_LENGTH, False, False)
"""The interval of each entry of growth.Fg0 (and det Fg0 > 0)."""
IDENTITY = ((1.0, 0.0), (0.0, 1.0))
REFERENCE_WIDTH = 4.0 * math.sqrt(3.0)  # = 8 cos(30 deg), exactly rounded
"""Reference tissue width 8c = 6.928203230275509 (docs/model.md section 9)."""
