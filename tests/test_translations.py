"""A take's translations store a constant joint once (issue 13: memory that follows the work),
and read as the whole ``(F, J, 3)`` array, bit for bit; world rotations made when read."""

from __future__ import annotations

import numpy as np
import pytest

from engine.io import bvh
from engine.io.bvh import read_bvh
from engine.model import fastkin
from engine.model.translations import Translations
from engine.model.world_rotations import WorldRotations
from tests.conftest import MOCAP

#: real files of each kind: root-only positions (LAFAN1, gestification with its zero row,
#: ManipNet), position channels on every joint (BEAT, Bandai)
FILES = [
    "lafan1/dance1_subject1.bvh",
    "gestification/gesture-pointing.bvh",
    "manipnet/mug1_rightHand.bvh",
    "beat/1_wayne_0_1_1.bvh",
    "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh",
]


def _all_values(path) -> tuple[np.ndarray, int]:
    """Every data row of a BVH file as one ``(F, C)`` array, read without the chunked reader
    (split, ``float()``), and the number of rows ``Frames:`` announces."""
    lines = path.read_text().splitlines()
    at = next(i for i, ln in enumerate(lines) if ln.strip().lower().startswith("frame time"))
    frames = int(lines[at - 1].split(":")[1])
    rows = [ln.split() for ln in lines[at + 1 :] if ln.strip()]
    return np.array([[float(v) for v in r] for r in rows]), frames


@pytest.mark.parametrize("name", FILES)
def test_the_reader_gives_the_arrays_of_all_values_read_at_once(name: str):
    """The chunked reader with its compact translations: the same rotations and
    translations, bit for bit, as converting every value of the file in one go (the reader
    before issue 13's memory work), and no joint stored per frame that never moves."""
    path = MOCAP / name
    m = read_bvh(path)
    values, frames = _all_values(path)
    if len(values) == frames + 1 and not values[0].any():
        values = values[1:]  # gestification's zero row
    rots, trans = bvh._channels_to_pose(m.skeleton, values)
    assert np.array_equal(m.rotations.view(np.int64), rots.view(np.int64))
    t = m.translations
    assert isinstance(t, Translations)
    assert np.array_equal(np.asarray(t).view(np.int64), trans.view(np.int64))
    varies = [j for j in range(m.skeleton.n_joints) if np.ptp(trans[:, j], axis=0).any()]
    assert t.joints.tolist() == varies
    assert t.moving.nbytes == m.n_frames * len(varies) * 3 * 8


def test_a_root_only_take_keeps_its_bone_offsets_once(bandai):
    """LAFAN1 (root positions only): the frames of the root alone are held; the Bandai take
    (position channels on all 22 joints, repeating the offsets): its hips alone (its root
    joint stands still)."""
    lafan = read_bvh(MOCAP / "lafan1/dance1_subject1.bvh")
    for m, moving in ((lafan, [0]), (bandai("2_wave-right-hand"), [1])):
        t = m.translations
        assert t.joints.tolist() == moving
        assert t.stored_nbytes == (m.n_frames + m.skeleton.n_joints) * 3 * 8
        assert t.nbytes == m.n_frames * m.skeleton.n_joints * 3 * 8  # numpy's meaning
        assert t.stored_nbytes < t.nbytes / 15


def test_translations_index_and_compute_as_the_whole_array():
    rng = np.random.default_rng(3)
    whole = np.broadcast_to(rng.normal(size=(6, 3)), (40, 6, 3)).copy()
    whole[:, [0, 4]] = rng.normal(size=(40, 2, 3))
    whole[:, 2, 1] = -0.0  # a sign bit is a difference: -0.0 at joint 2 in frame 0 only
    whole[1:, 2, 1] = 0.0
    t = Translations.of(whole)
    assert t.joints.tolist() == [0, 2, 4] and t.shape == whole.shape
    keys = [
        5,
        -1,
        slice(3, 9),
        slice(None, None, -3),
        np.array([7, 1, 1]),
        whole[:, 0, 0] > 0,
        (slice(None), 0),
        (slice(None), 3),
        (slice(2, 5), [4, 1, 3]),
        (slice(None), slice(1, 5), 2),
        (-1, 4),
        (0, 0, 1),
        (Ellipsis, 1),
        (np.array([1, 2]), np.array([0, 3])),
    ]
    for key in keys:
        got, want = t[key], whole[key]
        assert np.shape(got) == want.shape and type(got) is type(want), key
        assert np.array_equal(np.asarray(got).view(np.int64), want.view(np.int64)), key
    assert np.array_equal(np.asarray(t.frames(4, 30, 3)), whole[4:30:3])
    flip = np.array([1.0, -1.0, 1.0])
    assert np.array_equal(np.asarray(t.scaled(flip)), whole * flip)
    assert np.array_equal(t * 100.0, whole * 100.0)
    assert np.array_equal(t - whole, np.zeros_like(whole))
    assert np.array_equal(np.concatenate([t, t]), np.concatenate([whole, whole]))
    copy = t.copy()
    copy[0, 1] = 99.0  # a plain array of its own
    assert not np.array_equal(np.asarray(t), copy)
    with pytest.raises(TypeError):
        t[0, 1] = 99.0


def test_forward_kinematics_in_place_and_world_rotations_read_on_demand():
    """The FK's positions made in the translations' own array are the kernel's with
    separate arrays; ``WorldRotations`` reads are ``forward_kinematics(motion)[1]``'s."""
    m = read_bvh(MOCAP / "manipnet/mug1_rightHand.bvh").frames(0, 600)
    pos, wrot = fastkin.forward_kinematics(m)
    rot = np.ascontiguousarray(m.rotations)
    trans = np.asarray(m.translations)
    p2, r2 = np.zeros(trans.shape), np.zeros(rot.shape)
    fastkin._fk_kernel(rot, trans, np.asarray(m.skeleton.parents), p2, r2)
    assert np.array_equal(pos, p2) and np.array_equal(wrot, r2)
    w = WorldRotations(m)
    assert w.shape == wrot.shape
    for key in [slice(None), slice(100, 130), 7, np.array([5, 3, 599]), (slice(None), 4)]:
        assert np.array_equal(w[key], wrot[key]), key
    assert np.array_equal(np.asarray(w), wrot)


def test_the_spliced_take_keeps_per_frame_only_the_bodys_moving_joints(bandai):
    """The transfer's output holds the frames of the body's moving joint (Bandai's hips)
    and every other joint's translation once; its values are those the body gives."""
    from engine.splice import pipeline as P

    body = bandai("2_wave-right-hand")
    hand = read_bvh(MOCAP / "gestification/gesture-pointing.bvh")
    out = P.splice(body, hand).motion
    t = out.translations
    hips = out.skeleton.index(body.skeleton.names[1])
    assert t.joints.tolist() == [hips]
    assert t.stored_nbytes == (out.n_frames + out.skeleton.n_joints) * 3 * 8
    assert np.array_equal(t[:, hips], body.translations[:, 1])
