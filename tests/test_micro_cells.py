"""The micro model on a tissue given as cells (issue 34, docs/real_tissues.md): the regular
honeycomb given as cells is today's micro model, irregular and free tissues solve, and mpirun -n 2
gives the serial answers."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from test_micro_water import every_edge, hydraulics, scene_data

from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.meshes.cell_walls import wall_network
from plantgrowth.meshes.geometry_error import GeometryError
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models.micro.around import side_pairs
from plantgrowth.models.micro.model import MicroModel, scene_cell
from plantgrowth.scene import parse_scene
from plantgrowth.scene.micro_tissue import micro_tissue

COMM = MPI.COMM_WORLD
NX = 4
ROUND_OFF = 1e-8  # the micro model's documented round-off (tests/test_micro.py: LU solves of
# the thin walls' ill-conditioned stiffness); measured 1.2e-10 relative in u between the
# honeycomb and its perturbed copy, and the same against main's code (42b6a2a)
SERIAL_MPI = 1e-8  # serial against mpirun -n 2 (MUMPS on both), as tests/test_micro.py
BALANCE = 1e-12  # the water balance error relative to the water held, linear kinematics
# (tests/test_micro_water.py: sums of lumen areas and an LU solve; measured 2e-16 to 1.2e-15)
PERTURBATION = 1e-15  # relative: vertices moved by a few ulps, so the cells are another object
ORDERINGS = 1e-12  # two LU orderings of the same system: the refined solve's forward error,
# measured 4.0e-14 (AMD against AMF, below); unrefined, kappa eps (kappa ~ 1e7 on thin walls):
# 7.8e-12 (growth_anisotropy; PORD against AMD: 1.3e-10 in the vertices' displacements)


def _scene(kinematics: str, water: bool, t_max: float = 2.0):
    tables = (
        {"hydraulics": hydraulics(supply=every_edge(0.5, 0.0005))}
        if water
        else {"pressure": {"P1": 0.001}}
    )
    return parse_scene(scene_data(NX, t_max, kinematics, **tables))


def _honeycomb_loops(scene, nx: int = NX) -> tuple[TissueLayout, list[np.ndarray]]:
    layout = TissueLayout(scene_cell(scene), nx)
    return layout, [layout.hexagon(i) for i in range(layout.n_cells)]


def perturbed_honeycomb(scene, amplitude: float, seed: int = 3, nx: int = NX) -> CellTissue:
    """The honeycomb's cells with each vertex moved by ``amplitude`` times delta_s times a seeded
    random vector (vertices on x2 = 0 along x1 only); w as the honeycomb's."""
    layout, loops = _honeycomb_loops(scene, nx)
    cells = CellPolygons.from_loops(loops)
    rng = np.random.default_rng(seed)
    move = amplitude * layout.delta_s * rng.uniform(-1.0, 1.0, cells.vertices.shape)
    move[np.abs(cells.vertices[:, 1]) < 1e-12, 1] = 0.0
    moved = CellPolygons(cells.vertices + move, cells.cells, cells.labels)
    return CellTissue.from_cells(moved, layout.cell.w * layout.delta_s)


def _answers(model: MicroModel, steps: int = 2) -> dict[str, np.ndarray]:
    """u at the output space's nodes (ordered by position), and cells.csv's columns, per step."""
    out, Fg = {}, model.initial_growth()
    for step in range(steps):
        result = model.step(Fg)
        x = model.u_out.function_space.tabulate_dof_coordinates()[:, :2]
        values = model.u_out.x.array.reshape(-1, 2)[: len(x)]
        order = np.lexsort((np.round(x[:, 1], 8), np.round(x[:, 0], 8)))
        out[f"u{step}"] = values[order]
        rows = model.outlines.rows(step, float(step))
        for key in rows[0]:
            out[f"{key}{step}"] = np.array([row[key] for row in rows])
        model.end_step(1.0)
        Fg = np.einsum("nij,njk->nik", np.eye(2) + result.G, Fg)
    return out


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-300))


