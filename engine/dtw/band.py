"""DTW bands: for every row ``i`` an inclusive column range ``lo[i]..hi[i]``.

Rows are body frames (``n``), columns hand frames (``m``); all indices are
0-based. A path runs from ``(0, 0)`` to ``(n-1, m-1)`` with steps ``(1, 0)``,
``(0, 1)`` and ``(1, 1)``.

Feasibility, precisely. Such a path exists inside ``lo``/``hi`` if and only if

1. ``lo[0] == 0`` and ``hi[n-1] == m-1`` (the two corners are in the band);
2. ``lo[i+1] <= hi[i] + 1`` for every ``i`` (a step advances at most one column);
3. ``max(lo[0..i]) <= hi[i]`` for every ``i`` (a path never moves left, so once
   some row forced it to column ``c`` every later row must reach ``c``).

Cells that no path can use (left of ``max(lo[0..i])`` or right of
``min(hi[i..n-1])``) are trimmed when a ``Band`` is made, so a stored band
always has non-decreasing ``lo`` and ``hi``; the set of paths is unchanged.

Constructors
------------
``Band.full(n, m)``, ``Band.sakoe_chiba(n, m, width)``,
``Band.from_constraints(n, m, width, points)`` (METHOD.md §4, eqs. 4-5),
``Band.around_path(path, n, m, radius, points=None)`` (pass 2) and
``band.intersect(other)``. Errors are ``ParameterError`` (a ``ValueError``)
naming the row or matching point at fault.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from engine.base.errors import ParameterError
from engine.dtw.constraints import EPS as _EPS
from engine.dtw.constraints import check_points, half_width


def _as_count(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ParameterError(f"{name} must be a positive whole number of frames, got {value!r}")
    return int(value)


@dataclass(frozen=True, eq=False)
class Band:
    """Per-row inclusive column bounds of a DTW band.

    Parameters
    ----------
    lo, hi : (n,) int arrays
        First and last allowed column (hand frame) of each row (body frame).
    m : int
        Number of columns.

    The constructor checks the feasibility conditions in the module docstring
    (``ParameterError`` naming the first bad row) and trims unusable cells.
    ``lo``, ``hi`` and ``start`` are read-only int64 arrays; ``start`` (n + 1)
    is the prefix sum of the row widths, the flat offset of each row in
    per-cell storage.
    """

    lo: np.ndarray
    hi: np.ndarray
    m: int
    open_ends: bool = False
    start: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        m = _as_count(self.m, "band column count m")
        lo = np.asarray(self.lo)
        hi = np.asarray(self.hi)
        if lo.ndim != 1 or hi.ndim != 1 or lo.shape != hi.shape or lo.size == 0:
            raise ParameterError(
                f"band bounds lo and hi must be 1-D arrays of the same non-zero length, "
                f"got shapes {lo.shape} and {hi.shape}"
            )
        for name, arr in (("lo", lo), ("hi", hi)):
            if arr.dtype.kind not in "iu":
                if (
                    arr.dtype.kind != "f"
                    or not np.all(np.isfinite(arr))
                    or np.any(arr != np.round(arr))
                ):
                    raise ParameterError(f"band bound {name} must hold whole column numbers")
        lo = lo.astype(np.int64)
        hi = hi.astype(np.int64)
        n = lo.size
        bad = np.flatnonzero((lo < 0) | (hi > m - 1) | (lo > hi))
        if bad.size:
            i = int(bad[0])
            raise ParameterError(
                f"band row {i}: columns {lo[i]}..{hi[i]} are not a range inside 0..{m - 1}"
            )
        if lo[0] != 0 and not self.open_ends:
            raise ParameterError(
                f"band row 0 starts at column {lo[0]}, but every path starts at (0, 0)"
            )
        if hi[-1] != m - 1 and not self.open_ends:
            raise ParameterError(
                f"band row {n - 1} ends at column {hi[-1]}, but every path ends at "
                f"({n - 1}, {m - 1})"
            )
        gap = np.flatnonzero(lo[1:] > hi[:-1] + 1)
        if gap.size:
            i = int(gap[0])
            raise ParameterError(
                f"band row {i + 1} starts at column {lo[i + 1]} but row {i} ends at column "
                f"{hi[i]}: a step advances at most one column, so no path connects them"
            )
        reach = np.maximum.accumulate(lo)
        stuck = np.flatnonzero(reach > hi)
        if stuck.size:
            i = int(stuck[0])
            first = int(np.flatnonzero(lo[: i + 1] == reach[i])[0])
            raise ParameterError(
                f"band row {i} ends at column {hi[i]}, but row {first} already starts at "
                f"column {reach[i]} and a path never moves back: no path fits"
            )
        hi = np.minimum.accumulate(hi[::-1])[::-1].copy()
        start = np.zeros(n + 1, np.int64)
        np.cumsum(hi - reach + 1, out=start[1:])
        for arr in (reach, hi, start):
            arr.flags.writeable = False
        object.__setattr__(self, "lo", reach)
        object.__setattr__(self, "hi", hi)
        object.__setattr__(self, "m", m)
        object.__setattr__(self, "start", start)

    # -- basic properties ----------------------------------------------------
    @property
    def n(self) -> int:
        """Number of rows (body frames)."""
        return int(self.lo.size)

    @property
    def shape(self) -> tuple[int, int]:
        return self.n, self.m

    @property
    def area(self) -> int:
        """Number of cells in the band."""
        return int(self.start[-1])

    @property
    def widths(self) -> np.ndarray:
        """(n,) number of cells per row."""
        return self.hi - self.lo + 1

    def __repr__(self) -> str:
        return f"Band(n={self.n}, m={self.m}, area={self.area})"

    def __eq__(self, other) -> bool:
        if not isinstance(other, Band):
            return NotImplemented
        return (
            self.m == other.m
            and np.array_equal(self.lo, other.lo)
            and np.array_equal(self.hi, other.hi)
        )

    __hash__ = None  # mutable-looking numpy payload; compare with ==

    def contains(self, i, j):
        """True where cell ``(i, j)`` is in the band (scalars or broadcastable arrays)."""
        i = np.asarray(i)
        j = np.asarray(j)
        inside = (i >= 0) & (i < self.n)
        ic = np.clip(i, 0, self.n - 1)
        result = inside & (j >= self.lo[ic]) & (j <= self.hi[ic])
        return bool(result) if result.ndim == 0 else result

    def check_fits(self, shape: Sequence[int], what: str = "cost matrix") -> None:
        """Raise ``ValueError`` unless ``shape`` is ``(n, m)``."""
        if tuple(int(s) for s in shape) != (self.n, self.m):
            raise ParameterError(
                f"{what} has shape {tuple(shape)} but the band is for "
                f"{self.n} x {self.m} (body frames x hand frames)"
            )

    def mask(self) -> np.ndarray:
        """Dense (n, m) bool mask of the band (for small bands, tests and plots)."""
        cols = np.arange(self.m)
        return (cols >= self.lo[:, None]) & (cols <= self.hi[:, None])

    def row_of(self, flat: np.ndarray) -> np.ndarray:
        """Row index of flat per-cell offsets (inverse of ``start``)."""
        return np.searchsorted(self.start, flat, side="right") - 1

    def reversed(self) -> Band:
        """The band of the problem with both sequences reversed."""
        # a stored band is feasible and trimmed, so its mirror image is too:
        # build it directly (the incremental solver does this on every edit)
        lo = self.m - 1 - self.hi[::-1]
        hi = self.m - 1 - self.lo[::-1]
        start = np.zeros(self.n + 1, np.int64)
        np.cumsum(hi - lo + 1, out=start[1:])
        band = object.__new__(Band)
        for name, value in (("lo", lo), ("hi", hi), ("start", start)):
            value.flags.writeable = False
            object.__setattr__(band, name, value)
        object.__setattr__(band, "m", self.m)
        object.__setattr__(band, "open_ends", self.open_ends)
        return band

    def intersect(self, other: Band) -> Band:
        """Cells in both bands; ``ParameterError`` if no path fits in the intersection."""
        if not isinstance(other, Band):
            raise TypeError(f"can only intersect with a Band, got {type(other).__name__}")
        if other.shape != self.shape:
            raise ParameterError(
                f"cannot intersect a {self.n} x {self.m} band with a {other.n} x {other.m} band"
            )
        lo = np.maximum(self.lo, other.lo)
        hi = np.minimum(self.hi, other.hi)
        empty = np.flatnonzero(lo > hi)
        if empty.size:
            i = int(empty[0])
            raise ParameterError(
                f"the two bands share no cell in row {i} (columns {self.lo[i]}..{self.hi[i]} "
                f"and {other.lo[i]}..{other.hi[i]})"
            )
        try:
            return Band(lo, hi, self.m, open_ends=self.open_ends or other.open_ends)
        except ParameterError as err:
            raise ParameterError(f"intersection of bands admits no path: {err}") from None

    # -- constructors ------------------------------------------------------
    @classmethod
    def full(cls, n: int, m: int) -> Band:
        """Every cell of the n x m matrix."""
        n = _as_count(n, "n (body frames)")
        m = _as_count(m, "m (hand frames)")
        return cls(np.zeros(n, np.int64), np.full(n, m - 1, np.int64), m)

    @classmethod
    def sakoe_chiba(cls, n: int, m: int, width: float) -> Band:
        """Diagonal band of width ``width * n`` frames (the paper's W).

        Centre line from the virtual cell ``(-1, -1)`` to ``(n-1, m-1)``
        (METHOD.md's 1-based ``(0, 0)`` to ``(n, m)``), so row ``i`` is centred
        on column ``(i + 1) * m / n - 1``; vertical half-width
        ``Λ = W * sqrt(n² + m²) / (2 n)`` with ``W = width * n``. Equal to
        ``from_constraints(n, m, width, [])``.
        """
        return cls.from_constraints(n, m, width, ())

    @classmethod
    def from_constraints(
        cls,
        n: int,
        m: int,
        width: float | None,
        points: Iterable[Sequence[float]] = (),
        open_ends: bool = False,
    ) -> Band:
        """Band through user matching points (METHOD.md §4, Majkowska et al. eqs. 4-5).

        Parameters
        ----------
        n, m : int
            Body frames (rows) and hand frames (columns).
        width : float or None
            Band width as a fraction of ``n`` (paper's W = ``width * n`` frames);
            ``None`` puts no diagonal limit, only the tolerance clips below.
        points : sequence of ``(x, y)`` or ``(x, y, tol)``
            Body frame ``x`` matches hand frame ``y`` (whole numbers, 0-based),
            within ``tol >= 0`` hand frames (default 0). ``x`` must increase
            strictly and ``y`` must not decrease from one point to the next.

        Segment ``k`` runs from anchor ``k-1`` to anchor ``k``; the anchors are
        the virtual start ``(-1, -1)``, the points, and ``(n-1, m-1)``. Its rows
        ``x_{k-1} < i <= x_k`` allow the columns within ``Λ_k`` of the straight
        line between the anchors, ``Λ_k = W sqrt(dx² + dy²) / (2 dx)``,
        clipped to ``[y_{k-1} - tol_{k-1}, y_k + tol_k]``. In addition row
        ``x_k`` of a point is clipped to ``[y_k - tol_k, y_k + tol_k]``.

        Guarantee: every path in the band, the optimal one included, crosses
        body frame ``x_k`` only at hand frames within ``tol_k`` of ``y_k``; with
        ``tol = 0`` it passes exactly through ``(x_k, y_k)`` (and moves on
        diagonally or vertically). This is slightly stronger than the paper's
        clip, which lets a diagonal step skip the point.

        Where the diagonal band is too narrow for a path (a steep segment with
        a small ``width``, or a corner outside it) it is widened by the fewest
        cells that connect it, never beyond the tolerance clips. Points that
        contradict each other raise ``ParameterError`` naming them.

        ``open_ends``: paths may start and end away from the corners
        (``engine.dtw.Ends``), so a point may sit on the first or last body frame
        at any hand frame; the band need not hold the corners. The corners are then no
        anchors: before the first point and after the last one the band keeps every
        cell of the band without points too (only the tolerance clips remove cells
        there), so a point never pushes an open end out of reach.
        """
        n = _as_count(n, "n (body frames)")
        m = _as_count(m, "m (hand frames)")
        if width is not None:
            if isinstance(width, bool) or not isinstance(width, int | float | np.number):
                raise ParameterError(f"band width must be a number (fraction of n), got {width!r}")
            if not math.isfinite(width) or width < 0:
                raise ParameterError(f"band width must be a finite fraction >= 0, got {width!r}")
        xs, ys, tols = check_points(points, n, m, open_ends=open_ends)
        hard_lo, hard_hi = _tolerance_clips(n, m, xs, ys, tols)
        if width is None:
            return cls(hard_lo, hard_hi, m, open_ends=open_ends)
        soft_lo, soft_hi = _diagonal_segments(n, m, float(width) * n, xs, ys)
        if open_ends and len(xs):
            _keep_open_ends(soft_lo, soft_hi, n, m, float(width) * n, xs, ys)
        lo = np.maximum(soft_lo, hard_lo)
        hi = np.minimum(soft_hi, hard_hi)
        _connect(lo, hi, hard_lo, hard_hi, m)
        return cls(lo, hi, m, open_ends=open_ends)

    @classmethod
    def around_path(
        cls,
        path: np.ndarray,
        n: int,
        m: int,
        radius: int,
        points: Iterable[Sequence[float]] | None = None,
        open_ends: bool = False,
    ) -> Band:
        """Cells within ``radius`` frames (Chebyshev distance) of a path (pass 2).

        Row ``i`` spans from the first column the path visits in row
        ``i - radius`` minus ``radius`` to the last column it visits in row
        ``i + radius`` plus ``radius`` (clipped). The path itself is inside, so
        the band is feasible. With ``points`` the band is intersected with
        those points' tolerance clips (``from_constraints(n, m, None, points)``),
        so pass 2 keeps the user's matching points.

        ``open_ends``: the path may start on the first row or column and end on
        the last row or column (an open-end path); rows it does not visit take
        the column range of its nearest end cell, so the band lets pass 2 move
        the ends by up to ``radius`` frames. The band is then an open-end band.
        """
        n = _as_count(n, "n (body frames)")
        m = _as_count(m, "m (hand frames)")
        if isinstance(radius, bool) or not isinstance(radius, int | np.integer) or radius < 0:
            raise ParameterError(f"radius must be a whole number of frames >= 0, got {radius!r}")
        path = check_path(path, n, m, open_ends)
        first = np.full(n, m, np.int64)
        last = np.full(n, -1, np.int64)
        np.minimum.at(first, path[:, 0], path[:, 1])
        np.maximum.at(last, path[:, 0], path[:, 1])
        i0, i1 = int(path[0, 0]), int(path[-1, 0])
        first[:i0] = path[0, 1]
        last[:i0] = path[0, 1]
        first[i1 + 1 :] = path[-1, 1]
        last[i1 + 1 :] = path[-1, 1]
        rows = np.arange(n)
        r = int(radius)
        lo = np.maximum(first[np.maximum(rows - r, 0)] - r, 0)
        hi = np.minimum(last[np.minimum(rows + r, n - 1)] + r, m - 1)
        band = cls(lo, hi, m, open_ends=open_ends)
        if points is not None:
            try:
                band = band.intersect(cls.from_constraints(n, m, None, points, open_ends))
            except ParameterError as err:
                raise ParameterError(
                    f"the matching points are not within {r} frames of the path: {err}"
                ) from None
        return band


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def check_path(path, n: int, m: int, open_ends: bool = False) -> np.ndarray:
    """Validate a warping path (k, 2) from (0, 0) to (n-1, m-1) (``open_ends``: from the
    first row or column to the last row or column); return it as int64."""
    arr = np.asarray(path)
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] == 0:
        raise ParameterError(
            f"path must be a (k, 2) array of (row, column) cells, got shape {arr.shape}"
        )
    if arr.dtype.kind not in "iu":
        if arr.dtype.kind != "f" or np.any(arr != np.round(arr)):
            raise ParameterError("path cells must be whole frame numbers")
    arr = arr.astype(np.int64)
    if open_ends:
        if (
            min(arr[0]) != 0
            or (arr[-1, 0] != n - 1 and arr[-1, 1] != m - 1)
            or arr[:, 0].max() > n - 1
            or arr[:, 1].max() > m - 1
            or arr.min() < 0
        ):
            raise ParameterError(
                f"an open-end path must start on body frame 0 or hand frame 0 and end on body "
                f"frame {n - 1} or hand frame {m - 1}, got {tuple(int(v) for v in arr[0])} to "
                f"{tuple(int(v) for v in arr[-1])}"
            )
    elif tuple(arr[0]) != (0, 0) or tuple(arr[-1]) != (n - 1, m - 1):
        raise ParameterError(
            f"path must run from (0, 0) to ({n - 1}, {m - 1}), "
            f"got {tuple(int(v) for v in arr[0])} to {tuple(int(v) for v in arr[-1])}"
        )
    steps = np.diff(arr, axis=0)
    ok = (steps >= 0).all(axis=1) & (steps <= 1).all(axis=1) & (steps.sum(axis=1) > 0)
    bad = np.flatnonzero(~ok)
    if bad.size:
        k = int(bad[0])
        raise ParameterError(
            f"path step {k} from {tuple(int(v) for v in arr[k])} to "
            f"{tuple(int(v) for v in arr[k + 1])} is not (1, 0), (0, 1) or (1, 1)"
        )
    return arr


def _anchors(n: int, m: int, xs, ys):
    """Anchor rows/columns: virtual start (-1, -1), the points, end (n-1, m-1)."""
    ax = [-1, *xs.tolist()]
    ay = [-1, *ys.tolist()]
    if ax[-1] != n - 1:
        ax.append(n - 1)
        ay.append(m - 1)
    return ax, ay


def _tolerance_clips(n: int, m: int, xs, ys, tols):
    """The hard part of eq. 5: per-segment column clips and the points' own rows."""
    lo = np.zeros(n, np.int64)
    hi = np.full(n, m - 1, np.int64)
    ax, ay = _anchors(n, m, xs, ys)
    at = [0, *tols.tolist()] + [0] * (len(ax) - 1 - len(tols))
    for k in range(1, len(ax)):
        rows = slice(ax[k - 1] + 1, ax[k] + 1)
        lo[rows] = max(ay[k - 1] - at[k - 1], 0)
        hi[rows] = min(ay[k] + at[k], m - 1)
    for x, y, t in zip(xs.tolist(), ys.tolist(), tols.tolist()):
        lo[x] = max(y - t, 0)
        hi[x] = min(y + t, m - 1)
    return lo, hi


def _diagonal_segments(n: int, m: int, w_frames: float, xs, ys):
    """The soft part of eq. 5: per segment the columns within Λ_k of the anchor line.

    Each row also keeps floor(c)..ceil(c) of its centre c, so no row is empty.
    """
    lo = np.empty(n, np.int64)
    hi = np.empty(n, np.int64)
    ax, ay = _anchors(n, m, xs, ys)
    for k in range(1, len(ax)):
        x0, y0, x1, y1 = ax[k - 1], ay[k - 1], ax[k], ay[k]
        dx, dy = x1 - x0, y1 - y0
        lam = half_width(w_frames, dx, dy)  # Λ_k, eq. 4
        t = np.arange(1, dx + 1, dtype=np.float64)
        c = y0 + dy * t / dx  # exact at t = dx
        rows = slice(x0 + 1, x1 + 1)
        lo[rows] = np.minimum(np.ceil(c - lam - _EPS), np.floor(c))
        hi[rows] = np.maximum(np.floor(c + lam + _EPS), np.ceil(c))
    np.clip(lo, 0, m - 1, out=lo)
    np.clip(hi, 0, m - 1, out=hi)
    return lo, hi


def _keep_open_ends(lo, hi, n: int, m: int, w_frames: float, xs, ys) -> None:
    """Widen (in place) the first and last segments of an open-end band through points
    ``xs``/``ys`` to the union with the band without points.

    With fixed ends the corners anchor the first and last segments (eq. 5). With open
    ends they do not: a path may start up to the open-end limit from a corner, and a
    segment line drawn from the corner to a point can leave the true start outside its
    Λ (a hand take that starts seconds earlier, with a point placed near the other end:
    the unmatched stretch is then cut by the narrowed band).
    """
    base_lo, base_hi = _diagonal_segments(n, m, w_frames, xs[:0], ys[:0])
    first, last = int(xs[0]), int(xs[-1])
    for rows in (slice(0, first), slice(last + 1, n)):
        lo[rows] = np.minimum(lo[rows], base_lo[rows])
        hi[rows] = np.maximum(hi[rows], base_hi[rows])


def _connect(lo, hi, hard_lo, hard_hi, m: int) -> None:
    """Widen (in place) a band whose rows are non-empty and ordered so a path fits.

    Adds the fewest cells that close each gap between consecutive rows, first
    by extending the earlier row to the right, then the later row to the left,
    never outside the hard clips (which are feasible on their own).
    """
    lo[0] = min(lo[0], hard_lo[0])  # == 0, checked in _parse_points
    hi[-1] = max(hi[-1], hard_hi[-1])  # == m - 1
    # a fix of gap i changes only hi[i] and lo[i + 1], so the gaps are independent
    gap = np.flatnonzero(lo[1:] > hi[:-1] + 1)
    hi[gap] = np.minimum(lo[gap + 1] - 1, hard_hi[gap])
    still = gap[lo[gap + 1] > hi[gap] + 1]
    lo[still + 1] = np.maximum(hard_lo[still + 1], hi[still] + 1)
