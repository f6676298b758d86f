"""A long FOG record kept on disk and read a slice at a time.

API
    DiskArray(path, dtype=float64)      # a 1-D array of the file's values
    as_samples(x) -> np.ndarray | DiskArray
    searchsorted(a, v, side) -> np.ndarray

Why: a pair at 0.1 deg/s is 36 M FOG samples at 1 kHz (180 M at 5 kHz); held as arrays
(times and rates) it would cost 0.6 (2.9) GB, and memory-mapping does not help, since
every page touched by a pass counts in the process's resident memory until the mapping
goes. The analysis only ever reads its samples in chunks (window.py, sums.py, angle.py),
a few at scattered indices, and by binary search; this class serves exactly those reads
from the file (pread), so the analysis of any record needs a few chunks of memory. The
values read are the file's, bit for bit: an analysis on a DiskArray equals the same
analysis on the in-memory array to the last digit.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Literal, overload

import numpy as np
import numpy.typing as npt

#: which end of a run of equal values np.searchsorted places a value at
Side = Literal["left", "right"]


class DiskArray:
    """A read-only 1-D array of float64 in a binary file (native byte order, no header)."""

    ndim = 1

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.dtype = np.dtype(np.float64)
        self._fd = os.open(self.path, os.O_RDONLY)
        self.size: int = os.fstat(self._fd).st_size // self.dtype.itemsize
        self.shape = (self.size,)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __del__(self) -> None:
        self.close()

    def __len__(self) -> int:
        return self.size

    def read(self, lo: int, hi: int) -> np.ndarray:
        """Values lo .. hi - 1, a fresh array."""
        lo, hi = max(lo, 0), min(hi, self.size)
        if hi <= lo:
            return np.empty(0, dtype=self.dtype)
        n = (hi - lo) * self.dtype.itemsize
        buf = os.pread(self._fd, n, lo * self.dtype.itemsize)
        if len(buf) != n:
            raise OSError(f"{self.path}: short read ({len(buf)} of {n} bytes)")
        return np.frombuffer(buf, dtype=self.dtype).copy()

    def _index(self, i: int) -> int:
        j = i + self.size if i < 0 else i
        if not 0 <= j < self.size:
            raise IndexError(f"index {i} out of range for {self.size} values in {self.path}")
        return j

    @overload
    def __getitem__(self, key: int | np.integer) -> np.float64: ...
    @overload
    def __getitem__(self, key: slice | np.ndarray | Sequence[int]) -> np.ndarray: ...

    def __getitem__(self, key: int | np.integer | slice | np.ndarray | Sequence[int]
                    ) -> np.float64 | np.ndarray:
        if isinstance(key, slice):
            lo, hi, step = key.indices(self.size)
            if step != 1:
                raise IndexError(f"{self.path}: only contiguous slices are read from disk")
            return self.read(lo, hi)
        if isinstance(key, int | np.integer):
            j = self._index(int(key))
            return np.float64(self.read(j, j + 1)[0])
        idx = np.asarray(key)
        if idx.dtype.kind not in "iu":
            raise IndexError(f"{self.path}: index with integers or slices, got {idx.dtype}")
        out = np.empty(idx.shape, dtype=self.dtype)
        for pos, i in np.ndenumerate(idx):  # a few scattered values (edges, probes)
            out[pos] = self.read(self._index(int(i)), self._index(int(i)) + 1)[0]
        return out

    def __array__(self, dtype: npt.DTypeLike | None = None, copy: bool | None = None
                  ) -> np.ndarray:
        raise TypeError(f"{self.path} is read in chunks, not as one array "
                        f"({self.size} values): slice it")

    def searchsorted(self, v: npt.ArrayLike, side: Side = "left") -> np.ndarray | np.intp:
        """np.searchsorted for sorted values, by binary search on the file."""
        values = np.atleast_1d(np.asarray(v, dtype=float))
        out = np.empty(values.shape, dtype=np.int64)
        for pos, x in np.ndenumerate(values):
            lo, hi = 0, self.size
            while lo < hi:
                mid = (lo + hi) // 2
                a = self.read(mid, mid + 1)[0]
                if a < x or (side == "right" and a == x):
                    lo = mid + 1
                else:
                    hi = mid
            out[pos] = lo
        return out if np.ndim(v) else out[0]


#: a 1-D record held in memory or read from its file in chunks
Samples = np.ndarray | DiskArray


def as_samples(x: npt.ArrayLike | DiskArray) -> Samples:
    """A record's samples as the analysis reads them: on disk stays on disk."""
    return x if isinstance(x, DiskArray) else np.asarray(x, dtype=float)


@overload
def searchsorted(a: np.ndarray | DiskArray, v: float, side: Side = "left") -> np.intp: ...
@overload
def searchsorted(a: np.ndarray | DiskArray, v: np.ndarray, side: Side = "left"
                 ) -> np.ndarray: ...


def searchsorted(a: np.ndarray | DiskArray, v: float | np.ndarray, side: Side = "left"
                 ) -> np.ndarray | np.intp:
    if isinstance(a, DiskArray):
        return a.searchsorted(v, side)
    return np.searchsorted(a, v, side)
