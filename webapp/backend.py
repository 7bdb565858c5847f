"""The app's only door into the engine: load, align, view, splice, render.

Each function here is a short sequence of engine calls (no algorithm code) plus
caching, so the session object and the views stay free of engine details:

* :func:`prepare` reads both takes and computes what every alignment of that
  pair needs (features of both passes, signals and phases for the axes). It is
  cached per server by file identity and side, so a second browser session (or a
  reload) on the same pair costs nothing.
* :func:`solve` runs pass 1 and pass 2 for a band width pair and matching points,
  reusing the previous solution's work where the engine allows it.
* :func:`cost_view` returns the part of a cost matrix in the visible range at
  screen resolution.
* :func:`splice` and the render helpers produce the spliced take and previews.
"""

from __future__ import annotations

import math
import re
import threading
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.base import tolerances as T
from engine.base.errors import HandSpliceError, check_cancelled, first_line

#: command-line wording in engine messages -> what the page calls the same control
_PAGE_WORDS = (
    (re.compile(r"try --side (\w+)"), r"choose side \1 in the page"),
    (re.compile(r"--roles\b"), "joint-role overrides"),
)


def one_line(exc: BaseException) -> str:
    """An exception as the one line shown in the page (command-line flags named as the
    page's controls)."""
    text = str(exc).strip()
    if isinstance(exc, KeyError) and len(exc.args) == 1 and isinstance(exc.args[0], str):
        text = exc.args[0]
    text = first_line(text) or type(exc).__name__
    for pattern, words in _PAGE_WORDS:
        text = pattern.sub(words, text)
    return text


@dataclass(frozen=True)
class PassResult:
    """One pass's alignment: ``path`` (k, 2) int (body frame, hand frame), ``cost``, band."""

    path: np.ndarray
    cost: float
    band: object  # engine.dtw.Band: lo, hi (n,) int inclusive columns per body row
    alignment: object = None

    @property
    def band_cells(self) -> int:
        return int(np.maximum(self.band.hi - self.band.lo + 1, 0).sum())


@dataclass(frozen=True)
class Solution:
    """Both passes and the merged warp ``warp`` (n,) float: hand frame per body frame."""

    pass1: PassResult
    pass2: PassResult
    warp: np.ndarray
    points: tuple = ()
    band: object = None  # engine.dtw.constraints.Width (or a fraction) as given
    refine_band: object = None
    seconds: float = 0.0
    #: the open-end limit given (seconds each take may stay unmatched), None: the default
    max_unmatched_s: float | None = None
    cache: dict = field(default_factory=dict, compare=False, repr=False)


@dataclass(frozen=True)
class CostView:
    """A window of a cost matrix: ``image`` (cols_x, rows_y) covering body frames
    ``x0..x1`` and hand frames ``y0..y1`` (half-open), each pixel ``stride`` cells."""

    image: np.ndarray
    x0: int
    x1: int
    y0: int
    y1: int
    stride: tuple[int, int]


@dataclass
class Prepared:
    """Everything the alignments of one (body, hand, side) need, computed once."""

    key: tuple
    body: object  # Motion or MarkerSet
    hand: object
    side: str
    n: int
    m: int
    features: object  # the splice engine's per-pair features
    body_signal: np.ndarray  # (n,) in 0..1, drawn along the x axis
    hand_signal: np.ndarray  # (m,) in 0..1, drawn along the y axis
    body_phases: np.ndarray | None = None  # (n,) Phase codes
    hand_phases: np.ndarray | None = None  # (m,)
    pass1_cost: np.ndarray | None = None  # (n, m) D1 of every cell, when small enough
    #: the preview's TakeViews of the body and hand takes (the same for every alignment)
    views: dict = field(default_factory=dict, repr=False)
    #: held by the solves (they reuse and extend the features' caches) and the cumulative views
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    #: held by the spliced takes (:func:`splice`): they read only the takes, the
    #: transfer plan and the solution's map, so a drag's solve never waits for a
    #: preview's or download's splice (~0.2-0.9 s on a 2-minute pair) to finish; a
    #: splice that starts while a solve runs waits for it (``lock``)
    splice_lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def m_hand(self) -> int:
        """Frames of the hand file (people count hand frames in these)."""
        return int(self.features.m_hand)

    @property
    def fps(self) -> float:
        """Body frame rate (also the alignment grid's)."""
        return float(self.features.fps)

    @property
    def hand_fps(self) -> float:
        return float(self.features.hand_fps)


def points_to_grid(prepared: Prepared, points) -> list[tuple[int, int, float]]:
    """``[(body, hand-file frame, tol in hand frames)]`` -> alignment-grid points."""
    from engine.splice import pipeline

    return pipeline.hand_points_to_grid(prepared.features, points)


def grid_points_to_hand(prepared: Prepared, points) -> list[tuple[int, int, float | None]]:
    """Alignment-grid points (old session files and links) -> hand-file frames."""
    from engine.splice import pipeline

    return pipeline.grid_points_to_hand(prepared.features, points)


_PREPARED: dict[tuple, Prepared] = {}
_PREPARED_ORDER: list[tuple] = []
_PREPARED_LIMIT = 4
#: pass-1 local costs are tabulated once per pair up to this many cells (8 bytes each):
#: a drag then re-solves from the table (a few ns per cell) instead of evaluating the
#: sign metric with its θ (eq. 7) per cell (tens of ns)
DENSE_PASS1_MAX_CELLS = T.DENSE_PASS1_MAX_CELLS  # engine.base.tolerances: every cell budget
_PREPARE_LOCK = threading.Lock()


def _file_key(path: Path) -> tuple:
    st = Path(path).stat()
    return (str(path), st.st_size, st.st_mtime_ns)


