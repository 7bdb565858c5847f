"""The two-pass splice: features -> pass 1 -> pass 2 -> merge -> transfer.

Public calls (the CLI, the app and the benchmarks use only these)::

    from engine.splice import pipeline

    feats = pipeline.prepare(body, hand, side="both")          # once per pair
    result = pipeline.align_passes(feats, band=0.3, refine_band=0.1,
                                   points=[(120, 98, 2)])        # per parameter change
    motion = pipeline.transfer(feats, result)                   # the spliced Motion

    # or all at once
    spliced = pipeline.splice(body, hand, side="both", band=0.3, refine_band=0.1)

Frame units. Rows are body frames ``0..n-1``. Columns are hand frames on the
**alignment grid**: the hand take resampled to the body's frame rate
(``m = round((m_hand - 1) * fps_body / fps_hand) + 1``). Matching points,
paths, bands and ``result.warp`` are in grid units; ``result.map`` is the same
warp in frames of the original hand take (``features.hand_to_grid`` /
``features.grid_to_hand`` convert). When both takes share a frame rate the two
are equal.

Both hands are aligned jointly by default (as in the paper): pass 1 sums both
arms' sign costs under one θ, pass 2 sums both arms' angles, and one warp drives
both hands.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from engine.align import metrics as M
from engine.align.features import (
    HandFrame,
    hand_frame,
    marker_set_markers,
    marker_set_yaw,
    take_markers,
    take_sides,
)
from engine.base import limits
from engine.base import tolerances as T
from engine.base.errors import HandSpliceError, ParameterError, RoleError, SideError
from engine.dtw import Aligner, Band, Ends, align_features, ends_through_points, fixed
from engine.dtw import constraints as C
from engine.dtw.align import SharedCosts
from engine.dtw.kernels import get_metric, metric_names
from engine.model.hand_side import match_chirality, undecided_message
from engine.model.motion import MarkerSet, Motion
from engine.model.world_rotations import WorldRotations
from engine.splice import coarse as CO
from engine.splice import merge as MG
from engine.splice import point_rate as PR
from engine.splice import spin as SP
from engine.splice import transfer as TR
from engine.splice.end_band import open_end_band

Progress = Callable[[str, float], None]

#: defaults (the paper's values where it gives them); band widths: engine.dtw.constraints
#: the registered local-cost metrics of pass 1 (eq. 6, on ``metrics.phase_rows`` rows) and
#: pass 2 (eqs. 8-9, on ``AngleFeatures.rows``); any metric in ``engine.dtw``'s registry that
#: reads the same rows may replace them (``metrics=`` of :func:`align_passes`)
DEFAULT_METRICS = ("splice_phase", "splice_angle")
SMOOTHING_S = 0.2
DEAD_ZONE = 0.1
#: constant added to every cell (charges non-diagonal steps; 0 = the paper)
STEP1 = 0.0
STEP2 = 0.05
#: where the alignment may start and end: "open" (either take may begin earlier or end
#: later; up to ``MAX_UNMATCHED`` at each end) or "fixed" (the paper: corner to corner)
ENDS = C.DEFAULT_ENDS
#: frames (Gaussian σ, body frames) over which the fingers ease into the first matched hand
#: pose / out of the last one at the ends of the overlap
EASE_FRAMES = 3.0
#: random cell pairs that estimate the cost of matching unrelated frames (the skip cost)
CHANCE_CELLS = 4096
#: cell budgets: engine.base.tolerances (one place, with the app's)
INCREMENTAL_MAX_CELLS = T.INCREMENTAL_MAX_CELLS
CUMULATIVE_MAX_CELLS = T.CUMULATIVE_MAX_CELLS


def _noop(stage: str, fraction: float) -> None:
    return None


# --------------------------------------------------------------------------------------------
# features
# --------------------------------------------------------------------------------------------


@dataclass
class SpliceFeatures:
    """Everything the alignments of one (body, hand, side) pair need, computed once.

    Attributes
    ----------
    body, hand : Motion or MarkerSet
    sides : tuple of ``"right"``/``"left"``
    n, m : int
        Body frames; hand frames on the alignment grid (body frame rate).
    m_hand : int
        Frames of the original hand take.
    fps, hand_fps : float
    body_markers, hand_markers : (n, 4A, 3), (m, 4A, 3) float, metres, y up
    body_phase, hand_phase : metrics.PhaseFeatures
    pass1_rows : (a (n, d1), b (m, d1')) rows of the ``splice_phase`` metric
    hand_has_yaw : bool, the hand take has a trunk heading (``hand_phase.yaw``)
    theta : ``"window"``, ``"trunk"`` or ``"none"``
    yaw_offset : float, radians (trunk mode, hand take without a trunk)
    params : dict of the parameters used
    timings : dict stage -> seconds
    """

    body: Motion | MarkerSet
    hand: Motion | MarkerSet
    sides: tuple[str, ...]
    n: int
    m: int
    m_hand: int
    fps: float
    hand_fps: float
    body_markers: np.ndarray
    hand_markers: np.ndarray
    body_phase: M.PhaseFeatures
    hand_phase: M.PhaseFeatures
    pass1_rows: tuple[np.ndarray, np.ndarray]
    hand_has_yaw: bool
    theta: str
    n_bins: int
    yaw_offset: float
    body_roles: object = None
    hand_roles: object = None
    body_frames: dict[str, HandFrame] = field(default_factory=dict)
    hand_frames: dict[str, HandFrame] = field(default_factory=dict)
    body_fk: tuple | None = None
    params: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    #: pass-1 rows at the capped rate (multi-resolution pass 1, ``engine.splice.coarse``);
    #: None for takes at or below ``tolerances.PASS1_RATE_CAP_HZ``
    coarse: CO.CoarseRows | None = None

    def hand_to_grid(self, frames) -> np.ndarray:
        """Original hand-take frames -> alignment-grid columns (float)."""
        return MG.hand_frames_to_grid(frames, self.fps, self.hand_fps)

    def grid_to_hand(self, columns) -> np.ndarray:
        """Alignment-grid columns -> original hand-take frames (float)."""
        return MG.grid_to_hand_frames(columns, self.fps, self.hand_fps, self.m_hand)


def _take_name(take) -> str:
    src = getattr(take.meta, "source", "")
    return Path(src).name if src else "the take"


def marker_body(body) -> bool:
    """True when ``body`` holds markers (C3D/TRC): no skeleton to receive fingers, so the
    splice of such a pair is the hand take retimed to it (``engine.splice.retime``)."""
    return isinstance(body, MarkerSet)


def require_skeletal(body, hand, marker_body_ok: bool = False) -> None:
    """Raise ``HandSpliceError`` unless both takes are skeletal (``Motion``): marker takes
    (C3D/TRC) can be aligned, but have no skeleton to receive fingers (body) or no finger
    rotations to give (hand). Call it before the passes to fail fast on long takes.
    ``marker_body_ok``: a marker body is allowed (its output is the retimed hand)."""
    if not isinstance(body, Motion) and not (marker_body_ok and marker_body(body)):
        raise HandSpliceError(
            f"{_take_name(body)}: holds markers; a marker take has no "
            "skeleton to receive fingers: the body take must be a skeletal "
            "take (.bvh)"
        )
    if not isinstance(hand, Motion):
        raise HandSpliceError(
            f"{_take_name(hand)}: holds markers; a marker take has no finger "
            "rotations to give: the hand take must be a skeletal take (.bvh) "
            "with finger joints"
        )


def _roles_for(take, overrides, side: str | None = None):
    """Roles from joint names; a hand-only rig without a side gets ``side`` (``--side
    right|left``: it wins over the file name, which the CLI then warns about, as the page
    does: ``engine.model.roles.side_name_conflict``), else the file name's, else its
    geometry (``engine.model.hand_side``)."""
    from engine.model.hand_side import sided_roles
    from engine.model.roles import find_roles, side_from_name

    if isinstance(take, MarkerSet):
        return None
    if overrides is not None and not isinstance(overrides, dict):
        return overrides  # a Roles object
    hint = side_from_name(take.meta.source) if take.meta.source else None
    if side in ("right", "left"):
        hint = side
    roles = find_roles(take.skeleton, overrides=overrides or None, side_hint=hint)
    return sided_roles(take, roles, side)


def resolve_sides(
    side: str,
    body_sides: Sequence[str],
    hand_sides: Sequence[str],
    body_name: str = "body",
    hand_name: str = "hand",
) -> tuple[str, ...]:
    """Sides to splice. ``"auto"``: both when both takes have both, else the shared side."""
    side = (side or "auto").lower()
    common = [s for s in ("right", "left") if s in body_sides and s in hand_sides]
    if side == "auto":
        if not common:
            raise RoleError(
                f"no side to splice: {body_name} has arms {list(body_sides) or 'none'}, "
                f"{hand_name} has hands {list(hand_sides) or 'none'} (need a wrist on the "
                f"same side in both)"
            )
        return tuple(common)
    if side not in ("right", "left", "both"):
        raise ParameterError(f"side must be 'right', 'left', 'both' or 'auto', got {side!r}")
    wanted = ("right", "left") if side == "both" else (side,)
    for s in wanted:
        if s not in body_sides:
            raise SideError(
                f"{body_name} has no {s} wrist (arms found: {', '.join(body_sides) or 'none'})",
                body_sides,
            )
        if s not in hand_sides:
            raise SideError(
                f"{hand_name} has no {s} hand (hands found: "
                f"{', '.join(hand_sides) or 'none'}); try --side "
                f"{hand_sides[0] if hand_sides else 'right'}",
                hand_sides,
            )
    return wanted


def _hand_sides(take, roles) -> list[str]:
    if isinstance(take, MarkerSet):
        return take_sides(take)
    return [s for s in roles.sides_found()]


def prepare(
    body: Motion | MarkerSet,
    hand: Motion | MarkerSet,
    side: str = "auto",
    body_roles=None,
    hand_roles=None,
    theta: str = "window",
    n_bins: int = M.THETA_BINS,
    smoothing_s: float = SMOOTHING_S,
    dead_zone: float = DEAD_ZONE,
    step1: float = STEP1,
    step2: float = STEP2,
    progress: Progress | None = None,
) -> SpliceFeatures:
    """Per-pair features of both passes.

    Parameters
    ----------
    body, hand : Motion (BVH) or MarkerSet (C3D/TRC; alignment only)
    side : ``"auto"`` (default: both hands when both takes have both, else the shared
        side), ``"both"``, ``"right"`` or ``"left"``.
    body_roles, hand_roles : dict of role overrides (``{"right.wrist": "Name"}``) or a
        ``Roles``; default from joint names.
    theta : ``"window"`` (eq. 7, default), ``"trunk"`` (trunk yaw difference) or ``"none"``.
    n_bins : θ quantisation (directions).
    smoothing_s : Savitzky-Golay window (seconds) for the derivatives.
    dead_zone : ε as a fraction of each take's 90th-percentile speed / acceleration.
    step1, step2 : constant added to every pass-1 / pass-2 cell (sign-cost units /
        radians): each horizontal or vertical step of a path then costs extra, so in
        ambiguous stretches (holds) the path keeps a steady rate.
    """
    progress = progress or _noop
    t0 = time.perf_counter()
    progress("features", 0.0)
    if theta not in ("window", "trunk", "none"):
        raise ParameterError(f"theta must be 'window', 'trunk' or 'none', got {theta!r}")
    rb = _roles_for(body, body_roles)
    rh = _roles_for(hand, hand_roles, side)
    body_name, hand_name = _take_name(body), _take_name(hand)
    sides = _sides_to_align(body, hand, rb, rh, side, body_name, hand_name)
    fps = float(body.fps)
    # the alignment grid: the hand take at the body's rate, bounded before anything is built
    limits.check_grid(hand_name, hand.n_frames, float(hand.fps), fps)
    timings: dict[str, float] = {}

    side_notes: list[str] = []
    if isinstance(hand, Motion):  # a hand take written in left-handed axes: mirror it
        hand, side_notes = match_chirality(body, hand, rb, rh, sides)
    mk = _arm_markers(body, hand, rb, rh, sides, fps)
    body_markers, hand_markers = mk.body_markers, mk.hand_markers
    n, m = body_markers.shape[0], hand_markers.shape[0]
    if n < 2 or m < 2:
        raise ParameterError(
            f"takes too short to align: {body_name} {n} frames, "
            f"{hand_name} {m} frames at {fps:g} fps"
        )

    # trunk headings (radians about the vertical), where the takes have a trunk
    body_yaw, hand_yaw = mk.body_yaw, mk.hand_yaw
    if hand_yaw is not None:
        from engine.align.features import resample_points

        hand_yaw = resample_points(hand_yaw, hand.fps, fps)
    if theta == "trunk" and body_yaw is None:
        raise RoleError(
            f"theta='trunk': {body_name} has no left and right shoulders "
            "to give the trunk's heading"
        )
    timings["markers"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    bp, hp, rows1, yaw_offset = _pass1_features(
        body_markers,
        hand_markers,
        body_yaw,
        hand_yaw,
        fps,
        theta,
        n_bins,
        smoothing_s,
        dead_zone,
        step1,
    )
    coarse = None
    k = C.pass1_decimation(fps)
    if k > 1 and n >= 2 * k and m >= 2 * k:  # pass 1 first at the capped rate (same windows in s)
        # every k-th frame of the full-rate rows: the same signs (derivatives over the same
        # seconds, the takes' own dead zones), θ windows of the coarse frames
        rows_c = M.decimate_phase_rows(rows1, bp, hp, k)
        coarse = CO.CoarseRows(k, len(rows_c[0]), len(rows_c[1]), fps / k, rows_c)
    timings["features"] = time.perf_counter() - t1
    progress("features", 1.0)
    M.register_metrics()
    body_frames, hand_frames, body_fk = mk.body_frames, mk.hand_frames, mk.body_fk
    if hand_frames and all(not hand_frames[s].elbow_apart for s in sides):
        side_notes.append(
            "the hand take has no measured forearm: pass 2 compares how the hand "
            "turns (angular velocity relative to the trunk, in the hand's frame) "
            "instead of its direction relative to the forearm"
        )
    return SpliceFeatures(
        body=body,
        hand=hand,
        sides=tuple(sides),
        n=n,
        m=m,
        m_hand=hand.n_frames,
        fps=fps,
        hand_fps=float(hand.fps),
        body_markers=body_markers,
        hand_markers=hand_markers,
        body_phase=bp,
        hand_phase=hp,
        pass1_rows=rows1,
        hand_has_yaw=hand_yaw is not None,
        theta=theta,
        n_bins=n_bins,
        yaw_offset=yaw_offset,
        body_roles=rb,
        hand_roles=rh,
        body_frames=body_frames,
        hand_frames=hand_frames,
        body_fk=body_fk,
        params={
            "side": side,
            "sides": list(sides),
            "theta": theta,
            "n_bins": n_bins,
            "smoothing_s": smoothing_s,
            "dead_zone": dead_zone,
            "step1": step1,
            "step2": step2,
        },
        timings=timings,
        notes=side_notes,
        coarse=coarse,
    )


def _pass1_features(
    body_markers,
    hand_markers,
    body_yaw,
    hand_yaw,
    fps,
    theta,
    n_bins,
    smoothing_s,
    dead_zone,
    step1,
):
    """``(body, hand PhaseFeatures, pass-1 rows, θ offset)``: the sign codes and headings of
    both takes (eqs. 6-7) and the pass-1 cost rows; a hand take without a trunk gets a
    constant heading offset for ``theta="trunk"``, estimated near the diagonal."""
    n, m = body_markers.shape[0], hand_markers.shape[0]
    bp = M.phase_features(body_markers, fps, yaw=body_yaw, window_s=smoothing_s, relative=dead_zone)
    hp = M.phase_features(
        hand_markers,
        fps,
        yaw=hand_yaw if hand_yaw is not None else np.zeros(m),
        window_s=smoothing_s,
        relative=dead_zone,
    )
    if theta == "trunk" and hand_yaw is None:
        i = np.arange(n)
        j = np.minimum(np.round(i * (m - 1) / max(n - 1, 1)).astype(np.int64), m - 1)
        yaw_offset = -heading_offset(bp, hp, np.column_stack([i, j]))
    else:
        yaw_offset = 0.0
    rows1 = M.phase_rows(bp, hp, theta=theta, n_bins=n_bins, yaw_offset=yaw_offset, step=step1)
    return bp, hp, rows1, yaw_offset


def _sides_to_align(body, hand, rb, rh, side: str, body_name: str, hand_name: str) -> list:
    """The hands to align (``resolve_sides``): of a BVH hand take, only hands with fingers
    (RoleError when it has none, or when its side is undecided)."""
    body_sides = _hand_sides(body, rb)
    hand_sides = _hand_sides(hand, rh)
    if isinstance(hand, Motion):  # a hand take without fingers cannot give any
        with_fingers = [s for s in hand_sides if rh.side(s).has_fingers]
        if not with_fingers:
            undecided = undecided_message(hand_name, hand, rh)
            if undecided:
                raise RoleError(undecided)
            swapped = isinstance(body, Motion) and any(rb.side(s).has_fingers for s in body_sides)
            raise RoleError(
                f"{hand_name} has no finger joints (hands found: "
                f"{', '.join(hand_sides) or 'none'}); the hand take must carry "
                "the fingers to splice"
                + (
                    f" ({body_name}, given as the body, has fingers: are body and hand swapped?)"
                    if swapped
                    else ""
                )
            )
        hand_sides = with_fingers
    sides = resolve_sides(side, body_sides, hand_sides, body_name, hand_name)
    if isinstance(body, Motion):
        _check_body_arms(rb, sides, body_name)
    return sides


def _check_body_arms(rb, sides, body_name: str) -> None:
    """RoleError when a spliced arm of the body take stops at the elbow: no shoulder or
    clavicle above it, as in a hand take (a forearm, the hand and its fingers). Every
    body rig we know names both shoulders; a hand take given as the body would otherwise
    align and splice into a floating forearm."""
    for s in sides:
        if not rb.side(s).has_shoulder:
            raise RoleError(
                f"{body_name}: the body take has no {s} shoulder or clavicle above the elbow "
                f"(it looks like a hand take); the body take must be a full- or "
                f"upper-body skeleton, or name its shoulder with a role override "
                f'(--roles MAP.json: {{"body": {{"{s}.shoulder": "JointName"}}}})'
            )


@dataclass(frozen=True)
class _ArmMarkers:
    """Both takes' virtual arm markers of ``sides`` side by side, ``(frames, markers, 3)``
    (the hand take at the body's rate ``fps``), their trunk headings (radians, None without
    a trunk; the hand's at its own rate) and the hand frames of BVH takes; ``body_fk`` gives
    the body's world rotations for the transfer (``WorldRotations``: made when read, the
    same floats as the features' forward kinematics)."""

    body_markers: np.ndarray
    hand_markers: np.ndarray
    body_yaw: np.ndarray | None
    hand_yaw: np.ndarray | None
    body_frames: dict
    hand_frames: dict
    body_fk: tuple | None


def _arm_markers(body, hand, rb, rh, sides, fps: float) -> _ArmMarkers:
    """Forward kinematics by blocks of frames (features.take_markers): neither take keeps
    its world rotations (the body's are posed again when the transfer reads them); marker
    sets give their markers as they are."""
    body_frames: dict[str, HandFrame] = {}
    hand_frames: dict[str, HandFrame] = {}
    body_fk = None
    if isinstance(body, Motion):
        body_frames = {s: hand_frame(body, rb, s) for s in sides}
        bmk, body_yaw, _ = take_markers(body, rb, body_frames)
        body_fk = (None, WorldRotations(body))  # posed again when read: nothing kept
        bm = [bmk[s] for s in sides]
    else:
        bm = [marker_set_markers(body, s).markers for s in sides]
        body_yaw = marker_set_yaw(body)
    if isinstance(hand, Motion):
        hand_frames = {s: hand_frame(hand, rh, s) for s in sides}
        hmk, hand_yaw, _ = take_markers(hand, rh, hand_frames, fps=fps)
        hm = [hmk[s] for s in sides]
    else:
        hm = [marker_set_markers(hand, s, fps=fps).markers for s in sides]
        hand_yaw = marker_set_yaw(hand)
    return _ArmMarkers(
        np.concatenate(bm, axis=1),
        np.concatenate(hm, axis=1),
        body_yaw,
        hand_yaw,
        body_frames,
        hand_frames,
        body_fk,
    )


def heading_offset(
    body: M.PhaseFeatures, hand: M.PhaseFeatures, cells: np.ndarray, theta=None
) -> float:
    """Constant heading (radians) of a hand take without a trunk.

    For cells ``(i, j)`` believed to match (a path, or the diagonal), eq. 7 gives
    ``θ(i, j) ≈ yaw_body(i) - heading``. Eq. 7 is unreliable where the arms are still
    or posed differently, so the estimate is the *mode* of ``yaw_body - θ`` weighted
    by how much both wrists move (5° bins, circular smoothing), refined by the
    weighted circular mean within 20° of the mode. Without a body trunk the body's
    yaw counts as 0. ``theta``: ``θ`` at ``cells`` when known (:func:`_cells_theta`).
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    i, j = cells[:, 0], cells[:, 1]
    th = M.cell_theta_window(body, hand, i, j) if theta is None else theta
    yb = body.yaw[i] if body.yaw is not None else 0.0
    v = np.angle(np.exp(1j * (yb - th)))
    w = _wrist_speed(body)[i] * _wrist_speed(hand)[j] + 1e-12
    bins = 72
    k = np.floor((v + np.pi) / (2 * np.pi) * bins).astype(np.int64) % bins
    hist = np.bincount(k, weights=w, minlength=bins)
    hist = hist + 0.5 * (np.roll(hist, 1) + np.roll(hist, -1))
    mode = (np.argmax(hist) + 0.5) / bins * 2 * np.pi - np.pi
    near = np.abs(np.angle(np.exp(1j * (v - mode)))) < np.radians(20)
    if not near.any():
        return float(mode)
    return float(np.angle(np.sum(w[near] * np.exp(1j * v[near]))))


#: cells whose θ a pair keeps for the next edits' headings (about 24 bytes each)
THETA_CELLS_KEPT = 200_000


def _cells_theta(features: SpliceFeatures, cells: np.ndarray) -> np.ndarray:
    """``(k,)`` eq.-7 θ at ``cells (k, 2)`` (body frame, grid hand frame), remembered per pair.

    An edit's pass-1 path shares most of its cells with the last one, so only the new
    cells' θ are computed (each cell's θ is its own: :func:`engine.align.metrics.
    cell_theta_window` per cell gives the same values as over the whole path)."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    keys = cells[:, 0] * features.m + cells[:, 1]
    known_keys, known = features.params.get("_theta_cells", (np.empty(0, np.int64), np.empty(0)))
    th = np.empty(len(keys))
    at = np.minimum(np.searchsorted(known_keys, keys), max(len(known_keys) - 1, 0))
    hit = known_keys[at] == keys if len(known_keys) else np.zeros(len(keys), bool)
    th[hit] = known[at[hit]]
    miss = ~hit
    if miss.any():
        th[miss] = M.cell_theta_window(
            features.body_phase, features.hand_phase, cells[miss, 0], cells[miss, 1]
        )
        if len(known_keys) + int(miss.sum()) > THETA_CELLS_KEPT:  # keep this path's only
            known_keys, known = np.empty(0, np.int64), np.empty(0)
            miss = np.ones(len(keys), bool)
        merged_keys, first = np.unique(np.concatenate([known_keys, keys[miss]]), return_index=True)
        merged = np.concatenate([known, th[miss]])[first]
        features.params["_theta_cells"] = (merged_keys, merged)
    return th


def _wrist_speed(ph: M.PhaseFeatures) -> np.ndarray:
    v = ph.velocity.reshape(ph.n_frames, -1, 4, 3)
    return np.linalg.norm(0.5 * (v[:, :, 0] + v[:, :, 1]), axis=-1).sum(axis=1)


# --------------------------------------------------------------------------------------------
# alignment
# --------------------------------------------------------------------------------------------


@dataclass
class PassResult:
    """One DTW pass.

    path : (k, 2) int64 cells (body frame, grid hand frame)
    cost : float, total local cost along the path
    band : engine.dtw.Band
    rows : (a, b) float64 rows of the pass's metric (the local-cost inputs: the
        cost of cell (i, j) is ``metric(a[i], b[j])``)
    metric : name of the pass's metric in ``engine.dtw``'s registry
    solver : engine.dtw.Aligner or None (kept for incremental re-solves and γ)
    seconds : float
    probe : engine.dtw.Aligner or None: pass 2's first open-ends solve (the one that sizes
        ``ends.skip``, :func:`_solve_pass2`), kept for incremental re-solves
    coarse : ``engine.splice.coarse.CoarsePass`` or None: pass 1's coarse solve (takes
        above ``tolerances.PASS1_RATE_CAP_HZ``); ``band`` stays the W1 band (what the app
        draws and the trust assessment spreads over), ``coarse.fine_band`` is the narrow
        full-rate band the exact pass 1 solved (``solver.band``)
    cost_table : (n, m) float64 ``metric(a[i], b[j])`` of every cell, or None: the app's
        tabulated pass-1 costs, which the trust assessment reads instead of the metric
    """

    path: np.ndarray
    cost: float
    band: Band
    rows: tuple[np.ndarray, np.ndarray]
    metric: str
    solver: object = None
    seconds: float = 0.0
    ends: Ends = field(default_factory=Ends)
    probe: object = None
    cost_table: np.ndarray | None = field(default=None, repr=False)
    coarse: object = None

    def local_costs(self, rows_idx=None, cols_idx=None) -> np.ndarray:
        """Local costs on a grid of cells (all cells by default: small takes only)."""
        a, b = self.rows
        r = np.arange(len(a)) if rows_idx is None else np.asarray(rows_idx)
        c = np.arange(len(b)) if cols_idx is None else np.asarray(cols_idx)
        return local_cost_grid(self.rows, self.metric, r, c)

    def path_costs(self) -> np.ndarray:
        """(k,) local cost of every path cell."""
        a, b = self.rows
        return M.path_values(get_metric(self.metric).cell, a, b, self.path)


def check_metrics(metrics) -> tuple[str, str]:
    """The (pass 1, pass 2) metric names, each registered with ``engine.dtw``."""
    M.register_metrics()
    if isinstance(metrics, str) or len(metrics) != 2:
        raise ParameterError(f"metrics: expected (pass-1 name, pass-2 name), got {metrics!r}")
    known = metric_names()
    for k, name in enumerate(metrics):
        if name not in known:
            raise ParameterError(
                f"metrics[{k}]: unknown metric {name!r}; known: "
                f"{', '.join(known)} (add one with "
                "engine.dtw.register_metric)"
            )
    return metrics[0], metrics[1]


@dataclass
class SpliceAlignment:
    """Both passes and the merged warp.

    pass1, pass2 : PassResult
    warp : (n,) float, grid hand frame per body frame (merged and smoothed); outside the
        overlap it holds the first / last matched hand frame (no invented timing)
    map : (n,) float, frame of the original hand take per body frame
    overlap : ((first, last) body frame, (first, last) grid hand frame) the pass-2 path
        matches (the whole takes with fixed ends)
    ends : ``"open"`` or ``"fixed"``; max_unmatched_s : float or None (the limit asked for)
    body_heading, hand_heading : (n,), (m,) float radians, trunk headings removed from
        each take's pass-2 vectors (:func:`pass2_headings`)
    points : list of (body, grid hand, tol) matching points used
    band, refine_band : float fractions of n; radius : int (pass-2 band, frames)
    timings : dict stage -> seconds
    """

    pass1: PassResult
    pass2: PassResult
    warp: np.ndarray
    map: np.ndarray
    body_heading: np.ndarray
    hand_heading: np.ndarray
    points: list
    band: float
    refine_band: float
    radius: int
    blend: float
    timings: dict = field(default_factory=dict)
    features_id: int = 0
    metrics: tuple[str, str] = DEFAULT_METRICS
    overlap: tuple = ((0, 0), (0, 0))
    ends: str = ENDS
    max_unmatched_s: float | None = None

    @property
    def unmatched_body(self) -> list[tuple[int, int]]:
        """Body frame ranges ``[first, last]`` outside the overlap (fingers eased, not timed)."""
        (i0, i1), _ = self.overlap
        n = len(self.warp)
        out = []
        if i0 > 0:
            out.append((0, i0 - 1))
        if i1 < n - 1:
            out.append((i1 + 1, n - 1))
        return out

    def unmatched_limit(self, fps: float) -> int | None:
        """Body frames each end may leave unmatched (open ends: :func:`unmatched_limits`);
        None with fixed ends. An unmatched end this long was stopped by the limit, not by
        the data (``engine.splice.report.unmatched_summary`` says so)."""
        if self.ends != "open":
            return None
        n, m = len(self.warp), len(self.hand_heading)
        return unmatched_limits(n, m, fps, self.max_unmatched_s)[0]


#: a hold: every alignment marker slower than the take's velocity dead zone for at least
#: this long (seconds); holds matched within HOLD_SLACK_S are straightened (merge)
HOLD_MIN_S = 0.4
HOLD_SLACK_S = 0.15


def holds(phase: M.PhaseFeatures, fps: float) -> list[tuple[int, int]]:
    """Frame runs ``[first, last]`` where the take's arms hold still, ≥ :data:`HOLD_MIN_S`:
    the mean marker speed is below sqrt(3) times the pass-1 velocity dead zone (a marker
    whose three velocity components read 0 moves slower than that)."""
    speed = np.linalg.norm(phase.velocity, axis=-1).mean(axis=1)
    return MG.still_runs(
        speed, np.sqrt(3.0) * phase.zone.velocity, max(2, int(round(HOLD_MIN_S * fps)))
    )


def straighten_holds(features: SpliceFeatures, warp: np.ndarray, points=()) -> np.ndarray:
    """:func:`engine.splice.merge.straighten_holds` with the pair's holds (found once per
    ``features``: an app edit does not scan the takes again); the body frames of
    ``points`` (matching points) keep their matched column."""
    runs = features.params.get("_holds")
    if runs is None:
        runs = (holds(features.body_phase, features.fps), holds(features.hand_phase, features.fps))
        features.params["_holds"] = runs
    return MG.straighten_holds(
        warp, runs[0], runs[1], HOLD_SLACK_S * features.fps, keep=[p[0] for p in points]
    )


def _solve(
    rows,
    metric: str,
    band: Band,
    solver=None,
    incremental: bool = False,
    ends: Ends | None = None,
    exact: bool = False,
):
    """Solve one pass; returns (Alignment, solver or None).

    ``exact``: a re-solve by ``solver`` gives a fresh solve's path, ties included
    (``Aligner.solve(forward_only=True)``)."""
    a, b = rows
    if solver is not None:  # an Aligner, or SharedCosts (one-shot solves: always fresh)
        return solver.solve(band, ends, forward_only=exact), solver
    if incremental:
        solver = Aligner(a, b, metric=metric)
        return solver.solve(band, ends, forward_only=exact), solver
    return align_features(a, b, band, metric=metric, ends=ends), None


def check_ends_option(ends: str, max_unmatched_s: float | None) -> tuple[str, float | None]:
    """Validated ``(ends, max_unmatched_s)``: ``"open"`` or ``"fixed"``, seconds >= 0 or None.

    The splice's entry to the ends rule, which :mod:`engine.dtw.constraints` owns (the
    CLI's ``--ends``/``--max-unmatched``, the batch and the app read it there too)."""
    return C.parse_ends(ends), C.parse_max_unmatched(max_unmatched_s)


def unmatched_limits(n: int, m: int, fps: float, max_unmatched_s: float | None) -> tuple[int, int]:
    """Frames of the body take and of the hand take (grid) that may stay unmatched at each
    end: ``max_unmatched_s`` seconds, else the default (``constraints.unmatched_limits``,
    the one owner of the rule: half the shorter take, plus the length difference for the
    longer one)."""
    return C.unmatched_limits(n, m, fps, max_unmatched_s)


def chance_cost(rows, metric: str, seed: int = 0) -> float:
    """Mean local cost of :data:`CHANCE_CELLS` random cells: matching unrelated frames."""
    a, b = rows
    rng = np.random.default_rng(seed)
    cells = np.column_stack(
        [rng.integers(0, len(a), CHANCE_CELLS), rng.integers(0, len(b), CHANCE_CELLS)]
    )
    vals = M.path_values(get_metric(metric).cell, a, b, cells)
    vals = vals[np.isfinite(vals)]
    return float(vals.mean()) if vals.size else 0.0


def unmatched_frames(path: np.ndarray, n: int, m: int) -> int:
    """Frames of both takes an open-end path leaves out (0 for a corner-to-corner path)."""
    p = np.asarray(path)
    return int(p[0].sum()) + (n - 1 - int(p[-1, 0])) + (m - 1 - int(p[-1, 1]))


def pass1_ends(features: SpliceFeatures, kind: str, max_unmatched_s: float | None) -> Ends:
    """Open ends of pass 1: ``skip`` = half the cost of matching unrelated frames.

    Open ends charge ``skip`` per unmatched frame (``engine.dtw.Ends``), so every frame
    of both takes is paid for, matched or not, and a short overlap is not cheaper by
    itself (plain subsequence DTW, skip 0, would cut every end). With half the chance
    cost (:func:`chance_cost`) an end stretch is left out only when its cells are no
    better than matching random frames (a diagonal cell covers a frame of each take).
    Pass 1's sign costs are coarse, so nothing stricter is safe there. Cached on
    ``features`` (it depends on the pair and the limits only). The skip is rounded to a
    multiple of ``engine.dtw.fixed.QUANTUM`` (3e-8 at most): with the whole-number sign
    costs every γ sum is exact, so an edit's re-solve reuses the rows that settle
    (``engine.dtw.fixed``).
    """
    if kind == "fixed":
        return Ends()
    limits = unmatched_limits(features.n, features.m, features.fps, max_unmatched_s)
    cache = features.params.setdefault("_ends", {})
    if "chance1" not in cache:
        cache["chance1"] = chance_cost(features.pass1_rows, "splice_phase")
    return Ends(limits[0], limits[1], float(fixed.on_grid(0.5 * cache["chance1"])))


#: pass 2's skip per unmatched frame is rounded down to this many steps per octave, so
#: the small cost changes of an edit mostly leave it (and the solver's rows) as they were
SKIP_STEPS_PER_OCTAVE = 32


def skip_step(value: float) -> float:
    """``value`` (>= 0) rounded down to :data:`SKIP_STEPS_PER_OCTAVE` steps per octave
    (at most 1/32 = 3 % lower)."""
    if not (np.isfinite(value) and value > 0.0):
        return 0.0
    mant, exp = np.frexp(value)  # value = mant * 2**exp, mant in [0.5, 1)
    steps = 2 * SKIP_STEPS_PER_OCTAVE
    return float(np.ldexp(np.floor(mant * steps) / steps, int(exp)))


def _solve_pass2(
    rows,
    band: Band,
    solver,
    incremental: bool,
    pass1: Ends,
    metric: str = DEFAULT_METRICS[1],
    probe=None,
    exact: bool = False,
    chance: float | None = None,
):
    """Pass 2 with open ends (when ``pass1`` is open): returns (Alignment, solver, Ends,
    probe solver). ``chance``: :func:`chance_cost` of ``rows`` when known.

    ``skip`` is the smaller of half the chance cost and the mean local cost per cell of
    the open path found with it (rounded down by :func:`skip_step`). Pass 2's angle costs
    change smoothly, so the neighbours
    of the true start cost far less than chance: with the typical matched cost, the
    path does not absorb extra frames of one take by horizontal or vertical runs whose
    cells cost more than a typical matched cell, and an end stretch stays matched on the
    diagonal while its cells cost less than about twice that. The band around the
    pass-1 path keeps the ends near pass 1's.

    Incremental (the app): both solves keep an ``Aligner`` (``probe`` for the first), so
    an edit recomputes only the rows its band change touches in each, as long as the
    rounded skip stays the same (``exact``: as :func:`_solve`). Both skips are multiples of
    ``engine.dtw.fixed.QUANTUM``: with exact costs (the hand-spin pass's) every γ sum is
    exact and an edit's forward re-solve keeps the rows that settle.
    """
    if pass1.fixed:
        al, solver = _solve(rows, metric, band, solver, incremental, Ends(), exact)
        return al, solver, Ends(), None
    n, m = len(rows[0]), len(rows[1])
    chance = chance_cost(rows, metric) if chance is None else chance
    first = replace(pass1, skip=float(fixed.on_grid(0.5 * chance)))  # pass 1's limits
    # one-shot (the CLI): both solves share one computation of the band's costs
    shared = None if incremental else SharedCosts(*rows, metric=metric)
    al, probe = _solve(rows, metric, band, probe or shared, incremental, first, exact)
    matched = al.cost - first.skip * unmatched_frames(al.path, n, m)
    typical = float(fixed.on_grid(skip_step(max(matched, 0.0) / len(al.path))))
    ends = replace(pass1, skip=min(first.skip, typical))
    if shared is not None:
        probe = None
    if ends == first:
        return al, probe, ends, probe
    if solver is probe:
        solver = None
    al, solver = _solve(rows, metric, band, solver or shared, incremental, ends, exact)
    return al, (None if shared is not None else solver), ends, probe


def _pass2_chance(features: SpliceFeatures, rows, metric: str) -> float:
    """:func:`chance_cost` of pass 2's ``rows``, kept with the features for the rows
    objects it was made of (an edit that keeps pass 2's rows does not sample them again)."""
    kept = features.params.get("_chance2")
    if kept is not None and kept[0] is rows[0] and kept[1] is rows[1] and kept[2] == metric:
        return kept[3]
    value = chance_cost(rows, metric)
    features.params["_chance2"] = (rows[0], rows[1], metric, value)
    return value


def _same_headings(previous, body_heading: np.ndarray, hand_heading: np.ndarray) -> bool:
    """True when ``previous`` (a ``SpliceAlignment``) turned both takes by these headings."""
    b = getattr(previous, "body_heading", None)
    h = getattr(previous, "hand_heading", None)
    return (
        b is not None
        and h is not None
        and np.array_equal(b, body_heading)
        and np.array_equal(h, hand_heading)
    )


def pass2_headings(features: SpliceFeatures, path1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Headings (radians) removed from the body ``(n,)`` and hand ``(m,)`` before pass 2.

    D2 compares vectors in world axes, so both takes are turned to face the same way:
    the body by its trunk yaw, the hand by its own trunk yaw or, for a hand take
    without a trunk (Leap, ManipNet), by a constant heading estimated along the pass-1
    path (:func:`heading_offset`). ``theta="none"`` turns nothing.
    """
    n, m = features.n, features.m
    if features.theta == "none":
        return np.zeros(n), np.zeros(m)
    bp, hp = features.body_phase, features.hand_phase
    body = bp.yaw if bp.yaw is not None else np.zeros(n)
    if features.hand_has_yaw:
        return body, hp.yaw
    c = heading_offset(bp, hp, path1, _cells_theta(features, path1))
    c = np.round(c / np.radians(5.0)) * np.radians(5.0)  # stable across small path edits
    return body, np.full(m, c)


def hand_lacks_forearm(features: SpliceFeatures) -> bool:
    """True when no spliced arm of the hand take has a measured forearm (ManipNet's wrist
    root, Leap's forearm joint at the wrist). D2 (pass 2) compares the hand's direction
    relative to the forearm; there it never changes, so pass 2 compares the hand's
    turning instead (:func:`uses_spin`, :mod:`engine.splice.spin`)."""
    frames = features.hand_frames
    return bool(frames) and all(s in frames and not frames[s].elbow_apart for s in features.sides)


def uses_spin(features: SpliceFeatures) -> bool:
    """Pass 2 compares the hand's turning (:mod:`engine.splice.spin`) instead of D2: the
    hand take has no forearm and both takes are skeletal."""
    return hand_lacks_forearm(features) and SP.spin_available(features)


def alignment_pass(features: SpliceFeatures) -> int:
    """1 or 2: the pass whose path the splice follows (``SpliceAlignment.warp`` and ``map``
    are made from it). Pass 2, except for a hand take without a forearm that pass 2 cannot
    compare by its turning either (D2 is constant there): then pass 1."""
    return 1 if hand_lacks_forearm(features) and not uses_spin(features) else 2


def align_passes(
    features: SpliceFeatures,
    band=None,
    refine_band=None,
    metrics: Sequence[str] = DEFAULT_METRICS,
    points: Sequence = (),
    previous: SpliceAlignment | None = None,
    blend: float | None = None,
    incremental: bool | None = None,
    progress: Progress | None = None,
    ends: str = ENDS,
    max_unmatched_s: float | None = None,
) -> SpliceAlignment:
    """Pass 1 (phase matching) and pass 2 (refinement), then merge and smooth.

    Parameters
    ----------
    features : SpliceFeatures from :func:`prepare`
    band : pass-1 band width as a fraction of n (paper: 0.30)
    refine_band : pass-2 band width around the pass-1 path, fraction of n (paper: 0.10)
    points : ``[(body_frame, grid_hand_frame, tol), ...]`` user matching points
        (grid units; tol in grid frames). Carried over to pass 2.
    previous : the last result for the same ``features`` (reuses DTW rows that the
        edit cannot change)
    blend : merge smoothing (Gaussian σ, body frames); default ``MG.blend_frames(fps)``
        (0.1 s: 3 frames at 30 fps, 12 at 120 fps)
    (a hand take without a forearm: pass 2 compares the hand's turning over pass 1's band,
    ``engine.splice.spin``, whatever ``metrics[1]`` says)
    incremental : keep ``Aligner`` solvers (γ for cumulative-cost views, partial
        re-solves); default when the pass-1 band has at most 12 M cells.
    ends : ``"open"`` (default: either take may start earlier or end later; the
        unmatched body frames hold the first / last matched hand pose, eased over
        :data:`EASE_FRAMES`) or ``"fixed"`` (the paper: first to last frames).
    max_unmatched_s : limit of unmatched seconds of each take at each end (default:
        ``constraints.UNMATCHED_DEFAULT``, see ``constraints.unmatched_limits``).

    Raises ``ParameterError`` for infeasible bands or points (naming the point).
    """
    progress = progress or _noop
    n, m = features.n, features.m
    if blend is None:
        blend = MG.blend_frames(features.fps)
    pts = C.point_triples(points)
    metric1, metric2 = check_metrics(metrics)
    kind, max_unmatched_s = check_ends_option(ends, max_unmatched_s)
    is_open = kind == "open"
    timings: dict[str, float] = {}
    band = C.BAND.resolve(band, n, features.fps)
    refine_band = C.REFINE_BAND.resolve(refine_band, n, features.fps)
    t0 = time.perf_counter()
    progress("pass 1", 0.0)
    band1 = Band.from_constraints(n, m, float(band), pts, open_ends=is_open)
    if is_open:  # room for the unmatched ends (engine.splice.end_band)
        limits1 = unmatched_limits(n, m, features.fps, max_unmatched_s)
        band1 = open_end_band(band1, float(band), limits1, pts, features.fps)
        if band1.area > limits.MAX_BAND_CELLS and n != m:
            raise ParameterError(
                f"pass 1: the band has {band1.area:,} cells, more than "
                f"{limits.MAX_BAND_CELLS:,}: the takes differ by {abs(n - m) / features.fps:.1f} s "
                "and the band holds every place of the shorter take inside the longer one; "
                "--max-unmatched SECONDS (how long an end may stay unmatched) narrows it"
            )
    limits.check_band("pass 1", band1.area)
    if incremental is None:
        incremental = band1.area <= INCREMENTAL_MAX_CELLS
    same = previous is not None and previous.features_id == id(features)
    # a forearm-less hand take's alignment rests on pass 1, whose sign costs tie often: its
    # re-solves (both passes) give a fresh solve's path, ties included, so the app and the
    # CLI agree; they recompute the rows from the first edited one on
    exact = hand_lacks_forearm(features)
    solver1 = previous.pass1.solver if same else None
    # a point on the hand take's first or last frame pins that end (stranger 14 F1)
    ends1 = ends_through_points(pass1_ends(features, kind, max_unmatched_s), pts, n, m)
    coarse1 = None
    if features.coarse is not None:  # multi-resolution pass 1 (engine.splice.coarse)
        cr = features.coarse
        if is_open and cr.chance is None:
            cr.chance = chance_cost(cr.rows, "splice_phase")
        al1, solver1, coarse1 = CO.solve(
            features.pass1_rows,
            cr,
            band1,
            float(band),
            pts,
            is_open,
            unmatched_limits(n, m, features.fps, max_unmatched_s) if is_open else None,
            ends1,
            float(fixed.on_grid(0.5 * cr.chance)) if is_open else 0.0,
            _solve,
            metric1,
            previous=getattr(previous.pass1, "coarse", None) if same else None,
            fine_solver=solver1,
            incremental=incremental,
            exact=exact,
            fps=features.fps,
        )
        timings["pass1_coarse"] = coarse1.seconds
    else:
        al1, solver1 = _solve(
            features.pass1_rows, metric1, band1, solver1, incremental, ends1, exact
        )
    t1 = time.perf_counter()
    timings["pass1"] = t1 - t0
    progress("pass 1", 1.0)

    progress("pass 2", 0.0)
    body_heading, hand_heading = pass2_headings(features, al1.path)
    prev2 = previous.pass2 if same else None
    radius = C.refine_radius(n, m, refine_band)
    spin = uses_spin(features)
    if spin:  # no forearm in the hand take: the hand's turning, over pass 1's band
        (body2, hand2), metric2, band2 = SP.spin_pass_rows(features), SP.METRIC, band1
    else:
        if prev2 is not None and _same_headings(previous, body_heading, hand_heading):
            body2, hand2 = prev2.rows  # an edit that keeps the headings keeps pass 2's rows
        else:
            body2 = M.angle_features(features.body_markers, -body_heading).rows(
                features.params.get("step2", 0.0)
            )
            hand2 = M.angle_features(features.hand_markers, -hand_heading).rows()
        band2 = Band.around_path(
            al1.path, n, m, radius, points=pts if pts else None, open_ends=is_open
        )
    limits.check_band("pass 2", band2.area)
    solver2 = probe2 = None
    if prev2 is not None and prev2.rows[1] is not None and np.array_equal(prev2.rows[1], hand2):
        solver2, probe2 = prev2.solver, getattr(prev2, "probe", None)
    al2, solver2, ends2, probe2 = _solve_pass2(
        (body2, hand2),
        band2,
        solver2,
        incremental,
        ends1,
        metric2,
        probe2,
        exact,
        None if ends1.fixed else _pass2_chance(features, (body2, hand2), metric2),
    )
    t2 = time.perf_counter()
    timings["pass2"] = t2 - t1
    progress("pass 2", 1.0)

    progress("merge", 0.0)
    final = al1 if alignment_pass(features) == 1 else al2
    warp = straighten_holds(features, MG.median_warp(final.path, n), pts)
    if pts:  # near a point the hand runs at the local rate (engine.splice.point_rate)
        warp = PR.rate_lines(warp, [p[0] for p in pts], features.fps, final.overlap[0])
    warp = MG.smooth_warp(
        warp,
        blend,
        m,
        anchors=[p[0] for p in pts],
    )
    hand_map = features.grid_to_hand(warp)
    overlap = final.overlap
    timings["merge"] = time.perf_counter() - t2
    progress("merge", 1.0)
    p1 = PassResult(
        path=np.asarray(al1.path),
        cost=float(al1.cost),
        band=band1,
        rows=features.pass1_rows,
        metric=metric1,
        solver=solver1,
        seconds=timings["pass1"],
        ends=ends1,
        coarse=coarse1,
    )
    p2 = PassResult(
        path=np.asarray(al2.path),
        cost=float(al2.cost),
        band=band2,
        rows=(body2, hand2),
        metric=metric2,
        solver=solver2,
        seconds=timings["pass2"],
        ends=ends2,
        probe=probe2,
    )
    return SpliceAlignment(
        pass1=p1,
        pass2=p2,
        warp=warp,
        map=hand_map,
        body_heading=body_heading,
        hand_heading=hand_heading,
        points=pts,
        band=float(band),
        refine_band=float(refine_band),
        radius=radius,
        blend=float(blend),
        timings=timings,
        features_id=id(features),
        metrics=(metric1, metric2),
        overlap=overlap,
        ends=kind,
        max_unmatched_s=max_unmatched_s,
    )


# --------------------------------------------------------------------------------------------
# transfer
# --------------------------------------------------------------------------------------------


def transfer(
    features: SpliceFeatures,
    result: SpliceAlignment,
    progress: Progress | None = None,
    cancelled=None,
) -> Motion:
    """The body take with the hand take's wrists and fingers sampled at ``result.map``.
    ``cancelled``: a callable; once it returns True the transfer stops between blocks of
    frames (``engine.base.errors.Cancelled``; ``transfer.apply_transfer``)."""
    progress = progress or _noop
    body, hand = features.body, features.hand
    require_skeletal(body, hand)
    progress("transfer", 0.0)
    plan = plan_for(features)
    out = TR.apply_transfer(
        plan, body, hand, result.map, body_fk=features.body_fk, cancelled=cancelled
    )
    progress("transfer", 1.0)
    return out


def plan_for(features: SpliceFeatures) -> TR.TransferPlan:
    """The transfer plan of a pair (cached on the features)."""
    cached = features.params.get("_plan")
    if cached is None:
        cached = TR.plan_transfer(
            features.body,
            features.hand,
            features.body_roles,
            features.hand_roles,
            features.body_frames,
            features.hand_frames,
            features.sides,
        )
        cached = replace(cached, notes=tuple(features.notes) + cached.notes)
        features.params["_plan"] = cached
    return cached


# --------------------------------------------------------------------------------------------
# everything at once
# --------------------------------------------------------------------------------------------


@dataclass
class SpliceResult:
    """``motion`` (the spliced take), ``features``, ``alignment``, ``timings`` (seconds)."""

    motion: Motion | None
    features: SpliceFeatures
    alignment: SpliceAlignment
    timings: dict


def hand_points_to_grid(features: SpliceFeatures, points) -> list[tuple[int, int, float]]:
    """Matching points ``(body, hand, tol)`` with ``hand`` and ``tol`` in frames of the hand
    file -> alignment-grid columns (:func:`engine.dtw.constraints.points_to_grid` at this
    pair's frame rates)."""
    return C.points_to_grid(points, features.fps, features.hand_fps, features.m)


def grid_points_to_hand(features: SpliceFeatures, points) -> list[tuple[int, int, float | None]]:
    """The inverse for reading old (version 1) session files: ``(body, grid column, tol or
    None)`` -> ``(body, hand-file frame, tol in hand frames or None)``
    (:func:`engine.dtw.constraints.points_to_hand`)."""
    out = []
    for x, y, t in points:
        ((bx, hy, ht),) = C.points_to_hand(
            [(x, y, t or 0.0)], features.fps, features.hand_fps, features.m_hand
        )
        out.append((bx, hy, None if t is None else ht))
    return out


def splice(
    body: Motion,
    hand: Motion,
    side: str = "auto",
    band=None,
    refine_band=None,
    points: Sequence = (),
    hand_points: bool = False,
    theta: str = "window",
    body_roles=None,
    hand_roles=None,
    blend: float | None = None,
    smoothing_s: float = SMOOTHING_S,
    dead_zone: float = DEAD_ZONE,
    n_bins: int = M.THETA_BINS,
    step1: float = STEP1,
    step2: float = STEP2,
    progress: Progress | None = None,
    transfer_fingers: bool = True,
    ends: str = ENDS,
    max_unmatched_s: float | None = None,
    metrics: Sequence[str] = DEFAULT_METRICS,
) -> SpliceResult:
    """Align and splice in one call (CLI, batch and benchmarks).

    ``points`` are ``(body_frame, hand_frame[, tol])``; with ``hand_points=True`` the
    hand frame and tolerance are in frames of the original hand take (as a person
    reads them off the file) and are converted to the alignment grid, else they are
    grid units. With ``transfer_fingers=False`` only the alignment is computed.
    ``ends``/``max_unmatched_s``: see :func:`align_passes`.
    """
    t0 = time.perf_counter()
    feats = prepare(
        body,
        hand,
        side=side,
        body_roles=body_roles,
        hand_roles=hand_roles,
        theta=theta,
        n_bins=n_bins,
        smoothing_s=smoothing_s,
        dead_zone=dead_zone,
        step1=step1,
        step2=step2,
        progress=progress,
    )
    t1 = time.perf_counter()
    pts = C.point_triples(points)
    if hand_points and pts:
        # check order and range in the user's own frame numbers first
        C.check_points(
            pts,
            feats.n,
            feats.m_hand,
            open_ends=check_ends_option(ends, None)[0] == "open",
            grid_scale=feats.fps / feats.hand_fps,
        )
        pts = hand_points_to_grid(feats, pts)
    result = align_passes(
        feats,
        band=band,
        refine_band=refine_band,
        metrics=metrics,
        points=pts,
        blend=blend,
        incremental=False,
        progress=progress,
        ends=ends,
        max_unmatched_s=max_unmatched_s,
    )
    t2 = time.perf_counter()
    motion = transfer(feats, result, progress) if transfer_fingers else None
    t3 = time.perf_counter()
    timings = {
        "prepare": t1 - t0,
        **{f"prepare.{k}": v for k, v in feats.timings.items()},
        "pass1": result.timings["pass1"],
        "pass2": result.timings["pass2"],
        "merge": result.timings["merge"],
        "transfer": t3 - t2,
        "total": t3 - t0,
    }
    return SpliceResult(motion=motion, features=feats, alignment=result, timings=timings)


# --------------------------------------------------------------------------------------------
# views for the app
# --------------------------------------------------------------------------------------------


def wrist_speeds(features: SpliceFeatures) -> tuple[np.ndarray, np.ndarray]:
    """Speed of the wrist centre (m/s, summed over spliced arms): body ``(n,)``, hand ``(m,)``."""

    def speed(ph: M.PhaseFeatures) -> np.ndarray:
        v = ph.velocity.reshape(ph.n_frames, -1, 4, 3)
        centre = 0.5 * (v[:, :, 0] + v[:, :, 1])
        return np.linalg.norm(centre, axis=-1).sum(axis=1)

    return speed(features.body_phase), speed(features.hand_phase)


def local_cost_grid(rows_ab, metric: str, rows, cols) -> np.ndarray:
    """Local costs ``metric(a[r], b[c])`` of the feature rows ``rows_ab = (a, b)`` on the
    grid body frames ``rows`` × grid hand frames ``cols``: ``(len(rows), len(cols))``
    float64 (``metrics.cost_grid``: for the splice metrics, machine code cached on disk)."""
    a, b = rows_ab
    return M.cost_grid(get_metric(metric).cell, a, b, rows, cols)


def cost_image(
    features: SpliceFeatures, kind: str, rows, cols, result: SpliceAlignment | None = None
) -> np.ndarray:
    """Cost matrix values at body frames ``rows`` × grid hand frames ``cols``.

    kind : ``"pass1"`` / ``"pass2"`` (local costs; pass 2 uses the headings of
        ``result``, or none without a result) or ``"cumulative1"`` /
        ``"cumulative2"`` (γ of the last solve; NaN outside the band; needs a result
        solved incrementally).
    Returns ``(len(rows), len(cols))`` float64.
    """
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    metric1, metric2 = DEFAULT_METRICS if result is None else result.metrics
    if kind == "pass1":
        return local_cost_grid(features.pass1_rows, metric1, rows, cols)
    if kind == "pass2":
        if result is not None:
            ab = result.pass2.rows
        else:
            ab = (
                M.angle_features(features.body_markers).rows(),
                M.angle_features(features.hand_markers).rows(),
            )
        return local_cost_grid(ab, metric2, rows, cols)
    if kind in ("cumulative1", "cumulative2"):
        if result is None:
            return np.full((rows.size, cols.size), np.nan)
        pr = result.pass1 if kind == "cumulative1" else result.pass2
        if pr.solver is None or not pr.solver.stores_every_row:  # γ of every row: 8 bytes per cell
            if pr.band.area > CUMULATIVE_MAX_CELLS:
                raise ParameterError(
                    f"the cumulative-cost view of this pass needs γ for {pr.band.area:,} band "
                    f"cells (limit {CUMULATIVE_MAX_CELLS:,}, about 18 bytes each): narrow the "
                    "band or add matching points, or view the local cost"
                )
        if pr.solver is None:
            pr.solver = Aligner(pr.rows[0], pr.rows[1], metric=pr.metric)
            pr.solver.solve(pr.band)
        bv = pr.solver.cumulative_cost()
        bd = bv.band
        lo, hi = bd.lo[rows][:, None], bd.hi[rows][:, None]
        inside = (cols[None, :] >= lo) & (cols[None, :] <= hi)
        flat = bd.start[rows][:, None] + cols[None, :] - lo
        flat = np.where(inside, flat, 0)
        return np.where(inside, bv.values[flat], np.nan)
    raise ParameterError(
        f"cost image kind must be pass1, pass2, cumulative1 or cumulative2, got {kind!r}"
    )
