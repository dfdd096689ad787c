"""``plantgrowth render DIR --field NAME | --cells COLUMN [--time T|all] [--component K]
[--vmin A --vmax B] -o FILE [--force] [--regions] [--fibres]``.

Draws one written field of a finished (or still running) run on the deformed tissue, x + u(t),
with matplotlib's Agg canvas (no display needed): scalars and tensor components as colours per
cell (or node), vectors as arrows with a scale key (directions as headless bars: an axis has no
sign), the initial outline dashed and, for micro runs, the cells' outlines (cells.xdmf); with
``--fibres`` the fibre director's glyphs on top (:mod:`plantgrowth.results.fibre_glyphs`). FILE is
a .png, .pdf or .svg picture, or with ``--time all`` a .gif animation over the written times
(:mod:`plantgrowth.results.animate`); the pictures of one request share a :class:`View` (box,
colour range, arrow scale) so that they compare. Reads the run through
:mod:`plantgrowth.results.reader` and writes only FILE: never into DIR, never over an existing
file unless ``force`` (then atomically: a temporary file renamed into place).
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from plantgrowth.base.errors import InputError
from plantgrowth.results.fibre_glyphs import draw_fibres
from plantgrowth.results.field_hints import bad_component, missing_field
from plantgrowth.results import cell_columns, output_file
from plantgrowth.results.reader import (
    COMPONENTS,
    NODE_FIELDS,
    ResultSeries,
    boundary_outline,
    read_series,
)
from plantgrowth.results.region_outlines import region_outlines

VECTOR_COMPONENTS = ("1", "2", "norm")
MAX_ARROWS = 600  # macro vector fields: arrows thinned to about this many
TIME_TOLERANCE = 1e-9  # relative: --time just outside the written range is its end
PICTURES = (".png", ".pdf", ".svg")  # matplotlib's Agg, PDF and SVG backends
ALL_TIMES = "all"  # --time all: an animation over the written times
ARROW_SPACINGS = 1.5  # the longest arrow, in site spacings: matplotlib's own autoscale drew
# the longest u arrow 2.1 (macro) and 2.2 (micro) spacings long on the tests' runs (into its
# neighbours); 1.5 keeps them apart
BAR_SPACINGS = 0.9  # a direction bar: matplotlib's autoscale length for unit vectors (0.91 on
# the macro test run; 0.25 for the 8 cells of the micro one, too short to read)
FIGURE_WIDTH = 9.0  # inches (the README figures)
STRIP = 0.4  # inches: the row under the axes that holds the legend and the arrows' key
KEY_AT = FIGURE_WIDTH - 1.3  # inches from the left: the key arrow's tip (its label after it)


class RenderError(InputError):
    """A render request that cannot be met; the message starts with the option."""


def check_output(output: Path, directory: Path, animation: bool = False) -> None:
    """FILE must be a picture (.png, .pdf, .svg; .gif for an animation) outside DIR, in an
    existing directory (whether it is new: :func:`check_new`, once the field is known)."""
    suffix = output.suffix.lower()
    if animation and suffix != ".gif":
        raise RenderError(f"-o {output}: --time all writes an animation: give a .gif file")
    if not animation and suffix not in PICTURES:
        raise RenderError(
            f"-o {output}: the picture must be a {', '.join(PICTURES)} file (or, with --time "
            "all, a .gif animation)"
        )
    output_file.check_place(output, directory, RenderError)


def check_new(output: Path, force: bool) -> None:
    """FILE must be new unless ``force``."""
    output_file.check_new(output, force, "--force", RenderError)


def check_limits(vmin: float | None, vmax: float | None) -> None:
    """--vmin and --vmax, when given, are finite and vmin < vmax."""
    for option, value in (("--vmin", vmin), ("--vmax", vmax)):
        if value is not None and not math.isfinite(value):
            raise RenderError(f"{option} = {value!r} is not a finite number")
    if vmin is not None and vmax is not None and not vmin < vmax:
        raise RenderError(f"--vmin = {vmin:g} must be below --vmax = {vmax:g}")


def open_run(directory: Path) -> ResultSeries:
    """The run's series, or RenderError naming DIR."""
    if not directory.is_dir():
        raise RenderError(f"DIR {directory}: no such directory")
    try:
        return read_series(directory)
    except FileNotFoundError:
        raise RenderError(f"DIR {directory}: not a run directory (no fields.xdmf)") from None
    except (OSError, ValueError, KeyError) as err:
        raise RenderError(f"DIR {directory}: cannot read the run: {err}") from None


