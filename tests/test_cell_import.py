"""Imported cells (issue 34): ``[tissue] cells = "file"`` from a label image (TIFF, PNG, with
``tissue.pixel_size``) or a polygon table (JSON, CSV), the shipped synthetic example's round trip
(scenes/real_tissues/), and the named errors of bad images and tables."""

from __future__ import annotations

import json
import re
import runpy
import tomllib
from pathlib import Path
from types import SimpleNamespace

import malformed_inputs as mi
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
    area is within its perimeter times p (measured: 0.31 P p), its perimeter within 2 p per
    side (measured: 2.2 p in all), its centroid within p (measured: 0.51 p), and every wall longer
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


@pytest.mark.parametrize("case", mi.BAD_IMAGES, ids=list(mi.BAD_IMAGES))
def test_bad_image_is_named(case, tmp_path):
    """The fuzzer's bad images (tests/malformed_inputs.py), each with its error."""
    image, message = mi.BAD_IMAGES[case]
    tifffile.imwrite(tmp_path / "cells.tif", image)
    with pytest.raises(SceneError, match=r"tissue.cells = '.*cells.tif': .*" + re.escape(message)):
        imported(tmp_path, "cells.tif")


def test_a_grid_and_an_isolated_cell_are_traced(tmp_path):
    image = mi.label_grid()
    image[:, -1:] = 0
    wide = np.pad(image, ((0, 0), (0, 12)))
    wide[4:12, -10:-2] = 50  # a cell with background all round: allowed
    tifffile.imwrite(tmp_path / "cells.tif", wide)
    cells = imported(tmp_path, "cells.tif", 0.5)
    assert cells.n_cells == 13 and np.allclose(cells.areas, 64 * 0.25)  # squares stay exact
    assert cells.neighbour_counts[cells.labels == 50] == 0
    assert cells.neighbour_counts[cells.labels == 6].item() == 4


def test_a_speck_goes_to_the_label_around_it(tmp_path):
    """A pixel of cell 1 touching it only diagonally (a rasteriser's or segmenter's speck) goes
    to the cell bordering it most; a detached piece of 16 pixels or more is an error."""
    clean = mi.label_grid()
    tifffile.imwrite(tmp_path / "clean.tif", clean)
    tifffile.imwrite(tmp_path / "speck.tif", mi._with(clean, (10, 10), 1))  # inside cell 6
    speck, expected = imported(tmp_path, "speck.tif"), imported(tmp_path, "clean.tif")
    assert np.array_equal(speck.vertices, expected.vertices)
    tifffile.imwrite(tmp_path / "piece.tif", mi._with(clean, (slice(10, 14), slice(10, 14)), 1))
    with pytest.raises(SceneError, match="label 1 is split into 2 separate pieces"):
        imported(tmp_path, "piece.tif")


def test_unreadable_image_is_named(tmp_path):
    (tmp_path / "cells.tif").write_bytes(b"not a tiff at all")
    with pytest.raises(SceneError, match="cannot be read as an image"):
        imported(tmp_path, "cells.tif")


@pytest.mark.parametrize("case", mi.BAD_TABLES, ids=list(mi.BAD_TABLES))
def test_bad_table_is_named(case, tmp_path):
    """The fuzzer's bad polygon tables, each with its error."""
    table, message = mi.BAD_TABLES[case]
    (tmp_path / "cells.json").write_text(json.dumps(table))
    with pytest.raises(SceneError, match=r"tissue.cells = '.*cells.json': .*" + re.escape(message)):
        imported(tmp_path, "cells.json", None)


BAD_TEXT = [*mi.BAD_CSV.values(), ('{"cells": [', "cannot be read as JSON")]


@pytest.mark.parametrize("text, message", BAD_TEXT)
def test_bad_csv_or_json_text_is_named(text, message, tmp_path):
    name = "cells.json" if text.startswith("{") else "cells.csv"
    (tmp_path / name).write_text(text)
    with pytest.raises(SceneError, match=re.escape(message)):
        imported(tmp_path, name, None)


def test_table_and_scene_pixel_sizes_must_agree(tmp_path):
    (tmp_path / "t.json").write_text(json.dumps({"cells": [{"id": 1, "vertices": mi.SQUARE}],
                                                 "pixel_size": 2.0}))  # fmt: skip
    with pytest.raises(SceneError, match="pixel_size = 2.0 in the file, but tissue.pixel_size"):
        imported(tmp_path, "t.json", 3.0)
    assert imported(tmp_path, "t.json", 2.0).areas[0] == 4.0


def test_imported_scene_round_trips_through_toml():
    scene = load_scene(EXAMPLE / "synthetic.toml")
    data = scene.to_dict()
    assert data["tissue"]["cells"] == str(EXAMPLE / "synthetic_r05.tif")  # made absolute
    assert data["tissue"]["pixel_size"] == 0.02 and "nx" not in data["micro"]
    again = parse_scene(tomllib.loads(scene.to_toml()))
    assert again.tissue == scene.tissue
    assert cell_polygons(again) is cell_polygons(scene)  # the same file: read once


def test_a_file_removed_after_the_scene_was_read_is_named(tmp_path):
    tifffile.imwrite(tmp_path / "cells.tif", mi.label_grid())
    scene = parse_scene(BASE | {"tissue": {"cells": "cells.tif", "pixel_size": 1.0}},
                        directory=tmp_path)  # fmt: skip
    (tmp_path / "cells.tif").unlink()
    with pytest.raises(SceneError, match="tissue.cells = .*cells.tif.*No such file"):
        cell_polygons(scene)
