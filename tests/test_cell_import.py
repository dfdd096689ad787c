"""Imported cells (issue 34): ``[tissue] cells = "file"`` from a label image (TIFF, PNG, with
``tissue.pixel_size``) or a polygon table (JSON, CSV), the shipped synthetic example's round trip
(scenes/real_tissues/), and the named errors of bad images and tables."""

from __future__ import annotations

import json
import runpy
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import tifffile

from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.scene import SceneError, load_scene, parse_scene
from plantgrowth.scene.tissue_cells import cell_polygons

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "scenes" / "real_tissues"
BASE = {"model": "micro", "growth": {"law": "none"}}


MAKER = SimpleNamespace(  # the script's functions and constants
    **runpy.run_path(str(REPO / "scripts" / "studies" / "make_synthetic_tissue.py"))
)


def imported(tmp_path: Path, name: str, pixel_size: float | None = 1.0) -> CellPolygons:
    tissue = {"cells": name} | ({} if pixel_size is None else {"pixel_size": pixel_size})
    return cell_polygons(parse_scene(BASE | {"tissue": tissue}, directory=tmp_path))


# --- the shipped example's round trip -------------------------------------------------------------


def test_shipped_image_is_what_the_script_makes():
    shipped = tifffile.imread(EXAMPLE / "synthetic_r05.tif")
    made = MAKER.rasterise(MAKER.generated(), MAKER.PIXEL_SIZE, MAKER.MARGIN)
    assert shipped.dtype == made.dtype and np.array_equal(shipped, made)
    assert (EXAMPLE / "synthetic_r05.tif").stat().st_size < 200_000


def test_round_trip_image_to_the_generators_cells():
    """Image -> polygons equal the generator's within a pixel's error: each traced vertex is a
    pixel corner within about one pixel p of the true one (the rasterised wall's staircase is
    within p/sqrt(2) of it, the Douglas-Peucker tolerance 1.5 p straightens it), so a cell's
    area is within its perimeter times p (measured: 0.34 P p), its perimeter within 2 p per
    side (measured: 1.95 p), its centroid within p (measured: 0.36 p), and every wall longer
    than the 2-pixel collapse tolerance is found (neighbour counts equal)."""
    cells = cell_polygons(load_scene(EXAMPLE / "synthetic.toml"))
    truth = MAKER.generated()
    p = MAKER.PIXEL_SIZE
    assert sorted(cells.labels.tolist()) == list(range(1, truth.n_cells + 1))
    order = np.argsort(cells.labels)
    sides = np.array([len(c) for c in truth.cells])
    assert np.all(np.abs(cells.areas[order] - truth.areas) <= truth.perimeters * p)
    assert np.all(np.abs(cells.perimeters[order] - truth.perimeters) <= 2 * p * sides)
    assert np.abs(cells.centroids[order] - truth.centroids).max() <= p
    assert np.array_equal(cells.neighbour_counts[order], truth.neighbour_counts)
    cells.check()
    # the bottom row lies on the image's bottom edge: cut by the symmetry plane x2 = 0
    bottom = order[:8]
    assert all(np.count_nonzero(cells.polygon(i)[:, 1] == 0.0) == 2 for i in bottom)
    assert cells.vertices[:, 1].min() == 0.0


def test_pixel_size_scales_the_cells_and_png_reads_as_tiff(tmp_path):
    from skimage import io

    labels = tifffile.imread(EXAMPLE / "synthetic_r05.tif")
    io.imsave(tmp_path / "cells.png", labels, check_contrast=False)
    tifffile.imwrite(tmp_path / "cells.tif", labels)
    png, tif = imported(tmp_path, "cells.png", 0.5), imported(tmp_path, "cells.tif", 0.5)
    assert np.array_equal(png.vertices, tif.vertices)
    double = imported(tmp_path, "cells.tif", 1.0)
    np.testing.assert_allclose(double.areas, 4.0 * tif.areas, rtol=1e-12)  # exact up to rounding


# --- polygon tables ------------------------------------------------------------------------------


def _json(path: Path, cells: CellPolygons, pixel_size: float | None = None) -> None:
    data = {"cells": [{"id": int(label), "vertices": cells.polygon(i).tolist()}
                      for i, label in enumerate(cells.labels)]}  # fmt: skip
    path.write_text(json.dumps(data | ({} if pixel_size is None else {"pixel_size": pixel_size})))


