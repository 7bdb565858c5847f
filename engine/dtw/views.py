"""Cost views for the app: band values and block-downsampled cost images.

* ``BandValues`` holds one value per band cell (e.g. the cumulative cost γ
  from ``Aligner.cumulative_cost()``) in the band's flat layout, with
  ``dense()`` (n x m, NaN outside the band; small problems only) and
  ``image(max_size)`` (downsampled, never n x m).
* ``local_cost_image(a, b, metric, max_size)`` and ``cost_image(cost, max_size)``
  downsample the local cost matrix block by block, computing costs row by row
  (a ``band`` restricts them to band cells), so a long take never
  materialises ``n x m``.

Downsampling: with ``max_size = (h, w)`` each pixel covers
``rows_per_pixel = ceil(n / h)`` rows and ``cols_per_pixel = ceil(m / w)``
columns; ``reduce="mean"`` averages the cells of a block that are in the band,
``"min"`` takes their minimum (good for spotting a cheap valley). A block with
no band cell is NaN. Cell ``(i, j)`` is pixel
``(i // rows_per_pixel, j // cols_per_pixel)``; ``CostImage.to_pixels(path)``
maps a path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba.core.dispatcher import Dispatcher

from engine.base.errors import ParameterError

from . import kernels as K
from ._config import njit, njit_cached
from .band import Band

_REDUCE = {"mean": 0, "min": 1}


@dataclass(frozen=True, eq=False)
class CostImage:
    """A downsampled cost matrix.

    Attributes
    ----------
    image : (h, w) float64
        Reduced cost per block; NaN where a block has no band cell.
    rows_per_pixel, cols_per_pixel : int
        Block size in body frames (rows) and hand frames (columns).
    reduce : str
        ``"mean"`` or ``"min"``.
    """

    image: np.ndarray
    rows_per_pixel: int
    cols_per_pixel: int
    reduce: str

    def to_pixels(self, path) -> np.ndarray:
        """(k, 2) cells -> (k, 2) pixel indices (row, column) in ``image``."""
        path = np.asarray(path, dtype=np.int64)
        return np.column_stack(
            (path[:, 0] // self.rows_per_pixel, path[:, 1] // self.cols_per_pixel)
        )


@dataclass(frozen=True, eq=False)
class BandValues:
    """One float per band cell, in ``band``'s flat layout (``band.start``)."""

    band: Band
    values: np.ndarray

    def __post_init__(self):
        if self.values.shape != (self.band.area,):
            raise ParameterError(
                f"band values must have one entry per band cell ({self.band.area}), "
                f"got shape {self.values.shape}"
            )

    def row(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """(columns, values) of band row ``i``."""
        b = self.band
        lo, hi = int(b.lo[i]), int(b.hi[i])
        return np.arange(lo, hi + 1), self.values[b.start[i] : b.start[i + 1]]

    def dense(self, fill: float = np.nan) -> np.ndarray:
        """(n, m) array with ``fill`` outside the band (allocates n x m)."""
        b = self.band
        out = np.full((b.n, b.m), fill, dtype=np.float64)
        rows = b.row_of(np.arange(b.area))
        cols = b.lo[rows] + (np.arange(b.area) - b.start[rows])
        out[rows, cols] = self.values
        return out

    def image(self, max_size=(512, 512), reduce: str = "mean") -> CostImage:
        """Block-reduced image at most ``max_size = (h, w)`` pixels."""
        b = self.band
        rpp, cpp, h, w, code = _grid(b.n, b.m, max_size, reduce)
        acc, cnt = _blocks_values(self.values, b.lo, b.hi, b.start, rpp, cpp, h, w, code)
        return _finish(acc, cnt, rpp, cpp, reduce)


def local_cost_image(
    a,
    b,
    metric: str | Dispatcher = "sqeuclidean",
    max_size=(512, 512),
    reduce: str = "mean",
    band: Band | None = None,
) -> CostImage:
    """Downsampled local cost ``metric(a[i], b[j])`` of two feature sequences.

    ``a`` (n, d), ``b`` (m, d) as for ``align_features``; only cells of
    ``band`` are evaluated (default: all). Memory is O(m + h * w).
    """
    from .align import Problem

    problem = Problem.from_features(a, b, metric)
    band = _band_or_full(band, problem)
    rpp, cpp, h, w, code = _grid(problem.n, problem.m, max_size, reduce)
    if problem.kind == "builtin":
        acc, cnt = _blocks_builtin(
            problem.a, problem.bT, problem.metric.kind, band.lo, band.hi, rpp, cpp, h, w, code
        )
    else:
        acc, cnt = _blocks_metric(
            problem.metric.cell, problem.a, problem.b, band.lo, band.hi, rpp, cpp, h, w, code
        )
    return _finish(acc, cnt, rpp, cpp, reduce)


def cost_image(
    cost, max_size=(512, 512), reduce: str = "mean", band: Band | None = None
) -> CostImage:
    """Downsampled view of a precomputed (n, m) cost matrix (cells of ``band`` only)."""
    from .align import Problem

    problem = Problem.from_cost(cost)
    band = _band_or_full(band, problem)
    rpp, cpp, h, w, code = _grid(problem.n, problem.m, max_size, reduce)
    acc, cnt = _blocks_matrix(problem.cost, band.lo, band.hi, rpp, cpp, h, w, code)
    return _finish(acc, cnt, rpp, cpp, reduce)


# ---------------------------------------------------------------------------
def _band_or_full(band, problem) -> Band:
    if band is None:
        return Band.full(problem.n, problem.m)
    if not isinstance(band, Band):
        raise TypeError(f"band must be an engine.dtw.Band or None, got {type(band).__name__}")
    band.check_fits((problem.n, problem.m), problem.what)
    return band


def _grid(n: int, m: int, max_size, reduce: str):
    if reduce not in _REDUCE:
        raise ParameterError(f"reduce must be one of {sorted(_REDUCE)}, got {reduce!r}")
    try:
        h_max, w_max = (int(v) for v in max_size)
    except (TypeError, ValueError):
        raise ParameterError(
            f"max_size must be (height, width) in pixels, got {max_size!r}"
        ) from None
    if h_max < 1 or w_max < 1:
        raise ParameterError(f"max_size must be at least (1, 1) pixels, got {max_size!r}")
    rpp = math.ceil(n / h_max)
    cpp = math.ceil(m / w_max)
    return rpp, cpp, math.ceil(n / rpp), math.ceil(m / cpp), _REDUCE[reduce]


def _finish(acc, cnt, rpp, cpp, reduce) -> CostImage:
    with np.errstate(invalid="ignore", divide="ignore"):
        image = acc / cnt if reduce == "mean" else np.where(cnt > 0, acc, np.nan)
    image[cnt == 0] = np.nan
    return CostImage(image=image, rows_per_pixel=rpp, cols_per_pixel=cpp, reduce=reduce)


@njit_cached()
def _accumulate(acc, cnt, vals, offset, r, lo, hi, cpp, use_min):
    """Add columns lo..hi of one row (value of column j is vals[j - offset]) to pixel row r."""
    j = lo
    while j <= hi:
        blk = j // cpp
        stop = min(hi, (blk + 1) * cpp - 1)
        if use_min:
            best = acc[r, blk]
            for k in range(j, stop + 1):
                v = vals[k - offset]
                if v < best:
                    best = v
            acc[r, blk] = best
        else:
            s = 0.0
            for k in range(j, stop + 1):
                s += vals[k - offset]
            acc[r, blk] += s
        cnt[r, blk] += stop - j + 1
        j = stop + 1


@njit_cached()
def _new_blocks(h, w, use_min):
    acc = np.full((h, w), np.inf) if use_min else np.zeros((h, w))
    return acc, np.zeros((h, w), np.int64)


@njit_cached()
def _blocks_values(values, lo, hi, start, rpp, cpp, h, w, use_min):
    acc, cnt = _new_blocks(h, w, use_min)
    for i in range(lo.shape[0]):
        _accumulate(
            acc, cnt, values[start[i] : start[i + 1]], lo[i], i // rpp, lo[i], hi[i], cpp, use_min
        )
    return acc, cnt


@njit_cached()
def _blocks_matrix(cost, lo, hi, rpp, cpp, h, w, use_min):
    acc, cnt = _new_blocks(h, w, use_min)
    for i in range(lo.shape[0]):
        _accumulate(acc, cnt, cost[i], 0, i // rpp, lo[i], hi[i], cpp, use_min)
    return acc, cnt


@njit_cached()
def _blocks_builtin(a, bT, kind, lo, hi, rpp, cpp, h, w, use_min):
    acc, cnt = _new_blocks(h, w, use_min)
    crow = np.zeros(bT.shape[1])
    for i in range(lo.shape[0]):
        K.fill_builtin(a, bT, kind, i, lo[i], hi[i], crow)
        _accumulate(acc, cnt, crow, 0, i // rpp, lo[i], hi[i], cpp, use_min)
    return acc, cnt


@njit()
def _blocks_metric(metric, a, b, lo, hi, rpp, cpp, h, w, use_min):
    acc, cnt = _new_blocks(h, w, use_min)
    crow = np.zeros(b.shape[0])
    for i in range(lo.shape[0]):
        K.fill_metric(metric, a, b, i, lo[i], hi[i], crow)
        _accumulate(acc, cnt, crow, 0, i // rpp, lo[i], hi[i], cpp, use_min)
    return acc, cnt
