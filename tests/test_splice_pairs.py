"""Every sensible pair of the shared captures splices (short crops keep this quick).

Body takes: every BVH with arms (BEAT, Bandai, AnimatedDrawings incl. the CMU-style rig,
LAFAN1). Hand takes: every BVH with finger joints (BEAT, gestification's Leap takes
rooted at the forearm, ManipNet's takes rooted at the wrist). Different skeletons, units,
up axes and frame rates (30, 37-40, 120 fps).
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from conftest import mocap_files

from engine.io.bvh import format_bvh, parse_bvh, read_bvh
from engine.model.roles import find_roles, side_from_name
from engine.splice import pipeline as P

CROP_S = 2.5


def _hands():
    out = []
    for p in mocap_files("**/*.bvh"):
        m = read_bvh(p)
        roles = find_roles(m.skeleton, side_hint=side_from_name(p.name))
        # a hand take carries a hand: at least three fingers (AnimatedDrawings' lone
        # thumb makes it a body take here)
        if any(
            sum(bool(roles.side(s).fingers[f]) for f in roles.side(s).fingers) >= 3
            for s in ("right", "left")
        ):
            out.append(p)
    return out


def _bodies():
    out = []
    for p in mocap_files("**/*.bvh"):
        m = read_bvh(p)
        roles = find_roles(m.skeleton)
        if m.skeleton.n_joints >= 20 and len(roles.sides_found()) == 2:
            out.append(p)
    return out


BODIES = _bodies()
HANDS = _hands()


@cache
def _crop(path) -> object:
    m = read_bvh(path)
    return m.frames(0, max(8, int(CROP_S * m.fps)))


def test_the_pair_lists_cover_the_captures():
    names = {p.parent.name for p in BODIES}
    assert {"beat", "bandai-namco", "animated-drawings", "lafan1"} <= names
    assert {p.parent.name for p in HANDS} == {"beat", "gestification", "manipnet"}
    assert len(BODIES) >= 14 and len(HANDS) >= 14


@pytest.mark.parametrize("hand", HANDS, ids=lambda p: p.stem)
@pytest.mark.parametrize("body", BODIES, ids=lambda p: p.stem)
def test_pair_splices(body, hand):
    b, h = _crop(body), _crop(hand)
    res = P.splice(b, h)
    out = res.motion
    assert out.n_frames == b.n_frames and out.fps == b.fps
    assert np.all(np.isfinite(res.alignment.map))
    assert np.all(np.diff(res.alignment.map) >= -1e-9)
    assert 0 <= res.alignment.map.min() and res.alignment.map.max() <= h.n_frames - 1
    assert np.all(np.isfinite(out.rotations))
    roles = find_roles(out.skeleton)
    for side in res.features.sides:
        assert roles.side(side).has_fingers
    # the spliced take is standard BVH that reads back the same
    back = parse_bvh(format_bvh(out))
    assert back.skeleton.n_joints == out.skeleton.n_joints