def test_a_cut_cell_is_the_mirrored_cell_and_the_network_is_the_honeycombs():
    """The honeycomb as cells (vertices moved by 1e-15): a cut cell's outline is the whole
    hexagon, centres are TissueLayout.centres, voids its voids, the wall network and the cells
    across each side those of the lattice (k + 3 opposite). Round-off: O(1) coordinates moved by
    1e-15 relative, so 1e-13 absolute is ~100 ulps."""
    scene = _scene("linear", False)
    layout, loops = _honeycomb_loops(scene)
    rng = np.random.default_rng(0)
    moved = [p * (1.0 + PERTURBATION * rng.standard_normal(p.shape)) for p in loops]
    tissue = CellTissue.from_cells(CellPolygons.from_loops(moved), layout.cell.w * layout.delta_s)
    assert tissue.cut_cells.tolist() == list(range(NX))
    np.testing.assert_allclose(tissue.centres, layout.centres, atol=1e-13)
    for i in range(layout.n_cells):
        whole = layout.delta_s * layout.cell.hexagon() + layout.centres[i]
        np.testing.assert_allclose(tissue.outline(i), whole, atol=1e-13)
        np.testing.assert_allclose(tissue.void(i), layout.void(i), atol=1e-13)
    mine, lattice = wall_network(tissue), wall_network(layout)
    assert sorted(map(tuple, mine.pairs.tolist())) == sorted(map(tuple, lattice.pairs.tolist()))
    assert sorted(zip(mine.outer_cell.tolist(), mine.outer_edge.tolist(), strict=True)) == sorted(
        zip(lattice.outer_cell.tolist(), lattice.outer_edge.tolist(), strict=True)
    )
    across, opposite = side_pairs(tissue)
    assert across.shape == (layout.n_cells, 6)
    assert np.all((opposite == -1) | (opposite == (np.arange(6) + 3) % 6))
    assert np.array_equal(across, side_pairs(layout)[0])
    # cells.csv's perimeter_ref and neighbours: a cut cell has half its mirrored hexagon's walls
    full = np.linalg.norm(np.diff(whole, axis=0, append=whole[:1]), axis=1).sum()
    np.testing.assert_allclose(tissue.perimeters, np.where(tissue.cut, 0.5, 1.0) * full, rtol=1e-13)
    counted = [len(set(row[row >= 0].tolist())) for row in across]
    assert tissue.cells.neighbour_counts.tolist() == counted
    assert max(counted) == 4  # Nx = 4, two rows: 2 beside, 2 above (or below), none below a cut


def test_every_wall_of_an_irregular_tissue_is_its_cells_and_only_theirs():
    """The wall network of an irregular tissue (the honeycomb's vertices moved by 0.15 delta_s,
    cut cells included): each shared wall joins two different cells, and each cell's water
    crosses all its walls: its shared walls' and outer walls' mid-line lengths add up to its
    perimeter (cells.csv's perimeter_ref; a cut cell's side on x2 = 0 is none). Sums of about
    ten O(1) lengths: 1e-12 relative is round-off. (A shared wall given to one of its cells only
    leaves the other short by that wall.)"""
    tissue = perturbed_honeycomb(_scene("linear", False), 0.15)
    network = wall_network(tissue)
    assert len(network.pairs) > 0 and np.all(network.pairs[:, 0] != network.pairs[:, 1])
    shared = np.linalg.norm(network.shared, axis=1)
    lengths = np.bincount(network.pairs.ravel(), np.repeat(shared, 2), tissue.n_cells)
    lengths += np.bincount(network.outer_cell, np.linalg.norm(network.outer, axis=1),
                           tissue.n_cells)  # fmt: skip
    np.testing.assert_allclose(lengths, tissue.perimeters, rtol=1e-12)