def prepare(
    body_path: Path,
    hand_path: Path,
    side: str,
    roles: dict | None = None,
    takes: tuple | None = None,
) -> Prepared:
    """Load both takes and compute the per-pair features (cached per server).

    ``roles``: ``{"body": {"right.wrist": NAME}, "hand": {...}}`` joint-role overrides.
    ``takes``: ``(body, hand)`` already read from these files (an upload's check read
    them), or None entries to read here.
    """
    import json

    roles = roles or {}
    key = (
        str(body_path),
        str(hand_path),
        side,
        _file_key(body_path),
        _file_key(hand_path),
        json.dumps(roles, sort_keys=True),
    )
    with _PREPARE_LOCK:
        hit = _PREPARED.get(key)
        if hit is not None:
            return hit
    prepared = _prepare(Path(body_path), Path(hand_path), side, key, roles, takes)
    with _PREPARE_LOCK:
        _PREPARED[key] = prepared
        _PREPARED_ORDER.append(key)
        while len(_PREPARED_ORDER) > _PREPARED_LIMIT:
            _PREPARED.pop(_PREPARED_ORDER.pop(0), None)
    return prepared


def _normalised(x: np.ndarray) -> np.ndarray:
    x = np.nan_to_num(np.asarray(x, dtype=float))
    span = np.ptp(x) if x.size else 0.0
    return (x - x.min()) / span if span > 0 else np.zeros_like(x)


def _prepare(
    body_path: Path, hand_path: Path, side: str, key: tuple, roles: dict, takes: tuple | None = None
) -> Prepared:
    from engine.io import load_take
    from engine.splice import pipeline

    progress = _STAGES  # the server's console during its warm-up, else None
    body, hand = takes or (None, None)
    if progress is not None:
        progress("reading the takes", 0.0)
    body = body if body is not None else load_take(body_path)
    hand = hand if hand is not None else load_take(hand_path)
    if progress is not None:
        progress("reading the takes", 1.0)
    features = pipeline.prepare(
        body,
        hand,
        side=side,
        body_roles=roles.get("body") or None,
        hand_roles=roles.get("hand") or None,
        progress=progress,
    )
    body_speed, hand_speed = pipeline.wrist_speeds(features)
    body_phases, hand_phases = _phases(features)
    n, m = features.n, features.m
    pass1_cost = None
    if n * m <= DENSE_PASS1_MAX_CELLS:
        if progress is not None:
            progress(f"pass-1 local costs ({n:,} × {m:,} frames)", 0.0)
        pass1_cost = _local_costs(
            features.pass1_rows, pipeline.DEFAULT_METRICS[0], np.arange(n), np.arange(m)
        )
        if progress is not None:
            progress(f"pass-1 local costs ({n:,} × {m:,} frames)", 1.0)
    return Prepared(
        key=key,
        body=body,
        hand=hand,
        side=side,
        n=n,
        m=m,
        features=features,
        body_signal=_normalised(body_speed),
        hand_signal=_normalised(hand_speed),
        body_phases=body_phases,
        hand_phases=hand_phases,
        pass1_cost=pass1_cost,
    )


def _phases(features) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Gesture phases of the first spliced arm's wrist: body ``(n,)``, hand ``(m,)``."""
    try:
        from engine.gesture.phases import marker_phase_labels

        return (
            marker_phase_labels(features.body_markers, features.fps),
            marker_phase_labels(features.hand_markers, features.fps),
        )
    except (ImportError, AttributeError, HandSpliceError, ValueError):
        return None, None


#: ``progress(stage, fraction)`` of the server's warm-up (:func:`stages_to`), which runs
#: before the server listens, on one thread: the console says what it is doing
_STAGES = None


class stages_to:
    """``with stages_to(progress): ...``: the engine's stages of the pairs prepared and
    solved inside (reading, features, pass 1, pass 2, ...) go to ``progress(stage,
    fraction)``. For the warm-up only (one thread, before any page)."""

    def __init__(self, progress):
        self.progress = progress

    def __enter__(self):
        global _STAGES
        _STAGES = self.progress
        return self

    def __exit__(self, *exc):
        global _STAGES
        _STAGES = None
        return False


def solve(
    prepared: Prepared,
    band,
    refine_band,
    points,
    previous=None,
    progress=None,
    max_unmatched_s: float | None = None,
) -> Solution:
    """Pass 1 and pass 2 for band widths ``band``/``refine_band`` (``constraints.Width``,
    fractions of n or ``"10s"``) and matching points ``[(body, hand, tol), ...]``;
    ValueError/HandSpliceError if infeasible (the checks are engine.dtw.constraints').
    ``max_unmatched_s``: the open-end limit (``--max-unmatched``), None for the default.

    ``progress(stage, fraction)``: the engine's stages (pass 1, pass 2, merge) as they
    start and end. Safe on a worker thread (the app runs long solves there)."""
    from engine.splice import pipeline

    t0 = time.perf_counter()
    points = tuple(points)
    with prepared.lock:
        earlier = None if previous is None else previous.cache.get("engine")
        if earlier is not None and previous.cache.get("shared"):  # every tab's: a copy
            earlier = _own(earlier)
        if earlier is None and prepared.pass1_cost is not None:
            earlier = _seed(prepared)
        result = pipeline.align_passes(
            prepared.features,
            band=band,
            refine_band=refine_band,
            points=list(points),
            previous=earlier,
            progress=progress or _STAGES,
            max_unmatched_s=max_unmatched_s,
        )
    p1, p2 = result.pass1, result.pass2
    sol = Solution(
        pass1=PassResult(np.asarray(p1.path), float(p1.cost), p1.band, p1),
        pass2=PassResult(np.asarray(p2.path), float(p2.cost), p2.band, p2),
        warp=np.asarray(result.warp, dtype=float),
        points=points,
        band=band,
        refine_band=refine_band,
        seconds=time.perf_counter() - t0,
        max_unmatched_s=max_unmatched_s,
    )
    sol.cache["engine"] = result
    return sol


