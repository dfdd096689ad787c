"""``plantgrowth render DIR --field NAME [--time T] [--component K] -o FILE.png [--force]``.

Draws one written field of a finished (or still running) run on the deformed tissue, x + u(t),
with matplotlib's Agg canvas (no display needed): scalars and tensor components as colours per
cell (or node), vectors as arrows (directions as headless bars: an axis has no sign), the
initial outline dashed and, for micro runs, the cells' outlines (cells.xdmf). Reads the run
through :mod:`plantgrowth.results.reader` and writes only FILE.png: never into DIR, never over
an existing file unless ``force`` (then atomically: a temporary file renamed into place).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from plantgrowth.base.errors import InputError
from plantgrowth.results.reader import COMPONENTS, ResultSeries, boundary_outline, read_series
from plantgrowth.results.region_outlines import region_outlines

VECTOR_COMPONENTS = ("1", "2", "norm")
MAX_ARROWS = 600  # macro vector fields: arrows thinned to about this many
TIME_TOLERANCE = 1e-9  # relative: --time just outside the written range is its end


class RenderError(InputError):
    """A render request that cannot be met; the message starts with the option."""


def check_output(output: Path, directory: Path, force: bool) -> None:
    """FILE.png must be a .png outside DIR, in an existing directory, new unless ``force``."""
    if output.suffix.lower() != ".png":
        raise RenderError(f"-o {output}: the picture must be a .png file")
    if output.is_dir():
        raise RenderError(f"-o {output}: is a directory; give a file name ending in .png")
    if output.exists() and not force:
        raise RenderError(f"-o {output}: the file exists; give --force to replace it")
    if not output.parent.resolve().is_dir():
        raise RenderError(f"-o {output}: the directory {output.parent} does not exist")
    run = directory.resolve()
    if run == output.parent.resolve() or run in output.parent.resolve().parents:
        raise RenderError(
            f"-o {output}: inside the run directory {directory}; plantgrowth never writes "
            "into a run after it: choose a path outside it"
        )


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


def pick_time(series: ResultSeries, time: float | None) -> float:
    """The written time nearest ``time`` (default: the last); RenderError outside the run."""
    times = series.times
    if not times:
        raise RenderError(f"DIR {series.directory}: no step written yet")
    if time is None:
        return times[-1]
    slack = TIME_TOLERANCE * max(1.0, abs(times[-1]))
    if not np.isfinite(time) or time < times[0] - slack or time > times[-1] + slack:
        raise RenderError(
            f"--time = {time!r} is out of range: the run wrote t in [{times[0]:g}, "
            f"{times[-1]:g}] ({len(times)} written times)"
        )
    return min(times, key=lambda s: abs(s - time))


def field_values(
    series: ResultSeries, name: str, t: float, component: str | None
) -> tuple[np.ndarray, bool]:
    """(values, on nodes): (n,) for a scalar or a component, (n, 2) for a vector."""
    if name not in series.names:
        raise RenderError(
            f"--field = {name!r} is not written in {series.directory}: one of "
            f"{', '.join(series.names)}"
        )
    on_nodes = name == "u"
    data = series.displacement(t) if on_nodes else series.cell_field(name, t)
    if data.ndim == 2 and data.shape[1] == 9:
        if component not in COMPONENTS:
            raise RenderError(
                f"--component = {component!r} is invalid for the tensor field {name}: one of "
                f"{', '.join(COMPONENTS)}"
            )
        return series.cell_field(name, t, component), on_nodes
    if data.ndim == 2:
        vectors = data[:, :2]
        if component is None:
            return vectors, on_nodes
        if component not in VECTOR_COMPONENTS:
            raise RenderError(
                f"--component = {component!r} is invalid for the vector field {name}: one of "
                f"{', '.join(VECTOR_COMPONENTS)} (or none, for arrows)"
            )
        if component == "norm":
            return np.linalg.norm(vectors, axis=1), on_nodes
        return vectors[:, int(component) - 1], on_nodes
    if component is not None:
        raise RenderError(f"--component = {component!r}: {name} is a scalar field, it has none")
    return data, on_nodes


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


def _arrows(ax, name: str, where: np.ndarray, vectors: np.ndarray) -> None:
    if name.endswith("_direction"):  # an axis: a bar centred on its site
        ax.quiver(*where.T, *vectors.T, pivot="middle", headwidth=0, headlength=0,
                  headaxislength=0, color="C3", width=0.004)  # fmt: skip
    else:
        ax.quiver(*where.T, *vectors.T, color="C3", width=0.003)


def _colour_bar(fig, ax, mappable, values: np.ndarray, label: str) -> None:
    spread, scale = float(np.ptp(values)), max(float(np.abs(values).max()), 1e-300)
    if spread <= 1e-6 * scale:  # uniform to round-off: one colour, not a map of the noise
        mean = float(values.mean())
        mappable.set_clim(mean - 1e-3 * scale, mean + 1e-3 * scale)
        label += f" (uniform {mean:.4g})"
    fig.colorbar(mappable, ax=ax, shrink=0.9, format="%.5g").set_label(label)


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
    regions: bool = False,
) -> Figure:  # fmt: skip
    """The figure of one field at one written time (see the module docstring); with
    ``regions``, the outlines of the scene's regions (plantgrowth/results/region_outlines.py)."""
    values, on_nodes = field_values(series, name, t, component)
    x0 = series.points
    x = x0 + series.displacement(t) if "u" in series.names else x0
    tri = Triangulation(x[:, 0], x[:, 1], series.triangles)
    cells = _Cells(series, t) if series.outlines is not None and "cell_id" in series.names else None
    fig = Figure(figsize=(9, 4.5), constrained_layout=True)
    FigureCanvasAgg(fig)
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
            _colour_bar(fig, ax, polygons, per_cell, f"{label} at t = {t:g}")
        else:
            _arrows(ax, name, cells.centres, per_cell)
    elif scalar:
        mesh = ax.tripcolor(tri, values) if on_nodes else ax.tripcolor(tri, facecolors=values)
        _colour_bar(fig, ax, mesh, values, f"{label} at t = {t:g}")
    else:
        ax.tripcolor(tri, facecolors=np.ones(len(series.triangles)), cmap="Greys",
                     vmin=0.0, vmax=5.0)  # fmt: skip
        centres = x if on_nodes else x[series.triangles].mean(axis=1)
        sites = _thinned(centres)
        _arrows(ax, name, centres[sites], values[sites])
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
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("$x_1$")
    ax.set_ylabel("$x_2$")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), fontsize=9, frameon=False)
    ax.set_title(title or f"{series.directory.name}: {label}, t = {t:g}")
    return fig


def render(
    directory: Path, name: str, output: Path, time: float | None = None,
    component: str | None = None, force: bool = False, title: str | None = None, dpi: int = 150,
    regions: bool = False,
) -> Path:  # fmt: skip
    """Draw ``name`` of the run in ``directory`` at the written time nearest ``time`` (default
    the last) into the PNG ``output``; returns the time drawn's file. RenderError on bad input."""
    directory, output = Path(directory), Path(output)
    check_output(output, directory, force)
    series = open_run(directory)
    t = pick_time(series, time)
    fig = draw(series, name, t, component, title, regions)
    tmp = output.with_name(f".{output.name}.tmp")
    try:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.replace(tmp, output)
    finally:
        tmp.unlink(missing_ok=True)
    return output