def pick_times(series: ResultSeries, time: float | str | None) -> list[float]:
    """``[pick_time(time)]``, or every written time for ``ALL_TIMES``."""
    if time == ALL_TIMES:
        return written_times(series)
    if isinstance(time, str):
        raise RenderError(f"--time = {time!r} is invalid: a number or {ALL_TIMES}")
    return [pick_time(series, time)]


def written_times(series: ResultSeries) -> list[float]:
    """The run's written times; RenderError if there are none yet."""
    if not series.times:
        raise RenderError(f"DIR {series.directory}: no step written yet")
    return series.times


def pick_time(series: ResultSeries, time: float | None) -> float:
    """The written time nearest ``time`` (default: the last); RenderError outside the run."""
    times = written_times(series)
    if time is None:
        return times[-1]
    slack = TIME_TOLERANCE * max(1.0, abs(times[-1]))
    if not np.isfinite(time) or time < times[0] - slack or time > times[-1] + slack:
        raise RenderError(
            f"--time = {time!r} is out of range: the run wrote t in [{times[0]:g}, "
            f"{times[-1]:g}] ({len(times)} written times)"
        )
    return min(times, key=lambda s: abs(s - time))


def check_field(series: ResultSeries, name: str) -> None:
    """RenderError unless the run wrote the field ``name`` (with what it wrote, and the field
    it may mean) or, for ``cells.csv:<column>``, its cells.csv has the column."""
    if cell_columns.is_column(name):
        cell_columns.check_column(series, name)
    elif name not in series.names:
        raise RenderError(missing_field(series, name))


def field_values(
    series: ResultSeries, name: str, t: float, component: str | None
) -> tuple[np.ndarray, bool]:
    """(values, on nodes): (n,) for a scalar or a component, (n, 2) for a vector."""
    check_field(series, name)
    if cell_columns.is_column(name):
        if component is not None:
            raise RenderError(bad_component(name, "scalar", component, ()))
        return cell_columns.column_values(series, name, t), False
    on_nodes = name in NODE_FIELDS
    data = series.field(name, t)
    if data.ndim == 2 and data.shape[1] == 9:
        if component not in COMPONENTS:
            raise RenderError(bad_component(name, "tensor", component, COMPONENTS))
        return series.cell_field(name, t, component), on_nodes
    if data.ndim == 2:
        vectors = data[:, :2]
        if component is None:
            return vectors, on_nodes
        if component not in VECTOR_COMPONENTS:
            raise RenderError(bad_component(name, "vector", component, VECTOR_COMPONENTS))
        if component == "norm":
            return np.linalg.norm(vectors, axis=1), on_nodes
        return vectors[:, int(component) - 1], on_nodes
    if component is not None:
        raise RenderError(bad_component(name, "scalar", component, ()))
    return data, on_nodes


@dataclass(frozen=True)
class Colours:
    """The colour range: [low, high], the colour bar's ``extend`` for values outside it and a
    note for the label (a field uniform to round-off)."""

    low: float
    high: float
    extend: str = "neither"
    note: str = ""


@dataclass(frozen=True)
class Arrows:
    """Arrows of a vector field: ``scale`` field units per unit length (quiver's scale, in x
    units), the key's value (None: direction bars, or a field zero everywhere)."""

    scale: float
    key: float | None


@dataclass(frozen=True)
class View:
    """What the pictures of one request share, so that they compare: the axes' box (x1 min,
    x1 max, x2 min, x2 max) and the colour range or the arrows' scale."""

    box: tuple[float, float, float, float]
    colours: Colours | None = None
    arrows: Arrows | None = None


def plan_view(
    series: ResultSeries, name: str, component: str | None, times: list[float],
    vmin: float | None = None, vmax: float | None = None,
) -> View:  # fmt: skip
    """The view of ``name`` over ``times``: colours from vmin, vmax (default: the values' range
    over all times), arrows scaled by the largest vector over all times."""
    frames = [field_values(series, name, t, component) for t in times]
    values, on_nodes = np.concatenate([v for v, _ in frames]), frames[0][1]
    if values.ndim == 2:
        if vmin is not None or vmax is not None:
            raise RenderError(
                f"--vmin/--vmax: {name} is drawn as arrows, without colours; give --component "
                f"{', '.join(VECTOR_COMPONENTS)} to draw it as colours"
            )
        arrows = arrow_scale(series, name, values, on_nodes)
        reach = BAR_SPACINGS / 2 if arrows.key is None else ARROW_SPACINGS  # beyond the sites
        return View(_box(series, times, reach * arrows_spacing(series, on_nodes)), None, arrows)
    return View(_box(series, times, 0.0), colour_range(values, vmin, vmax))


