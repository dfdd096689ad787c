"""The picture file of ``plantgrowth render``: one picture (.png, .pdf, .svg) of a written
field at one time, drawn by :func:`plantgrowth.results.render.draw`, or a .gif over every written
time (:mod:`plantgrowth.results.animate`), in one shared view; written to a temporary file
renamed into place, never into the run's directory.
"""

from __future__ import annotations

from pathlib import Path

from plantgrowth.results.animate import ANIMATION_DPI, write_animation
from plantgrowth.results.fibre_glyphs import check_fibres
from plantgrowth.results.output_file import written_atomically
from plantgrowth.results.render import (
    ALL_TIMES,
    check_field,
    check_limits,
    check_new,
    check_output,
    draw,
    open_run,
    pick_times,
    plan_view,
)


def render(
    directory: Path, name: str, output: Path, time: float | str | None = None,
    component: str | None = None, force: bool = False, title: str | None = None,
    dpi: int | None = None, vmin: float | None = None, vmax: float | None = None,
    regions: bool = False, fibres: bool = False,
) -> Path:  # fmt: skip
    """Draw ``name`` of the run in ``directory`` at the written time nearest ``time`` (default
    the last) into the picture ``output`` (.png, .pdf, .svg), or at every written time
    (``time = "all"``) into the animation ``output`` (.gif); colours in [vmin, vmax] (default:
    the values' range); with ``fibres``, the fibre director's glyphs on top
    (:mod:`plantgrowth.results.fibre_glyphs`); returns ``output``. InputError (RenderError) on
    bad input, before anything is written."""
    directory, output = Path(directory), Path(output)
    animation = time == ALL_TIMES
    check_limits(vmin, vmax)
    check_output(output, directory, animation)
    series = open_run(directory)
    check_field(series, name)  # a wrong field name before "the file exists"
    check_new(output, force)
    times = pick_times(series, time)
    view = plan_view(series, name, component, times, vmin, vmax)
    if fibres:
        check_fibres(series)
    with written_atomically(output) as tmp:
        if animation:
            write_animation(series, name, component, times, view, title, tmp,
                            dpi or ANIMATION_DPI, regions, fibres)  # fmt: skip
        else:
            fig = draw(series, name, times[0], component, title, view, regions=regions,
                       fibres=fibres)  # fmt: skip
            fig.savefig(tmp, dpi=dpi or 150, format=output.suffix.lower()[1:])
    return output
