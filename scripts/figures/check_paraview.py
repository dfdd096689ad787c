"""Open a run's fields.xdmf with ParaView's own XDMF3 reader and print what it sees.

Run with ParaView's batch interpreter (Debian: apt-get install paraview python3-paraview xvfb
xauth); without a display, under a virtual X server (pvbatch needs one to render):
    xvfb-run -a pvbatch scripts/figures/check_paraview.py results/reference_stress/fields.xdmf
Prints one JSON line: the time values, point/cell counts and the array names at the last time.
With ``--png FILE`` it also renders the last time (coloured by u, or by the first point array
where there is no u, as in ``coarse.xdmf``) into FILE.
"""

import argparse
import json

from paraview import servermanager
from paraview.simple import ColorBy, GetActiveViewOrCreate, SaveScreenshot, Show, Xdmf3ReaderS


def main() -> None:
    parser = argparse.ArgumentParser(description="ParaView's view of a plantgrowth run")
    parser.add_argument("xdmf", help="the run's fields.xdmf")
    parser.add_argument("--png", default=None, help="also render the last time into this file")
    args = parser.parse_args()
    reader = Xdmf3ReaderS(FileName=[args.xdmf])
    reader.UpdatePipelineInformation()
    values = reader.TimestepValues  # a bare float when the series has one time
    times = [values] if isinstance(values, float) else list(values)
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