#: the first alignment of a pair at given settings (band widths, matching points), shared
#: by every tab of this server that opens the pair with them: ``handsplice serve``'s
#: warm-up solves it before any page asks, the first tab otherwise; a second tab (or a
#: reload) shows it at once instead of solving again. Kept with the pair (``Prepared``:
#: files by content or identity, side, roles, :func:`prepare`) under its settings. The shared
#: solution's incremental solvers are never run: a session's first edit from it runs on a
#: copy of them (:func:`_own`), so the edits stay per session.
#: (The cumulative-cost view may complete their stored γ rows: they stay valid.)
_FIRST_LOCK = threading.Lock()
#: counters of :func:`first_solution` (read by tests):
#: ``solved`` first alignments computed, ``shared`` handed out without solving
FIRST_STATS = {"solved": 0, "shared": 0}


def _first_key(band, refine_band, points) -> tuple:
    return ("first alignment", repr(band), repr(refine_band), tuple(tuple(p) for p in points))


def first_solution(
    prepared: Prepared, band, refine_band, points, progress=None, wait: bool = True, owner=None
) -> Solution | None:
    """The pair's shared first alignment at these settings (see the note above
    :data:`FIRST_STATS`): the one another tab (or the warm-up) computed, else solved here
    and kept for the next tab.
    A tab asking while another computes it waits for that one (``wait``; else None).

    ``owner``: who asks (a session's id); the solution computed here names it in its
    ``cache["solved_for"]`` (the page says whether its alignment was solved for it).
    Never mutate it: :func:`solve` with ``previous`` set to it solves on copies."""
    import concurrent.futures as cf

    key = _first_key(band, refine_band, points)
    with _FIRST_LOCK:
        entry = prepared.views.get(key)
        mine = entry is None
        if mine:
            entry = prepared.views[key] = cf.Future()
    if not mine:
        if not wait and not entry.done():
            return None
        sol = entry.result()  # the other tab's refusal is this one's too
        with _FIRST_LOCK:
            FIRST_STATS["shared"] += 1
        return sol
    try:
        sol = solve(prepared, band, refine_band, points, progress=progress)
    except BaseException as exc:
        with _FIRST_LOCK:
            prepared.views.pop(key, None)  # the next tab tries again
        entry.set_exception(exc)
        raise
    sol.cache["shared"] = True
    sol.cache["solved_for"] = owner
    with _FIRST_LOCK:
        FIRST_STATS["solved"] += 1
    entry.set_result(sol)
    return sol


def shared_ready(prepared: Prepared, band, refine_band, points) -> Solution | None:
    """The shared first alignment at these settings when it is already computed, else None
    (the event loop's quick look before it queues a solve)."""
    with _FIRST_LOCK:
        entry = prepared.views.get(_first_key(band, refine_band, points))
    if entry is None or not entry.done() or entry.exception() is not None:
        return None
    with _FIRST_LOCK:
        FIRST_STATS["shared"] += 1
    return entry.result()


def offer(prepared: Prepared, solution: Solution) -> None:
    """Share ``solution`` (the warm-up's first alignment of ``prepared``) with every tab."""
    import concurrent.futures as cf

    key = _first_key(solution.band, solution.refine_band, solution.points)
    future = cf.Future()
    solution.cache["shared"] = True
    future.set_result(solution)
    with _FIRST_LOCK:
        prepared.views[key] = future


def _own(result):
    """``result`` (an engine ``SpliceAlignment``) with copies of its incremental solvers:
    a session's edit from a shared alignment re-solves on its own copy (the shared rows
    stay as they are for every other tab). Call under the pair's lock."""
    from dataclasses import fields, is_dataclass, replace

    if result is None or not is_dataclass(result):
        return result
    memo: dict[int, object] = {}
    changes = {}
    for f in fields(result):
        part = getattr(result, f.name)
        if is_dataclass(part) and hasattr(part, "solver"):
            extra = {"probe": _own_solver(part.probe, memo)} if hasattr(part, "probe") else {}
            changes[f.name] = replace(part, solver=_own_solver(part.solver, memo), **extra)
    return replace(result, **changes)


def _own_solver(solver, memo: dict):
    """A copy of an ``engine.dtw.Aligner`` whose stored rows (γ, β, back-pointers) are its
    own; the problem (the features' rows) and bands are read-only and stay shared. Other
    solvers (one-shot ones) are returned as they are."""
    import copy

    if solver is None or not all(hasattr(solver, a) for a in ("_fwd", "_bwd", "_lock")):
        return solver
    if id(solver) not in memo:
        twin = copy.copy(solver)
        band, rband = getattr(solver, "_band", None), getattr(solver, "_rband", None)
        twin._fwd = _own_side(solver._fwd, None if band is None else band.start)
        twin._bwd = _own_side(solver._bwd, None if rband is None else rband.start)
        twin._lock = threading.Lock()
        memo[id(solver)] = twin
    return memo[id(solver)]


