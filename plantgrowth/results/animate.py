"""``plantgrowth render ... --time all -o FILE.gif``: one frame per written time, drawn by
:func:`plantgrowth.results.render.draw` in one shared view (box, colour range, arrow scale) and
written by matplotlib's Pillow writer (``matplotlib.animation.PillowWriter``, python3-pil)."""

from __future__ import annotations

from pathlib import Path

from matplotlib.animation import PillowWriter

from plantgrowth.results.reader import ResultSeries
from plantgrowth.results.render import View, draw

FPS = 4  # frames per second: a 40-step run plays in 10 s
ANIMATION_DPI = 80  # a 720-pixel-wide frame, ~1 MB in memory while the GIF is assembled
MAX_FRAMES = 200  # more written times are thinned evenly (first and last kept): <= ~0.3 GB


def frame_times(times: list[float]) -> list[float]:
    """All of ``times``, or MAX_FRAMES of them evenly spread (the first and last kept)."""
    if len(times) <= MAX_FRAMES:
        return list(times)
    step = (len(times) - 1) / (MAX_FRAMES - 1)
    return [times[round(i * step)] for i in range(MAX_FRAMES)]


def write_animation(
    series: ResultSeries, name: str, component: str | None, times: list[float], view: View,
    title: str | None, output: Path, dpi: int, regions: bool = False, fibres: bool = False,
) -> None:  # fmt: skip
    """The GIF ``output`` of ``name`` at ``times`` (a frame each, at most MAX_FRAMES); a given
    ``title`` gets each frame's time appended. The figure is sized once, on the frame whose
    title is longest, so that every frame has the same size."""
    frames = frame_times(times)

    def title_at(t: float) -> str | None:
        return None if title is None else f"{title}, t = {t:g}"

    longest = max(frames, key=lambda t: len(title_at(t) or f"{t:g}"))
    fig = draw(series, name, longest, component, title_at(longest), view, regions=regions,
               fibres=fibres)  # fmt: skip
    writer = PillowWriter(fps=FPS)
    with writer.saving(fig, str(output), dpi):
        for t in frames:
            draw(series, name, t, component, title_at(t), view, fig, regions, fibres)
            fig.canvas.draw()  # the layout's second pass (see render.fit_height)
            writer.grab_frame()
