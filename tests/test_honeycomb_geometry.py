"""Honeycomb cell geometry (docs/model.md section 2): vertices, lattice, void, wall
fraction, validation.

Pure numpy: no mesh, no MPI communication; every check is exact up to float round-off unless a
comment says otherwise.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from plantgrowth.meshes.honeycomb import GeometryError, HoneycombCell, polygon_area

# Cells used across the file: reference, elongated, flat and steep walls, short vertical walls
# (the last one has w_max set by the inclined walls, not by the vertical ones).
CELLS = [
    HoneycombCell(),
    HoneycombCell(l1=2.0),
    HoneycombCell(l1=1.5, l2=0.8, theta_deg=45.0, w=0.03),
    HoneycombCell(theta_deg=10.0, w=0.02),
    HoneycombCell(l1=0.2, theta_deg=60.0, w=0.04),
]
ROUND_OFF = 1e-12  # float round-off on O(1) lengths and areas


def _side_line_distance(p: np.ndarray, q: np.ndarray, x: np.ndarray) -> float:
    """Signed distance of x to the line p->q, positive on the left (inside a CCW polygon)."""
    d = q - p
    return float((d[0] * (x[1] - p[1]) - d[1] * (x[0] - p[0])) / np.linalg.norm(d))


def _offset_area(cell: HoneycombCell) -> float:
    """Area of the hexagon offset inwards by w, while no side vanishes.

    Independent of the clipping code: A(w) = A - P w + w^2 sum cot(alpha_i / 2), alpha_i the
    interior angles (180 - 2 theta at B and E, 90 + theta at A, C, D, F), P = 2 l1 + 4 l2.
    """
    th = math.radians(cell.theta_deg)
    angles = [math.pi - 2 * th] * 2 + [0.5 * math.pi + th] * 4
    cot_sum = sum(1.0 / math.tan(0.5 * a) for a in angles)
    perimeter = 2 * cell.l1 + 4 * cell.l2
    return cell.area - perimeter * cell.w + cell.w**2 * cot_sum


def test_reference_cell_values():
    cell = HoneycombCell()
    c, s = math.cos(math.radians(30)), 0.5
    assert cell.c == pytest.approx(c, abs=ROUND_OFF)
    assert cell.s == pytest.approx(s, abs=ROUND_OFF)
    assert cell.area == pytest.approx(2 * c * (1 + s), abs=ROUND_OFF)
    assert cell.w_max == pytest.approx(c, abs=ROUND_OFF)
    # the void of a regular hexagon is a regular hexagon with apothem c - w
    assert cell.phi_w == pytest.approx(1 - (1 - 0.05 / c) ** 2, abs=ROUND_OFF)
    assert round(cell.phi_w, 5) == 0.11214  # docs/model.md section 2 sanity value


def test_hexagon_vertices_follow_model_convention():
    cell = HoneycombCell(l1=1.5, l2=0.8, theta_deg=45.0, w=0.03)
    c, s, h = cell.c, cell.s, 0.75
    expected = [[c, h], [0, h + s], [-c, h], [-c, -h], [0, -h - s], [c, -h]]
    np.testing.assert_allclose(cell.hexagon(), expected, atol=ROUND_OFF)
    np.testing.assert_allclose(cell.b1, [2 * c, 0], atol=ROUND_OFF)
    np.testing.assert_allclose(cell.b2, [c, 1.5 + s], atol=ROUND_OFF)


@pytest.mark.parametrize("cell", CELLS, ids=str)
def test_hexagon_tiles_the_plane(cell):
    """CCW, area |Y|, and each side is the opposite one reversed and shifted by a lattice vector."""
    hexagon = cell.hexagon()
    assert polygon_area(hexagon) == pytest.approx(cell.area, rel=ROUND_OFF)
    lattice = {(1, 0), (0, 1), (-1, 1), (-1, 0), (0, -1), (1, -1)}
    for i in range(3):
        p, q = hexagon[i], hexagon[(i + 1) % 6]
        p_opp, q_opp = hexagon[i + 3], hexagon[(i + 4) % 6]
        shift = p - q_opp
        np.testing.assert_allclose(q, p_opp + shift, atol=ROUND_OFF)
        a = cell.lattice_coordinates(shift[None, :])[0]
        np.testing.assert_allclose(a, np.round(a), atol=ROUND_OFF)
        assert tuple(np.round(a).astype(int)) in lattice


def test_lattice_coordinates_of_basis():
    cell = HoneycombCell(l1=2.0, theta_deg=40.0)
    np.testing.assert_allclose(
        cell.lattice_coordinates(np.array([cell.b1, cell.b2, cell.b1 - 2 * cell.b2])),
        [[1, 0], [0, 1], [1, -2]],
        atol=ROUND_OFF,
    )


@pytest.mark.parametrize("cell", CELLS, ids=str)
def test_void_is_inward_offset_by_w(cell):
    """Each void side lies on the hexagon side line shifted inwards by exactly w."""
    hexagon, void = cell.hexagon(), cell.void()
    assert len(void) == 6
    assert polygon_area(void) > 0  # CCW
    for k in range(6):
        p, q = void[k], void[(k + 1) % 6]
        # the hexagon side parallel to this void side
        d = (q - p) / np.linalg.norm(q - p)
        side = next(
            i
            for i in range(6)
            if np.allclose(
                (hexagon[(i + 1) % 6] - hexagon[i])
                / np.linalg.norm(hexagon[(i + 1) % 6] - hexagon[i]),
                d,
                atol=1e-10,
            )
        )
        for x in (p, q):
            dist = _side_line_distance(hexagon[side], hexagon[(side + 1) % 6], x)
            assert dist == pytest.approx(cell.w, abs=ROUND_OFF)
        # and no void vertex is closer than w to any side
    for i in range(6):
        for x in void:
            assert _side_line_distance(hexagon[i], hexagon[(i + 1) % 6], x) >= cell.w - ROUND_OFF


@pytest.mark.parametrize("cell", CELLS, ids=str)
def test_wall_fraction_matches_offset_formula(cell):
    assert cell.phi_w == pytest.approx(1 - _offset_area(cell) / cell.area, rel=1e-11)
    assert 0 < cell.phi_w < 1


@pytest.mark.parametrize(
    "l1, l2, theta",
    [(1.0, 1.0, 30.0), (2.0, 1.0, 30.0), (0.2, 1.0, 60.0), (1.0, 1.0, 80.0), (0.5, 2.0, 15.0)],
)
def test_w_max_is_where_the_void_vanishes(l1, l2, theta):
    w_max = HoneycombCell(l1, l2, theta).w_max
    # independent: the centre's distance to the nearest side line (the hexagon is centrally
    # symmetric and convex, so its inradius is attained at the centre)
    hexagon = HoneycombCell(l1, l2, theta).hexagon()
    inradius = min(
        _side_line_distance(hexagon[i], hexagon[(i + 1) % 6], np.zeros(2)) for i in range(6)
    )
    assert w_max == pytest.approx(inradius, rel=ROUND_OFF)
    almost = HoneycombCell(l1, l2, theta, w=w_max * (1 - 1e-6))
    area = polygon_area(almost.void())
    # the void shrinks to a segment or a point: its area is O(1e-6 * cell size)
    assert 0 < area < 1e-5 * almost.area
    assert almost.phi_w == pytest.approx(1.0, abs=1e-5)
    with pytest.raises(GeometryError, match=r"\bw\b"):
        HoneycombCell(l1, l2, theta, w=w_max)


def test_phi_w_increases_with_w():
    phis = [HoneycombCell(w=w).phi_w for w in (0.01, 0.05, 0.1, 0.3, 0.6, 0.85)]
    assert all(np.diff(phis) > 0)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"w": 0.0}, "w"),
        ({"w": -0.1}, "w"),
        ({"w": 0.9}, "w"),  # >= w_max = cos 30
        ({"w": math.nan}, "w"),
        ({"w": math.inf}, "w"),
        ({"l1": 0.0}, "l1"),
        ({"l1": -1.0}, "l1"),
        ({"l1": math.nan}, "l1"),
        ({"l2": 0.0}, "l2"),
        ({"l2": math.inf}, "l2"),
        ({"theta_deg": 0.0}, "theta"),
        ({"theta_deg": 90.0}, "theta"),
        ({"theta_deg": -10.0}, "theta"),
        ({"theta_deg": 120.0}, "theta"),
        ({"theta_deg": math.nan}, "theta"),
        ({"w": "0.05"}, "w"),
        ({"l1": True}, "l1"),
        ({"theta_deg": None}, "theta"),
    ],
)
def test_invalid_geometry_names_the_parameter(kwargs, name):
    with pytest.raises(GeometryError) as info:
        HoneycombCell(**kwargs)
    assert re.search(rf"(^|\W){name}(\W|$)", str(info.value)), str(info.value)
    assert isinstance(info.value, ValueError)


def test_cell_is_frozen():
    cell = HoneycombCell()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cell.w = 0.1  # type: ignore[misc]
