"""``plantgrowth render ... --fibres``: the fibre director drawn as headless line glyphs (an
axis: m and -m are the same fibres) over the field picture.

What is drawn: the fibres as they lie in the drawn tissue. The director m = (cos a, sin a) lives
in the grown frame (docs/fibres.md); a material segment along m there lies along
``Fe m = F Fg^-1 m`` in the drawn tissue, F the map from the reference tissue to it (I + grad u;
I when the run wrote no u) and Fg the growth tensor the run wrote. Each glyph is the unit
vector ``F Fg^-1 m / |F Fg^-1 m|``. A run that did not write Fg gets m itself (grown frame), and
the legend says which of the two is drawn.

Where, and how long (each glyph is centred on its site):

- macro (``fibre_direction``, one m per fine triangle): a regular square grid of picks over the
  reference tissue's box, spacing ``s = max(sqrt(box area / MAX_GLYPHS), sqrt(2 * median
  triangle area))`` (the second term keeps a coarse mesh from being picked twice in a
  triangle), its points at the centres of the grid's squares; each point inside the mesh picks
  the fine triangle that contains it (once), and the glyph sits at that triangle's current
  midpoint with the triangle's m and F (P1 u: one F per triangle). The picks are made on the
  reference tissue, so every time of a run draws the same material cells. Length
  ``GLYPH_LENGTH * s * sqrt(det F)``: the side of the current area of one grid square;
- micro (cells.csv's ``fibre_angle``, one a per biological cell): one glyph per cell at its
  current centroid (cells.csv's x1, x2), with F the least-squares affine map of the cell's
  outline vertices (cells.xdmf, reference to current: exact for a cell deformed affinely) and Fg
  the cell's (constant on its walls). Each end reaches GLYPH_LENGTH of the way from the centre
  to the cell's current outline along the glyph, on the nearer side: the glyph stays inside its
  cell (a cut bottom cell too) and scales with it.

Colour: white with a black outline, readable over every part of a colour map.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import patheffects
from matplotlib.collections import LineCollection
from matplotlib.tri import Triangulation

from plantgrowth.base.errors import InputError
from plantgrowth.results.field_hints import missing_fibres
from plantgrowth.results.reader import ResultSeries

MAX_GLYPHS = 300  # macro: about this many glyphs. Measured on the default mesh (h = 0.1) of the
# 6.93 x 3 reference tissue: 26 x 11 glyphs, 0.25 inch apart in the 9-inch picture, 0.17 inch
# long (render's 600 arrows would make them 0.12 inch); the micro model at its default
# Nx = 16 draws one per cell, 0.42 inch apart
GLYPH_LENGTH = 0.7  # macro: of the grid's spacing, 0.3 spacing between the ends of aligned
# neighbours; micro: of the way to the cell's outline (a regular hexagon's glyph: 1.2 to 1.4
# sides long, 0.3 to 0.6 side from its neighbour's)
GLYPHS_GID = "fibre_glyphs"
"""The ``gid`` of the glyphs' LineCollection (to find them in a figure)."""
TURNED_LABEL = r"fibres ($F\,F_g^{-1} m$)"
GROWN_LABEL = "fibres ($m$, grown frame: no Fg written)"
TIME_TOLERANCE = 1e-9  # relative: cells.csv's t and the written time agree to round-off


@dataclass(frozen=True)
class Glyphs:
    """Glyphs centred at ``centres`` (k, 2) along the unit ``directions`` (k, 2), ``lengths``
    (k,) long; ``turned``: the directions are F Fg^-1 m (else m, the grown frame's)."""

    centres: np.ndarray
    directions: np.ndarray
    lengths: np.ndarray
    turned: bool

    def segments(self) -> np.ndarray:
        """(k, 2, 2): each glyph's two ends, ``centre -+ length / 2 * direction``."""
        half = 0.5 * self.lengths[:, None] * self.directions
        return np.stack([self.centres - half, self.centres + half], axis=1)


def _is_micro(series: ResultSeries) -> bool:
    return series.outlines is not None


def _header(path: Path) -> list[str]:
    """The first row of a CSV file ([] if there is none)."""
    if not path.is_file():
        return []
    with path.open(newline="", encoding="utf-8") as f:
        return next(csv.reader(f), [])


