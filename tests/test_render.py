"""``plantgrowth render`` (issue 11, item 4; issue 21, item 7): PNGs of a macro and a micro
run, headless, and its named errors; it never writes into the run directory nor over a file
without --force. Issue 21: --vmin/--vmax, .pdf and .svg, the arrows' scale key, titles that fit,
hints for a missing field or component, --time all into a .gif.

In-process through ``main`` (serial and under mpirun: rank 0 draws, every rank returns the same
code); :func:`draw` directly on every rank (a figure in memory). Runs: macro h = 0.5, micro
Nx = 4 with one element across a wall, two steps; "bare": the macro run writing u and G only.
"""

from __future__ import annotations

from xml.etree import ElementTree

import numpy as np
import pytest
from cli_helpers import RANK0, call, runs_and_pictures, write
from matplotlib.figure import Figure
from matplotlib.image import imread
from matplotlib.quiver import QuiverKey
from PIL import Image

from plantgrowth.results import picture as picture_module
from plantgrowth.results import render as render_module
from plantgrowth.results.animate import MAX_FRAMES, frame_times
from plantgrowth.results.reader import read_series
from plantgrowth.results.render import draw, pick_time, plan_view

FIELDS = '["u", "G", "E_hom", "trG", "growth_anisotropy", "growth_direction", "stress_direction"]'
MACRO = f"""\
[tissue]
h = 0.5
H = 1.0
[growth]
law = "stress"
eta = {{from = 0.5, to = 2.0}}
[time]
t_max = 2
[accuracy]
cell_resolution = 1
[output]
fields = {FIELDS}
"""
MICRO = MACRO.replace("[tissue]\nh = 0.5\nH = 1.0\n", 'model = "micro"\n') + (
    "[micro]\nnx = 4\nresolution = 1\n"
)
BARE = MACRO.replace(FIELDS, '["u", "G"]')


