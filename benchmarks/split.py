"""Split real captures into a body take and a hand take with known truth (the splice test bench).

Used by ``benchmarks/bench_splice_accuracy.py`` and the tests; also a way to see the
method work on a pair whose answer is known.

Two families of cases (``make_case``):

* ``beat``: the BEAT take (body and 30 finger joints captured together). The body
  take is BEAT with every joint below the wrists removed. The hand take is BEAT
  (fingers included) re-timed by a smooth random warp, resampled to another frame
  rate, with the trunk held still (and turned to face another way), the arms'
  amplitude shrunk (shoulder, collar and elbow rotations pulled toward their mean,
  a performer in a small capture volume) and rotation noise on every joint.
* ``bandai`` / ``lafan1``: real body-only takes. Synthetic fingers (five 3-joint
  chains grafted under each wrist, flexing with a smooth random curl signal) make a
  "full" take whose finger timing is known; it is split the same way.

Each case carries ``truth`` (for every body frame, the hand-take frame captured at
the same instant, float) and ``reference`` (the full take at body frames: the
fingers the splice should reproduce).

Everything random comes from ``numpy.random.Generator(seed)``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d

from engine.align.features import hand_frame
from engine.io.bvh import read_bvh
from engine.model import rotations as rot
from engine.model.kinematics import forward_kinematics, rest_positions, sample
from engine.model.motion import Motion, Skeleton
from engine.model.roles import FINGERS, find_roles

#: the shared real captures beside the checkout (``HANDSPLICE_MOCAP`` overrides), as
#: tests/conftest.py finds them; this bench lives in the repository, not the package
MOCAP = Path(
    os.environ.get(
        "HANDSPLICE_MOCAP", Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"
    )
)
BEAT = "beat/1_wayne_0_1_1.bvh"
BANDAI = [
    "bandai-namco/dataset-2_wave-both-hands_normal_001.bvh",
    "bandai-namco/dataset-1_call_normal_001.bvh",
    "bandai-namco/dataset-1_guide_normal_001.bvh",
    "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh",
    "bandai-namco/dataset-1_byebye_normal_001.bvh",
    "bandai-namco/dataset-1_respond_normal_001.bvh",
]
LAFAN = ["lafan1/multipleActions1_subject1.bvh", "lafan1/dance1_subject1.bvh"]


@dataclass
class Case:
    """One split pair with its truth."""

    name: str
    family: str
    seed: int
    body: Motion  # body take, no fingers
    hand: Motion  # hand take (re-timed, other fps, trunk still, arms shrunk, noise)
    truth: np.ndarray  # (n,) float: hand-take frame for every body frame
    reference: Motion  # full take (with fingers) at body frames
    params: dict


# --------------------------------------------------------------------------------------------
# skeleton surgery
# --------------------------------------------------------------------------------------------


def subset(
    motion: Motion, keep: np.ndarray, end_sites: dict[int, np.ndarray] | None = None
) -> Motion:
    """The take restricted to joints ``keep`` (bool mask).

    A kept joint whose parent is dropped becomes a root carrying its world rotation and
    position (as exporters bake a partial skeleton: a Leap take rooted at the forearm, an
    arm rooted at the collar), so the kept joints stay where they were in the world.
    """
    sk = motion.skeleton
    idx = np.flatnonzero(keep)
    new_roots = [j for j in idx if sk.parents[j] >= 0 and not keep[sk.parents[j]]]
    if new_roots:
        pos, wrot = forward_kinematics(motion)
        rots = motion.rotations.copy()
        trans = motion.translations.copy()
        for j in new_roots:
            rots[:, j] = wrot[:, j]
            trans[:, j] = pos[:, j]
        motion = replace(motion, rotations=rots, translations=trans)
        if not all(sk.has_position_channels(j) for j in new_roots):
            channels = list(sk.channels)
            for j in new_roots:
                rot_ch = tuple(c for c in channels[j] if c.endswith("rotation")) or (
                    "Zrotation",
                    "Xrotation",
                    "Yrotation",
                )
                channels[j] = ("Xposition", "Yposition", "Zposition") + rot_ch
            sk = Skeleton(sk.names, sk.parents, sk.offsets, tuple(channels), sk.end_sites)
            motion = replace(motion, skeleton=sk)
    new = -np.ones(sk.n_joints, dtype=np.int64)
    new[idx] = np.arange(idx.size)
    parents = np.array([new[sk.parents[j]] if sk.parents[j] >= 0 else -1 for j in idx])
    ends = {int(new[j]): v for j, v in sk.end_sites.items() if keep[j]}
    for j, v in (end_sites or {}).items():
        ends[int(new[j])] = np.asarray(v, dtype=float)
    skel = Skeleton(
        names=tuple(sk.names[j] for j in idx),
        parents=parents,
        offsets=sk.offsets[idx],
        channels=tuple(sk.channels[j] for j in idx),
        end_sites=ends,
    )
    return Motion(
        skel, motion.rotations[:, idx], motion.translations[:, idx], motion.fps, motion.meta
    )


def strip_fingers(motion: Motion, roles=None) -> Motion:
    """Remove every joint below the wrists; each wrist gets an End Site at its fingers' base."""
    roles = roles or find_roles(motion.skeleton)
    sk = motion.skeleton
    keep = np.ones(sk.n_joints, dtype=bool)
    ends = {}
    for side in roles.sides_found():
        w = roles.side(side).wrist
        kids = sk.descendants(w)[1:]
        if kids:
            ends[w] = np.mean([sk.offsets[c] for c in sk.children(w)], axis=0)
        keep[kids] = False
    return subset(motion, keep, ends)