def _own_side(side, start):
    """A copy of one direction's stored rows: the back-pointers of its valid rows and γ of
    its stored rows only (γ lives in sparse memory: a whole copy would make every page of
    the band resident)."""
    import copy

    from engine.dtw.incremental import _sparse_floats

    twin = copy.copy(side)
    twin.has = side.has.copy()
    twin.last_col = side.last_col.copy()
    twin.last_row = side.last_row.copy()
    if start is None or side.gamma.size <= 1:
        twin.gamma, twin.bp = side.gamma.copy(), side.bp.copy()
        return twin
    twin.bp = side.bp.copy()
    twin.gamma = _sparse_floats(side.gamma.size)
    for r in np.flatnonzero(side.has[: side.valid]):
        twin.gamma[start[r] : start[r + 1]] = side.gamma[start[r] : start[r + 1]]
    return twin


@dataclass
class _SeedPass:
    solver: object = None
    rows: tuple = (None, None)


@dataclass
class _Seed:
    """Stands in for a previous ``SpliceAlignment`` so that ``align_passes`` reuses a pass-1
    solver over the tabulated local costs (same costs, same path; only faster)."""

    features_id: int
    pass1: _SeedPass
    pass2: _SeedPass


def _seed(prepared: Prepared) -> _Seed:
    from engine.dtw import Aligner

    return _Seed(
        features_id=id(prepared.features),
        pass1=_SeedPass(solver=Aligner.from_cost(prepared.pass1_cost)),
        pass2=_SeedPass(),
    )


def _local_costs(rows_ab, metric: str, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Local costs ``metric(a[r], b[c])`` on the grid ``rows`` x ``cols`` (float64): the
    splice metrics through the pipeline's grid (kernels cached on disk; the cost view's
    kernel takes the metric as an argument, so it compiled anew in every server), others
    (the built-in cells) through the DTW engine's cost view at one cell per pixel."""
    from engine.dtw.views import local_cost_image
    from engine.splice import pipeline

    if metric in pipeline.DEFAULT_METRICS:
        return pipeline.local_cost_grid(rows_ab, metric, rows, cols)
    a, b = rows_ab
    sub_a = np.ascontiguousarray(a[rows])
    sub_b = np.ascontiguousarray(b[cols])
    view = local_cost_image(sub_a, sub_b, metric, max_size=(len(rows), len(cols)))
    return np.ascontiguousarray(view.image, dtype=np.float64)


