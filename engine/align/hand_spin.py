"""The hand's turning: a pass-2 signal for hand takes without a forearm (issue 12).

Pass 2 (METHOD.md §3) compares the hand's direction *relative to the forearm*, the one
thing a body take and a separately captured hand take share at the true timing (the
wrist's own rotation). A hand rig without a forearm (ManipNet's 6-DoF wrist root, Leap's
forearm joint sitting at the wrist) has nothing to measure it against, so D2 is constant
there. What both takes still share is how the hand *turns*: its angular velocity relative
to the trunk's heading, seen from the hand itself.

* In the hand's own frame, the angular velocity does not depend on where the take faces
  (no θ, no heading estimate) nor on the rig's rest pose (components along the hand's
  anatomical axes ``along, radial, dorsal`` of :class:`engine.align.features.HandFrame`).
* The trunk's turning (a dancer's spin) is removed first: the body take's world angular
  velocity minus its trunk yaw rate about the vertical. A hand take without a trunk is
  taken as captured in a still frame (a desk, a Leap device), as it is in practice.
* The wrist's own rotation adds the same angular velocity in both takes; a smaller arm
  motion in the hand take (the "amplitude differences" of the paper) scales the arm's
  share but rarely turns its direction.

Rows are soft-normalised, ``u = ω / sqrt(|ω|² + ε²)`` with ``ε`` the take's median
speed of turning, so a moving hand is compared by the direction it turns, two still hands
cost nothing, and a hand take's smaller or noisier motion does not change the scale.
The local cost is the Euclidean distance of the rows, summed over arms through the
concatenation, rounded to the nearest multiple of ``engine.dtw.fixed.QUANTUM`` (2**-24;
``"euclidean_fixed"`` in ``engine.dtw``'s registry): the sums along a path are then exact,
so an app edit's re-solve keeps the rows that settle (drag31; before, ``"euclidean"``:
the costs differ by at most 3e-8 per cell).

Angular velocity from noisy rotations: quaternions are made continuous, single-frame
spikes removed (:func:`engine.align.features.despike`), then Savitzky-Golay smoothed and
differentiated over ``window_s`` (``ω_world = 2 q̇ q*``), so a 2° frame jitter does not
turn into a large angular velocity at 120 fps.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

from engine.align.features import despike, resample_points, up_vector
from engine.model import rotations as rot

#: Savitzky-Golay window (seconds) of the angular velocity (half the pass-1 window: the
#: signal is already a derivative; chosen on seeds 300-311, clean and with 2° jitter)
WINDOW_S = 0.1
#: ε of the soft normalisation: this percentile of the take's own turning speed
NOISE_PERCENTILE = 50.0
#: the ``engine.dtw`` metric of the rows (fixed-point Euclidean: exact sums)
METRIC = "euclidean_fixed"


def _window(fps: float, frames: int, window_s: float) -> int:
    k = max(5, int(round(window_s * fps)) | 1)
    return min(k, frames if frames % 2 else frames - 1)


def hand_spin(
    world_rotations: np.ndarray,
    fps: float,
    basis: np.ndarray,
    up_axis: str = "y",
    yaw: np.ndarray | None = None,
    window_s: float | None = None,
) -> np.ndarray:
    """Angular velocity of the hand relative to the trunk's heading, in the hand's frame.

    Parameters
    ----------
    world_rotations : (F, 4) float unit quaternions (w, x, y, z), the hand joint's world
        rotation per frame (file axes; identity at rest, as BVH joints).
    fps : float, frames per second of the rotations
    basis : (3, 3) float, columns ``along, radial, dorsal`` of the hand at rest (file
        axes): :attr:`engine.align.features.HandFrame.basis`
    up_axis : ``"y"`` or ``"z"``, the take's up axis
    yaw : (F,) float radians or None, the trunk's heading about the vertical (y-up, as
        :func:`engine.align.features.skeleton_yaw`); its rate is removed. None: a still trunk.
    window_s : smoothing window, seconds (default :data:`WINDOW_S`)

    Returns
    -------
    (F, 3) float, rad/s, components along the hand's ``along, radial, dorsal`` axes.
    """
    q = np.asarray(world_rotations, dtype=float)
    f = q.shape[0]
    if f < 3:
        return np.zeros((f, 3))
    q = despike(rot.make_continuous(q))
    k = _window(fps, f, WINDOW_S if window_s is None else window_s)
    if k >= 5:
        qs = savgol_filter(q, k, 2, axis=0)
        qd = savgol_filter(q, k, 2, deriv=1, delta=1.0 / fps, axis=0)
    else:
        qs, qd = q, np.gradient(q, 1.0 / fps, axis=0)
    qs = rot.normalize(qs)
    w = 2.0 * rot.multiply(qd, rot.conjugate(qs))[:, 1:]  # world axes, rad/s
    if yaw is not None:
        rate = np.gradient(np.unwrap(np.asarray(yaw, dtype=float)), 1.0 / fps)
        w = w - rate[:, None] * up_vector(up_axis)[None, :]
    local = rot.rotate(rot.conjugate(qs), w)
    return local @ np.asarray(basis, dtype=float)


def spin_rows(spins: list[np.ndarray], percentile: float = NOISE_PERCENTILE) -> np.ndarray:
    """``(F, 3A)`` rows of the spin signal: each arm's ``(F, 3)`` angular velocity
    soft-normalised by its own ``percentile`` speed (see the module docstring)."""
    cols = []
    for s in spins:
        s = np.asarray(s, dtype=float)
        s = np.where(np.isfinite(s), s, 0.0)
        mag = np.linalg.norm(s, axis=1)
        eps = float(np.percentile(mag, percentile)) if mag.size else 0.0
        eps = max(eps, 1e-6)
        cols.append(s / np.sqrt(mag**2 + eps**2)[:, None])
    return np.ascontiguousarray(np.concatenate(cols, axis=1), dtype=np.float64)


def take_spins(
    world_rotations: np.ndarray,
    frames,
    sides,
    fps: float,
    up_axis: str,
    yaw: np.ndarray | None = None,
    target_fps: float | None = None,
) -> list[np.ndarray]:
    """:func:`hand_spin` of each side's hand joint (``frames[side]``, a HandFrame), from
    world rotations ``(F, J, 4)``; resampled to ``target_fps`` when given (low-passed when
    the rate drops, :func:`engine.align.features.resample_points`)."""
    out = []
    for s in sides:
        fr = frames[s]
        w = hand_spin(world_rotations[:, fr.hand_joint], fps, fr.basis, up_axis, yaw)
        if target_fps is not None and target_fps != fps:
            w = resample_points(w, fps, target_fps)
        out.append(w)
    return out
