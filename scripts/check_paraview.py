"""Open a run's fields.xdmf with ParaView's own XDMF3 reader and print what it sees.

Run with ParaView's batch interpreter (Debian: apt-get install paraview python3-paraview):
    pvbatch scripts/check_paraview.py results/reference_stress/fields.xdmf
Prints one JSON line: the time values, point/cell counts and the array names at the last time.
"""

import json
import sys

from paraview import servermanager
from paraview.simple import Xdmf3ReaderS


def main(path: str) -> None:
    reader = Xdmf3ReaderS(FileName=[path])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues)
    reader.UpdatePipeline(times[-1])
    data = servermanager.Fetch(reader)
    points, cells = data.GetPointData(), data.GetCellData()
    print(
        json.dumps(
            {
                "times": times,
                "n_points": data.GetNumberOfPoints(),
                "n_cells": data.GetNumberOfCells(),
                "point_arrays": [points.GetArrayName(i) for i in range(points.GetNumberOfArrays())],
                "cell_arrays": [cells.GetArrayName(i) for i in range(cells.GetNumberOfArrays())],
                "u_max_abs_x": max(abs(v) for v in points.GetArray("u").GetRange(0)),
            }
        )
    )


if __name__ == "__main__":
    main(sys.argv[1])
