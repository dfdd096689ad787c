"""``plantgrowth render ... --fibres`` (issue 22, item 5): the fibre director drawn as headless
glyphs over the field picture (plantgrowth/results/fibre_glyphs.py), read back from the drawn
LineCollection; the hint for a run without a director; the pictures it writes.

Runs (in process through ``main`` on every rank, so under mpirun they are 2-rank runs and the
pictures are drawn from their output): a macro (h = 0.5) and a micro (Nx = 4, one element across
a wall) tissue with fibres along ``a = 30 + 40 x1 / 3`` degrees (30 to 122: every glyph its own
direction), two steps of the strain law; and three runs without a director to draw. ROUND_OFF:
the drawn and the expected glyphs come from the same written float32 data through different
float64 arithmetic (inverse versus barycentric gradients, normal equations versus lstsq), so they
agree to ~1e-15; 1e-12 leaves room and still fails on any wrong F, Fg, site or length.
"""

from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest
from cli_helpers import RANK0, call, runs_and_pictures
from matplotlib.image import imread
from matplotlib.path import Path as PolygonPath
from PIL import Image

from plantgrowth.base.errors import InputError
from plantgrowth.results import animate as animate_module
from plantgrowth.results import picture as picture_module
from plantgrowth.results.fibre_glyphs import (
    GLYPH_LENGTH,
    GLYPHS_GID,
    GROWN_LABEL,
    MAX_GLYPHS,
    TURNED_LABEL,
    macro_picks,
)
from plantgrowth.results.reader import read_series
from plantgrowth.results.render import draw

ROUND_OFF = 1e-12  # module docstring
WALLS = '[walls]\nfibre_stiffness = 5.0\nfibre_angle = {expr = "30 + 40*x1/3"}\n'
COMMON = '[growth]\nlaw = "strain"\n[time]\nt_max = 2\n[regions]\nleft = {expr = "x1 < 3"}\n'
MACRO = "[tissue]\nh = 0.5\nH = 1.0\n[accuracy]\ncell_resolution = 1\n"
MICRO = 'model = "micro"\n[micro]\nnx = 4\nresolution = 1\n'
SCENES = {
    "macro": MACRO + WALLS + COMMON + '[output]\nfields = ["u", "Fg", "trG", "fibre_direction"]\n',
    "micro": MICRO + WALLS + COMMON + '[output]\nfields = ["u", "Fg", "trG"]\n',
}
SCENES |= {  # without a director to draw (the hints): one step
    name: text.replace("t_max = 2", "t_max = 1") + '[output]\nfields = ["u", "trG"]\n'
    for name, text in (("macro_unwritten", MACRO + WALLS + COMMON),
                       ("macro_plain", MACRO + COMMON), ("micro_plain", MICRO + COMMON))
}  # fmt: skip


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{name: DIR} of SCENES' runs and a directory for pictures."""
    return runs_and_pictures(tmp_path_factory, "render_fibres", SCENES)


def drawn_glyphs(fig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres, unit directions, lengths) of the glyphs drawn in ``fig``."""
    found = [c for c in fig.axes[0].collections if c.get_gid() == GLYPHS_GID]
    assert len(found) == 1
    ends = np.array(found[0].get_segments())
    along = ends[:, 1] - ends[:, 0]
    lengths = np.linalg.norm(along, axis=1)
    return ends.mean(axis=1), along / lengths[:, None], lengths


def legend_labels(fig) -> list[str]:
    return fig.axes[0].get_legend_handles_labels()[1]


def sine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|sin| of the angle between unit vectors: 0 for the same axis, whatever the sign."""
    return np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def reduced(degrees: np.ndarray) -> np.ndarray:
    """An axis angle in (-90, 90]."""
    return 90.0 - np.mod(90.0 - degrees, 180.0)