def add_fingers(motion: Motion, rng: np.random.Generator, roles=None) -> Motion:
    """Graft five 3-joint fingers under each wrist, flexing with smooth random curls.

    Finger bases fan out across the palm (radial to ulnar), bones point along the
    hand; joint ``k`` of finger ``f`` flexes about the radial axis by
    ``curl_f(t) * (1.0, 1.1, 0.8)[k]`` (curl in 0..80°, thumb flexes about the
    dorsal axis). The curl signals are Gaussian-filtered noise (≈ 0.4 s scale).
    """
    roles = roles or find_roles(motion.skeleton)
    sk = motion.skeleton
    names, parents, offsets, channels = (
        list(sk.names),
        list(sk.parents),
        list(sk.offsets),
        list(sk.channels),
    )
    f = motion.n_frames
    extra_rot = []
    for side in roles.sides_found():
        fr = hand_frame(motion, roles, side)
        length = fr.forearm_length
        wrist = fr.wrist
        for fi, finger in enumerate(FINGERS):
            curl = gaussian_filter1d(rng.normal(size=f + 40), 0.4 * motion.fps)[20:-20]
            curl = curl / (np.abs(curl).max() + 1e-9)
            curl = np.radians(40.0 + 40.0 * curl)  # 0..80 degrees
            across = (fi - 2) * 0.08 * length
            if finger == "thumb":
                base = 0.12 * length * fr.along + 0.14 * length * fr.radial
                axis = fr.dorsal
                bone = _unit(fr.along + fr.radial)
            else:
                base = 0.36 * length * fr.along - across * fr.radial
                axis = fr.radial
                bone = fr.along
            parent = wrist
            for k, (blen, gain) in enumerate(zip((0.0, 0.16, 0.11), (1.0, 1.1, 0.8), strict=True)):
                names.append(f"{sk.names[wrist]}_{finger}{k + 1}")
                parents.append(parent)
                offsets.append(base if k == 0 else blen * length * bone)
                channels.append(("Zrotation", "Xrotation", "Yrotation"))
                sgn = 1.0 if side == "right" else -1.0
                extra_rot.append(
                    rot.from_axis_angle(np.broadcast_to(axis, (f, 3)), sgn * gain * curl)
                )
                parent = len(names) - 1
    ends = dict(sk.end_sites)
    n_old = sk.n_joints
    for j in range(n_old, len(names)):
        if j + 1 >= len(names) or parents[j + 1] != j:  # finger tip
            ends[j] = 0.8 * np.asarray(offsets[j], dtype=float)
    skel = Skeleton(
        names=tuple(names),
        parents=np.array(parents),
        offsets=np.array(offsets),
        channels=tuple(channels),
        end_sites=ends,
    )
    rots = np.concatenate([motion.rotations, np.stack(extra_rot, axis=1)], axis=1)
    trans = np.concatenate(
        [
            motion.translations,
            np.broadcast_to(np.array(offsets[n_old:]), (f, len(names) - n_old, 3)),
        ],
        axis=1,
    )
    return Motion(skel, rots, trans, motion.fps, motion.meta)