def test_a_non_convex_cell_gets_its_mitred_void_and_a_thick_wall_a_named_error():
    """An L-shaped cell (three unit squares, w = 0.1): its void is the L offset inward with a
    mitred re-entrant corner, [0.1, 1.9] x [0.1, 0.9] and [0.1, 0.9] x [0.9, 1.9] (shifted up
    by 1), area 1.8 * 0.8 + 0.8 * 1.0 = 2.24 (a few roundings of O(1) numbers: 1e-12 relative).
    w = 0.6 leaves no void: a GeometryError naming the wall thickness; cells below x2 = 0 one
    naming the half-plane."""
    square = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float) + [0, 1]
    cells = CellPolygons.from_loops([square])
    void = CellTissue.from_cells(cells, 0.1).void(0)
    x, y = void[:, 0], void[:, 1]
    assert 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) == pytest.approx(
        2.24, rel=1e-12
    )
    with pytest.raises(GeometryError, match="wall thickness"):
        CellTissue.from_cells(cells, 0.6).void(0)
    below = CellPolygons.from_loops([square - [0.0, 1.5]])
    with pytest.raises(GeometryError, match="x2 >= 0"):
        CellTissue.from_cells(below, 0.1)


@pytest.mark.parametrize("water", [False, True], ids=["turgor", "water"])
@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_the_honeycomb_given_as_cells_is_todays_micro_model(kinematics, water):
    """Steps of the Nx = 4 tissue from TissueLayout and from its hexagons as cells with
    vertices moved by 1e-15 (two with water and linear kinematics, whose water carries over to
    the second through the wall network; one otherwise): u and every cells.csv column agree to
    the micro round-off."""
    scene = _scene(kinematics, water)
    layout, loops = _honeycomb_loops(scene)
    rng = np.random.default_rng(1)
    moved = [p * (1.0 + PERTURBATION * rng.standard_normal(p.shape)) for p in loops]
    tissue = CellTissue.from_cells(CellPolygons.from_loops(moved), layout.cell.w * layout.delta_s)
    assert tissue.cells.vertices is not CellTissue.from_layout(layout).cells.vertices
    steps = 2 if water and kinematics == "linear" else 1
    reference = _answers(MicroModel(scene, COMM), steps)
    given = _answers(MicroModel(scene, COMM, tissue=tissue), steps)
    assert reference.keys() == given.keys()
    for key in reference:
        assert _relative(reference[key], given[key]) < ROUND_OFF, key


def _replicated(model: MicroModel, steps: int) -> dict[str, np.ndarray]:
    """Per step: cells.csv's columns, the polygons' vertex displacements and the summary's
    measures, all the same on every rank."""
    out, Fg = {}, model.initial_growth()
    for step in range(steps):
        result = model.step(Fg)
        rows = model.outlines.rows(step, float(step))
        out |= {f"{key}{step}": np.array([row[key] for row in rows]) for key in rows[0]}
        out[f"vertices{step}"] = model.outlines.displacement
        out |= {f"{k}{step}": np.array(v) for k, v in model.measures(Fg, result.G).items()}
        model.end_step(1.0)
        Fg = np.einsum("nij,njk->nik", np.eye(2) + result.G, Fg)
    return out