def barycentric_F(x0: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(k, 2, 2) F of P1 maps, triangles' corners x0 -> x (k, 3, 2): F_ij = sum_v x_vi dN_v/dX_j."""
    ones = np.ones(x0.shape[:2] + (1,))
    gradients = np.linalg.inv(np.concatenate([ones, x0], axis=2))[:, 1:, :]  # dN_v/dX_j: (k, j, v)
    return np.einsum("kvi,kjv->kij", x, gradients)


def fg_tensors(series, t: float) -> np.ndarray:
    return series.cell_field("Fg", t)[:, [0, 1, 3, 4]].reshape(-1, 2, 2).astype(float)


def test_macro_glyphs_are_the_written_director_in_the_drawn_tissue(runs):
    """Each glyph sits on a picked fine triangle's current midpoint, along F Fg^-1 m of that
    triangle's written m, GLYPH_LENGTH grid spacings times sqrt(det F) long; the same material
    triangles at every time, about MAX_GLYPHS or fewer on a regular grid."""
    dirs, _ = runs
    series = read_series(dirs["macro"])
    picks, spacing = macro_picks(series)
    span = np.ptp(series.points, axis=0)
    assert len(picks) == np.prod(np.floor(span / spacing)) <= MAX_GLYPHS  # a full grid, h = 0.5
    triangles_drawn = []
    for t in series.times[0], series.times[-1]:
        fig = draw(series, "trG", t, None, fibres=True)
        assert TURNED_LABEL in legend_labels(fig)
        centres, directions, lengths = drawn_glyphs(fig)
        x = series.points + series.displacement(t)
        midpoints = x[series.triangles].mean(axis=1)
        gaps = np.linalg.norm(centres[:, None] - midpoints[None], axis=2)
        assert gaps.min(axis=1).max() < ROUND_OFF
        cells = gaps.argmin(axis=1)
        triangles_drawn.append(sorted(cells))
        F = barycentric_F(series.points[series.triangles[cells]], x[series.triangles[cells]])
        m = series.cell_field("fibre_direction", t)[cells, :2].astype(float)
        image = np.einsum("kij,kj->ki", F, np.linalg.solve(fg_tensors(series, t)[cells], m))
        expected = image / np.linalg.norm(image, axis=1)[:, None]
        assert sine(directions, expected).max() < ROUND_OFF
        assert np.allclose(lengths, GLYPH_LENGTH * spacing * np.sqrt(np.linalg.det(F)),
                           rtol=ROUND_OFF, atol=0.0)  # fmt: skip
        # the written director is the scene's angle at the midpoint (float32: 1e-6); the drawn
        # glyph is turned from it by the elastic deformation only (measured: at most 0.22 deg
        # at t = 0, 0.40 at t = 2)
        a = np.radians(30 + 40 * series.points[series.triangles[cells]].mean(axis=1)[:, 0] / 3)
        scene = np.column_stack([np.cos(a), np.sin(a)])
        assert sine(m / np.linalg.norm(m, axis=1)[:, None], scene).max() < 1e-6
        turn = np.degrees(np.arcsin(sine(directions, scene)))
        assert 0.0 < turn.max() < 1.0
        assert np.ptp(reduced(np.degrees(a))) > 90.0  # not one direction for all
    assert triangles_drawn[0] == triangles_drawn[1]


def test_micro_glyphs_are_the_cells_directors_in_the_drawn_tissue(runs):
    """One glyph per cell at cells.csv's current centroid, along F Fg^-1 m of its fibre_angle
    (F: the affine fit of the cell's outline), inside the cell; at t = 0 m is the scene's angle
    at the cell's centre."""
    dirs, _ = runs
    series = read_series(dirs["micro"])
    with (dirs["micro"] / "cells.csv").open(newline="") as f:
        table = list(csv.DictReader(f))
    outline = series.outlines
    for t in series.times[0], series.times[-1]:
        rows = sorted((r for r in table if float(r["t"]) == t), key=lambda r: int(r["cell"]))
        column = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
        fig = draw(series, "trG", t, None, fibres=True)
        assert TURNED_LABEL in legend_labels(fig)
        centres, directions, lengths = drawn_glyphs(fig)
        assert len(centres) == len(rows) == 8
        assert np.abs(centres - np.column_stack([column["x1"], column["x2"]])).max() < ROUND_OFF
        ids, x = outline.cell_ids(t), outline.deformed(t)
        per_triangle = series.cell_field("cell_id", t).astype(int)
        Fg = fg_tensors(series, t)
        a = np.radians(column["fibre_angle"])
        for cell in range(len(rows)):
            vertices = np.unique(outline.segments[ids == cell])
            X = np.column_stack([outline.points[vertices], np.ones(len(vertices))])
            F = np.linalg.lstsq(X, x[vertices], rcond=None)[0][:2].T
            m = np.array([np.cos(a[cell]), np.sin(a[cell])])
            image = F @ np.linalg.solve(Fg[np.flatnonzero(per_triangle == cell)[0]], m)
            assert sine(directions[cell : cell + 1], image[None] / np.linalg.norm(image))[0] < (
                ROUND_OFF
            )
            polygon = PolygonPath(x[outline.segments[ids == cell][:, 0]])
            ends = centres[cell] + np.outer([-0.5, 0.5], lengths[cell] * directions[cell])
            assert polygon.contains_points(ends).all()  # order: the outline's own edges
            assert lengths[cell] > 0.3 * np.sqrt(column["area"][cell])  # not a dot
        if t == 0.0:
            assert np.abs(column["fibre_angle"] - reduced(30 + 40 * column["x1_ref"] / 3)).max() < (
                1e-9
            )


@pytest.mark.parametrize("model", ["macro", "micro"])
def test_without_fg_the_grown_frame_director_is_drawn_and_named(runs, model):
    """A run that wrote no Fg cannot turn m into the drawn tissue: the glyphs are m itself, and
    the legend says so."""
    dirs, _ = runs
    series = read_series(dirs[model])
    t = series.times[-1]
    turned_fig = draw(series, "trG", t, None, fibres=True)
    del series.datasets["Fg"]
    fig = draw(series, "trG", t, None, fibres=True)
    assert GROWN_LABEL in legend_labels(fig) and TURNED_LABEL not in legend_labels(fig)
    centres, directions, _ = drawn_glyphs(fig)
    if model == "macro":
        x = series.points + series.displacement(t)
        gaps = np.linalg.norm(centres[:, None] - x[series.triangles].mean(axis=1)[None], axis=2)
        m = series.cell_field("fibre_direction", t)[gaps.argmin(axis=1), :2].astype(float)
    else:
        with (dirs["micro"] / "cells.csv").open(newline="") as f:
            a = np.radians([float(r["fibre_angle"]) for r in csv.DictReader(f)
                            if float(r["t"]) == t])  # fmt: skip
        m = np.column_stack([np.cos(a), np.sin(a)])
    assert sine(directions, m / np.linalg.norm(m, axis=1)[:, None]).max() < ROUND_OFF
    # and the turn by F Fg^-1 is a real (small) one: the two pictures differ
    assert sine(directions, drawn_glyphs(turned_fig)[1]).max() > 1e-6


HINTS = {  # a run without a director to draw -> what the error names
    "macro_unwritten": 'its scene has a director but did not write it: add "fibre_direction" to '
    "the scene's [output] fields",
    "macro_plain": "its scene has no fibres: give it [walls] fibre_stiffness and fibre_angle (or "
    '[feedback]), add "fibre_direction"',
    "micro_plain": "(its cells.csv has no fibre_angle column): a micro run writes it when the "
    "scene has fibres: give it [walls] fibre_stiffness",
}


@pytest.mark.parametrize("time", [[], ["--time", "all"]], ids=["picture", "animation"])
@pytest.mark.parametrize("name", sorted(HINTS))
def test_fibres_of_a_run_without_a_director_name_the_scene_key(runs, name, time, capsys):
    dirs, pictures = runs
    picture = pictures / f"hint_{name}{'.gif' if time else '.png'}"
    code, _, err = call(["render", dirs[name], "--field", "trG", "--fibres", *time, "-o",
                         picture], capsys)  # fmt: skip
    assert code == 2
    if RANK0:
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith(
            f"plantgrowth: error: --fibres: {dirs[name]} has no fibre director to draw"
        )
        assert HINTS[name] in lines[0]
        assert not picture.exists() and not list(pictures.glob(".*"))


CASES = {  # name -> (run, options after the run, picture suffix)
    "macro_png": ("macro", ["--field", "trG"], ".png"),
    "micro_png_time": ("micro", ["--field", "trG", "--time", "1"], ".png"),
    "macro_pdf_limits": ("macro", ["--field", "trG", "--vmin", "0.003", "--vmax", "0.005"], ".pdf"),
    "micro_svg_arrows": ("micro", ["--field", "u"], ".svg"),
    "macro_regions": ("macro", ["--field", "u", "--component", "norm", "--regions"], ".png"),
    "micro_regions": ("micro", ["--field", "trG", "--regions"], ".png"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(CASES))
def test_fibres_pictures_are_written_with_every_option(runs, case, capsys, monkeypatch):
    """--fibres with --time, --vmin/--vmax, .png/.pdf/.svg, arrows and --regions: the picture is
    written and its figure holds the glyphs beside what the other options draw."""
    dirs, pictures = runs
    run, options, suffix = CASES[case]
    drawn = []
    monkeypatch.setattr(picture_module, "draw",
                        lambda *a, **k: drawn.append(draw(*a, **k)) or drawn[-1])  # fmt: skip
    picture = pictures / f"{case}{suffix}"
    code, out, err = call(["render", dirs[run], *options, "--fibres", "-o", picture], capsys)
    assert code == 0, err
    if not RANK0:
        return
    assert f"wrote {picture}" in out
    data = picture.read_bytes()
    if suffix == ".png":
        assert imread(picture).ndim == 3
    else:
        assert data.startswith(b"%PDF-" if suffix == ".pdf" else b"<?xml")
    (fig,) = drawn
    assert len(drawn_glyphs(fig)[0]) > 0
    labels = legend_labels(fig)
    assert TURNED_LABEL in labels
    if "--regions" in options:
        assert "region left" in labels
    if "--vmin" in options:
        assert fig.axes[0].collections[0].get_clim() == (0.003, 0.005)
    if "--time" in options:
        assert fig._suptitle.get_text().endswith("t = 1")


@pytest.mark.parametrize("model", ["macro", "micro"])
def test_fibres_over_time_into_a_gif(runs, model, capsys, monkeypatch):
    """--time all: a frame per written time, each with its time's glyphs (they move as the
    tissue grows), no temporary file left."""
    dirs, pictures = runs
    frames = []
    original = animate_module.draw

    def drawing(*args, **kwargs):
        fig = original(*args, **kwargs)
        frames.append(drawn_glyphs(fig)[0].copy())
        return fig

    monkeypatch.setattr(animate_module, "draw", drawing)
    gif = pictures / f"fibres_{model}.gif"
    code, _, err = call(["render", dirs[model], "--field", "trG", "--fibres", "--time", "all",
                         "-o", gif], capsys)  # fmt: skip
    assert code == 0, err
    if not RANK0:
        return
    with Image.open(gif) as image:
        assert image.n_frames == 3
    assert len(frames) == 4  # the sizing frame, then t = 0, 1, 2
    assert all(len(f) == len(frames[0]) for f in frames)
    assert np.abs(frames[3] - frames[1]).max() > 1e-4  # the sites moved with the tissue
    assert not list(pictures.glob(".*"))


def test_a_step_still_being_written_is_refused_not_drawn(runs, tmp_path):
    """cells.csv without all the rows of the time asked for (a run writing that step): a named
    error suggesting an earlier --time, not glyphs for some of the cells."""
    dirs, _ = runs
    copy = tmp_path / "micro"
    shutil.copytree(dirs["micro"], copy)  # each rank its own copy
    lines = (copy / "cells.csv").read_text().splitlines(keepends=True)
    (copy / "cells.csv").write_text("".join(lines[:-3]))
    series = read_series(copy)
    with pytest.raises(InputError, match=r"^--fibres: .*cells\.csv has 5 rows at t = 2, not one "
                       r"for each of the 8 cells \(a step still being written\? try an earlier "
                       r"--time\)$"):  # fmt: skip
        draw(series, "trG", 2.0, None, fibres=True)
    assert len(drawn_glyphs(draw(series, "trG", 1.0, None, fibres=True))[0]) == 8