def _unit(v):
    return v / np.linalg.norm(v)


# --------------------------------------------------------------------------------------------
# the hand take
# --------------------------------------------------------------------------------------------


def _mean_rotation(q: np.ndarray) -> np.ndarray:
    """Sign-consistent normalised mean of ``(F, 4)`` quaternions."""
    q = rot.make_continuous(q, axis=0)
    return rot.normalize(q.mean(axis=0))


def arm_joints(motion: Motion, roles) -> tuple[set[int], set[int]]:
    """(shrunk joints: clavicle/shoulder/elbow chain, free joints: the whole arm and hand)."""
    sk = motion.skeleton
    shrink, free = set(), set()
    for side in roles.sides_found():
        arm = roles.side(side)
        top = arm.clavicle if arm.clavicle is not None else arm.shoulder
        if top is None:
            continue
        free.update(sk.descendants(top))
        for j in sk.chain_to_root(arm.wrist)[1:]:
            shrink.add(j)
            if j == top:
                break
    return shrink, free


def _keep_forearm_roll(
    full: Motion, roles, before: np.ndarray, after: np.ndarray, trans: np.ndarray
) -> None:
    """Give each shrunk forearm the roll (pronation) it had before shrinking.

    Shrinking shoulder and elbow rotations toward their mean changes where the forearm
    points (the smaller arm motion we want) but also its roll about its own axis, which a
    performer keeps because it is part of the hand's gesture. The elbow joint's world
    rotation is set to the original one turned by the smallest rotation between the
    original and the shrunk forearm directions (swing only, no added roll).
    """
    sk = full.skeleton
    g_before = forward_kinematics(replace(full, rotations=before, translations=trans))[1]
    g_after = forward_kinematics(replace(full, rotations=after, translations=trans))[1]
    rest = rest_positions(sk)
    for side in roles.sides_found():
        arm = roles.side(side)
        e, w = arm.elbow, arm.wrist
        if e is None or e not in sk.chain_to_root(w) or sk.parents[e] < 0:
            continue
        along = rest[w] - rest[e]
        if np.linalg.norm(along) < 1e-9:
            continue
        a0 = rot.rotate(g_before[:, e], along)
        a1 = rot.rotate(g_after[:, e], along)
        swing = _between(a0, a1)
        g_new = rot.multiply(swing, g_before[:, e])
        parent = sk.parents[e]
        after[:, e] = rot.multiply(rot.conjugate(g_after[:, parent]), g_new)


def _between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations ``(F, 4)`` taking vectors ``a`` onto ``b`` (F, 3)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    q = np.concatenate([1.0 + np.sum(a * b, axis=-1, keepdims=True), np.cross(a, b)], axis=-1)
    return rot.normalize(q)


def smooth_warp(
    rng: np.random.Generator, duration: float, scale: float, sigma: float, corr_s: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """A smooth random monotone map from hand time (s) to original time (s).

    The hand take lasts ``duration * scale`` seconds; its local rate (original
    seconds per hand second) is ``exp(sigma * smooth noise)``, renormalised so both
    ends match. Returns (hand times, original times) sampled at 1 ms.
    """
    th = np.linspace(0.0, duration * scale, int(duration * scale * 1000) + 2)
    dt = th[1] - th[0]
    noise = gaussian_filter1d(rng.normal(size=th.size + 4000), corr_s / dt)[2000:-2000]
    noise = noise / (noise.std() + 1e-12)
    rate = np.exp(sigma * noise)
    t = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * dt)])
    t *= duration / t[-1]
    return th, t