def test_tables_give_the_generators_cells(tmp_path):
    truth = MAKER.generated()
    _json(tmp_path / "cells.json", truth)
    rows = ["cell_id,x,y"] + [
        f"{label},{x!r},{y!r}"
        for i, label in enumerate(truth.labels)
        for x, y in truth.polygon(i)[::-1]
    ]  # fmt: skip  clockwise
    (tmp_path / "cells.csv").write_text("\n".join(rows) + "\n")
    for name in ("cells.json", "cells.csv"):
        cells = imported(tmp_path, name, None)
        assert np.array_equal(cells.labels, truth.labels)
        np.testing.assert_allclose(cells.areas, truth.areas, rtol=1e-12)  # reordered, same points
        assert np.array_equal(cells.neighbour_counts, truth.neighbour_counts)
    _json(tmp_path / "scaled.json", truth, pixel_size=3.0)
    np.testing.assert_allclose(imported(tmp_path, "scaled.json", None).areas, 9 * truth.areas,
                               rtol=1e-12)  # fmt: skip


def test_a_vertex_on_a_neighbours_side_is_shared(tmp_path):
    """Two unit squares under one 2 x 1 rectangle: the squares' common corner (1, 1) lies on
    the rectangle's bottom side and is inserted there, so each square shares a wall with it."""
    table = {"cells": [
        {"id": 1, "vertices": [[0, 0], [1, 0], [1, 1], [0, 1]]},
        {"id": 2, "vertices": [[1, 0], [2, 0], [2, 1], [1, 1], [1, 0]]},  # closed: first repeated
        {"id": 3, "vertices": [[0, 1], [2, 1], [2, 2], [0, 2]]},
    ]}  # fmt: skip
    (tmp_path / "t.json").write_text(json.dumps(table))
    cells = imported(tmp_path, "t.json", None)
    assert len(cells.cells[2]) == 5
    assert cells.neighbour_counts.tolist() == [2, 2, 2]


# --- bad images and tables ------------------------------------------------------------------------


def grid(rows: int = 3, cols: int = 4, size: int = 8, margin: int = 2) -> np.ndarray:
    """A label image of rows x cols square cells of size x size pixels, labels 1.., background
    ``margin`` pixels wide around them."""
    out = np.zeros((rows * size + 2 * margin, cols * size + 2 * margin), dtype=np.int32)
    for r in range(rows):
        for c in range(cols):
            out[margin + r * size : margin + (r + 1) * size,
                margin + c * size : margin + (c + 1) * size] = 1 + r * cols + c  # fmt: skip
    return out


def _set(image: np.ndarray, where: tuple, value) -> np.ndarray:
    image = image.copy()
    image[where] = value
    return image


BAD_IMAGES = {
    "3D": (np.stack([grid(), grid()]), "a 3D image of shape"),
    "RGB": (np.stack([grid()] * 3, axis=-1).astype(np.uint8), r"an RGB\(A\) image"),
    "mask": (grid() > 0, "a binary mask"),
    "fraction": (_set(grid().astype(np.float32), (5, 5), 2.5), "a non-integer label 2.5"),
    "negative": (_set(grid(), (5, 5), -3), "a negative label -3 at column 5, row 5"),
    "no_background": (grid(margin=0), "no background"),
    "no_cells": (np.zeros((20, 20), np.uint8), "no cells"),
    "split": (_set(grid(), (slice(18, 26), slice(18, 26)), 2), "label 2 is split into 2"),
    "one_pixel": (_set(grid(), (1, 5), 99), "cell 99 has 1 pixels"),  # in the margin
    "small": (_set(grid(), (slice(0, 3), slice(4, 7)), 99), "cell 99 has 9 pixels"),
    "hole": (_set(grid(), (slice(4, 6), slice(4, 6)), 0), r"cell 1 has a hole \(background"),
    "island": (_set(grid(), (slice(3, 8), slice(3, 8)), 99), r"cell 1 has a hole \(cell 99"),
    "enclosed": (_set(grid(), (slice(9, 11), slice(9, 11)), 0), "enclosed by the tissue"),
}


@pytest.mark.parametrize("case", BAD_IMAGES, ids=list(BAD_IMAGES))
def test_bad_image_is_named(case, tmp_path):
    image, message = BAD_IMAGES[case]
    tifffile.imwrite(tmp_path / "cells.tif", image)
    with pytest.raises(SceneError, match=r"tissue.cells = '.*cells.tif': .*" + message):
        imported(tmp_path, "cells.tif")