def colour_range(values: np.ndarray, vmin: float | None, vmax: float | None) -> Colours:
    """[vmin, vmax] (each default: the values' extreme); a field uniform to round-off gets one
    colour (mean +- 1e-3 of its size), not a map of the noise."""
    low, high = float(values.min()), float(values.max())
    if vmin is None and vmax is None:
        scale = max(abs(low), abs(high), 1e-300)
        if high - low <= 1e-6 * scale:
            mean = float(values.mean())
            return Colours(mean - 1e-3 * scale, mean + 1e-3 * scale, note=f" (uniform {mean:.4g})")
    lo = low if vmin is None else vmin
    hi = high if vmax is None else vmax
    if not lo < hi:
        given = f"--vmin = {vmin:g}" if vmax is None else f"--vmax = {vmax:g}"
        raise RenderError(
            f"{given} leaves no range: the field's values lie in [{low:.4g}, {high:.4g}]; give "
            "both --vmin and --vmax"
        )
    extend = {(False, False): "neither", (True, False): "min", (False, True): "max"}
    return Colours(lo, hi, extend.get((low < lo, high > hi), "both"))


def arrows_spacing(series: ResultSeries, on_nodes: bool) -> float:
    """The distance between arrow sites on the reference tissue: sqrt(area of its box / number
    of sites), the sites the cells or the thinned nodes or triangles (chosen on the reference
    tissue, they follow it as it grows)."""
    x0 = series.points
    if series.outlines is not None and "cell_id" in series.names and not on_nodes:
        sites = len(np.unique(series.cell_field("cell_id", series.times[0])))
    else:
        sites = len(_thinned(_sites(x0, series.triangles, on_nodes)))
    span = np.ptp(x0, axis=0)
    return float(np.sqrt(span[0] * span[1] / sites))


def arrow_scale(series: ResultSeries, name: str, vectors: np.ndarray, on_nodes: bool) -> Arrows:
    """The longest vector is ARROW_SPACINGS site spacings long (a direction, a bar of
    BAR_SPACINGS); the key's value is the largest 1, 2 or 5 x 10^k not above the longest."""
    spacing = arrows_spacing(series, on_nodes)
    longest = float(np.linalg.norm(vectors, axis=1).max())
    if name.endswith("_direction"):
        return Arrows(max(longest, 1e-300) / (BAR_SPACINGS * spacing), None)
    if longest <= 0.0:
        return Arrows(1.0, None)
    power = 10.0 ** math.floor(math.log10(longest))
    key = max(m * power for m in (1.0, 2.0, 5.0) if m * power <= longest * (1 + 1e-12))
    return Arrows(longest / (ARROW_SPACINGS * spacing), key)


def _box(series: ResultSeries, times: list[float], pad: float) -> tuple[float, float, float, float]:
    """The initial and every deformed tissue, widened by ``pad`` (arrows) and 3% margins."""
    x0 = series.points
    shapes = [x0] + [x0 + series.displacement(t) for t in times if "u" in series.names]
    low = np.min([x.min(axis=0) for x in shapes], axis=0) - pad
    high = np.max([x.max(axis=0) for x in shapes], axis=0) + pad
    margin = 0.03 * (high - low)
    return (low[0] - margin[0], high[0] + margin[0], low[1] - margin[1], high[1] + margin[1])


class _Cells:
    """A micro run's biological cells at time t: deformed polygons, the initial outline (the
    polygons' unshared edges) and each cell's value of a DG0 field (constant per cell)."""

    def __init__(self, series: ResultSeries, t: float) -> None:
        outline = series.outlines
        ids = outline.cell_ids(t)
        deformed = outline.deformed(t)
        order = np.argsort(ids, kind="stable")  # a cell's edges stay in polygon order
        starts = outline.segments[order, 0]
        splits = np.cumsum(np.bincount(ids))[:-1]
        self.polygons = [deformed[v] for v in np.split(starts, splits)]
        self.centres = np.array([p.mean(axis=0) for p in self.polygons])
        edges = np.sort(outline.segments, axis=1)
        unique, counts = np.unique(edges, axis=0, return_counts=True)
        self.initial = outline.points[unique[counts == 1]]
        self.triangle_cell = series.cell_field("cell_id", t).astype(np.int64)

    def values(self, per_triangle: np.ndarray) -> np.ndarray:
        """Per-cell values of a field constant on each cell's walls."""
        first = np.unique(self.triangle_cell, return_index=True)[1]
        return per_triangle[first]