def make_hand_take(
    full: Motion,
    rng: np.random.Generator,
    fps: float,
    scale: float,
    warp_sigma: float,
    shrink: float,
    yaw_deg: float,
    noise_deg: float,
    roles=None,
    warp=None,
    perf_to_orig=None,
    still_frame: int | None = None,
) -> tuple[Motion, np.ndarray, np.ndarray]:
    """The hand take from a full take; returns (hand, hand times s, original times s).

    ``still_frame``: the frame whose trunk and legs the hand take holds (default the
    middle one).

    ``warp``: (hand times, performance times) to use instead of a new random
    :func:`smooth_warp`; ``perf_to_orig``: maps performance times to times of ``full``
    (holds), identity by default.
    """
    roles = roles or find_roles(full.skeleton)
    sk = full.skeleton
    shrink_set, free = arm_joints(full, roles)
    rots = full.rotations.copy()
    trans = full.translations.copy()
    mid = full.n_frames // 2 if still_frame is None else int(still_frame)
    for j in range(sk.n_joints):
        if j in free:
            continue
        rots[:, j] = rots[mid, j]  # trunk and legs still
        if sk.has_position_channels(j):
            trans[:, j] = trans[mid, j]
    unshrunk = rots.copy()
    for j in shrink_set:
        mean = _mean_rotation(rots[:, j])
        rots[:, j] = rot.slerp(
            np.broadcast_to(mean, rots[:, j].shape), rots[:, j], np.full(full.n_frames, shrink)
        )
    _keep_forearm_roll(full, roles, unshrunk, rots, trans)
    up = np.array([0.0, 0.0, 1.0]) if full.meta.up_axis == "z" else np.array([0.0, 1.0, 0.0])
    turn = rot.from_axis_angle(up, np.radians(yaw_deg))
    for j in np.flatnonzero(sk.parents < 0):
        rots[:, j] = rot.multiply(turn, rots[:, j])
        trans[:, j] = rot.rotate(turn, trans[:, j])
    still = replace(full, rotations=rots, translations=trans)

    duration = (full.n_frames - 1) / full.fps
    th, t = warp if warp is not None else smooth_warp(rng, duration, scale, warp_sigma)
    m = int(np.floor(th[-1] * fps + 1e-9)) + 1
    hand_t = np.arange(m) / fps
    orig_t = np.interp(hand_t, th, t)
    if perf_to_orig is not None:
        orig_t = perf_to_orig(orig_t)
    local, tr = sample(still, orig_t * full.fps)
    if noise_deg > 0:
        axis = rng.normal(size=local.shape[:2] + (3,))
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        ang = np.radians(noise_deg) * rng.normal(size=local.shape[:2])
        local = rot.multiply(local, rot.from_axis_angle(axis, ang))
    hand = Motion(sk, local, tr, fps, replace(full.meta, source=f"{full.meta.source}#hand"))
    return hand, hand_t, orig_t


@dataclass(frozen=True)
class Realism:
    """What makes a split pair look like two real capture sessions (issue 12).

    untrimmed_s : (lo, hi) seconds; the body take starts ``U(lo, hi)`` s later and ends
        ``U(lo, hi)`` s earlier than the hand take (0 = both cover the whole take).
    jitter_deg : rotation noise (degrees, per joint and frame) on the hand take (and the
        body take with ``noisy_body``).
    spike_rate : share of frames with a single-frame spike; on a spike frame each arm and
        hand joint turns by ``spike_deg`` (10-30 degrees random) with probability 1/2.
    holds : (count lo, count hi, length lo s, length hi s): the performer holds still at
        that many places, for another random length in each take.
    rush : local rate of the hand take outside holds (scale of the whole take; the hand
        take "rushes" when > 1).
    body_fps : frame rates to draw the body take's rate from (None = the capture's).
    hand_fps : frame rates to draw the hand take's rate from (None = 60/90/100/120).

    Random draws for these come from ``default_rng([seed, 1])``, after the base case's
    draws, so a case with and without realism shares the same warp (a clean twin).
    """

    untrimmed_s: tuple[float, float] = (0.0, 0.0)
    jitter_deg: float = 0.0
    spike_rate: float = 0.0
    spike_deg: tuple[float, float] = (10.0, 30.0)
    holds: tuple[int, int, float, float] | None = None
    rush: float = 1.0
    body_fps: tuple[float, ...] | None = None
    hand_fps: tuple[float, ...] | None = None
    noisy_body: bool = False


