"""The mirror plane x2 = 0 of every scene (docs/model.md sections 4, 7): what a scene's tissue
stands for. A scene simulates the upper half x2 >= 0 of a tissue symmetric about x2 = 0 (u2 = 0
and no tangential traction there), so whatever it holds is mirrored below the plane.

Left: ``scenes/examples/soft_disc.toml`` (an 8 x 4 tissue, a soft disc of radius 1 at (4, 2))
stands for an 8 x 8 tissue holding two discs, at (4, 2) and (4, -2). Right: one disc in the
middle of that 8 x 8 tissue is a disc centred on the plane, ``(x1 - 4)**2 + x2**2 < 1``, of which
the scene holds the upper half. Drawn from the geometry alone (no run):

    python scripts/figures/plot_mirror_plane.py [--out docs/figures/mirror_plane.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle, Rectangle, Wedge  # noqa: E402

WIDTH, HEIGHT, RADIUS = 8.0, 4.0, 1.0  # scenes/examples/soft_disc.toml
FADED = 0.25  # the mirrored half's opacity
PANELS = (  # (title, the disc centre's x2 in the scene)
    ("soft_disc.toml: disc at (4, 2)\n= two discs in an 8 x 8 tissue", 2.0),
    ("one disc in the middle: centre it on x2 = 0\n(x1 - 4)**2 + x2**2 < 1", 0.0),
)


def draw_panel(ax, title: str, x2_disc: float) -> None:
    """The simulated half (solid), its mirror image (faded) and the plane x2 = 0."""
    for sign, alpha, label in ((1.0, 1.0, "simulated (the scene)"), (-1.0, FADED, "mirror image")):
        y0 = 0.0 if sign > 0 else -HEIGHT
        ax.add_patch(Rectangle((0.0, y0), WIDTH, HEIGHT, facecolor="#cfe8cf", edgecolor="k",
                               alpha=alpha, label=label))  # fmt: skip
        centre = (WIDTH / 2, sign * x2_disc)
        style = {"facecolor": "#e8a0a0", "edgecolor": "k", "alpha": alpha}
        if x2_disc == 0.0:  # the disc on the plane: each half holds its own half-disc
            ax.add_patch(Wedge(centre, RADIUS, 0.0 if sign > 0 else 180.0,
                               180.0 if sign > 0 else 360.0, **style))  # fmt: skip
        else:
            ax.add_patch(Circle(centre, RADIUS, **style))
    ax.axhline(0.0, color="tab:blue", lw=2.0, ls="--", label="mirror plane $x_2 = 0$ ($u_2 = 0$)")
    ax.text(WIDTH + 0.1, 0.1, "$x_2 = 0$", va="bottom", color="tab:blue")
    ax.set_xlim(-0.3, WIDTH + 1.3)
    ax.set_ylim(-HEIGHT - 0.3, HEIGHT + 0.3)
    ax.set_aspect("equal")
    ax.set_xlabel("$x_1$")
    ax.set_ylabel("$x_2$")
    ax.set_title(title, fontsize=10)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/figures/mirror_plane.png"))
    args = parser.parse_args(argv)
    fig, axes = plt.subplots(1, len(PANELS), figsize=(9.0, 5.0))
    for ax, (title, x2_disc) in zip(axes, PANELS, strict=True):
        draw_panel(ax, title, x2_disc)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=9, frameon=False)
    fig.tight_layout(rect=(0.0, 0.07, 1.0, 1.0))
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
