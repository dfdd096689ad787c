"""Open a run's fields.xdmf with ParaView's own XDMF3 reader and print what it sees.

Run with ParaView's batch interpreter (Debian: apt-get install paraview python3-paraview xvfb
xauth); without a display, under a virtual X server (pvbatch needs one to render):
    xvfb-run -a pvbatch scripts/figures/check_paraview.py results/reference_stress/fields.xdmf
Prints one JSON line: the time values, point/cell counts and the array names at the last time.
With ``--png FILE`` it also renders the last time (coloured by u, or by the first point array
where there is no u, as in ``coarse.xdmf``) into FILE. A file that is absent, or that ParaView
reads no time from, ends the script with one line naming it (exit 2), checked before ParaView is
loaded: a run writes ``coarse.xdmf`` only when its scene's ``[output] fields`` has ``E_hom``.
"""

import argparse
import json
import sys
from pathlib import Path


def fail(message: str) -> None:
    """End with one line on stderr, exit code 2."""
    print(f"check_paraview.py: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def check_file(xdmf: Path) -> None:
    """The XDMF file must exist (what a run writes: docs/outputs.md)."""
    if xdmf.is_file():
        return
    hint = ""
    if xdmf.name == "coarse.xdmf":
        hint = (
            ": a run writes coarse.xdmf only when its scene's [output] fields lists E_hom "
            "(macro runs); open fields.xdmf, or add E_hom and run the scene again"
        )
    elif xdmf.suffix != ".xdmf":
        hint = ": give a run's fields.xdmf (or coarse.xdmf, cells.xdmf)"
    fail(f"{xdmf}: no such file{hint}")


def main() -> None:
    parser = argparse.ArgumentParser(description="ParaView's view of a plantgrowth run")
    parser.add_argument("xdmf", type=Path, help="the run's fields.xdmf")
    parser.add_argument("--png", default=None, help="also render the last time into this file")
    args = parser.parse_args()
    check_file(args.xdmf)
    from paraview import servermanager
    from paraview.simple import ColorBy, GetActiveViewOrCreate, SaveScreenshot, Show, Xdmf3ReaderS

    reader = Xdmf3ReaderS(FileName=[str(args.xdmf)])
    reader.UpdatePipelineInformation()
    values = reader.TimestepValues  # a bare float when the series has one time
    times = [values] if isinstance(values, float) else list(values)
    if not times:
        fail(f"{args.xdmf}: ParaView reads no time from it: is it a plantgrowth run's XDMF file?")
    reader.UpdatePipeline(times[-1])
    data = servermanager.Fetch(reader)
    points, cells = data.GetPointData(), data.GetCellData()
    u = points.GetArray("u")  # None in coarse.xdmf (E_hom at the coarse nodes only)
    if args.png:
        view = GetActiveViewOrCreate("RenderView")
        view.ViewTime = times[-1]
        first = points.GetArrayName(0) if points.GetNumberOfArrays() else None
        ColorBy(Show(reader, view), ("POINTS", "u" if points.GetArray("u") else first))
        view.ResetCamera()
        SaveScreenshot(args.png, view, ImageResolution=[640, 360])
    print(
        json.dumps(
            {
                "times": times,
                "n_points": data.GetNumberOfPoints(),
                "n_cells": data.GetNumberOfCells(),
                "point_arrays": [points.GetArrayName(i) for i in range(points.GetNumberOfArrays())],
                "cell_arrays": [cells.GetArrayName(i) for i in range(cells.GetNumberOfArrays())],
                "u_max_abs_x": None if u is None else max(abs(v) for v in u.GetRange(0)),
            }
        )
    )


if __name__ == "__main__":
    main()