def base_take(
    family: str,
    seed: int,
    rng: np.random.Generator,
    crop_s: float = 20.0,
    mocap: str | Path | None = None,
) -> tuple[Motion, str]:
    """The full take (with fingers) of a ``family`` case and its name."""
    root = Path(mocap) if mocap is not None else MOCAP
    if family == "beat":
        full = read_bvh(root / BEAT)
        name = f"beat/{seed}"
    elif family == "bandai":
        path = BANDAI[seed % len(BANDAI)]
        base = read_bvh(root / path)
        full = add_fingers(base, rng)
        name = f"{Path(path).stem}/{seed}"
    elif family == "lafan1":
        path = LAFAN[seed % len(LAFAN)]
        base = read_bvh(root / path)
        n = int(crop_s * base.fps)
        start = int(rng.integers(0, base.n_frames - n))
        base = base.frames(start, start + n)
        full = add_fingers(base, rng)
        name = f"{Path(path).stem}[{start}:{start + n}]/{seed}"
    else:
        raise ValueError(f"unknown family {family!r}")
    return full, name


def make_case(
    family: str,
    seed: int,
    crop_s: float = 20.0,
    mocap: str | Path | None = None,
    realism: Realism | None = None,
) -> Case:
    """One seeded case of ``family`` (``"beat"``, ``"bandai"`` or ``"lafan1"``).

    ``mocap`` is the folder of real captures (default :data:`MOCAP`). ``realism``
    (:class:`Realism`) adds untrimmed ends, noise, holds or other frame rates.
    """
    rng = np.random.default_rng(seed)
    full, name = base_take(family, seed, rng, crop_s, mocap)
    roles = find_roles(full.skeleton)
    body = strip_fingers(full, roles)
    body = replace(body, meta=replace(body.meta, source=f"{full.meta.source}#body"))
    params = {
        "fps": float(rng.choice([60.0, 90.0, 100.0, 120.0])),
        "scale": float(rng.uniform(0.85, 1.2)),
        "warp_sigma": float(rng.uniform(0.15, 0.3)),
        "shrink": float(rng.uniform(0.4, 0.7)),
        "yaw_deg": float(rng.uniform(-60.0, 60.0)),
        "noise_deg": 0.5,
    }
    if realism is not None:
        return _realistic_case(full, body, roles, rng, params, name, family, seed, realism)
    hand, hand_t, orig_t = make_hand_take(full, rng, roles=roles, **params)
    body_t = np.arange(body.n_frames) / body.fps
    truth = np.interp(body_t, orig_t, hand_t) * hand.fps
    return Case(
        name=name,
        family=family,
        seed=seed,
        body=body,
        hand=hand,
        truth=truth,
        reference=full,
        params=params,
    )


def _hold_maps(rng: np.random.Generator, duration: float, real: Realism):
    """Time maps with holds: (body-performance times, hand-performance times, original
    times), sampled together at 1 ms of the body performance (all non-decreasing).

    Hold ``k`` sits at original time ``t_k``; the body holds ``La_k`` s, the hand ``Lb_k``
    s, drawn independently from the same range. Inside a hold the maps are linear, so the
    truth of a body frame in a hold is the hand frame as far through the hand's hold.
    """
    orig = np.linspace(0.0, duration, int(duration * 1000) + 2)
    a, b = orig.copy(), orig.copy()
    holds = []
    if real.holds is not None:
        k_lo, k_hi, l_lo, l_hi = real.holds
        k = int(rng.integers(k_lo, k_hi + 1))
        at = np.sort(rng.uniform(0.15, 0.85, size=k)) * duration
        la = rng.uniform(l_lo, l_hi, size=k)
        lb = rng.uniform(l_lo, l_hi, size=k)
        for t, x, y in zip(at, la, lb, strict=True):
            holds.append((float(t), float(x), float(y)))
        # rebuild the grid with a 1 ms sampled hold inserted at each t_k
        o_list, a_list, b_list = [], [], []
        off_a = off_b = 0.0
        prev = 0.0
        for t, x, y in holds:
            seg = orig[(orig >= prev) & (orig < t)]
            o_list.append(seg)
            a_list.append(seg + off_a)
            b_list.append(seg + off_b)
            steps = max(2, int(x * 1000))
            f = np.linspace(0.0, 1.0, steps)
            o_list.append(np.full(steps, t))
            a_list.append(t + off_a + f * x)
            b_list.append(t + off_b + f * y)
            off_a += x
            off_b += y
            prev = t
        seg = orig[orig >= prev]
        o_list.append(seg)
        a_list.append(seg + off_a)
        b_list.append(seg + off_b)
        orig = np.concatenate(o_list)
        a = np.concatenate(a_list)
        b = np.concatenate(b_list)
        a = np.maximum.accumulate(a)
        b = np.maximum.accumulate(b)
    return a, b, orig, holds


