"""The merge blend is a time (issue 13): the same performance captured at 30 and 120 fps is
smoothed over the same 0.1 s and timed alike."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.split import make_case
from engine.model.kinematics import resample
from engine.splice import merge as MG
from engine.splice import pipeline as P


def test_blend_frames_follow_the_rate():
    assert MG.blend_frames(30.0) == pytest.approx(MG.BLEND_FRAMES)  # the value chosen at 30 fps
    assert MG.blend_frames(120.0) == pytest.approx(4 * MG.BLEND_FRAMES)


def test_the_same_pair_at_120_fps_is_timed_as_at_30_fps():
    case = make_case("lafan1", 0)
    f30 = P.prepare(case.body, case.hand)
    a30 = P.align_passes(f30)
    assert a30.blend == pytest.approx(3.0)
    body, hand = resample(case.body, 120.0), resample(case.hand, 120.0)
    f120 = P.prepare(body, hand)
    a120 = P.align_passes(f120)
    assert a120.blend == pytest.approx(12.0)
    assert P.align_passes(f120, blend=3.0).blend == 3.0  # an explicit blend stays frames
    # hand-take seconds per body second, both rates; truth from the 30 fps case
    t30 = np.arange(case.body.n_frames) / case.body.fps
    t120 = np.arange(body.n_frames) / body.fps
    s30 = np.asarray(a30.map) / case.hand.fps
    s120 = np.interp(t30, t120, np.asarray(a120.map) / hand.fps)
    truth = case.truth / case.hand.fps
    err30 = np.median(np.abs(s30 - truth))
    err120 = np.median(np.abs(s120 - truth))
    assert err120 <= err30 + 1.0 / 120.0, (err30, err120)
    assert np.median(np.abs(s120 - s30)) < 1.0 / 30.0