def _thinned(centres: np.ndarray) -> np.ndarray:
    """Indices of at most about MAX_ARROWS sites spread over the tissue (the first in each
    square bin)."""
    span = np.ptp(centres, axis=0)
    step = max(float(np.sqrt(span[0] * span[1] / MAX_ARROWS)), 1e-300)
    bins = np.floor((centres - centres.min(axis=0)) / step).astype(np.int64)
    return np.sort(np.unique(bins, axis=0, return_index=True)[1])


def _sites(x: np.ndarray, triangles: np.ndarray, on_nodes: bool) -> np.ndarray:
    """Where a field's values sit: the nodes, or the triangles' centres."""
    return x if on_nodes else x[triangles].mean(axis=1)


def _arrows(ax, name: str, where: np.ndarray, vectors: np.ndarray, arrows: Arrows) -> None:
    """Arrows (directions: bars centred on their site) at the view's scale, with a key; none
    for a zero vector (a site at rest, an isotropic cell: no direction), noted in the legend
    if every site drawn has one (matplotlib would draw dots)."""
    moving = np.linalg.norm(vectors, axis=1) > 0.0
    if not moving.any():
        ax.plot([], [], " ", label=f"{name} = 0 at every site")
    where, vectors = where[moving], vectors[moving]
    scaled = dict(angles="xy", scale_units="xy", scale=arrows.scale, color="C3")
    if name.endswith("_direction"):  # an axis: a bar centred on its site
        ax.quiver(*where.T, *vectors.T, pivot="middle", headwidth=0, headlength=0,
                  headaxislength=0, width=0.004, **scaled)  # fmt: skip
        return
    quiver = ax.quiver(*where.T, *vectors.T, width=0.003, **scaled)
    if arrows.key is not None:
        ax.quiverkey(quiver, KEY_AT, STRIP / 2, arrows.key,
                     f"|{name}| = {arrows.key:g}", labelpos="E", coordinates="inches",
                     fontproperties={"size": 9})  # fmt: skip


def _colour_bar(fig, ax, mappable, colours: Colours, label: str) -> None:
    mappable.set_clim(colours.low, colours.high)
    bar = fig.colorbar(mappable, ax=ax, shrink=0.9, format="%.5g", extend=colours.extend)
    bar.set_label(label + colours.note)


def _draw_regions(ax, series: ResultSeries, t: float) -> None:
    """Each region's outline in its own colour, named in the legend."""
    try:
        outlines = region_outlines(series, t)
    except InputError as err:
        raise RenderError(str(err)) from None
    for i, (name, segments) in enumerate(outlines.items()):
        colour = f"C{(i + 1) % 10}"  # C0 is the colour map's neighbour: start at C1
        lines = LineCollection(segments, colors=colour, linewidths=2.0, label=f"region {name}")
        ax.add_collection(lines)


def draw(
    series: ResultSeries, name: str, t: float, component: str | None, title: str | None = None,
    view: View | None = None, fig: Figure | None = None, regions: bool = False,
    fibres: bool = False,
) -> Figure:  # fmt: skip
    """The figure of one field at one written time (see the module docstring), in ``view``
    (default: this time's own) and into ``fig`` (cleared; default: a new figure sized to fit);
    with ``regions``, the outlines of the scene's regions
    (plantgrowth/results/region_outlines.py); with ``fibres``, the fibre director's glyphs
    (plantgrowth/results/fibre_glyphs.py)."""
    view = view or plan_view(series, name, component, [t])
    fitted = fig is None
    fig = fig or new_figure(view)
    fig.clear()
    values, on_nodes = field_values(series, name, t, component)
    x0 = series.points
    x = x0 + series.displacement(t) if "u" in series.names else x0
    tri = Triangulation(x[:, 0], x[:, 1], series.triangles)
    cells = _Cells(series, t) if series.outlines is not None and "cell_id" in series.names else None
    ax = fig.add_subplot()
    label = name if component is None else f"{name} [{component}]"
    scalar = values.ndim == 1
    if cells is not None and not on_nodes:  # one value per biological cell
        per_cell = cells.values(values)
        polygons = PolyCollection(cells.polygons, edgecolors="k", linewidths=0.5,
                                  facecolors="0.85" if not scalar else None)  # fmt: skip
        if scalar:
            polygons.set_array(per_cell)
        ax.add_collection(polygons)
        if scalar:
            _colour_bar(fig, ax, polygons, view.colours, f"{label} at t = {t:g}")
        else:
            _arrows(ax, name, cells.centres, per_cell, view.arrows)
    elif scalar:
        mesh = ax.tripcolor(tri, values) if on_nodes else ax.tripcolor(tri, facecolors=values)
        _colour_bar(fig, ax, mesh, view.colours, f"{label} at t = {t:g}")
    else:
        ax.tripcolor(tri, facecolors=np.ones(len(series.triangles)), cmap="Greys",
                     vmin=0.0, vmax=5.0)  # fmt: skip
        sites = _thinned(_sites(x0, series.triangles, on_nodes))  # the same at every time
        _arrows(ax, name, _sites(x, series.triangles, on_nodes)[sites], values[sites], view.arrows)
    if cells is not None:
        if on_nodes:
            ax.add_collection(PolyCollection(cells.polygons, facecolors="none",
                                             edgecolors="k", linewidths=0.5))  # fmt: skip
        initial = LineCollection(cells.initial, colors="k", linestyles="--", linewidths=1.0)
        ax.add_collection(initial)
        initial.set_label("initial outline (t = 0)")
    else:
        loop = boundary_outline(x0, series.triangles)[0]
        ax.plot(*x0[np.append(loop, loop[0])].T, "k--", lw=1.0, label="initial outline (t = 0)")
    if regions:
        _draw_regions(ax, series, t)
    if fibres:
        draw_fibres(ax, series, t)
    ax.set_aspect("equal")
    ax.set_xlim(*view.box[:2])
    ax.set_ylim(*view.box[2:])
    ax.set_xlabel("$x_1$")
    ax.set_ylabel("$x_2$")
    _legend_row(fig, ax)
    fig.suptitle(fitted_title(fig, title or f"{series.directory.name}: {label}, t = {t:g}"))
    if fitted:
        fit_height(fig)
    return fig