def _spiky(motion: Motion, rng: np.random.Generator, joints: np.ndarray, real: Realism) -> Motion:
    """``motion`` with rotation jitter on every joint and single-frame spikes on ``joints``."""
    local = motion.rotations.copy()
    if real.jitter_deg > 0:
        axis = rng.normal(size=local.shape[:2] + (3,))
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        ang = np.radians(real.jitter_deg) * rng.normal(size=local.shape[:2])
        local = rot.multiply(local, rot.from_axis_angle(axis, ang))
    if real.spike_rate > 0 and joints.size:
        f = local.shape[0]
        frames = np.flatnonzero(rng.random(f) < real.spike_rate)
        for fr in frames:
            js = joints[rng.random(joints.size) < 0.5]
            if not js.size:
                continue
            axis = rng.normal(size=(js.size, 3))
            axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
            ang = np.radians(rng.uniform(*real.spike_deg, size=js.size))
            local[fr, js] = rot.multiply(local[fr, js], rot.from_axis_angle(axis, ang))
    return replace(motion, rotations=local)


def _realistic_case(
    full: Motion, body_full: Motion, roles, rng, params, name, family, seed, real: Realism
) -> Case:
    """A case whose takes differ as two capture sessions do (see :class:`Realism`)."""
    rr = np.random.default_rng([seed, 1])
    duration = (full.n_frames - 1) / full.fps
    a_t, b_t, o_t, holds = _hold_maps(rr, duration, real)
    body_fps = float(rr.choice(real.body_fps)) if real.body_fps else float(full.fps)
    if real.hand_fps:
        params["fps"] = float(rr.choice(real.hand_fps))
    lo, hi = real.untrimmed_s
    cut0 = float(rr.uniform(lo, hi)) if hi > 0 else 0.0
    cut1 = float(rr.uniform(lo, hi)) if hi > 0 else 0.0
    # body frames: body-performance times cut0 .. end - cut1
    span = a_t[-1] - cut0 - cut1
    n = int(np.floor(span * body_fps + 1e-9)) + 1
    s = cut0 + np.arange(n) / body_fps
    body_orig = np.interp(s, a_t, o_t)
    rots, trans = sample(body_full, body_orig * full.fps)
    body = replace(body_full, rotations=rots, translations=trans, fps=body_fps)
    rrots, rtrans = sample(full, body_orig * full.fps)
    reference = replace(full, rotations=rrots, translations=rtrans, fps=body_fps)

    # the hand take: warp over the hand performance (with its holds), rushed
    scale = params["scale"] / real.rush
    th, tb = smooth_warp(rng, b_t[-1], scale, params["warp_sigma"])
    hand_fps = params["fps"]

    def perf_to_orig(t):
        return np.interp(t, b_t, o_t)

    hand, hand_t, _ = make_hand_take(
        full,
        rng,
        roles=roles,
        fps=hand_fps,
        scale=scale,
        warp_sigma=params["warp_sigma"],
        shrink=params["shrink"],
        yaw_deg=params["yaw_deg"],
        noise_deg=params["noise_deg"],
        warp=(th, tb),
        perf_to_orig=perf_to_orig,
    )
    # truth: body frame -> body performance time -> hand performance time -> hand time
    tb_of_s = np.interp(s, a_t, b_t)
    truth = np.interp(tb_of_s, tb, th) * hand_fps
    if real.jitter_deg > 0 or real.spike_rate > 0:
        sk = full.skeleton
        _, free = arm_joints(full, roles)
        free_h = np.array(sorted(free), dtype=np.int64)
        free_names = {sk.names[j] for j in free}
        free_b = np.array(
            [j for j, nm in enumerate(body.skeleton.names) if nm in free_names], dtype=np.int64
        )
        hand = _spiky(hand, rr, free_h, real)
        if real.noisy_body:
            body = _spiky(body, rr, free_b, real)
    params = {
        **params,
        "body_fps": body_fps,
        "untrimmed_s": [cut0, cut1],
        "holds": holds,
        "rush": real.rush,
        "jitter_deg": real.jitter_deg,
        "spike_rate": real.spike_rate,
    }
    return Case(
        name=name,
        family=family,
        seed=seed,
        body=body,
        hand=hand,
        truth=truth,
        reference=reference,
        params=params,
    )