@pytest.mark.mpi
@pytest.mark.parametrize(("kinematics", "water"), [("linear", True), ("finite", False)])
def test_an_irregular_tissue_gives_the_serial_answers_on_every_rank_count(kinematics, water):
    """The Nx = 4 honeycomb's vertices moved by up to 0.15 delta_s (irregular cells, 3 to 5
    neighbours): steps (two with water, one without) on COMM_WORLD (2 ranks under mpirun) and
    on COMM_SELF (serial, on every rank) agree to SERIAL_MPI in cells.csv, the vertices'
    displacements and summary.csv's measures (a serial run solves once: nothing to compare);
    the cells' areas differ from the honeycomb's by more than 1%, so it is not it."""
    scene = _scene(kinematics, water)
    tissue = perturbed_honeycomb(scene, 0.15)
    honeycomb = CellTissue.from_layout(_honeycomb_loops(scene)[0])
    assert np.abs(tissue.cells.areas / honeycomb.cells.areas - 1.0).max() > 0.01
    assert len(set(tissue.cells.neighbour_counts.tolist())) > 1
    steps = 2 if water else 1
    parallel = _replicated(MicroModel(scene, COMM, tissue=tissue), steps)
    serial = parallel
    if COMM.size > 1:
        serial = _replicated(MicroModel(scene, MPI.COMM_SELF, tissue=tissue), steps)
    assert serial.keys() == parallel.keys()
    for key in serial:
        if key.startswith("water_balance_error"):  # round-off itself: bounded, not compared
            step = key.removeprefix("water_balance_error")
            assert abs(parallel[key]) < BALANCE * parallel[f"water{step}"], key
            continue
        assert _relative(serial[key], parallel[key]) < SERIAL_MPI, key


def _reactions(model: MicroModel) -> tuple[np.ndarray, float]:
    """The supports' reactions ``A u - b`` at the constrained dofs (this rank's owned) of the
    linear problem assembled without them, and the largest load ``|b|`` (over every rank)."""
    from dolfinx import fem
    from petsc4py import PETSc

    A = fem.petsc.assemble_matrix(model.a)
    A.assemble()
    b = fem.petsc.assemble_vector(model.L)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    r = A.createVecLeft()
    A.mult(model.u.vector, r)
    r.axpy(-1.0, b)
    mark = b.duplicate()
    mark.set(1.0)
    fem.petsc.set_bc(mark, model.bcs)
    held = mark.array == 0.0
    return r.array[held], b.norm(PETSc.NormType.NORM_INFINITY)


def free_tissue(scene, amplitude: float, seed: int = 5) -> CellTissue:
    """The Nx = 4 honeycomb's cells whole (the bottom row not cut), lifted 0.1 above x2 = 0,
    vertices moved as :func:`perturbed_honeycomb`'s: a tissue with no symmetry plane whose rows
    are alike above and below (a cut row's half cells on one side would curl it under turgor)."""
    layout = TissueLayout(scene_cell(scene), NX)
    d, cell = layout.delta_s, layout.cell
    lift = np.array([0.0, d * (0.5 * cell.l1 + cell.s) + 0.1])
    cells = CellPolygons.from_loops([d * cell.hexagon() + c + lift for c in layout.centres])
    rng = np.random.default_rng(seed)
    moved = cells.vertices + amplitude * d * rng.uniform(-1.0, 1.0, cells.vertices.shape)
    return CellTissue.from_cells(CellPolygons(moved, cells.cells, cells.labels), cell.w * d)


@pytest.mark.mpi
@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_a_pressurised_free_tissue_solves_and_its_supports_hold_nothing(kinematics):
    """An irregular tissue off x2 = 0 (no cut cell, no symmetry plane), pressurised
    (P1 = 0.001) and growing: it solves, every cell swells, and (linear kinematics) the three
    supported dofs carry no load, ``|A u - b| < 1e-8 |b|`` there (the loads are self-equilibrated,
    so three dofs only hold the rigid motions; the LU's residual ~1e-12 relative)."""
    scene = _scene(kinematics, False, t_max=1.0)
    tissue = free_tissue(scene, 0.05)  # 0.1: finite kinematics curl it, Newton fails at P1
    assert not tissue.symmetric
    model = MicroModel(scene, COMM, tissue=tissue)
    result = model.step(model.initial_growth())
    assert result.reason > 0  # converged (step() also stops on a failed solve)
    assert np.all(model.outlines.area > tissue.cells.areas)
    if kinematics == "linear":
        reactions, load = _reactions(model)
        assert COMM.allreduce(len(reactions)) >= 3
        assert COMM.allreduce(np.abs(reactions).max(initial=0.0), op=MPI.MAX) < 1e-8 * load


