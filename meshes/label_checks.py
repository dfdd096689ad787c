"""Reading and checking a 2D label image (issue 34): one integer label per cell, 0 background.

TIFF through tifffile, PNG through skimage.io. Specks (a label's detached pieces of fewer than
:data:`MIN_CELL_PIXELS` pixels) go to the label bordering them most. A GeometryError names the
file (``name``) and what is wrong: not a 2D integer image, negative labels, no background, no
cell, a label in several 4-connected pieces, a cell of fewer than :data:`MIN_CELL_PIXELS`
pixels, a cell with a hole (background or another cell inside it), background enclosed by the
tissue. Positions are given as (column, row) of the image, from its top-left pixel.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage import measure

from .geometry_error import GeometryError

MIN_CELL_PIXELS = 16
"""Fewest pixels of a cell: smaller ones cannot be traced into a polygon (a 4 x 4 square)."""


def read_labels(path: str, name: str) -> np.ndarray:
    """The image at ``path`` (.tif, .tiff or .png) as it is stored, or a GeometryError."""
    try:
        if path.lower().endswith((".tif", ".tiff")):
            import tifffile

            return np.asarray(tifffile.imread(path))
        from skimage import io

        return np.asarray(io.imread(path))
    except Exception as e:  # any reader's failure on a damaged or foreign file
        raise GeometryError(f"{name}: cannot be read as an image: {e}") from None


def _where(mask: np.ndarray) -> str:
    row, col = np.argwhere(mask)[0]
    return f"at column {col}, row {row}"


def as_labels(image: np.ndarray, name: str) -> np.ndarray:
    """``image`` as a 2D int64 label array (singleton axes dropped), or a GeometryError."""
    image = np.squeeze(image)
    if image.ndim == 3 and image.shape[-1] in (3, 4):
        raise GeometryError(
            f"{name}: an RGB(A) image of shape {image.shape}, not a label image: save one "
            "integer label per cell as a single-channel (grey) image, 0 for background"
        )
    if image.ndim != 2:
        raise GeometryError(
            f"{name}: a {image.ndim}D image of shape {image.shape}: give one 2D slice "
            "(one integer label per cell, 0 for background)"
        )
    if image.dtype == bool:
        raise GeometryError(
            f"{name}: a binary mask, not a label image: give each cell its own integer label"
        )
    if not np.issubdtype(image.dtype, np.integer):
        if not np.issubdtype(image.dtype, np.floating) or not np.isfinite(image).all():
            raise GeometryError(f"{name}: pixels of type {image.dtype}: labels must be integers")
        if (fraction := image != np.round(image)).any():
            raise GeometryError(
                f"{name}: a non-integer label {image[fraction][0]!r} {_where(fraction)}: "
                "labels must be integers"
            )
    labels = image.astype(np.int64)
    if (negative := labels < 0).any():
        raise GeometryError(
            f"{name}: a negative label {labels[negative][0]} {_where(negative)}: labels must be "
            "integers >= 0 (0 for background)"
        )
    return labels


def absorb_specks(labels: np.ndarray) -> np.ndarray:
    """``labels`` with every piece of a label smaller than MIN_CELL_PIXELS that is not the
    label's largest (4-connected) piece given to the label bordering it most (background
    included): the specks a rasteriser or a segmentation leaves, e.g. a corner pixel touching
    its cell diagonally. Larger second pieces are left to :func:`check_labels`."""
    pieces = measure.label(labels, background=0, connectivity=1)
    out = labels.copy()
    by_label: dict[int, list] = {}
    for region in measure.regionprops(pieces, intensity_image=labels):
        by_label.setdefault(int(region.intensity_max), []).append(region)
    for label, regions in by_label.items():
        for region in sorted(regions, key=lambda r: -r.area)[1:]:
            if region.area >= MIN_CELL_PIXELS:
                continue
            r0, c0 = max(region.bbox[0] - 1, 0), max(region.bbox[1] - 1, 0)
            window = (slice(r0, region.bbox[2] + 1), slice(c0, region.bbox[3] + 1))
            speck = pieces[window] == region.label
            border = labels[window][ndimage.binary_dilation(speck) & ~speck]
            border = border[border != label]
            out[window][speck] = np.bincount(border).argmax() if border.size else 0
    return out


def check_labels(labels: np.ndarray, name: str) -> None:
    """A GeometryError unless every cell (label > 0) is one 4-connected piece of at least
    MIN_CELL_PIXELS pixels without holes, and the background (0) is present and connected to
    the image's border (a tissue without holes)."""
    background = labels == 0
    if not background.any():
        raise GeometryError(
            f"{name}: no background (label 0): the tissue must lie inside the image with "
            "background around it"
        )
    if background.all():
        raise GeometryError(f"{name}: no cells: every pixel is background (label 0)")
    pieces = measure.label(labels, background=0, connectivity=1)
    regions = measure.regionprops(pieces, intensity_image=labels)
    owner = np.array([int(r.intensity_max) for r in regions])
    if (twice := np.flatnonzero(np.bincount(owner) > 1)).size:
        label = int(twice[0])
        raise GeometryError(
            f"{name}: label {label} is split into {np.count_nonzero(owner == label)} separate "
            f"pieces (4-connected; one {_where(labels == label)}): one label per cell"
        )
    for region, label in zip(regions, owner, strict=True):
        if region.area < MIN_CELL_PIXELS:
            raise GeometryError(
                f"{name}: cell {label} has {int(region.area)} pixels (at column "
                f"{region.coords[0][1]}, row {region.coords[0][0]}): at least {MIN_CELL_PIXELS} "
                "are needed to trace its outline; merge it into a neighbour or use a finer image"
            )
        if region.area_filled > region.area:
            row, col = np.argwhere(region.image_filled & ~region.image)[0] + region.bbox[:2]
            inside = labels[row, col]
            what = "background" if inside == 0 else f"cell {inside}"
            raise GeometryError(
                f"{name}: cell {label} has a hole ({what} inside it, at column {col}, row {row}): "
                "a cell must be a simple region; fill the hole or split the cell"
            )
    outside, _ = ndimage.label(np.pad(background, 1, constant_values=True))
    if (holes := (outside[1:-1, 1:-1] != outside[0, 0]) & background).any():
        raise GeometryError(
            f"{name}: background {_where(holes)} is enclosed by the tissue (a hole between "
            f"cells, {int(holes.sum())} pixels): label it as a cell or open it to the outside"
        )