# --------------------------------------------------------------------------------------------
# error measures
# --------------------------------------------------------------------------------------------


def finger_pairs(out: Motion, ref: Motion) -> list[tuple[int, int]]:
    """(output joint, reference joint) for every finger joint role present in both."""
    ro, rr = find_roles(out.skeleton), find_roles(ref.skeleton)
    pairs = []
    for side in ("right", "left"):
        for finger in FINGERS:
            for k in (1, 2, 3):
                a = ro.get(side, f"{finger}{k}")
                b = rr.get(side, f"{finger}{k}")
                if a is not None and b is not None:
                    pairs.append((a, b))
    return pairs


def finger_error(out: Motion, ref: Motion, pairs=None) -> float:
    """Mean geodesic angle (degrees) between the finger joints' local rotations."""
    pairs = pairs or finger_pairs(out, ref)
    if not pairs:
        raise ValueError("no finger joints in common")
    a = out.rotations[:, [p[0] for p in pairs]]
    b = ref.rotations[:, [p[1] for p in pairs]]
    return float(np.mean(rot.angle_between(a, b)))


def inside_case(
    long_s: float,
    short_s: float,
    offset_s: float,
    seed: int = 0,
    hand_longer: bool = False,
    hand_fps: float = 30.0,
    path: str = LAFAN[0],
    mocap: str | Path | None = None,
    fps: float | None = None,
) -> Case:
    """A short take recorded during a long one, from one real LAFAN1 capture (30 fps).

    The first ``long_s`` seconds of ``path`` get synthetic fingers (:func:`add_fingers`);
    the long take is all of it, the short take its ``short_s`` seconds from ``offset_s``.
    Body longer (default): the body take is the long one without fingers, the hand take
    the short stretch re-timed by a mild smooth warp (rate 1, sigma 0.2) at ``hand_fps``,
    trunk still, arms shrunk, turned 20°, 0.5° noise, as :func:`make_hand_take` makes
    every hand take; ``truth`` is NaN on the body frames outside the stretch (they have
    no hand match). ``hand_longer``: the body take is the short stretch and the hand
    take all of it. ``fps``: the capture resampled to this rate first (the body take's)."""
    from engine.model.kinematics import resample

    root = Path(mocap) if mocap is not None else MOCAP
    rng = np.random.default_rng(seed)
    base = read_bvh(root / path)
    if fps is not None and fps != base.fps:
        base = resample(base, fps)
    fps = base.fps
    base = base.frames(0, int(round(long_s * fps)))
    full = add_fingers(base, rng)
    roles = find_roles(full.skeleton)
    first = int(round(offset_s * fps))
    piece = full.frames(first, first + int(round(short_s * fps)))
    body_full, hand_full = (piece, full) if hand_longer else (full, piece)
    body = strip_fingers(body_full, roles)
    body = replace(body, meta=replace(body.meta, source=f"{full.meta.source}#body"))
    params = {
        "fps": float(hand_fps),
        "scale": 1.0,
        "warp_sigma": 0.2,
        "shrink": 0.6,
        "yaw_deg": 20.0,
        "noise_deg": 0.5,
    }
    hand, hand_t, orig_t = make_hand_take(hand_full, rng, roles=roles, **params)
    # times of the hand take's source (orig_t) count from its own first frame
    body_t = np.arange(body.n_frames) / fps + (first / fps if hand_longer else -first / fps)
    truth = np.interp(body_t, orig_t, hand_t) * hand.fps
    truth[(body_t < orig_t[0]) | (body_t > orig_t[-1])] = np.nan
    params.update(long_s=long_s, short_s=short_s, offset_s=offset_s, hand_longer=hand_longer)
    name = f"{Path(path).stem}[{first}:+{piece.n_frames}]{'<hand' if hand_longer else '<body'}"
    return Case(name, "inside", seed, body, hand, truth, body_full, params)
