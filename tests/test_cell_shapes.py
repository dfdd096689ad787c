"""Each cell's shape tensor, stretch and initial growth against the unit cell's hexagon
(meshes/cell_shapes.py, issue 34).

Pure numpy: the polygon formulas are exact, so every comparison is to round-off. ROUND_OFF is
1e-12 relative (sums over a few vertices and one 2x2 eigen-decomposition; measured ~1e-15).
"""

from __future__ import annotations

import numpy as np
import pytest

from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.meshes.cell_shapes import (
    cell_shapes,
    mirrored_moment,
    reference_tensor,
    second_moment,
    stretch_between,
)
from plantgrowth.meshes.honeycomb import GeometryError, HoneycombCell, polygon_area
from plantgrowth.meshes.tissue import TissueLayout, clip_below

ROUND_OFF = 1e-12
REGULAR = HoneycombCell(1.0, 1.0, 30.0, 0.05)
IRREGULAR = HoneycombCell(1.4, 0.8, 40.0, 0.05)  # J0 anisotropic: F is not a plain root


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def spd(rng: np.random.Generator) -> np.ndarray:
    """A random symmetric positive definite stretch, shear included."""
    Q = rotation(rng.uniform(0, np.pi))
    return Q @ np.diag(rng.uniform(0.5, 2.0, 2)) @ Q.T


def voronoi_like(rng: np.random.Generator, k: int) -> np.ndarray:
    """A convex irregular k-gon (angles sorted, radii varied), counter-clockwise."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, k))
    radii = rng.uniform(0.7, 1.3, k)
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)]) + rng.uniform(2, 4, 2)


def tissue(cell: HoneycombCell, nx: int, M: np.ndarray | None = None) -> CellPolygons:
    """The honeycomb tissue of nx cells per row as cells, each stretched by M."""
    layout, M = TissueLayout(cell, nx), np.eye(2) if M is None else M
    return CellPolygons.from_loops([layout.hexagon(i) @ M.T for i in range(layout.n_cells)])


def test_second_moment_of_a_rectangle_and_a_regular_hexagon():
    a, b = 3.0, 0.5
    area, c, S = second_moment(np.array([[1, 2], [1 + a, 2], [1 + a, 2 + b], [1, 2 + b]]))
    assert area == pytest.approx(a * b, rel=ROUND_OFF)
    assert np.allclose(c, [1 + a / 2, 2 + b / 2], rtol=ROUND_OFF)
    assert np.allclose(S, np.diag([a**3 * b / 12, a * b**3 / 12]), rtol=ROUND_OFF, atol=0)
    # regular hexagon of side L: int x1^2 = int x2^2 = 5 sqrt(3) L^4 / 16
    L = REGULAR.l2
    area, _, S = second_moment(REGULAR.hexagon())
    assert area == pytest.approx(1.5 * np.sqrt(3) * L**2, rel=ROUND_OFF)
    assert np.allclose(S, 5 * np.sqrt(3) / 16 * L**4 * np.eye(2), rtol=ROUND_OFF, atol=1e-15)


def test_shape_tensor_transforms_as_M_J_M_transpose():
    rng = np.random.default_rng(1)
    for _ in range(5):
        P, M = voronoi_like(rng, rng.integers(4, 9)), rng.normal(size=(2, 2))
        M *= np.sign(np.linalg.det(M))  # keep the orientation (counter-clockwise)
        area, _, S = second_moment(P)
        area_m, _, S_m = second_moment(P @ M.T)
        assert area_m == pytest.approx(np.linalg.det(M) * area, rel=ROUND_OFF)
        assert np.allclose(S_m / area_m, M @ (S / area) @ M.T, rtol=ROUND_OFF, atol=1e-14)


def test_mirrored_moment_equals_the_whole_cell():
    """A hexagon cut at mid-height: its mirrored moments are the whole hexagon's."""
    hexagon = IRREGULAR.hexagon() + [0.3, 0.0]
    half = clip_below(hexagon)
    area, c, S = mirrored_moment(half)
    whole_area, whole_c, whole_S = second_moment(hexagon)
    assert area == pytest.approx(whole_area, rel=ROUND_OFF)
    assert c[1] == 0.0 and c[0] == pytest.approx(whole_c[0], rel=ROUND_OFF)
    assert np.allclose(S, whole_S, rtol=ROUND_OFF, atol=1e-14)


def test_a_skewed_cut_cell_is_its_mirrored_whole():
    """A cut cell whose half is skewed (its own mixed moment int (x1 - c1) x2 dA is not zero):
    the mirrored moments are those of the half united with its mirror image, an x2-symmetric
    hexagon whose mixed moment vanishes and whose stretch has no shear (F_12 = 0)."""
    half = np.array([[0.0, 0.0], [2.0, 0.0], [1.7, 1.2], [0.2, 0.8]])
    whole = np.array([[0.2, -0.8], [1.7, -1.2], [2.0, 0.0], [1.7, 1.2], [0.2, 0.8], [0.0, 0.0]])
    assert abs(second_moment(half)[2][0, 1]) > 0.01  # the half alone is sheared
    area, c, S = mirrored_moment(half)
    whole_area, whole_c, whole_S = second_moment(whole)
    assert area == pytest.approx(whole_area, rel=ROUND_OFF)
    assert c[1] == 0.0 and c[0] == pytest.approx(whole_c[0], rel=ROUND_OFF)
    assert np.allclose(S, whole_S, rtol=ROUND_OFF, atol=1e-14)
    shapes = cell_shapes(CellPolygons.from_loops([half]), REGULAR)
    assert abs(shapes.Fg0[0, 0, 1]) < 1e-14  # x2-symmetric cell: no shear to round-off