def check_fibres(series: ResultSeries) -> None:
    """InputError with a hint if the run wrote no director to draw (field_hints.missing_fibres)."""
    if _is_micro(series):
        if "fibre_angle" not in _header(series.directory / "cells.csv"):
            raise InputError(missing_fibres(series, micro=True, has_director=False))
    elif "fibre_direction" not in series.names:
        has = "fibre_order" in _header(series.directory / "summary.csv")
        raise InputError(missing_fibres(series, micro=False, has_director=has))


def turned(F: np.ndarray, Fg: np.ndarray | None, m: np.ndarray) -> np.ndarray:
    """(k, 2) unit vectors ``F Fg^-1 m / |F Fg^-1 m|`` (``Fg`` None: ``m / |m|``), for F, Fg
    (k, 2, 2) and m (k, 2)."""
    image = m if Fg is None else np.einsum("kij,kjl,kl->ki", F, np.linalg.inv(Fg), m)
    return image / np.linalg.norm(image, axis=1)[:, None]


def _growth(series: ResultSeries, t: float) -> np.ndarray | None:
    """Fg per triangle (M, 2, 2) at t, or None if the run did not write it."""
    if "Fg" not in series.names:
        return None
    return series.cell_field("Fg", t)[:, [0, 1, 3, 4]].reshape(-1, 2, 2).astype(float)