def test_a_grid_and_an_isolated_cell_are_traced(tmp_path):
    image = grid()
    image[:, -1:] = 0
    wide = np.pad(image, ((0, 0), (0, 12)))
    wide[4:12, -10:-2] = 50  # a cell with background all round: allowed
    tifffile.imwrite(tmp_path / "cells.tif", wide)
    cells = imported(tmp_path, "cells.tif", 0.5)
    assert cells.n_cells == 13 and np.allclose(cells.areas, 64 * 0.25)  # squares stay exact
    assert cells.neighbour_counts[cells.labels == 50] == 0
    assert cells.neighbour_counts[cells.labels == 6].item() == 4


def test_unreadable_image_is_named(tmp_path):
    (tmp_path / "cells.tif").write_bytes(b"not a tiff at all")
    with pytest.raises(SceneError, match="cannot be read as an image"):
        imported(tmp_path, "cells.tif")


SQUARE = [[0, 0], [1, 0], [1, 1], [0, 1]]
AROUND = [(0, 0), (1, 0), (2, 0), (2, 1), (2, 2), (1, 2), (0, 2), (0, 1)]  # squares round (1, 1)
RING = [{"id": k, "vertices": [[x + i, y + j] for x, y in SQUARE]}
        for k, (i, j) in enumerate(AROUND)]  # fmt: skip
BAD_TABLES = {
    "few": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, 0]]}]}, "cell 1: 2 vertices"),
    "nan": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, float("nan")], [0, 1]]}]},
            "cell 1: a vertex is not finite"),
    "text": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, "a"], [0, 1]]}]}, "pairs of numbers"),
    "ids": ({"cells": [{"id": 1, "vertices": SQUARE}, {"id": 1, "vertices": SQUARE}]},
            "cell id 1 is repeated"),
    "id_type": ({"cells": [{"id": "a", "vertices": SQUARE}]}, "ids must be integers"),
    "bow_tie": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, 1], [1, 0], [0, 1]]}]},
                "cell 1: its polygon intersects itself"),
    "repeat": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, 0], [1, 0], [0, 1]]}]},
               "cell 1: a vertex is repeated"),
    "overlap": ({"cells": [{"id": 1, "vertices": SQUARE},
                           {"id": 2, "vertices": [[0.5, 0], [1.5, 0], [1.5, 1], [0.5, 1]]}]},
                "cells 1 and 2 overlap"),
    "hole": ({"cells": RING}, "background enclosed by the tissue"),
    "below": ({"cells": [{"id": 4, "vertices": [[0, -1], [1, 0], [0, 1]]}]},
              "cell 4 reaches x2 = -1 < 0"),
    "unknown_key": ({"cells": [], "units": "um"}, "unknown key 'units'"),
    "empty": ({"cells": []}, "no cells"),
    "pixel_size": ({"cells": [{"id": 1, "vertices": SQUARE}], "pixel_size": -1},
                   "pixel_size = -1 must be a number > 0"),
}  # fmt: skip


@pytest.mark.parametrize("case", BAD_TABLES, ids=list(BAD_TABLES))
def test_bad_table_is_named(case, tmp_path):
    table, message = BAD_TABLES[case]
    (tmp_path / "cells.json").write_text(json.dumps(table))
    with pytest.raises(SceneError, match=r"tissue.cells = '.*cells.json': .*" + message):
        imported(tmp_path, "cells.json", None)


@pytest.mark.parametrize(
    "text, message",
    [
        ("id,x,y\n1,0,0\n", "expected the header cell_id,x,y"),
        ("cell_id,x,y\n1,0,0\n1,1,zero\n", "line 3: expected cell_id,x,y"),
        ("cell_id,x,y\n1,0,0\n1,1,0\n1,1,1\n2,2,0\n2,3,0\n2,3,1\n1,0,1\n", "cell id 1 is repeated"),
        ('{"cells": [', "cannot be read as JSON"),
    ],
)
def test_bad_csv_or_json_text_is_named(text, message, tmp_path):
    name = "cells.json" if text.startswith("{") else "cells.csv"
    (tmp_path / name).write_text(text)
    with pytest.raises(SceneError, match=message):
        imported(tmp_path, name, None)


def test_table_and_scene_pixel_sizes_must_agree(tmp_path):
    (tmp_path / "t.json").write_text(json.dumps({"cells": [{"id": 1, "vertices": SQUARE}],
                                                 "pixel_size": 2.0}))  # fmt: skip
    with pytest.raises(SceneError, match="pixel_size = 2.0 in the file, but tissue.pixel_size"):
        imported(tmp_path, "t.json", 3.0)
    assert imported(tmp_path, "t.json", 2.0).areas[0] == 4.0
