"""Public DTW calls: ``align`` (precomputed cost matrix) and ``align_features``.

Both return an ``Alignment``: the optimal path through a ``Band`` under the
step pattern of Majkowska et al. eqs. 1-2 (steps (1, 0), (0, 1), (1, 1), each
cell's local cost counted once) and its total cost.

Local costs, NaN and infinity
-----------------------------
* ``+inf`` forbids a cell. If every path through the band meets one, the call
  raises ``ValueError`` rather than returning an infinite-cost path.
* NaN or ``-inf`` inside the band raise ``ValueError`` naming the first such
  cell (row = body frame, column = hand frame). Cells outside the band are
  never read, so a NaN there is harmless. Capture gaps must be filled (or the
  metric must map them to a finite or ``+inf`` cost) before aligning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba.core.dispatcher import Dispatcher

from engine.base.errors import ParameterError

from . import fixed
from . import kernels as K
from .band import Band

_NO_GAMMA = np.empty(0, np.float64)


@dataclass(frozen=True)
class Ends:
    """Where a path may start and end (open ends).

    A path starts at ``(0, 0)`` or, leaving the first frames of one take unmatched,
    at ``(i, 0)`` with ``i <= body`` or ``(0, j)`` with ``j <= hand``; it ends at
    ``(n-1, m-1)``, ``(i, m-1)`` with ``n-1-i <= end_body`` or ``(n-1, j)`` with
    ``m-1-j <= end_hand``. ``body_end``/``hand_end`` (None: as ``body``/``hand``) are
    the end's own limits where they differ from the start's (:func:`ends_through_points`:
    a matching point on the hand take's first or last frame).

    Every unmatched frame costs ``skip`` (local-cost units per frame): the total of a
    path is the sum of its cells' local costs plus ``skip`` times the frames of both
    takes it leaves out, so every frame of both takes is paid for whether matched or
    not and a shorter overlap is not cheaper by itself (plain subsequence DTW, skip 0,
    favours cutting). A path on the diagonal covers two frames per cell, so an end
    stretch is left out when its cells cost more than about ``2 * skip`` each. The
    splice sets ``skip`` from the cost of matching unrelated frames
    (``engine.splice.pipeline``). ``Ends()`` (limits 0) are the paper's fixed ends.
    """

    body: int = 0
    hand: int = 0
    skip: float = 0.0
    body_end: int | None = None
    hand_end: int | None = None

    def __post_init__(self):
        for name in ("body", "hand", "body_end", "hand_end"):
            v = getattr(self, name)
            if v is None and name.endswith("_end"):
                continue
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0:
                raise ParameterError(
                    f"open ends: {name} must be a whole number of frames >= 0, got {v!r}"
                )
        for name, start in (("body_end", self.body), ("hand_end", self.hand)):
            if getattr(self, name) == start:  # one spelling of each set of limits
                object.__setattr__(self, name, None)
        if not (np.isfinite(self.skip) and self.skip >= 0):
            raise ParameterError(f"open ends: skip must be a finite cost >= 0, got {self.skip!r}")

    @property
    def end_body(self) -> int:
        """Body frames that may stay unmatched at the end."""
        return self.body if self.body_end is None else int(self.body_end)

    @property
    def end_hand(self) -> int:
        """Hand frames that may stay unmatched at the end."""
        return self.hand if self.hand_end is None else int(self.hand_end)

    @property
    def fixed(self) -> bool:
        """True when every path runs from (0, 0) to (n-1, m-1)."""
        return self.body == self.hand == self.end_body == self.end_hand == 0

    def array(self) -> np.ndarray:
        """``[skip, body, hand, end_body, end_hand]`` float64, as the kernels read it
        (the start's limits first: a forward pass reads them at its first rows)."""
        return np.array(
            [
                float(self.skip),
                float(self.body),
                float(self.hand),
                float(self.end_body),
                float(self.end_hand),
            ]
        )

    def reversed(self) -> Ends:
        """The same ends for the reversed problem (rows and columns in the opposite
        order): its start is this one's end."""
        return Ends(self.end_body, self.end_hand, self.skip, self.body, self.hand)


def ends_through_points(ends: Ends, points, n: int, m: int) -> Ends:
    """``ends`` narrowed so that every open-end path passes all matching ``points``
    (``(x, y, tol)`` frames of an ``n x m`` problem).

    The band's clips hold a path to a point's window only on the rows the path visits,
    and an open end lets it skip rows: when the first point's window reaches the hand
    take's first frame (``y - tol <= 0``), a path could start on that column below the
    point, leaving the point's body frame unmatched (stranger 14: ``--match 60:0`` started
    the hand at body frame 102); likewise at the end with the last point's window on the
    last hand frame. The start may then leave at most ``x`` body frames unmatched, the end
    at most ``n - 1 - x``. Every path these ends forbid misses a point, so nothing else
    changes; without such a point the ends are returned as they are."""
    pts = sorted((int(x), float(y), float(t or 0.0)) for x, y, t in points)
    if not pts or ends.fixed:
        return ends
    body, body_end = ends.body, ends.end_body
    x, y, t = pts[0]
    if y - t <= 0:
        body = min(body, max(x, 0))
    x, y, t = pts[-1]
    if y + t >= m - 1:
        body_end = min(body_end, max(n - 1 - x, 0))
    if (body, body_end) == (ends.body, ends.end_body):
        return ends
    return Ends(body, ends.hand, ends.skip, body_end, ends.end_hand)


FIXED = Ends()


def as_ends(ends) -> Ends:
    """``None`` -> fixed ends; an ``Ends`` as is."""
    if ends is None:
        return FIXED
    if not isinstance(ends, Ends):
        raise TypeError(f"ends must be an engine.dtw.Ends, got {type(ends).__name__}")
    return ends


@dataclass(frozen=True, eq=False)
class Alignment:
    """Result of a DTW alignment.

    Attributes
    ----------
    path : (k, 2) int64 array
        Cells ``(i, j)`` (body frame, hand frame) from ``(0, 0)`` to
        ``(n-1, m-1)`` (with open ends: from the first row or column to the last
        row or column); each step is ``(1, 0)``, ``(0, 1)`` or ``(1, 1)``.
    cost : float
        Sum of the local costs of the path's cells (γ(n-1, m-1)), plus
        ``ends.skip`` per frame left unmatched.
    band : Band
        The band the path was searched in.
    ends : Ends
        The open ends allowed (``Ends()``: fixed).
    """

    path: np.ndarray
    cost: float
    band: Band
    ends: Ends = FIXED

    @property
    def overlap(self) -> tuple[tuple[int, int], tuple[int, int]]:
        """((first, last) body frame, (first, last) hand frame) the path matches."""
        p = self.path
        return ((int(p[0, 0]), int(p[-1, 0])), (int(p[0, 1]), int(p[-1, 1])))

    @property
    def n(self) -> int:
        return self.band.n

    @property
    def m(self) -> int:
        return self.band.m

    def __repr__(self) -> str:
        return (
            f"Alignment(n={self.n}, m={self.m}, path_length={len(self.path)}, cost={self.cost:.6g})"
        )


def align(cost, band: Band, ends: Ends | None = None) -> Alignment:
    """Optimal banded DTW path through a precomputed local-cost matrix.

    Parameters
    ----------
    cost : (n, m) float array
        Local cost ``D(i, j)`` of body frame ``i`` against hand frame ``j``.
        Only cells inside ``band`` are read.
    band : Band
        Allowed cells; must be for ``n`` rows and ``m`` columns.
    ends : Ends, optional
        Open ends (default: fixed, (0, 0) to (n-1, m-1)).
    """
    problem = Problem.from_cost(cost)
    return problem.solve(check_band(band, problem), as_ends(ends))


def align_features(
    a, b, band: Band, metric: str | Dispatcher = "sqeuclidean", ends: Ends | None = None
) -> Alignment:
    """Optimal banded DTW path between two feature sequences.

    The local cost ``metric(a[i], b[j])`` is computed inside the kernel for
    band cells only; no ``n x m`` matrix is built.

    Parameters
    ----------
    a : (n, d) float array
        Body-take features per frame (1-D arrays are read as ``d = 1``).
    b : (m, d) float array
        Hand-take features per frame.
    band : Band
        Allowed cells, ``n`` rows and ``m`` columns.
    metric : str or numba function
        ``"sqeuclidean"`` (default), ``"euclidean"``, a name registered with
        ``register_metric``, or a ``numba.njit`` function ``f(a_row, b_row)``.
    ends : Ends, optional
        Open ends (default: fixed).
    """
    problem = Problem.from_features(a, b, metric)
    return problem.solve(check_band(band, problem), as_ends(ends))


class SharedCosts:
    """One-shot solves of one feature pair over one band (ends may differ) that compute the
    band's local costs once: a metric whose row state has ``keep_costs`` (the pass-2 angle
    kernel) keeps them from the first whole-band forward pass and reads them in the next
    ones. Same results as :func:`align_features` per solve; memory: 8 bytes per band cell
    while the object lives (the metric caps it)."""

    def __init__(self, a, b, metric: str | Dispatcher = "sqeuclidean"):
        self.problem = Problem.from_features(a, b, metric)
        self.problem.keep_costs = True

    def solve(self, band: Band, ends: Ends | None = None, forward_only: bool = False) -> Alignment:
        """One solve as :func:`align_features`. ``forward_only`` is :class:`Aligner`'s: every
        solve here is a fresh one, so it changes nothing (one interface for both solvers)."""
        return self.problem.solve(check_band(band, self.problem), as_ends(ends))


def check_band(band, problem: Problem) -> Band:
    if not isinstance(band, Band):
        raise TypeError(f"band must be an engine.dtw.Band, got {type(band).__name__}")
    band.check_fits((problem.n, problem.m), problem.what)
    return band


def _as_float_array(x, name: str, ndim: tuple[int, ...]) -> np.ndarray:
    arr = np.asarray(x)
    if arr.dtype.kind not in "fiub":
        raise ParameterError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    if arr.ndim not in ndim:
        want = " or ".join(f"{d}-D" for d in ndim)
        raise ParameterError(f"{name} must be a {want} array, got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.float64)


class Problem:
    """A local-cost source (matrix, built-in metric or numba metric) and its kernels.

    Internal to ``engine.dtw``: ``align``, ``align_features``, ``Aligner`` and
    the views share it.
    """

    def __init__(self, kind: str, n: int, m: int, what: str, **arrays):
        self.kind = kind  # "matrix" | "builtin" | "metric"
        self.n = n
        self.m = m
        self.what = what
        self.cost = arrays.get("cost")
        self.a = arrays.get("a")
        self.b = arrays.get("b")
        self.bT = arrays.get("bT")
        self.metric: K.Metric | None = arrays.get("metric")
        self._rows_state = None  # a metric's row-kernel data (Metric.prepare), made once
        self._exact: bool | None = None  # exact_costs(), asked once
        self.keep_costs = False  # SharedCosts: the row state keeps whole-band costs

    @classmethod
    def from_cost(cls, cost) -> Problem:
        cost = _as_float_array(cost, "cost matrix", (2,))
        if cost.shape[0] == 0 or cost.shape[1] == 0:
            raise ParameterError(
                f"cost matrix must have at least one row and column, got {cost.shape}"
            )
        return cls("matrix", cost.shape[0], cost.shape[1], "cost matrix", cost=cost)

    @classmethod
    def from_features(cls, a, b, metric) -> Problem:
        met = K.get_metric(metric)
        a = _as_float_array(a, "features a", (1, 2))
        b = _as_float_array(b, "features b", (1, 2))
        a = a.reshape(-1, 1) if a.ndim == 1 else a
        b = b.reshape(-1, 1) if b.ndim == 1 else b
        if a.shape[0] == 0 or b.shape[0] == 0:
            raise ParameterError(
                f"features need at least one frame each, got {a.shape[0]} and {b.shape[0]}"
            )
        if a.shape[1] != b.shape[1]:
            raise ParameterError(
                f"features a have {a.shape[1]} values per frame but b have {b.shape[1]}"
            )
        what = f"features ({a.shape[0]} x {b.shape[0]} frames)"
        if met.kind >= 0:
            return cls(
                "builtin",
                a.shape[0],
                b.shape[0],
                what,
                a=a,
                b=b,
                bT=np.ascontiguousarray(b.T),
                metric=met,
            )
        return cls("metric", a.shape[0], b.shape[0], what, a=a, b=b, metric=met)

    def reversed(self) -> Problem:
        """The same problem with both sequences reversed (for backward passes)."""
        if self.kind == "matrix":
            return Problem(
                "matrix",
                self.n,
                self.m,
                self.what,
                cost=np.ascontiguousarray(self.cost[::-1, ::-1]),
            )
        state = self._rows_state
        made = getattr(state, "reversed", None)
        reversed_state = made() if made is not None else None
        if reversed_state is not None:
            # a row kernel whose state reverses without the rows (``PhaseProblem``): the
            # rows stay views (read only for error messages), no reversed copies of them
            out = Problem(
                self.kind,
                self.n,
                self.m,
                self.what,
                a=self.a[::-1],
                b=self.b[::-1],
                metric=self.metric,
            )
            out._rows_state = reversed_state
            return out
        a = np.ascontiguousarray(self.a[::-1])
        b = np.ascontiguousarray(self.b[::-1])
        extra = {"bT": np.ascontiguousarray(b.T)} if self.kind == "builtin" else {}
        return Problem(self.kind, self.n, self.m, self.what, a=a, b=b, metric=self.metric, **extra)

    def exact_costs(self) -> bool:
        """True when every local cost is a whole multiple of ``fixed.QUANTUM`` (the
        metric's ``exact`` says so for these rows; a cost matrix is checked)."""
        if self._exact is None:
            if self.kind == "matrix":
                self._exact = fixed.is_on_grid(self.cost)
            else:
                claim = getattr(self.metric, "exact", None)
                self._exact = bool(claim is not None and claim(self.a, self.b))
        return self._exact

    # -- kernels ---------------------------------------------------------
    def forward(self, lo, hi, start, i0, i1, bp, gamma, keep_gamma: int, ends, last_col, last_row):
        """Rows ``i0..i1-1`` of γ; returns (bad_row, total) as the kernels do.

        ``keep_gamma``: which rows' γ go to ``gamma`` (0 none, 1 all, k every
        k-th and the last; ``kernels._keep``). ``ends``: ``Ends.array()``;
        ``last_col`` (n,) and ``last_row`` (m,) receive γ of the last column and
        of row ``i1 - 1`` (``kernels.best_end``)."""
        if self.kind == "matrix":
            return K.forward_matrix(
                self.cost, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row
            )
        if self.kind == "builtin":
            return K.forward_builtin(
                self.a,
                self.bT,
                self.metric.kind,
                lo,
                hi,
                start,
                i0,
                i1,
                bp,
                gamma,
                keep_gamma,
                ends,
                last_col,
                last_row,
            )
        if self.metric.forward is not None:  # a metric with its own row kernel
            if self._rows_state is None:
                self._rows_state = self.metric.prepare(self.a, self.b)
                if self.keep_costs and hasattr(self._rows_state, "keep_costs"):
                    self._rows_state.keep_costs = True
            return self.metric.forward(
                self._rows_state,
                lo,
                hi,
                start,
                i0,
                i1,
                bp,
                gamma,
                keep_gamma,
                ends,
                last_col,
                last_row,
            )
        return K.forward_metric(
            self.metric.cell,
            self.a,
            self.b,
            lo,
            hi,
            start,
            i0,
            i1,
            bp,
            gamma,
            keep_gamma,
            ends,
            last_col,
            last_row,
        )

    def cost_row(self, i: int, lo: int, hi: int) -> np.ndarray:
        """Local costs of row ``i``, columns ``lo..hi``."""
        if self.kind == "matrix":
            return self.cost[i, lo : hi + 1].copy()
        if self.kind == "builtin":
            return K.cost_row_builtin(self.a, self.bT, self.metric.kind, i, lo, hi)
        if self.metric.row is not None:  # the metric's own row kernel, cached on disk
            return self.metric.row(self.a, self.b, i, lo, hi)
        return K.cost_row_metric(self.metric.cell, self.a, self.b, i, lo, hi)

    def bad_cost_error(self, i: int, band: Band, reversed_: bool = False) -> ValueError:
        """The ValueError for the first NaN/-inf local cost in row ``i`` of ``band``."""
        lo, hi = int(band.lo[i]), int(band.hi[i])
        row = self.cost_row(i, lo, hi)
        bad = np.flatnonzero(~(row > -np.inf))
        j = lo + int(bad[0]) if bad.size else lo
        value = row[j - lo] if bad.size else np.nan
        if reversed_:
            i, j = self.n - 1 - i, self.m - 1 - j
        if self.kind == "matrix":
            return ParameterError(
                f"cost matrix cell (body frame {i}, hand frame {j}) is {value}; local costs "
                "inside the band must be finite or +inf"
            )
        detail = ""
        a = self.a if not reversed_ else self.a[::-1]
        b = self.b if not reversed_ else self.b[::-1]
        for name, row_vals, idx in (("a", a, i), ("b", b, j)):
            nan_dims = np.flatnonzero(np.isnan(row_vals[idx]))
            if nan_dims.size:
                detail += f"; {name}[{idx}] has NaN in dimension(s) {nan_dims.tolist()}"
        return ParameterError(
            f"metric {self.metric.name!r} gave {value} at body frame {i}, hand frame {j}{detail}; "
            "fill capture gaps (or make the metric return +inf) before aligning"
        )

    def solve(self, band: Band, ends: Ends = FIXED) -> Alignment:
        """One-shot forward pass (two γ rows, one byte per cell) and backtrack."""
        check_ends(band, ends)
        bp = np.empty(band.area, np.uint8)  # every entry is written by the forward pass
        last_col = np.empty(band.n)
        last_row = np.empty(band.m)
        e = ends.array()
        bad_row, _ = self.forward(
            band.lo, band.hi, band.start, 0, band.n, bp, _NO_GAMMA, 0, e, last_col, last_row
        )
        if bad_row >= 0:
            raise self.bad_cost_error(int(bad_row), band)
        total, i, j = K.best_end(last_row, last_col, band.lo, band.hi, e, band.n - 1)
        check_total(total)
        path = K.backtrack(bp, band.lo, band.start, i, j)
        path.flags.writeable = False
        return Alignment(path=path, cost=float(total), band=band, ends=ends)


def check_ends(band: Band, ends: Ends) -> None:
    """``ParameterError`` unless some path of ``band`` can start and end within ``ends``."""
    if band.lo[0] > ends.hand:
        raise ParameterError(
            f"the band's first body frame starts at hand frame {band.lo[0]}, but at most "
            f"{ends.hand} hand frames may be left unmatched at the start"
        )
    if band.hi[-1] < band.m - 1 - ends.end_hand:
        raise ParameterError(
            f"the band's last body frame ends at hand frame {band.hi[-1]}, but at most "
            f"{ends.end_hand} of the {band.m} hand frames may be left unmatched at the end"
        )


def check_total(total: float) -> None:
    if not np.isfinite(total):
        raise ParameterError(
            "every path through the band crosses a cell of infinite local cost; "
            "widen the band or check the costs"
        )