def triangle_gradients(x0: np.ndarray, x: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(M, 2, 2) F of the affine map of each triangle from ``x0`` to ``x``: F D0 = D, D's
    columns the edges from the first vertex."""

    def edges(p: np.ndarray) -> np.ndarray:
        corners = p[triangles]
        return np.stack([corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]], axis=2)

    return edges(x) @ np.linalg.inv(edges(x0))


def macro_picks(series: ResultSeries) -> tuple[np.ndarray, float]:
    """(the picked triangles in grid order, the grid's spacing s); see the module docstring."""
    x0 = series.points.astype(float)
    corners = x0[series.triangles]
    areas = 0.5 * np.abs(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    low, span = x0.min(axis=0), np.ptp(x0, axis=0)
    s = max(float(np.sqrt(span[0] * span[1] / MAX_GLYPHS)), float(np.sqrt(2 * np.median(areas))))
    n = np.maximum(np.floor(span / s).astype(int), 1)
    offset = low + 0.5 * (span - (n - 1) * s)  # the grid centred on the box
    g1, g2 = np.meshgrid(offset[0] + s * np.arange(n[0]), offset[1] + s * np.arange(n[1]))
    finder = Triangulation(x0[:, 0], x0[:, 1], series.triangles).get_trifinder()
    found = np.asarray(finder(g1.ravel(), g2.ravel()))
    found = found[found >= 0]
    return found[np.sort(np.unique(found, return_index=True)[1])], s


def macro_glyphs(series: ResultSeries, t: float) -> Glyphs:
    """The glyphs of a macro run at t (``fibre_direction`` on the fine triangles)."""
    picks, s = macro_picks(series)
    x0 = series.points.astype(float)
    x = x0 + series.displacement(t) if "u" in series.names else x0
    triangles = series.triangles[picks]
    F = triangle_gradients(x0, x, triangles)
    Fg = _growth(series, t)
    m = series.cell_field("fibre_direction", t)[picks, :2].astype(float)
    lengths = GLYPH_LENGTH * s * np.sqrt(np.abs(np.linalg.det(F)))
    directions = turned(F, None if Fg is None else Fg[picks], m)
    return Glyphs(x[triangles].mean(axis=1), directions, lengths, Fg is not None)


def cell_rows(series: ResultSeries, t: float) -> dict[str, np.ndarray]:
    """cells.csv's columns at the written time t, rows in cell id order (InputError if the
    rows of t are not all there: a step being written)."""
    with (series.directory / "cells.csv").open(newline="", encoding="utf-8") as f:
        rows = [r for r in csv.DictReader(f)
                if abs(float(r["t"]) - t) <= TIME_TOLERANCE * max(1.0, abs(t))]  # fmt: skip
    n = len(np.unique(series.outlines.cell_ids(t)))
    cells = sorted(int(r["cell"]) for r in rows)
    if cells != list(range(n)):
        raise InputError(
            f"--fibres: {series.directory}/cells.csv has {len(rows)} rows at t = {t:g}, not "
            f"one for each of the {n} cells (a step still being written? try an earlier --time)"
        )
    rows.sort(key=lambda r: int(r["cell"]))
    return {
        key: np.array([float(r[key]) for r in rows]) for key in ("x1", "x2", "area", "fibre_angle")
    }


def cell_gradients(series: ResultSeries, t: float) -> np.ndarray:
    """(n, 2, 2) the least-squares F of each cell's outline vertices, reference to time t:
    F = argmin sum_v |(x_v - mean x) - F (X_v - mean X)|^2 over the cell's vertices v."""
    outline = series.outlines
    ids, x0, x = outline.cell_ids(t), outline.points, outline.deformed(t)
    F = np.empty((ids.max() + 1, 2, 2))
    for cell in range(len(F)):
        vertices = np.unique(outline.segments[ids == cell])
        dX = x0[vertices] - x0[vertices].mean(axis=0)
        dx = x[vertices] - x[vertices].mean(axis=0)
        F[cell] = np.linalg.solve(dX.T @ dX, dX.T @ dx).T
    return F


def cell_reach(series: ResultSeries, t: float, centres: np.ndarray, directions: np.ndarray
               ) -> np.ndarray:  # fmt: skip
    """(n,) how far each cell's line ``centre + r direction`` runs before it leaves the cell's
    outline at time t, on its nearer side: min(r_max, -r_min) over the crossings with the
    outline's edges ``p + s (q - p)``, s in [0, 1]."""
    outline = series.outlines
    ids, x = outline.cell_ids(t), outline.deformed(t)
    p, q = x[outline.segments[:, 0]], x[outline.segments[:, 1]]
    c, d = centres[ids], directions[ids]
    edge = q - p

    def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

    with np.errstate(divide="ignore", invalid="ignore"):  # an edge parallel to the line
        r = cross(p - c, edge) / cross(d, edge)
        s = cross(p - c, d) / cross(d, edge)
    crossing = np.isfinite(r) & (s >= 0.0) & (s <= 1.0)
    ahead = np.full(len(centres), np.inf)
    behind = np.full(len(centres), np.inf)
    np.minimum.at(ahead, ids[crossing & (r >= 0)], r[crossing & (r >= 0)])
    np.minimum.at(behind, ids[crossing & (r < 0)], -r[crossing & (r < 0)])
    return np.minimum(ahead, behind)


def micro_glyphs(series: ResultSeries, t: float) -> Glyphs:
    """The glyphs of a micro run at t (cells.csv's ``fibre_angle``), one per cell."""
    rows = cell_rows(series, t)
    a = np.radians(rows["fibre_angle"])
    m = np.column_stack([np.cos(a), np.sin(a)])
    F = cell_gradients(series, t)
    Fg = _growth(series, t)
    if Fg is not None:  # the cell's own, constant on its walls: one triangle each
        first = np.unique(series.cell_field("cell_id", t).astype(np.int64), return_index=True)[1]
        Fg = Fg[first]
    centres = np.column_stack([rows["x1"], rows["x2"]])
    directions = turned(F, Fg, m)
    lengths = 2.0 * GLYPH_LENGTH * cell_reach(series, t, centres, directions)
    return Glyphs(centres, directions, lengths, Fg is not None)


def fibre_glyphs(series: ResultSeries, t: float) -> Glyphs:
    """The glyphs of the run at the written time t (InputError: no director written)."""
    check_fibres(series)
    return micro_glyphs(series, t) if _is_micro(series) else macro_glyphs(series, t)


def draw_fibres(ax, series: ResultSeries, t: float) -> LineCollection:
    """The glyphs on ``ax``, above the field, white lines outlined in black, with a legend
    entry saying what they show."""
    glyphs = fibre_glyphs(series, t)
    style = dict(color="w", linewidth=1.5,
                 path_effects=[patheffects.withStroke(linewidth=3.0, foreground="k")])  # fmt: skip
    lines = LineCollection(glyphs.segments(), capstyle="round", zorder=4, **style)
    lines.set_gid(GLYPHS_GID)
    ax.add_collection(lines)
    ax.plot([], [], **style, label=TURNED_LABEL if glyphs.turned else GROWN_LABEL)  # the
    # legend's own handle of a LineCollection drops the outline: white on white
    return lines