def _view_window(ranges, n: int, m: int, max_pixels: int):
    x0, x1, y0, y1 = ranges
    x0 = int(np.clip(np.floor(x0 + 0.5), 0, n - 1))
    x1 = int(np.clip(np.ceil(x1 + 0.5), x0 + 1, n))
    y0 = int(np.clip(np.floor(y0 + 0.5), 0, m - 1))
    y1 = int(np.clip(np.ceil(y1 + 0.5), y0 + 1, m))
    sx = max(1, -(-(x1 - x0) // max_pixels))
    sy = max(1, -(-(y1 - y0) // max_pixels))
    # snap the window to the stride grid so pixels do not shimmer while panning
    x0 -= x0 % sx
    y0 -= y0 % sy
    return x0, x1, y0, y1, sx, sy


def cost_view(
    prepared: Prepared, solution: Solution | None, kind: str, ranges, max_pixels: int
) -> CostView:
    """The visible part of matrix ``kind`` (pass1, pass2, cumulative1, cumulative2),
    at most ``max_pixels`` samples per axis (every ``stride``-th cell)."""
    from engine.splice import pipeline

    x0, x1, y0, y1, sx, sy = _view_window(ranges, prepared.n, prepared.m, max_pixels)
    rows = np.arange(x0, x1, sx)
    cols = np.arange(y0, y1, sy)
    engine_result = None if solution is None else solution.cache.get("engine")
    if kind == "pass1" and prepared.pass1_cost is not None:
        image = prepared.pass1_cost[np.ix_(rows, cols)]
    elif kind == "pass1":
        # the whole matrix at screen resolution is what every tab of the pair shows first:
        # computed once per pair (the server's warm-up, or the first tab), kept with it
        whole = (x0, x1, y0, y1) == (0, prepared.n, 0, prepared.m)
        key = ("pass1 overview", sx, sy)
        image = prepared.views.get(key) if whole else None
        if image is None:
            image = _local_costs(
                prepared.features.pass1_rows, pipeline.DEFAULT_METRICS[0], rows, cols
            )
            if whole:
                prepared.views[key] = image
    elif kind == "pass2" and engine_result is not None:
        image = _local_costs(engine_result.pass2.rows, engine_result.pass2.metric, rows, cols)
    else:
        with prepared.lock:
            image = pipeline.cost_image(prepared.features, kind, rows, cols, engine_result)
    return CostView(
        image=np.asarray(image, dtype=np.float32),
        x0=int(rows[0]),
        x1=int(rows[-1] + sx),
        y0=int(cols[0]),
        y1=int(cols[-1] + sy),
        stride=(sx, sy),
    )


def marker_body(prepared: Prepared) -> bool:
    """True when the body take holds markers (C3D/TRC): no skeleton to receive fingers."""
    return not hasattr(prepared.body, "skeleton")


def splice(prepared: Prepared, solution: Solution, cancelled=None):
    """The spliced Motion (body take with the hand take's wrist and fingers).

    A marker body (C3D/TRC) cannot receive fingers: then it is the hand take retimed
    to the body (one frame per body frame, at the body's rate), which is what such a
    pair gives (``engine.splice.retime``).

    ``cancelled``: a callable, asked between blocks of frames of the transfer; once it
    returns True the splice stops (``engine.base.errors.Cancelled``, nothing cached): a
    preview's splice of a long take (0.7 s of CPU at 72,000 frames) is given up when a
    newer edit is being solved, instead of sharing the cores with that edit's solve."""
    from engine.splice import pipeline

    cached = solution.cache.get("spliced")
    if cached is not None:
        return cached
    with prepared.lock:  # a solve that runs (a drag's) goes first: they would share the CPU
        pass
    with prepared.splice_lock:
        if marker_body(prepared):
            from engine.splice.retime import retimed_hand

            motion = retimed_hand(
                prepared.hand, solution.cache["engine"].map, prepared.features.fps
            )
        else:
            motion = pipeline.transfer(
                prepared.features, solution.cache["engine"], cancelled=cancelled
            )
    if not solution.cache.get("let go"):  # no page shows it: not kept (see showing)
        solution.cache["spliced"] = motion
    return motion


def bvh_bytes(motion) -> bytes:
    """``motion`` as BVH text (UTF-8), the CLI's bytes, formatted in a child process (a
    long take's text would hold the server's interpreter for seconds: ``webapp.downloads``)."""
    from webapp.downloads import encode

    return encode("bvh", motion)


def glb_bytes(motion, credit: str = "") -> bytes:
    """``motion`` as a GLB file (the skinned mannequin), made in a child process;
    ``credit`` (the takes' sources and licences) in its ``asset.copyright``."""
    from webapp.downloads import encode

    return encode("glb", motion, credit=credit)


def served_file(
    prepared: Prepared, solution: Solution, kind: str, name: str, owner=None, credit: str = ""
):
    """The spliced take's ``kind`` ("bvh" or "glb") file, written to the server's disk by a
    child (``webapp.downloads.write``: the command line's writer, the CLI's bytes) and
    served over HTTP under the browser name ``name`` (``webapp.served_files``: the page
    fetches it; the server holds none of its bytes). The file made for this alignment
    before is served again while the server keeps it (the same bytes: an alignment never
    changes); ``owner`` (a page) keeps its latest file of each kind. ``credit``: the takes'
    sources and licences, inside a GLB (``webapp.downloads.encode``; a BVH has no place)."""
    from webapp.downloads import write
    from webapp.served_files import STORE

    kept, kept_credit = solution.cache.get(("file", kind), (None, None))
    if (
        kept is not None
        and kept.name == name
        and kept_credit == credit
        and STORE.get(kept.token) is kept
    ):
        return kept
    motion = splice(prepared, solution)
    served = STORE.put(
        lambda path: write(kind, motion, path, credit=credit), name, kind, owner=owner
    )
    solution.cache[("file", kind)] = (served, credit)
    return served


# ---------------------------------------------------------------- previews

_PREVIEWS: dict[int, object] = {}
_PREVIEW_LOCK = threading.Lock()


def preview_for(prepared: Prepared, solution: Solution, cancelled=None):
    """An ``engine.render.offscreen.Preview`` of body | hand | spliced (cached per solution).
    ``cancelled``: a callable; once it returns True the spliced take and its view (posed
    block by block) are given up (``engine.base.errors.Cancelled``, nothing kept)."""

    cached = solution.cache.get("preview")
    if cached is not None:
        return cached
    # one preview per alignment, whichever tabs show it (a shared first alignment)
    with solution.cache.setdefault("preview lock", threading.Lock()):
        cached = solution.cache.get("preview")
        return cached if cached is not None else _new_preview(prepared, solution, cancelled)


def _new_preview(prepared: Prepared, solution: Solution, cancelled=None):
    from engine.render.offscreen import Preview

    spliced = splice(prepared, solution, cancelled)
    if marker_body(prepared):  # the markers are drawn apart (no mesh): hand | retimed hand
        takes, labels = [prepared.hand, spliced], ["hand take", "hand retimed to the body"]
    else:
        takes, labels = (
            [prepared.body, prepared.hand, spliced],
            ["body take", "hand take", "spliced"],
        )
    if not all(hasattr(t, "skeleton") for t in takes):
        raise HandSpliceError(
            "previews need a skeletal hand take (BVH); a marker hand take has no fingers to show"
        )
    sides = tuple(getattr(prepared.features, "sides", ()) or (prepared.side,))
    # the input takes' views (world joints of every frame, mannequin, framing) are the same
    # for every alignment: built once per pair, only the spliced take's after an edit
    views = [prepared.views.get((label, sides)) for label in labels[:-1]] + [None]
    # the spliced take's skeleton is the same after every edit: its mannequin (bound in
    # an earlier alignment's first frame; skinning carries it to any pose) is kept too
    skeleton = _skeleton_key(spliced.skeleton)
    kept = prepared.views.get(("spliced mesh", sides))
    meshes = [None] * (len(takes) - 1) + [kept[1] if kept and kept[0] == skeleton else None]
    preview = Preview(
        takes,
        labels=labels,
        size=(960, 360),
        close_up_sides=sides,
        views=views,
        meshes=meshes,
        cancelled=cancelled,
    )
    for label, view in zip(labels[:-1], preview.views[:-1], strict=True):
        prepared.views.setdefault((label, sides), view)
    prepared.views[("spliced mesh", sides)] = (skeleton, preview.views[-1].mesh)
    if not solution.cache.get("let go"):  # no page shows it: not kept (see showing)
        solution.cache["preview"] = preview
    with _PREVIEW_LOCK:  # close the previous solutions' OpenGL contexts of this pair
        old = _PREVIEWS.pop(id(prepared), None)
        _PREVIEWS[id(prepared)] = preview
    if old is not None and old is not preview:
        old.close()
    return preview


#: the alignment each page shows (a page's Session -> its Solution; see :func:`showing`)
_SHOWN: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_SHOWN_LOCK = threading.Lock()


def showing(page, solution: Solution | None) -> None:
    """Page ``page`` (its Session) shows ``solution`` now; None: the page closed.

    A pair's shared first alignment (:func:`first_solution`) is kept for every later tab,
    and so were its spliced take and preview: 0.14 GB at 10 minutes beside the edited
    alignment's own. Once no page shows it, it lets go of them (:func:`_let_go`); a page
    that shows it again makes them again (seconds for a long take). Its solve and trust
    stay. An edit's alignment that its page moved on from lets go of them too: during a
    run of drags the render worker, a trust assessment being given up or a queued job
    could still hold it, and with it a spliced take each (three of them, 0.43 GB, at
    once on the 10-minute pair: RESULTS.md, tenmin2); one whose page closed goes with it."""
    with _SHOWN_LOCK:
        old = _SHOWN.pop(page, None)
        if solution is not None:
            _SHOWN[page] = solution
        unseen = old is not None and all(s is not old for s in _SHOWN.values())
    if solution is not None:
        solution.cache.pop("let go", None)  # shown (again): kept while shown
    if unseen and old is not solution and (solution is not None or old.cache.get("shared")):
        _let_go(old)


def _let_go(solution: Solution) -> None:
    """Drop ``solution``'s spliced take and preview (made again when asked for, and then
    not kept until a page shows it again). Never waits: while its preview is being made (a
    render asked before the page moved on) that render keeps it."""
    solution.cache["let go"] = True
    solution.cache.pop("spliced", None)
    lock = solution.cache.setdefault("preview lock", threading.Lock())
    if not lock.acquire(blocking=False):
        return
    try:
        preview = solution.cache.pop("preview", None)
        solution.cache.pop("spliced", None)
    finally:
        lock.release()
    with _PREVIEW_LOCK:
        for key in [k for k, kept in _PREVIEWS.items() if kept is preview]:
            del _PREVIEWS[key]
    if preview is not None:
        preview.close()


def _skeleton_key(skeleton) -> tuple:
    """What a mannequin depends on of a skeleton: names, parents and offsets."""
    return (
        tuple(skeleton.names),
        np.asarray(skeleton.parents).tobytes(),
        np.asarray(skeleton.offsets, dtype=float).tobytes(),
        tuple((int(j), tuple(map(float, v))) for j, v in sorted(skeleton.end_sites.items())),
    )


def assess(prepared: Prepared, solution: Solution, cancelled=None):
    """Trust in ``solution`` (``engine.splice.uncertainty.Assessment``), cached per solution.

    About four solves' time (forward and backward γ of both passes): the app runs it
    off the event loop after an edit has been drawn. ``cancelled``: a callable; once it
    returns True the assessment stops (``engine.base.errors.Cancelled``, nothing cached):
    the app gives up an assessment as soon as a newer edit is being solved, so it never
    competes with that edit for the cores."""
    cached = solution.cache.get("trust")
    if cached is not None:
        return cached
    # one assessment per alignment, whichever tabs show it (a shared first alignment)
    with solution.cache.setdefault("trust lock", threading.Lock()):
        cached = solution.cache.get("trust")
        if cached is None:
            from engine.trust import assess_splice

            cached = assess_splice(
                prepared.features,
                _with_cost_table(prepared, solution.cache["engine"]),
                body_phases=prepared.body_phases,
                cancelled=cancelled,
            )
            solution.cache["trust"] = cached
    return cached


def _with_cost_table(prepared: Prepared, result):
    """``result`` (a ``SpliceAlignment``) whose pass 1 reads the pair's tabulated pass-1
    costs (:data:`DENSE_PASS1_MAX_CELLS`), when there is a table of its metric: the trust
    assessment's pass-1 spread then costs a table read per cell instead of the sign metric
    with its θ (about 0.3 s CPU at 2,000 x 2,000, beside the next edit's solve)."""
    from dataclasses import replace

    from engine.splice import pipeline

    table = prepared.pass1_cost
    if table is None or result.pass1.metric != pipeline.DEFAULT_METRICS[0]:
        return result
    return replace(result, pass1=replace(result.pass1, cost_table=table))


def frame_triplet(prepared: Prepared, solution: Solution, body_frame: int) -> tuple[int, int, int]:
    """(body frame, hand-take frame in its own frame rate, spliced frame) shown together."""
    i = int(np.clip(body_frame, 0, prepared.n - 1))
    hand_map = solution.cache["engine"].map  # frame of the original hand take per body frame
    last = int(prepared.features.m_hand) - 1
    return i, int(np.clip(round(float(hand_map[i])), 0, last)), i


def render_frame(
    prepared: Prepared,
    solution: Solution,
    body_frame: int,
    camera: str,
    trails: bool,
    size: tuple[int, int] = (960, 360),
    cancelled=None,
) -> np.ndarray:
    """(H, W, 3) uint8: body take, hand take and spliced result side by side. ``cancelled``:
    see :func:`preview_for` (the render itself is not given up once it has begun)."""
    preview = preview_for(prepared, solution, cancelled)
    frames = frame_triplet(prepared, solution, body_frame)
    if marker_body(prepared):
        return _marker_body_frame(prepared, preview, frames, camera, trails, size)
    return preview.frame(
        frames[0], view="side_by_side", camera=camera, size=size, frames=list(frames), trails=trails
    )


def _marker_body_frame(
    prepared: Prepared, preview, frames, camera: str, trails: bool, size: tuple[int, int]
) -> np.ndarray:
    """Body markers (a third of the width, the aligned arm highlighted) | hand take |
    hand retimed to the body."""
    from engine.model.roles import find_marker_roles
    from engine.render.markers import marker_image

    w, h = size
    left = w // 3
    try:
        arm = find_marker_roles(prepared.body.labels, side_hint=prepared.side).side(prepared.side)
        highlight = [k for k in arm.values() if k is not None]
    except (HandSpliceError, KeyError, ValueError):
        highlight = []
    markers = marker_image(prepared.body, frames[0], (left, h), highlight, "body take")
    hands = preview.frame(
        frames[1],
        view="side_by_side",
        camera=camera,
        size=(w - left, h),
        frames=[frames[1], frames[2]],
        trails=trails,
    )
    return np.concatenate([markers, hands[:, :, :3]], axis=1)


def render_closeup(
    prepared: Prepared, solution: Solution, body_frame: int, size: tuple[int, int] = (360, 300)
) -> np.ndarray:
    """(H, W, 3) uint8: the spliced take's hands close up (the hands fill the frame)."""
    preview = preview_for(prepared, solution)
    i = frame_triplet(prepared, solution, body_frame)[2]
    spliced = 1 if marker_body(prepared) else 2  # a marker body's preview: hand | spliced
    return preview.frame(i, view="single", take=spliced, camera="hands", size=size)


def png_bytes(image: np.ndarray) -> bytes:
    """PNG bytes of ``image (H, W, 3) uint8`` (engine.render.video's encoder)."""
    from engine.render.video import to_png_bytes

    return to_png_bytes(np.asarray(image, dtype=np.uint8))


#: the app's preview videos: at most this rate (every body frame of a 30 fps take; every
#: 4th of a 120 fps one: GIF delays are whole centiseconds, 30 fps plays exactly) and at
#: most this many frames (10 s at 30 fps; a longer take gives the 10 s from a start frame)
VIDEO_MAX_FPS = 30.0
VIDEO_MAX_FRAMES = 300
#: the preview videos' default camera (the page's videos use its preview's camera) and the
#: size of their three panels (body take, hand take, spliced; pixels)
VIDEO_CAMERA = "three-quarter"
VIDEO_SIZE = (720, 300)
#: width (pixels) of the spliced hands' close-up right of the three panels, as the page
#: shows it beside its preview: on the default camera the spliced fingers are a few pixels
#: of a whole body (stranger 7). The *hands* camera's panels are close-ups already: none.
VIDEO_CLOSEUP_WIDTH = 300
#: the close-up's label in the videos
CLOSEUP_LABEL = "spliced hands"


def video_frame(
    prepared: Prepared,
    solution: Solution,
    body_frame: int,
    camera: str = VIDEO_CAMERA,
    size: tuple[int, int] = VIDEO_SIZE,
    closeup: int = VIDEO_CLOSEUP_WIDTH,
) -> np.ndarray:
    """(H, W, 3) uint8: one frame of the preview videos: :func:`render_frame`'s three
    panels (``size``) and, right of them, the spliced hands close up (:func:`render_closeup`,
    ``closeup`` pixels wide, as tall, labelled), unless the camera is ``hands`` (its panels
    are close-ups already) or ``closeup`` is 0."""
    image = np.ascontiguousarray(
        render_frame(prepared, solution, body_frame, camera, False, size)[..., :3]
    )
    if camera == "hands" or closeup <= 0:
        return image
    from engine.render.offscreen import label_image

    near = render_closeup(prepared, solution, body_frame, (int(closeup), image.shape[0]))
    near = label_image(np.ascontiguousarray(near[..., :3]), CLOSEUP_LABEL)
    out = np.concatenate([image, near], axis=1)
    x = image.shape[1]
    out[:, x - 1 : x + 1] = 255  # the panels' white line
    return out


def video_frames(
    n: int,
    fps: float,
    start: int = 0,
    max_fps: float = VIDEO_MAX_FPS,
    max_frames: int = VIDEO_MAX_FRAMES,
) -> tuple[range, float]:
    """Which of ``n`` body frames at ``fps`` a preview video shows, and its frame rate.

    Every ``step``-th frame, ``step`` the smallest whole number that keeps the rate at
    or under ``max_fps``; when that is more than ``max_frames`` frames, the
    ``max_frames`` from body frame ``start`` (moved back so the video is full length).
    """
    if n <= 0:
        raise HandSpliceError("no frames to show")
    step = max(1, math.ceil(fps / max_fps - 1e-9))
    span = max_frames * step  # body frames one video covers
    first = 0 if n <= span else min(max(int(start), 0), n - span)
    return range(first, min(n, first + span), step), float(fps) / step


def preview_video(
    prepared: Prepared,
    solution: Solution,
    fmt: str,
    camera: str = VIDEO_CAMERA,
    max_frames: int = VIDEO_MAX_FRAMES,
    size: tuple[int, int] = VIDEO_SIZE,
    progress=None,
    start: int = 0,
    cancelled=None,
    closeup: int = VIDEO_CLOSEUP_WIDTH,
    credit: str = "",
    caption: str = "",
) -> bytes:
    """An animated preview (GIF or MP4 bytes) at the take's speed: the body frames of
    :func:`video_frames` (at most 30 fps, at most ``max_frames`` frames from body frame
    ``start`` of a long take), each drawn by :func:`video_frame` (three panels of ``size``
    and the spliced hands close up, ``closeup`` pixels wide).

    ``credit`` (the takes' sources and licences: ``webapp.views.credits.file_credit``) goes
    inside the file: the GIF's comment, the MP4's ``comment`` tag. ``caption``
    (``video_caption``) is burned under every frame, a strip of its own below the panels
    (``engine.render.offscreen.caption_strip``: it covers nothing, the frames grow by its
    height), and is the MP4's ``copyright`` tag. Empty: none.

    ``progress(done, total)`` is called after each rendered frame and once more (total,
    total) when the file is encoded. ``cancelled()`` (if given) is asked before each frame:
    True gives the video up (``engine.base.errors.Cancelled``, nothing kept; the app's
    page was closed). Safe to call from a worker thread (the renderer serialises OpenGL
    calls), which is how the app runs it.
    """
    import tempfile

    from engine.render.video import GifFrames, gif_bytes, write_mp4

    if prepared is None or solution is None:
        raise HandSpliceError("no takes loaded")
    if fmt not in ("gif", "mp4"):
        raise ValueError(f"format: expected gif or mp4, got {fmt!r}")
    indices, fps = video_frames(prepared.n, float(prepared.body.fps), start, max_frames=max_frames)
    total = len(indices) + 1  # + encoding
    key = _video_key(camera, size, indices, closeup, credit, caption)
    made = made_video(solution, fmt, key)
    if made is not None:  # nothing changed since this file was made: the same file
        if progress is not None:
            progress(total, total)
        return made

    strip = None  # the caption, drawn once at the frames' width

    def rendered():
        nonlocal strip
        for done, i in enumerate(indices, 1):
            check_cancelled(cancelled)
            image = video_frame(prepared, solution, i, camera, size, closeup)
            if caption:
                if strip is None:
                    from engine.render.offscreen import caption_strip

                    strip = caption_strip(caption, image.shape[1])
                image = np.concatenate([image, strip], axis=0)
            yield image
            if progress is not None:
                progress(done, total)

    # one video encoder for the CLI and the app: engine.render.video; either encodes
    # beside the rendering (GIF: a quantiser thread; MP4: ffmpeg fed frame by frame)
    if fmt == "gif":
        with GifFrames() as frames:
            for image in rendered():
                frames.add(image)
            images = frames.images()
        data = gif_bytes(images, fps, comment=credit)  # exact timing: centisecond delays
    else:
        with tempfile.TemporaryDirectory(prefix="handsplice-video-") as folder:
            path = Path(folder) / "preview.mp4"
            write_mp4(rendered(), path, fps, metadata={"comment": credit, "copyright": caption})
            data = path.read_bytes()
    solution.cache[("video", fmt)] = (key, data)  # the latest of each format, per alignment
    if progress is not None:
        progress(total, total)
    return data


def made_video(solution: Solution, fmt: str, key: tuple) -> bytes | None:
    """The ``fmt`` video of ``solution`` made last, if it was made with ``key`` (camera,
    size, body frames shown): an alignment's videos are kept with it (an edit makes a new
    solution, so a kept file is never stale)."""
    kept = solution.cache.get(("video", fmt))
    return kept[1] if kept is not None and kept[0] == key else None


def video_key(
    prepared: Prepared,
    start: int = 0,
    camera: str = VIDEO_CAMERA,
    credit: str = "",
    caption: str = "",
) -> tuple:
    """The key :func:`preview_video` keeps its file under (its default size, from
    ``start``, with ``camera``, ``credit`` and ``caption``)."""
    indices, _ = video_frames(prepared.n, float(prepared.body.fps), start)
    return _video_key(camera, VIDEO_SIZE, indices, VIDEO_CLOSEUP_WIDTH, credit, caption)


def _video_key(
    camera: str,
    size: tuple[int, int],
    indices: range,
    closeup: int,
    credit: str = "",
    caption: str = "",
) -> tuple:
    near = 0 if camera == "hands" else int(max(closeup, 0))
    return (camera, tuple(size), near, indices.start, indices.stop, indices.step, credit, caption)


#: the command line's program as a user who followed the README has it: ``make demo``
#: installs it in the clone's ``.venv`` (not on PATH)
CLI_PROGRAM = ".venv/bin/handsplice"
#: said above the page's command lines: where they run and what their file names are
CLI_WHERE = (
    "# run in your HandSplice folder (README: make demo installed .venv/bin/handsplice there); "
    "the takes' names stand for their paths on your disk"
)


def cli_command(
    body: str,
    hand: str,
    side: str,
    band,
    refine_band,
    points,
    roles: dict | None = None,
    max_unmatched_s: float | None = None,
) -> str:
    """The ``handsplice splice`` command line that reproduces this alignment
    (``band``, ``refine_band``: the widths set, None for the automatic default, left out
    as the command's own default is the same; ``max_unmatched_s``: the open-end limit,
    where one is set).

    ``points``: ``[(body, hand, tol)]`` in each file's own frames (the page's and
    ``--match``'s numbering), tolerance in hand frames: written as the page shows them;
    the CLI puts them on the alignment grid with the same rule as the page
    (``points_to_grid``), so the command gives the page's alignment.
    """
    import shlex

    from engine.dtw import constraints as C

    parts = [
        CLI_PROGRAM,
        "splice",
        shlex.quote(body),
        shlex.quote(hand),
        "-o",
        "spliced.bvh",
        "--side",
        side,
    ]
    for flag, rule, width in (
        ("--band", C.BAND, band),
        ("--refine-band", C.REFINE_BAND, refine_band),
    ):
        width = rule.parse(width)
        if width is not None:  # None: the automatic default, the command's own too
            parts += [flag, width.text()]
    if max_unmatched_s is not None:
        parts += ["--max-unmatched", f"{C.parse_max_unmatched(max_unmatched_s):g}"]
    for x, h, tol in points:
        parts += ["--match", C.MatchPoint(x, h, tol or None).text()]
    if roles:
        parts += ["--roles", "ROLES.json"]
    return " ".join(parts)


def cli_session_command(
    body: str, hand: str, session_file: str, output: str = "spliced.bvh"
) -> str:
    """The ``handsplice splice`` command line that redoes this splice from the session file
    the page downloads (side, bands, tolerance, matching points and roles all come from it)."""
    import shlex

    return " ".join(
        [
            CLI_PROGRAM,
            "splice",
            shlex.quote(body),
            shlex.quote(hand),
            "-o",
            shlex.quote(output),
            "--session",
            shlex.quote(session_file),
        ]
    )