@pytest.mark.parametrize("cell", [REGULAR, IRREGULAR], ids=["regular", "irregular"])
def test_stretch_maps_the_reference_onto_the_cell_exactly(cell):
    rng = np.random.default_rng(2)
    _, J0 = reference_tensor(cell)
    for _ in range(5):
        area, _, S = second_moment(voronoi_like(rng, rng.integers(4, 9)))
        F = stretch_between(J0, S / area)
        assert np.allclose(F, F.T, rtol=0, atol=1e-15) and np.all(np.linalg.eigvalsh(F) > 0)
        assert np.allclose(F @ J0 @ F, S / area, rtol=ROUND_OFF, atol=1e-14)


@pytest.mark.parametrize("cell", [REGULAR, IRREGULAR], ids=["regular", "irregular"])
def test_an_affine_image_of_the_hexagon_gives_its_stretch(cell):
    """F = M for a hexagon stretched (and sheared) by an SPD M; a scaled one gives s I."""
    rng = np.random.default_rng(3)
    for M in [spd(rng) for _ in range(4)] + [2.5 * np.eye(2), np.diag([1.5, 0.6])]:
        cells = CellPolygons.from_loops([cell.hexagon() @ M.T + [5.0, 5.0]])
        shapes = cell_shapes(cells, cell, delta=1.0)
        assert np.allclose(shapes.Fg0[0], M, rtol=ROUND_OFF, atol=1e-12)
        assert shapes.areas[0] == pytest.approx(np.linalg.det(M) * cell.area, rel=ROUND_OFF)


def test_a_rotated_regular_hexagon_is_unstretched():
    """Rotations of the regular hexagon leave J0 (isotropic) unchanged: Fg0 = s I, no
    rotation in it (Fg0 is symmetric)."""
    s = 1.7
    for angle in (0.1, 0.7, 2.0):
        loop = s * REGULAR.hexagon() @ rotation(angle).T + [4.0, 4.0]
        shapes = cell_shapes(CellPolygons.from_loops([loop]), REGULAR, delta=1.0)
        assert np.allclose(shapes.Fg0[0], s * np.eye(2), rtol=ROUND_OFF, atol=1e-12)


def test_irregular_cells_keep_their_area_and_the_shape_up_to_a_scalar():
    rng = np.random.default_rng(4)
    loops = [voronoi_like(rng, k) + [3.0 * i, 0.0] for i, k in enumerate([4, 5, 6, 7, 8])]
    shapes = cell_shapes(CellPolygons.from_loops(loops), IRREGULAR, delta=0.8)
    hexagon_area, J0 = reference_tensor(IRREGULAR)
    areas = np.array([polygon_area(p) for p in loops])
    assert np.allclose(shapes.areas, areas, rtol=ROUND_OFF)
    det = np.linalg.det(shapes.Fg0)
    assert np.allclose(det * 0.8**2 * hexagon_area, areas, rtol=ROUND_OFF)
    assert np.allclose(shapes.sizes, np.sqrt(areas / IRREGULAR.area), rtol=ROUND_OFF)
    for F, P in zip(shapes.Fg0, loops, strict=True):
        a, _, S = second_moment(P)
        mapped = F @ (0.8**2 * J0) @ F
        factor = np.trace(mapped) / np.trace(S / a)  # the area normalisation's scalar
        assert np.allclose(mapped, factor * S / a, rtol=ROUND_OFF, atol=1e-14)


@pytest.mark.parametrize("nx", [2, 6])
def test_a_regular_honeycomb_tissue_has_no_initial_growth(nx):
    layout = TissueLayout(REGULAR, nx)
    shapes = cell_shapes(tissue(REGULAR, nx), REGULAR)
    assert shapes.delta == pytest.approx(layout.delta_s, rel=ROUND_OFF)
    assert np.allclose(shapes.Fg0, np.eye(2), rtol=0, atol=ROUND_OFF)
    assert np.allclose(shapes.centres, layout.centres, rtol=0, atol=ROUND_OFF)
    assert np.allclose(shapes.sizes, layout.delta_s, rtol=ROUND_OFF)


def test_a_stretched_honeycomb_gets_its_stretch():
    """diag(a, b) keeps the symmetry plane: every cell (cut ones mirrored) is the stretched
    hexagon, Fg0 = diag(a, b) against delta_s, its unimodular part against the mean."""
    a, b, nx = 1.3, 0.8, 4
    cells = tissue(IRREGULAR, nx, np.diag([a, b]))
    shapes = cell_shapes(cells, IRREGULAR, delta=TissueLayout(IRREGULAR, nx).delta_s)
    assert np.allclose(shapes.Fg0, np.diag([a, b]), rtol=0, atol=ROUND_OFF)
    shapes = cell_shapes(cells, IRREGULAR)
    assert np.allclose(shapes.Fg0, np.diag([a, b]) / np.sqrt(a * b), rtol=0, atol=ROUND_OFF)


def test_cells_below_the_symmetry_plane_are_refused():
    loop = REGULAR.hexagon()  # centred at the origin: half of it below x2 = 0
    with pytest.raises(GeometryError, match="x2 >= 0"):
        cell_shapes(CellPolygons.from_loops([loop]), REGULAR)
