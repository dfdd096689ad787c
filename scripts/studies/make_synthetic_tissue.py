"""Write the shipped synthetic label image ``scenes/real_tissues/synthetic_r05.tif``
(docs/real_tissues.md): a generated tissue rasterised, for the import's round trip.

The tissue is ``cells = {voronoi = 32, seed = 1, regularity = 0.5}`` of the default honeycomb cell
(l1 = l2 = 1, theta = 30 deg). Pixel (row i, column j) of an image of n_rows rows has its centre
at ``x = ((j + 1/2) p, (n_rows - i - 1/2) p)``, p = 0.02, and takes the label (generator id + 1)
of the cell holding its centre (skimage.draw.polygon), 0 outside. The image's lower-left corner
is the origin, so the tissue's bottom row lies on the image's bottom edge (the symmetry plane)
and the imported cells are in the generator's coordinates; a margin of background is left
above and to the right. zlib-compressed uint8 TIFF.

    python scripts/studies/make_synthetic_tissue.py [--out scenes/real_tissues/synthetic_r05.tif]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import tifffile
from skimage.draw import polygon as fill

from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.label_checks import check_labels
from plantgrowth.meshes.voronoi_tissue import voronoi_tissue

ROOT = Path(__file__).resolve().parents[2]
CELLS, SEED, REGULARITY = 32, 1, 0.5
PIXEL_SIZE = 0.02
MARGIN = 6
"""Background pixels above and to the right of the tissue."""


def generated() -> CellPolygons:
    """The generator's tissue that the image shows."""
    return voronoi_tissue(HoneycombCell(), CELLS, SEED, REGULARITY)


def rasterise(tissue: CellPolygons, pixel_size: float, margin: int) -> np.ndarray:
    """The label image of ``tissue`` (module docstring): cell i is label i + 1."""
    top = tissue.vertices.max(axis=0)
    n_cols, n_rows = (int(np.ceil(x / pixel_size)) + margin for x in top)
    labels = np.zeros((n_rows, n_cols), dtype=np.uint8 if tissue.n_cells < 256 else np.uint16)
    for i in range(tissue.n_cells):
        p = tissue.polygon(i) / pixel_size
        rows, cols = fill(n_rows - p[:, 1] - 0.5, p[:, 0] - 0.5, labels.shape)
        labels[rows, cols] = i + 1
    return labels


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "scenes/real_tissues/synthetic_r05.tif")
    args = parser.parse_args(argv)
    labels = rasterise(generated(), PIXEL_SIZE, MARGIN)
    check_labels(labels, str(args.out))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tifffile.imwrite(args.out, labels, compression="zlib")
    print(f"wrote {args.out}: {labels.shape[1]} x {labels.shape[0]} pixels, {labels.max()} cells")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
