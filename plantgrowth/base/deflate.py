"""zlib streams (RFC 1950: the bytes HDF5's deflate filter stores and inflates) made by
libdeflate, or by Python's zlib where libdeflate cannot be loaded.

libdeflate (Debian's ``libdeflate0``, scripts/install.sh) is a whole-buffer DEFLATE encoder.
On the shuffled float32 fields of a step file, at level 1 against zlib's level 1 (used before;
``python scripts/benchmarks/bench_deflate.py``, benchmarks/results/deflate.json): a 1e5-dof
tissue's (11.4 MB) in 0.49 times the time, 4 % more bytes; the reference scene's (0.47 MB) in
0.54 times the time, 1 % fewer bytes. Any zlib decoder reads either library's streams; the two
differ in their bytes, not in what they decode to.
"""

from __future__ import annotations

import ctypes
import zlib

import numpy as np

LEVEL = 1
"""Compression level (1-12 in libdeflate, 1-9 in zlib): the fastest. Measured (bench_deflate.py)
on the tissue's step file, level 2 saves 7 % of the bytes for 1.3 times the time, levels 3-6
under 10 % for 1.6-3 times; on the reference scene's, level 2 saves 3 % for 2 times the
time."""


def _libdeflate() -> ctypes.CDLL | None:
    """The libdeflate library with the prototypes used here, or None if it cannot be loaded."""
    try:
        lib = ctypes.CDLL("libdeflate.so.0")
    except OSError:
        return None
    lib.libdeflate_alloc_compressor.restype = ctypes.c_void_p
    lib.libdeflate_alloc_compressor.argtypes = [ctypes.c_int]
    lib.libdeflate_zlib_compress_bound.restype = ctypes.c_size_t
    lib.libdeflate_zlib_compress_bound.argtypes = [ctypes.c_void_p, ctypes.c_size_t]
    lib.libdeflate_zlib_compress.restype = ctypes.c_size_t
    lib.libdeflate_zlib_compress.argtypes = [
        ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, ctypes.c_size_t
    ]  # fmt: skip
    return lib


class Deflater:
    """Compresses contiguous byte arrays to zlib streams at ``level``: with libdeflate (one
    compressor, kept) unless ``use_libdeflate`` is False or the library is missing."""

    def __init__(self, level: int = LEVEL, use_libdeflate: bool = True) -> None:
        self.level = level
        self._lib = _libdeflate() if use_libdeflate else None
        self._compressor = self._lib.libdeflate_alloc_compressor(level) if self._lib else None
        if self._lib is not None and not self._compressor:
            raise MemoryError("libdeflate could not allocate a compressor")

    @property
    def library(self) -> str:
        """Which library compresses: "libdeflate" or "zlib"."""
        return "zlib" if self._lib is None else "libdeflate"

    def __call__(self, data: np.ndarray) -> memoryview:
        """The zlib stream of the bytes of the C-contiguous array ``data``."""
        if self._lib is None:
            return memoryview(zlib.compress(data, self.level))
        bound = self._lib.libdeflate_zlib_compress_bound(self._compressor, data.nbytes)
        out = np.empty(bound, dtype=np.uint8)
        n = self._lib.libdeflate_zlib_compress(
            self._compressor, data.ctypes.data, data.nbytes, out.ctypes.data, bound
        )
        if n == 0:  # the bound is libdeflate's own worst case: never too small
            raise RuntimeError("libdeflate: the output did not fit its own bound")
        return memoryview(out[:n])


deflate = Deflater()
"""The process's compressor (libdeflate where it loads)."""