def snapshot(directory) -> dict:
    return {str(p): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{"macro": DIR, "micro": DIR, "bare": DIR} and a directory for pictures."""
    return runs_and_pictures(tmp_path_factory, "render",
                             {"macro": MACRO, "micro": MICRO, "bare": BARE})  # fmt: skip


@pytest.mark.parametrize(
    "model, field",
    [("macro", ["trG"]), ("macro", ["G", "--component", "tr"]), ("macro", ["growth_direction"]),
     ("macro", ["u"]), ("micro", ["trG"]), ("micro", ["stress_direction"]),
     ("micro", ["u", "--component", "norm"]), ("macro", ["E1111"])],
)  # fmt: skip
def test_render_writes_a_png_and_leaves_the_run_alone(runs, model, field, capsys):
    dirs, pictures = runs
    picture = pictures / f"{model}_{'_'.join(field)}.png"
    before = snapshot(dirs[model]) if RANK0 else None
    code, out, err = call(["render", dirs[model], "--field", *field, "-o", picture], capsys)
    assert code == 0, err
    if RANK0:
        assert f"wrote {picture}" in out
        assert picture.stat().st_size > 0
        image = imread(picture)  # a valid PNG: matplotlib decodes it
        assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
        assert np.ptp(image[..., :3]) > 0  # not a blank canvas
        assert snapshot(dirs[model]) == before
        assert not list(pictures.glob(".*"))  # no temporary file left


@pytest.mark.mpi
def test_existing_picture_is_refused_unless_force(runs, capsys):
    dirs, pictures = runs
    picture = pictures / "mine.png"
    write(picture, "a user's file\n")
    code, _, err = call(["render", dirs["macro"], "--field", "trG", "-o", picture], capsys)
    assert code == 2
    if RANK0:
        assert "--force" in err and picture.read_text() == "a user's file\n"
    code, _, _ = call(["render", dirs["macro"], "--field", "trG", "-o", picture, "--force"],
                      capsys)  # fmt: skip
    assert code == 0
    if RANK0:
        assert imread(picture).ndim == 3


ERRORS = {  # name -> (argv after "render", with {dir} the run and {pic} a new picture; text)
    "unknown_field": (["{dir}", "--field", "sigma", "-o", "{pic}"],
                      "--field = 'sigma' is not written in"),
    "no_such_dir": (["{dir}/nothing", "--field", "trG", "-o", "{pic}"], "no such directory"),
    "not_a_run": (["{dir}/fields", "--field", "trG", "-o", "{pic}"], "not a run directory"),
    "time_after": (["{dir}", "--field", "trG", "--time", "3", "-o", "{pic}"],
                   "--time = 3.0 is out of range: the run wrote t in [0, 2]"),
    "time_before": (["{dir}", "--field", "trG", "--time", "-1", "-o", "{pic}"], "--time"),
    "tensor_needs_component": (["{dir}", "--field", "G", "-o", "{pic}"],
                               "--component is required for the tensor field G: give one of 11, "
                               "12, 21, 22, tr, det"),
    "scalar_has_none": (["{dir}", "--field", "trG", "--component", "11", "-o", "{pic}"],
                        "is a scalar field"),
    "vector_component": (["{dir}", "--field", "u", "--component", "3", "-o", "{pic}"],
                         "1, 2, norm"),
    "inside_the_run": (["{dir}", "--field", "trG", "-o", "{dir}/pic.png"],
                       "inside the run directory"),
    "unknown_extension": (["{dir}", "--field", "trG", "-o", "{pic}.jpg"],
                          "must be a .png, .pdf, .svg file"),
    "gif_of_one_time": (["{dir}", "--field", "trG", "-o", "{pic}.gif"], "with --time all, a .gif"),
    "animation_not_gif": (["{dir}", "--field", "trG", "--time", "all", "-o", "{pic}"],
                          "--time all writes an animation: give a .gif file"),
    "time_word": (["{dir}", "--field", "trG", "--time", "last", "-o", "{pic}"],
                  "--time: expected a number or all: 'last'"),
    "vmin_not_below_vmax": (["{dir}", "--field", "trG", "--vmin", "1", "--vmax", "0.5", "-o",
                             "{pic}"], "--vmin = 1 must be below --vmax = 0.5"),
    "vmin_equal_vmax": (["{dir}", "--field", "trG", "--vmin", "1", "--vmax", "1", "-o", "{pic}"],
                        "--vmin = 1 must be below --vmax = 1"),
    "vmin_nan": (["{dir}", "--field", "trG", "--vmin", "nan", "-o", "{pic}"],
                 "--vmin = nan is not a finite number"),
    "vmax_inf": (["{dir}", "--field", "trG", "--vmax", "inf", "-o", "{pic}"],
                 "--vmax = inf is not a finite number"),
    "vmin_above_the_values": (["{dir}", "--field", "trG", "--vmin", "5", "-o", "{pic}"],
                              "--vmin = 5 leaves no range: the field's values lie in ["),
    "limits_on_arrows": (["{dir}", "--field", "u", "--vmax", "1", "-o", "{pic}"],
                         "u is drawn as arrows, without colours; give --component 1, 2, norm"),
    "E_hom_as_components": (["{dir}", "--field", "E_hom", "-o", "{pic}"],
                            "E_hom is written as its components: give --field E1111 or E1112"),
    "misspelt_field": (["{dir}", "--field", "stres_direction", "-o", "{pic}"],
                       "did you mean stress_direction"),
    "scalar_component_hint": (["{dir}", "--field", "trG", "--component", "tr", "-o", "{pic}"],
                              "trG is a scalar field, it has none: drop --component"),
    "no_field": (["{dir}", "-o", "{pic}"], "--field"),
    "dpi": (["{dir}", "--field", "trG", "--dpi", "0", "-o", "{pic}"], "--dpi = 0"),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(ERRORS))
def test_bad_render_requests_name_the_option_and_write_nothing(runs, name, capsys):
    dirs, pictures = runs
    argv, text = ERRORS[name]
    picture = pictures / f"error_{name}.png"
    argv = [a.replace("{dir}", str(dirs["macro"])).replace("{pic}", str(picture)) for a in argv]
    before = snapshot(dirs["macro"].parent) if RANK0 else None
    code, _, err = call(["render", *argv], capsys)
    assert code == 2
    if RANK0:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("plantgrowth: error: "), err
        assert text in lines[0], lines[0]
        if name == "unknown_field":
            assert "trG, u" in lines[0]  # the written fields are listed
        assert snapshot(dirs["macro"].parent) == before


def test_time_picks_the_nearest_written_time(runs):
    dirs, _ = runs
    series = read_series(dirs["macro"])
    assert series.times == [0.0, 1.0, 2.0]
    assert pick_time(series, None) == 2.0
    assert pick_time(series, 1.4) == 1.0
    assert pick_time(series, 1.6) == 2.0
    assert pick_time(series, 2.0 + 1e-12) == 2.0


HINTS = {  # a field the bare run (u and G) did not write -> what the error names
    "trG": "trG is a component of G: give --field G --component tr",
    "sigma_hom": "a field is written when the scene's [output] fields lists it: add it there",
}


@pytest.mark.parametrize("field", sorted(HINTS))
def test_a_missing_field_names_the_written_ones_and_a_way_to_it(runs, field, capsys):
    dirs, pictures = runs
    picture = pictures / f"hint_{field}.png"
    code, _, err = call(["render", dirs["bare"], "--field", field, "-o", picture], capsys)
    assert code == 2
    if RANK0:
        assert f"--field = {field!r} is not written in {dirs['bare']}: it wrote G, u;" in err
        assert HINTS[field] in err
        assert not picture.exists()


def test_colours_span_vmin_vmax_in_every_run(runs, capsys, monkeypatch):
    """The same --vmin/--vmax give the macro and the micro pictures the same colour bar; without
    them each spans its own values (read back from the figures the CLI draws)."""
    dirs, pictures = runs
    drawn = []
    monkeypatch.setattr(picture_module, "draw",
                        lambda *a, **k: drawn.append(draw(*a, **k)) or drawn[-1])  # fmt: skip
    for model in ("macro", "micro"):
        for limits in ([], ["--vmin", "0.01", "--vmax", "0.02"]):
            picture = pictures / f"limits_{model}_{len(limits)}.png"
            code, _, err = call(["render", dirs[model], "--field", "trG", *limits, "-o", picture],
                                capsys)  # fmt: skip
            assert code == 0, err
    if not RANK0:
        return
    for fig, model in zip(drawn[::2], ("macro", "micro"), strict=True):
        series = read_series(dirs[model])
        values = series.cell_field("trG", series.times[-1])
        mappable = fig.axes[0].collections[0]
        assert mappable.get_clim() == (values.min(), values.max())
    for fig in drawn[1::2]:
        assert fig.axes[0].collections[0].get_clim() == (0.01, 0.02)
        # the values reach beyond 0.02 (0.03 at t = 2, printed by the vmin_above_the_values case)
        assert fig.axes[1].get_ylim() == (0.01, 0.02)  # the colour bar's axes


@pytest.mark.parametrize("suffix", [".pdf", ".svg"])
def test_pdf_and_svg_are_written(runs, suffix, capsys):
    dirs, pictures = runs
    picture = pictures / f"vector{suffix}"
    code, _, err = call(["render", dirs["micro"], "--field", "u", "-o", picture], capsys)
    assert code == 0, err
    if RANK0:
        data = picture.read_bytes()
        if suffix == ".pdf":
            assert data.startswith(b"%PDF-") and data.rstrip().endswith(b"%%EOF")
        else:
            root = ElementTree.fromstring(data)  # well-formed XML
            assert root.tag == "{http://www.w3.org/2000/svg}svg"
            assert any(True for _ in root.iter("{http://www.w3.org/2000/svg}path"))


def _inside(box, outer) -> bool:
    return box.x0 >= outer.x0 and box.y0 >= outer.y0 and box.x1 <= outer.x1 and box.y1 <= outer.y1


def test_arrows_have_a_key_in_the_picture(runs):
    """u's arrows: a key of 1, 2 or 5 x 10^k, at most the longest arrow and more than 2/5 of it;
    direction bars (unit axes) have none."""
    dirs, _ = runs
    for model in ("macro", "micro"):
        series = read_series(dirs[model])
        t = series.times[-1]
        fig = draw(series, "u", t, None)
        keys = [a for a in fig.axes[0].artists if isinstance(a, QuiverKey)]
        assert len(keys) == 1
        longest = np.linalg.norm(series.displacement(t), axis=1).max()
        mantissa = keys[0].U / 10 ** np.floor(np.log10(keys[0].U))
        assert np.isclose(mantissa, [1, 2, 5]).any()
        assert 0.4 * longest < keys[0].U <= longest
        assert keys[0].text.get_text() == f"|u| = {keys[0].U:g}"
        renderer = fig.canvas.get_renderer()
        assert _inside(keys[0].text.get_window_extent(renderer), fig.bbox)
        bars = draw(series, "stress_direction", t, None)
        assert not [a for a in bars.axes[0].artists if isinstance(a, QuiverKey)]


KINDS = [
    ("macro", "trG", None),
    ("macro", "u", "1"),
    ("macro", "u", None),
    ("micro", "trG", None),
    ("micro", "u", "norm"),
    ("micro", "stress_direction", None),
]
# colours per cell, colours per node, arrows; on a macro and a micro run
LONG = "growth of the shoot apical meristem under anisotropic stress, " * 3 + "x" * 150


@pytest.mark.parametrize("model, field, component", KINDS)
@pytest.mark.parametrize("title", [None, LONG], ids=["default_title", "long_title"])
def test_titles_and_legends_fit_in_the_figure(runs, model, field, component, title):
    """The title (wrapped), the legend and the axes lie inside the figure and do not overlap
    (before issue 21: the title outside the macro arrows' picture, the legend on the x1 label of
    the micro trG one; a 330-character title ran off both sides)."""
    dirs, _ = runs
    series = read_series(dirs[model])
    fig = draw(series, field, series.times[-1], component, title)
    renderer = fig.canvas.get_renderer()
    heading = fig._suptitle.get_window_extent(renderer)
    assert _inside(heading, fig.bbox)
    legend = fig.legends[0].get_window_extent(renderer)
    assert _inside(legend, fig.bbox)
    assert fig.axes[0].get_window_extent(renderer).y1 <= heading.y0
    assert legend.y1 <= fig.axes[0].xaxis.get_tightbbox(renderer).y0  # under the x1 label
    if title is not None:
        text = fig._suptitle.get_text()
        assert "".join(text.split()) == "".join(title.split())  # only broken into lines
        assert len(text.splitlines()) >= 3  # 330 characters: wrapped, not shrunk nor cut


@pytest.mark.mpi
def test_time_all_writes_one_frame_per_written_time(runs, capsys):
    dirs, pictures = runs
    gif = pictures / "run.gif"
    code, out, err = call(["render", dirs["micro"], "--field", "trG", "--time", "all", "-o", gif],
                          capsys)  # fmt: skip
    assert code == 0, err
    if RANK0:
        assert f"wrote {gif}" in out
        times = read_series(dirs["micro"]).times
        with Image.open(gif) as image:
            assert image.format == "GIF" and image.n_frames == len(times) == 3
            frames = []
            for i in range(image.n_frames):
                image.seek(i)
                frames.append(np.asarray(image.convert("RGB"), dtype=float))
        assert all(f.shape == frames[0].shape for f in frames)
        moves = [np.abs(a - b).max() for a, b in zip(frames, frames[1:], strict=False)]
        assert min(moves) > 0  # each frame is its own time
        assert not list(pictures.glob(".*"))


def test_frames_of_a_long_run_are_spread_evenly():
    times = [0.1 * i for i in range(1001)]
    frames = frame_times(times)
    assert len(frames) == MAX_FRAMES and frames[0] == times[0] and frames[-1] == times[-1]
    assert np.all(np.diff(frames) > 0)
    assert max(np.diff(frames)) < 2 * min(np.diff(frames))  # even: steps 5 or 6 written times
    assert frame_times(times[:5]) == times[:5]


def test_one_view_for_all_times(runs):
    """--time all: one colour range over every frame (each frame's own would not compare)."""
    dirs, _ = runs
    series = read_series(dirs["macro"])
    view = plan_view(series, "trG", None, series.times)
    values = np.concatenate([series.cell_field("trG", t) for t in series.times])
    assert (view.colours.low, view.colours.high) == (values.min(), values.max())
    first = draw(series, "trG", series.times[0], None, view=view)
    assert first.axes[0].collections[0].get_clim() == (values.min(), values.max())


def test_arrows_follow_the_same_material_points_over_time(runs, monkeypatch):
    """The arrow sites are chosen on the reference tissue: at every time the same nodes, moved
    by u (an animation's arrows do not jump from site to site). Thinned to about 30 of the 105
    nodes: chosen on the deformed tissue instead, 12 of the 36 sites differ between t = 0 and 2
    (measured)."""
    monkeypatch.setattr(render_module, "MAX_ARROWS", 30)
    dirs, _ = runs
    series = read_series(dirs["macro"])
    view = plan_view(series, "u", None, series.times)
    nodes = []
    for t in (series.times[0], series.times[-1]):
        quiver = draw(series, "u", t, None, view=view).axes[0].collections[-1]
        moved = series.points + series.displacement(t)
        gaps = np.linalg.norm(moved[None] - quiver.get_offsets()[:, None], axis=2)
        assert gaps.min(axis=1).max() < 1e-12  # each arrow sits on a moved node
        nodes.append(sorted(gaps.argmin(axis=1)))
    assert nodes[0] == nodes[1] and 30 < len(nodes[0]) <= 36


def test_zero_vectors_draw_no_arrow_and_say_so():
    """An isotropic tissue's growth_direction is 0 everywhere: no dots, a note in the legend."""
    fig = Figure()
    ax = fig.add_subplot()
    where, zero = np.zeros((4, 2)), np.zeros((4, 2))
    render_module._arrows(ax, "growth_direction", where, zero, render_module.Arrows(1.0, None))
    assert len(ax.collections[-1].get_offsets()) == 0
    assert ax.get_legend_handles_labels()[1] == ["growth_direction = 0 at every site"]


def test_cells_draws_a_cells_csv_column_one_colour_per_cell(runs, capsys, monkeypatch):
    """--cells area: each cell's polygon has the colour of its cells.csv area at the drawn time
    (read back from the figure: the polygons' values, in cell id order, are the column's)."""
    dirs, pictures = runs
    drawn = []
    monkeypatch.setattr(picture_module, "draw",
                        lambda *a, **k: drawn.append(draw(*a, **k)) or drawn[-1])  # fmt: skip
    picture = pictures / "cells_area.png"
    code, out, err = call(["render", dirs["micro"], "--cells", "area", "-o", picture], capsys)
    assert code == 0, err
    if not RANK0:
        return
    assert f"wrote {picture}" in out and imread(picture).ndim == 3
    t = read_series(dirs["micro"]).times[-1]
    rows = [line.split(",") for line in (dirs["micro"] / "cells.csv").read_text().splitlines()]
    header = rows[0]
    at_t = [r for r in rows[1:] if float(r[header.index("t")]) == t]
    area = np.array([float(r[header.index("area")]) for r in
                     sorted(at_t, key=lambda r: int(r[header.index("cell")]))])  # fmt: skip
    assert len(area) == 8  # Nx = 4: 8 cells, not all of one area (the bottom row is cut)
    assert np.ptp(area) > 0.1 * area.max()
    assert np.array_equal(drawn[0].axes[0].collections[0].get_array(), area)


@pytest.mark.mpi
@pytest.mark.parametrize("model, column, text", [
    ("micro", "turgor", "--cells 'turgor': {dir}/cells.csv has no such column; valid: x1_ref, "
     "x2_ref, x1, x2, area_ref, perimeter_ref, neighbours, area, trG,"),
    ("micro", "step", "--cells 'step': {dir}/cells.csv has no such column; valid: x1_ref,"),
    ("macro", "area", "--cells: {dir} has no cells.csv (a micro run writes it"),
])  # fmt: skip
def test_cells_with_a_wrong_column_is_a_named_error(runs, model, column, text, capsys):
    dirs, pictures = runs
    picture = pictures / f"cells_{model}_{column}.png"
    code, _, err = call(["render", dirs[model], "--cells", column, "-o", picture], capsys)
    assert code == 2
    if RANK0:
        assert text.format(dir=dirs[model]) in err
        assert not picture.exists()