def _legend_row(fig: Figure, ax) -> None:
    """The legend in one row in the bottom STRIP, from the left (the arrows' key is right)."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="center left", ncol=max(len(labels), 1), fontsize=9,
               frameon=False, bbox_to_anchor=(0.5, STRIP / 2),
               bbox_transform=fig.dpi_scale_trans)  # fmt: skip


def new_figure(view: View) -> Figure:
    """A figure FIGURE_WIDTH wide whose height fits the box's aspect (plus the title, the
    labels, the legend and, for colours, the colour bar's width), 3 to 12 inches."""
    axes_width = FIGURE_WIDTH - (2.2 if view.colours is not None else 1.0)
    aspect = (view.box[3] - view.box[2]) / (view.box[1] - view.box[0])
    height = min(max(axes_width * aspect + 1.8, 3.0), 12.0)
    fig = Figure(figsize=(FIGURE_WIDTH, height), layout="constrained")
    FigureCanvasAgg(fig)
    _keep_strip(fig)
    return fig


def _keep_strip(fig: Figure) -> None:
    """Lay the axes out above the bottom STRIP (legend, key), whatever the figure's height."""
    strip = STRIP / fig.get_figheight()
    fig.get_layout_engine().set(rect=(0.0, strip, 1.0, 1.0 - strip))


def fitted_title(fig: Figure, title: str) -> str:
    """``title`` broken into lines (at spaces, else anywhere) no wider than the figure less
    5%, in the figure title's font."""
    probe = fig.suptitle(title)
    renderer = fig.canvas.get_renderer()
    room = 0.95 * fig.bbox.width
    lines = title
    while probe.get_window_extent(renderer).width > room:
        longest = max(len(line) for line in lines.splitlines())
        width = int(longest * room / probe.get_window_extent(renderer).width)
        if width < 1 or width >= longest:
            width = longest - 1
        if width < 1:
            break
        lines = textwrap.fill(title, width=width, break_long_words=True, break_on_hyphens=False)
        probe.set_text(lines)
    return lines


def fit_height(fig: Figure) -> None:
    """Lay the figure out until the axes settle (after one pass with a wrapped title the x1
    label sat on the legend: measured, macro u with a 3-line title) and grow it until everything
    lies inside it (a safety net: before issue 21 an equal-aspect axes that filled the width
    pushed the title out of the macro arrow pictures)."""
    placed = None
    for _ in range(6):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        inches = fig.dpi_scale_trans.inverted()
        boxes = [fig.get_tightbbox(renderer)]
        boxes += [key.text.get_window_extent(renderer).transformed(inches)
                  for ax in fig.axes for key in ax.artists if hasattr(key, "text")]  # fmt: skip
        below = max(-min(b.y0 for b in boxes), 0.0)
        above = max(max(b.y1 for b in boxes) - fig.get_figheight(), 0.0)
        if below + above > 0.0:
            fig.set_figheight(fig.get_figheight() + below + above + 0.1)
            _keep_strip(fig)
            placed = None
            continue
        now = np.array([ax.get_position().bounds[1::2] for ax in fig.axes])  # bottom, height
        if placed is not None and np.allclose(now, placed, rtol=0.0, atol=1e-3):
            return
        placed = now