@pytest.mark.skip_in_parallel  # compares two meshes' rank-local arrays, partitioned apart on
# 2 ranks; serial = mpirun for generated tissues: test_an_irregular_tissue_gives_the_serial_...
def test_a_generated_tissue_at_regularity_zero_is_the_honeycomb_and_r_half_runs(tmp_path):
    """``[tissue] cells = {voronoi = 8, ...}`` (Nx = 4): at r = 0 the micro model on the
    generated cells (w scaled by 4 / Nx) gives the honeycomb's u and cells.csv to ROUND_OFF; at
    r = 0.5 ``plantgrowth run`` writes cells.csv with the cells' neighbour counts (not all alike)
    and perimeters; only the bottom row is cut (seed 6: a top-row cell on x2 = 0 is not)."""
    from test_micro_water import cells, run

    data = scene_data(NX, 1.0, "linear", pressure={"P1": 0.001})
    regular = data | {"tissue": {"cells": {"voronoi": 8, "seed": 2, "regularity": 0.0}}}
    regular["micro"] = {"resolution": 1}
    generated = MicroModel(parse_scene(regular), COMM)
    assert generated.layout is None and generated.tissue.n_cells == 8
    reference, given = _answers(MicroModel(parse_scene(data), COMM), 1), _answers(generated, 1)
    for key in reference:
        assert _relative(reference[key], given[key]) < ROUND_OFF, key
    irregular = regular | {"tissue": {"cells": {"voronoi": 8, "seed": 1, "regularity": 0.5}}}
    table = cells(run(tmp_path, "irregular", irregular), 0)
    assert len(table["cell"]) == 8
    assert len(set(table["neighbours"].tolist())) > 1
    assert np.all(table["perimeter_ref"] > 0.0)
    # seed 6: a top-row cell reaches x2 = 0 beside its own mirror image, by a side shorter
    # than 2 w: it is no cut cell (its void, not mirrored, is one polygon)
    meets = regular | {"tissue": {"cells": {"voronoi": 8, "seed": 6, "regularity": 0.5}}}
    tissue = micro_tissue(parse_scene(meets))
    assert tissue.cut.tolist() == [True] * NX + [False] * NX
    assert np.any(tissue.on_plane & ~tissue.cut)
    assert tissue.wall_area > 0.0


def test_two_lu_orderings_give_the_linear_answers_to_the_refined_solves_accuracy():
    """A generated Nx = 4 tissue (r = 0.25, seed 1), linear kinematics, one step solved with
    MUMPS's AMD and AMF orderings (ICNTL(7) = 0, 2): both LUs are backward stable (~2 eps), so
    unrefined they differ by the forward error kappa eps, as serial and 2-rank MUMPS do; the
    step's refinement with a long-double residual (plantgrowth/models/refinement.py) brings both
    to the system's answer: cells.csv, the vertices' displacements and the measures agree to
    ORDERINGS."""
    from petsc4py import PETSc

    from plantgrowth.models.linear import lu_solver

    data = scene_data(NX, 1.0, "linear", pressure={"P1": 0.001})
    data["tissue"] = {"cells": {"voronoi": 8, "seed": 1, "regularity": 0.25}}
    model, options = MicroModel(parse_scene(data), MPI.COMM_SELF), PETSc.Options()
    key = "plantgrowth_micro_mat_mumps_icntl_7"
    answers = []
    try:
        for ordering in (0, 2):  # one model, a factorization of each ordering
            options[key] = ordering
            model.ksp = lu_solver(model.A, MPI.COMM_SELF, "plantgrowth_micro_")
            answers.append(_replicated(model, 1))
    finally:
        options.delValue(key)
    for name, value in answers[0].items():
        assert _relative(value, answers[1][name]) < ORDERINGS, name
