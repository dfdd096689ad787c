"""Scenes: one TOML file describes one simulation (docs/model.md sections 4-6 and 9).

Every table and key is optional and defaults to the reference scene of docs/model.md section 9,
except ``growth.law``. Unknown keys, wrong types, NaN/inf and out-of-range values are errors
(:class:`SceneError`) whose message starts with the dotted key, e.g. ``material.nu = 0.5 is out
of range: ...``. Integers are accepted for floats. Everything is non-dimensional (wall E = 1,
inclined wall length l2 = 1)::

    model = "macro"            # "macro" | "micro" | "both"
    kinematics = "linear"      # "linear": the paper's eps_el; "finite": F = Fe Fg, Green-Lagrange
                               # Ee, Newton's method (docs/model.md section 10,
                               # docs/finite_kinematics.md)
    [tissue]                   # the rectangle [0, width] x [0, height]; x2 = 0 is a symmetry plane
    width = 6.928203230275509  # 8 cos(30 deg), at most 1e6
    height = 3.0               # at most 1e6
    # or outline = [[x1, x2], ...]: a simple polygon (3 to 500 points, either orientation, in
    #   [0, 1e6]^2) with at least one edge on x2 = 0; edge i runs from point i to point i + 1
    #   and is loaded as loads.edge<i> (not the edges on x2 = 0)
    # or mesh = "file.msh": a gmsh mesh (relative to the scene file) with the curve group
    #   "symmetry" on x2 = 0, the point group "pinned" and named curve groups, loaded as
    #   loads.<name>
    # (docs/shapes.md; not with width or height: the shape's bounding box sets them)
    # or cells = {voronoi = N, seed = 0, regularity = 0.0}: a generated tissue of N = Nx^2/2
    #   cells (Nx even; micro.nx is then Nx), seed an integer >= 0, regularity r in [0, 1]
    #   from the honeycomb (0) to a perturbed centroidal-Voronoi tissue (1)
    # or cells = "file": a label image (.tif, .tiff, .png; needs pixel_size = the side of a
    #   pixel in the scene's length unit) or a polygon table (.json, .csv) (relative to the
    #   scene file; not with outline, mesh, width, height or micro.nx; docs/real_tissues.md)
    # model = "micro" | "both" and plantgrowth compare: width and height other than these
    #   defaults are an error (the cellular tissue is micro.nx cells per row, its own size)
    h = 0.1                    # (preset) fine-mesh edge: 0 < h <= min(width, height)/2,
                               # at most 4e6 cells
    H = 0.5                    # (preset) coarse-mesh edge (cell-problem nodes):
                               # h <= H <= max(width, height)
    [cell]                     # honeycomb unit cell, docs/model.md section 2
    l1 = 1.0                   # vertical wall length, > 0
    l2 = 1.0                   # inclined wall length, > 0
    theta = 30.0               # inclined wall angle in degrees, in (0, 90)
    w = 0.05                   # one cell's own wall thickness, > 0 and leaving a void
    [material]                 # wall material, docs/model.md section 1
    E = 1.0                    # Young modulus, > 0
    nu = 0.3                   # Poisson ratio, in (-1, 0.5)
    [pressure]
    P1 = 0.001                 # turgor pressure, >= 0 (docs/model.md section 6)
    [growth]                   # growth law, docs/model.md section 4
    law = "stress"             # REQUIRED: "stress" | "strain" | "none"
    eta = 1.0                  # extensibility, >= 0
    tau = 0.0                  # yield threshold, >= 0
    clamp = 1.0                # M: G is clipped component-wise to [-M, M], M > 0
    Fg0 = [[1.0, 0.0], [0.0, 1.0]]  # initial growth tensor, finite entries (numbers or
                               # fields), det > 0 wherever it is used
    [time]
    t_max = 60.0               # end time, a whole number (<= 1e6) of steps dt
    dt = 1.0                   # (preset) time step, > 0
    integrator = "exp"         # (preset) "exp": Fg <- expm(dt G) Fg (det Fg >= 1); "euler":
                               # the paper's Fg <- Fg + dt G Fg; "adaptive": exp with step
                               # doubling (below)
    tolerance = 1e-3           # adaptive: largest relative local error of Fg per step, (0, 0.1]
    [loads]                    # traction f on an edge (default none); "bottom" cannot be loaded
    right = [0.0, 0.0]         # also "left", "top"; an outline's "edge<i>", a mesh's group names;
                               # on left/right/top a component may be {expr = "..."} of s, the
                               # coordinate along the edge (x2 on left/right, x1 on top)
    [supports]                 # held edges (default none; macro only): "clamped" (u = 0) or
    left = "clamped"           # "roller" (the normal component of u is 0; an edge parallel to
                               # x1 or x2); the keys of [loads] and the edge(s) on x2 = 0
                               # ("bottom": "clamped" only); not an edge that is also loaded
    [output]
    fields = ["u", "Fg", "G", "sigma_hom", "E_hom"]  # any of these, "eps_hom" and the growth
                               # outputs (docs/outputs.md), computed only when listed:
                               # "trG" (tr G, areal growth rate), "growth_anisotropy"
                               # ((g1 - g2)/(|g1| + |g2|) of G's principal rates g1 >= g2, in
                               # [0, 1], 0 when both vanish), "growth_direction" (unit vector of
                               # g1, x1 >= 0; zero vector where G is isotropic), "stress_direction"
                               # (same for sigma_hom; micro: the cells' mean wall stress),
                               # "elastic_strain" (largest principal |strain|: eps_el, or Ee;
                               # micro: each cell's wall mean), "elastic_strain_tensor",
                               # "fibre_direction" (macro, the fibre director; needs [walls]),
                               # "cue_anisotropy" (A of the feedback's cue; needs [feedback]).
                               # Not given: the list above, plus fibre_direction for a scene
                               # with a director and cue_anisotropy with [feedback].
                               # Micro runs write u, Fg, G, cell_id and the growth outputs
                               # listed, plus cells.csv and cells.xdmf (cell outlines)
    every = 1                  # fields at t = 0, every k-th step and t_max (summary.csv has
                               # every step), integer in [1, 1e6]
    precision = "float32"      # of the written fields: "float32" | "float64" (the resume
                               # state is float64 either way)
    [accuracy]
    preset = "balanced"        # "draft" | "balanced" | "fine": sets the keys marked (preset)
    cell_resolution = 2        # (preset) P2 elements across a cell wall, integer in [1, 64]
    key_tolerance = 1e-6       # cell-problem inputs are rounded to this before caching, (0, 1e-2]
    cell_tolerance = 1e-3      # (preset) surrogate's relative error of the homogenized tensors,
                               # [0, 0.1] (0: solve every distinct input exactly; surrogate.py)
    cell_interpolant = "bilinear"  # the surrogate's answers between its lattice points:
                               # "bilinear" (C0) or "c1" (C1, refinements blended in over 8
                               # steps: fewer CG iterations on large tissues, but its cell phase
                               # costs about 3x bilinear's while refinements blend, so the organ
                               # scene runs 1.66x slower: docs/surrogate_c1.md)
    [micro]
    nx = 16                    # cells per row of the micro model, even integer in [2, 256]
                               # (with [hydraulics], the macro model's cells: 4 / nx x [cell])
    resolution = 2             # P2 elements across one cell's own wall, integer in [1, 64]
    [solver]                   # linear solvers: speed only, results agree to the solver tolerance
    macro = "auto"             # "direct" (LU), "iterative" (CG + AMG, true relative residual
                               # <= macro_rtol) or "auto": iterative from macro_threshold dofs on
    macro_threshold = 30000    # fine dofs (2 per node) where "auto" switches, integer in [0, 1e9]
    macro_rtol = 1e-8          # CG's stop |b - A u| / |b| (algebraic error of u <= 4 macro_rtol),
                               # [1e-14, 1e-4] (docs/large_tissues.md)
    macro_spare_iterations = 0 # CG goes on to macro_rtol / 4 while a solve has taken fewer than
                               # this many iterations, integer in [0, 1000]; 0: off (the organ
                               # scene: 6, its 1- and 2-rank runs then agree within 6e-7:
                               # docs/large_tissues.md)
    [numerics]
    on_instability = "stop"    # where the walls' law loses strong ellipticity on a set larger
                               # than a cell (they would buckle; smaller sets are singular points,
                               # reported only): "stop" (a named error, every completed step
                               # kept) or "warn" (as it appears and doubles, and go on)
    [parameters]               # named numbers (none by default) that every expression may use:
    E_in = 0.3                 # a name of letters, digits and _ (not x1, x2, s, pi or a
                               # function), a finite number of magnitude <= 1e12; replaced by
                               # its value when an expression is read (scene/parameters.py)
    [regions]                  # named conditions on the reference (x1, x2) (none by default),
    disc = {expr = "(x1 - 3)**2 + (x2 - 1.5)**2 < 1"}  # true where non-zero; summary.csv gets
                               # <name>.area, .trG, .growth_rate_11, _22, _12 per step; a region
                               # holding no growth unit of the mesh is an error (scene/regions.py)
    [walls]                    # fibre-reinforced walls (none by default: the paper's isotropic
    fibre_stiffness = 2.0      # walls): E_f / E, a field >= 0 (the constant 0: the paper's)
    fibre_angle = 30.0         # the fibre director at t = 0, degrees from x1, a field (finite,
                               # |a| <= 1e6); required unless fibre_stiffness is 0, and only with
                               # fibre_stiffness
    [feedback]                 # the director turns toward the cue's principal direction (none
    cue = "stress"             # by default; needs both walls keys): "stress" | "strain"
    rate = 0.5                 # k >= 0 in da/dt = -(k A / 2) sin(2 (a - a_Q)) (models/fibres.py)
    walls = "around"           # micro cue: "around" (default), the walls around the cell, both
                               # halves of each shared wall, each with its own cell's tensor;
                               # "own", the cell's own halves only (unstable cell by cell,
                               # docs/fibres.md); macro runs have no halves and ignore it
                               # Both models read [walls] and [feedback] (macro output
                               # "fibre_direction", micro cells.csv "fibre_angle": the director)
    [hydraulics]               # water fluxes (none by default: turgor is pressure.P1), micro
    osmotic = 0.001            # or macro (either kinematics; its cells are those of micro.nx),
                               # any integrator (docs/model.md, water fluxes):
    conductivity = 1.0         # Pi, a field >= 0, replaces pressure.P1 (not with it); L, a field
    initial_potential = 0.0    # >= 0, required; psi_0: every cell starts at P = Pi + psi_0
    [[hydraulics.supply]]      # any number: edge = "left" | "right" | "top" (an outline's or
    edge = "left"              # mesh's edges as [loads]; not x2 = 0) or region = a [regions]
    potential = 0.0            # name, each once; psi_s (default 0) or {times = [...], values =
    conductance = 1.0          # [...], interpolation = "step" | "linear"}; L_s > 0 per unit
                               # grown edge length, L_r > 0 per unit grown area (a region)
                               # (plantgrowth/scene/hydraulics.py)

The x1 forces of the loads must balance (only the pinned point, the origin of the rectangle,
holds the tissue along x1): the sum over the loaded edges of ``f[0]`` times the edge's length is
0 to a relative 1e-6, unless a held edge holds u1 (clamped, or a roller on an edge parallel to
x2): it then replaces the pinned point and carries the net force. With an outline or mesh the
pinned point is the bottom-left-most vertex on x2 = 0 or the mesh's "pinned" point, coarse nodes
outside the tissue get no cell problem, and only ``model = "macro"`` is possible (the micro model
builds its own honeycomb tissue).

Keys marked (preset) take the value of ``accuracy.preset`` (plantgrowth/scene/presets.py; the values
shown are ``balanced``'s) unless the scene gives them; the preset's ``h`` and ``H`` are clipped
to the tissue (``h <= min(width, height)/2``, ``h <= H <= max(width, height)``).

The keys of ``[cell]``, ``[material]``, ``[walls]``, ``pressure.P1``, ``growth.eta``,
``growth.tau`` and each entry of ``growth.Fg0`` are *fields* (docs/fields.md):

- a number;
- ``{from = a, to = b}`` (``along = "x1"``, the default) or ``{from = a, to = b, along = "x2"}``:
  linear from a at 0 to b at the end of the tissue simulated along that axis (docs/model.md
  sections 7, 9): the macro rectangle's width or height, the cellular tissue's own extent for micro
  runs and the macro side of ``both`` and ``compare``, so a field never leaves [a, b];
- ``{expr = "..."}``: an expression of x1 and x2 (plantgrowth/scene/expression.py: numbers, pi,
  ``+ - * / **``, parentheses, comparisons, exp log sqrt sin cos tanh abs min max and
  ``where(cond, a, b)``; never Python's eval), in absolute coordinates.

A number's and a linear field's range is checked at its ends when the scene is built, the cell
geometry at the ends and middle of each axis a field varies along. A non-constant expression, or
a varying Fg0, is checked where the run uses it (plantgrowth/scene/places.py): at every coarse node
and fine cell of the macro domain and at every cell centre of a micro tissue, before anything is
written; the error names the key, the place (x1, x2) and the range. Magnitudes above 1e12 (1e6
for lengths and Fg0) are rejected as typos: the model is non-dimensional with reference values of
order 1.

Load with :func:`load_scene` (a file), :func:`parse_scene` or ``Scene.from_dict`` (a dict);
``Scene.to_toml()`` writes the fully resolved scene, which loads back to an equal ``Scene``.
"""

from plantgrowth.base.errors import SceneError
from plantgrowth.scene.schema import Scene, load_scene, parse_scene

__all__ = ["Scene", "SceneError", "load_scene", "parse_scene"]
