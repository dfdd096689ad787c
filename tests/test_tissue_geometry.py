"""The cellular tissue of the micro model (docs/model.md section 7): layout, walls mesh,
outline mesh.

The layout is pure geometry (no mesh) and is checked against the formulas of section 7. The
walls are straight-sided polygons (each cell's mid-line hexagon minus its void, cut at x2 = 0),
so a conforming triangulation represents them exactly: areas and lengths assembled on the mesh
must equal the polygon formulas to round-off (1e-10 relative; measured ~1e-14). Meshes are
built on COMM_WORLD, so under mpirun they are distributed and every integral is reduced.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from plantgrowth.meshes.honeycomb import GeometryError, HoneycombCell, polygon_area
from plantgrowth.meshes.tissue import (
    FACET_TAGS,
    TissueLayout,
    build_outline_mesh,
    build_walls_mesh,
    clip_below,
)

REFERENCE = HoneycombCell(1.0, 1.0, 30.0, 0.05)
THICK = HoneycombCell(1.2, 0.9, 40.0, 0.2)  # an irregular cell: the formulas are not special
ROUND_OFF = 1e-10  # straight-sided polygons meshed exactly: only floating-point sums differ


def integrate(form, comm: MPI.Comm) -> float:
    return comm.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM)


def perimeter_above_cut(polygon: np.ndarray) -> float:
    """Perimeter of a polygon without its sides lying on x2 = 0 (the symmetry plane)."""
    nxt = np.roll(polygon, -1, axis=0)
    on_cut = (np.abs(polygon[:, 1]) < 1e-12) & (np.abs(nxt[:, 1]) < 1e-12)
    return float(np.linalg.norm(nxt - polygon, axis=1)[~on_cut].sum())


@pytest.fixture(scope="module", params=[(REFERENCE, 4), (REFERENCE, 8), (THICK, 6)])
def walls(request):
    cell, nx = request.param
    layout = TissueLayout(cell, nx)
    msh, cell_tags, facet_tags = build_walls_mesh(layout, 1, MPI.COMM_WORLD)
    return layout, msh, cell_tags, facet_tags


# --- layout -----------------------------------------------------------------------------------


@pytest.mark.parametrize("nx", [2, 4, 8, 12])
@pytest.mark.parametrize("cell", [REFERENCE, THICK], ids=["regular", "irregular"])
def test_layout_rows_centres_and_scale(cell, nx):
    layout = TissueLayout(cell, nx)
    assert layout.n_cells == nx * nx // 2
    assert layout.delta_s == pytest.approx(4.0 / nx, rel=1e-15)
    d, c, s = 4.0 / nx, cell.c, cell.s
    expected = np.array(
        [
            [(k + 0.5 + 0.5 * (r % 2)) * d * 2.0 * c, r * d * (cell.l1 + s)]
            for r in range(nx // 2)
            for k in range(nx)
        ]
    )
    np.testing.assert_allclose(layout.centres, expected, rtol=1e-14, atol=1e-14)
    # the tissue's size does not depend on Nx: width 8c + (odd rows' offset c d), height ~2 (l1+s)
    width, height = layout.bounding_box
    assert width == pytest.approx(8.0 * c + (c * d if nx > 2 else 0.0), rel=1e-12)
    top = (nx // 2 - 1) * d * (cell.l1 + s) + d * (0.5 * cell.l1 + s)
    assert height == pytest.approx(top, rel=1e-12)


@pytest.mark.parametrize("nx", [2, 4, 8])
def test_bottom_row_is_cut_at_mid_height(nx):
    layout = TissueLayout(REFERENCE, nx)
    full = layout.delta_s**2 * REFERENCE.area
    for i in range(layout.n_cells):
        hexagon = layout.hexagon(i)
        assert hexagon[:, 1].min() >= -1e-15
        expected = 0.5 * full if i < nx else full
        assert polygon_area(hexagon) == pytest.approx(expected, rel=1e-12)
    # void of a bottom cell: open at x2 = 0, exactly half of it is above the cut
    void = layout.void(0)
    assert polygon_area(clip_below(void)) == pytest.approx(0.5 * polygon_area(void), rel=1e-12)


@pytest.mark.parametrize("nx", [3, 7, 1, 0, -2, 4.0, "8", True, None])
def test_bad_nx_raises_geometry_error_naming_micro_nx(nx):
    with pytest.raises(GeometryError, match=r"micro\.nx"):
        TissueLayout(REFERENCE, nx)


# --- walls mesh -------------------------------------------------------------------------------


def test_walls_mesh_has_one_tag_per_cell(walls):
    layout, msh, cell_tags, _ = walls
    n_owned = msh.topology.index_map(2).size_local
    owned = cell_tags.values[cell_tags.indices < n_owned]
    tags = set().union(*msh.comm.allgather(set(owned.tolist())))
    assert tags == set(range(1, layout.n_cells + 1))
    # every mesh cell belongs to a biological cell
    counts = msh.comm.allreduce(np.array([owned.size, n_owned]), op=MPI.SUM)
    assert counts[0] == counts[1]


@pytest.mark.mpi
def test_wall_areas_are_hexagon_minus_void(walls):
    """Per cell and in total: |walls of cell i| = |hexagon_i| - |void_i above x2 = 0|; for a
    full cell that is phi_w |hexagon_i| (docs/model.md section 2)."""
    layout, msh, cell_tags, _ = walls
    dx = ufl.Measure("dx", domain=msh, subdomain_data=cell_tags)
    one = fem.Constant(msh, 1.0)
    total = integrate(one * dx, msh.comm)
    expected = [
        polygon_area(layout.hexagon(i)) - polygon_area(clip_below(layout.void(i)))
        for i in range(layout.n_cells)
    ]
    assert total == pytest.approx(sum(expected), rel=ROUND_OFF)
    full = layout.cell.phi_w * layout.delta_s**2 * layout.cell.area
    for i in (0, layout.nx, layout.n_cells - 1):  # a cut cell, a full cell, the last one
        area = integrate(one * dx(i + 1), msh.comm)
        assert area == pytest.approx(expected[i], rel=ROUND_OFF)
        assert area == pytest.approx(full * (0.5 if i < layout.nx else 1.0), rel=ROUND_OFF)


def test_membrane_length_is_the_voids_perimeter(walls):
    layout, msh, _, facet_tags = walls
    ds = ufl.Measure("ds", domain=msh, subdomain_data=facet_tags)
    one = fem.Constant(msh, 1.0)
    membrane = integrate(one * ds(FACET_TAGS["membrane"]), msh.comm)
    expected = sum(perimeter_above_cut(clip_below(layout.void(i))) for i in range(layout.n_cells))
    assert membrane == pytest.approx(expected, rel=ROUND_OFF)
    # the cut: each bottom cell contributes its two wall thicknesses (one hexagon width minus
    # the void's width at x2 = 0)
    bottom = integrate(one * ds(FACET_TAGS["bottom"]), msh.comm)
    widths = [np.ptp(layout.hexagon(i)[:, 0]) for i in range(layout.nx)]
    void_widths = [np.ptp(clip_below(layout.void(i))[:, 0]) for i in range(layout.nx)]
    assert bottom == pytest.approx(sum(widths) - sum(void_widths), rel=ROUND_OFF)


@pytest.mark.mpi
def test_walls_mesh_is_conforming(walls):
    """No duplicated nodes (each P1 node at a distinct point) and no untagged exterior facet
    (a seam between cells that is not glued would show as both)."""
    _, msh, _, facet_tags = walls
    comm = msh.comm
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    imap = V.dofmap.index_map
    owned = V.tabulate_dof_coordinates()[: imap.size_local, :2]
    points = np.vstack(comm.allgather(owned))
    assert len(points) == imap.size_global
    scale = np.ptp(points, axis=0).max()
    unique = np.unique(np.round(points / (1e-9 * scale)), axis=0)
    assert len(unique) == imap.size_global

    msh.topology.create_connectivity(1, 2)
    exterior = mesh.exterior_facet_indices(msh.topology)
    n_facets = msh.topology.index_map(1).size_local
    tagged = facet_tags.indices[facet_tags.indices < n_facets]
    n_exterior = comm.allreduce(int(np.sum(exterior < n_facets)), op=MPI.SUM)
    n_tagged = comm.allreduce(tagged.size, op=MPI.SUM)
    assert n_tagged == n_exterior
    assert np.all(np.isin(exterior[exterior < n_facets], tagged))


# --- outline mesh -----------------------------------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("nx", [4, 8])
def test_outline_area_is_the_union_of_hexagons(nx):
    layout = TissueLayout(REFERENCE, nx)
    msh, _, _ = build_outline_mesh(layout, 0.2, MPI.COMM_WORLD)
    area = integrate(fem.Constant(msh, 1.0) * ufl.dx, msh.comm)
    expected = sum(polygon_area(layout.hexagon(i)) for i in range(layout.n_cells))
    assert area == pytest.approx(expected, rel=ROUND_OFF)
    # the hexagons tile without overlap: n_cells full cells minus Nx halves
    full = layout.delta_s**2 * REFERENCE.area
    assert expected == pytest.approx((layout.n_cells - 0.5 * nx) * full, rel=1e-12)
