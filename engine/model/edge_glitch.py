"""A take's first or last frame that is a one-frame outlier pose (a tracking glitch).

A Leap Motion take may open on a pose the tracker had not settled: in gestification's
hello-world ``rIndex1`` sits about 170° away from frame 1 and back. A splice holds a hand
take's first and last poses over the body frames the hand does not match, so such a frame
is held for a second in the output; the readers say it as a note.

The rule, per joint with rotation channels: the end frame is more than ``AWAY_DEG`` from
both of its two neighbours (frames 1 and 2, or the two before the last), and those two agree
within ``AGREE_DEG``. Measured on every BVH take in ``/work/shared/data/mocap`` (bodies and
hands: Bandai, LAFAN1, BEAT, CMU, AnimatedDrawings, ManipNet, gestification), with the same
test at every inner frame as a control: it holds only at frame 0 of three gestification
takes (hello-world ``rIndex1``; gesture-pointing and thumbelina several fingers), at no
inner frame and at no other end (``tests/test_edge_glitch.py``).
"""

from __future__ import annotations

import numpy as np

from engine.model.rotations import angle_between

#: an end pose this far (degrees) from both its neighbours is an outlier ...
AWAY_DEG = 90.0
#: ... when the neighbours agree within this (degrees)
AGREE_DEG = 30.0


def edge_outliers(
    rotations: np.ndarray, names: list[str] | tuple[str, ...], joints
) -> list[tuple[int, str, float]]:
    """The take's end frames that are one-frame outlier poses.

    Parameters
    ----------
    rotations : (frames, joints, 4) float, local unit quaternions
    names : joint names, (joints,)
    joints : the joints to test (indices: those with rotation channels)

    Returns
    -------
    ``[(frame, joint name, degrees), ...]``: per outlying end (``0`` or ``frames - 1``)
    the joint that turns the most and by how much (to the nearer neighbour); empty for a
    take of fewer than 4 frames or none.
    """
    joints = np.asarray(list(joints), dtype=int)
    n = rotations.shape[0]
    if n < 4 or joints.size == 0:
        return []
    out = []
    for end, near, far in ((0, 1, 2), (n - 1, n - 2, n - 3)):
        r = rotations[[end, near, far]][:, joints]
        to_near = angle_between(r[0], r[1])
        to_far = angle_between(r[0], r[2])
        between = angle_between(r[1], r[2])
        hit = (to_near > AWAY_DEG) & (to_far > AWAY_DEG) & (between < AGREE_DEG)
        if hit.any():
            k = int(np.argmax(np.where(hit, to_near, -1.0)))
            out.append((end, names[joints[k]], float(to_near[k])))
    return out


def edge_outlier_notes(take_name: str, outliers: list[tuple[int, str, float]]) -> tuple[str, ...]:
    """One note per outlying end frame, naming the file, the frame and the joint."""
    return tuple(
        f"{take_name}: frame {frame} is a one-frame outlier pose ({joint} is {deg:.0f}° from "
        f"the {'next' if frame == 0 else 'previous'} two frames, which agree): a tracking "
        f"glitch? A splice holds a hand take's {'first' if frame == 0 else 'last'} pose where "
        "the body has no hand match"
        for frame, joint, deg in outliers
    )
