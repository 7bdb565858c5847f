"""A pass's metric is a parameter chosen from engine.dtw's registry: a new metric is one
numba kernel plus one registration, and the splice runs with it."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from conftest import MOCAP

from engine.base.errors import ParameterError
from engine.dtw import metric_names, register_metric
from engine.io.bvh import read_bvh
from engine.splice import pipeline as P


@numba.njit(nogil=True)
def _toy_l1(body_row, hand_row):
    """A toy pass-2 metric: L1 distance of the angle rows (``AngleFeatures.rows``)."""
    total = 0.0
    for k in range(min(body_row.size, hand_row.size)):
        total += abs(body_row[k] - hand_row[k])
    return total


@pytest.fixture(scope="module")
def pair():
    body = read_bvh(MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh")
    hand = read_bvh(MOCAP / "beat" / "1_wayne_0_1_1.bvh")
    return body, hand


def test_a_registered_toy_metric_drives_pass_2(pair):
    register_metric("toy_l1", _toy_l1, replace=True)  # the one registration
    assert "toy_l1" in metric_names()
    body, hand = pair
    # fixed ends: the pass cost is then exactly the metric summed along the path (open ends
    # add skip costs for unmatched frames)
    default = P.splice(body, hand, side="right", ends="fixed")
    toy = P.splice(body, hand, side="right", ends="fixed", metrics=("splice_phase", "toy_l1"))
    assert toy.motion is not None and toy.motion.n_frames == body.n_frames
    a2 = toy.alignment.pass2
    assert a2.metric == "toy_l1" and toy.alignment.metrics == ("splice_phase", "toy_l1")
    # the pass-2 cost is the toy metric summed along the pass-2 path
    a, b = a2.rows
    along = [_toy_l1(a[i], b[j]) for i, j in a2.path]
    assert a2.cost == pytest.approx(float(np.sum(along)), rel=1e-9)
    assert np.allclose(a2.path_costs(), along)
    # pass 1 is untouched; pass 2 found its own path under the other cost
    assert np.array_equal(toy.alignment.pass1.path, default.alignment.pass1.path)
    assert a2.cost != pytest.approx(default.alignment.pass2.cost)
    # the cost views read the pass's metric from the registry too
    img = P.cost_image(toy.features, "pass2", a2.path[:5, 0], a2.path[:5, 1], toy.alignment)
    assert np.allclose(np.diag(img), along[:5])


def test_an_unknown_metric_is_refused_naming_the_known_ones(pair):
    body, hand = pair
    with pytest.raises(
        ParameterError,
        match=r"metrics\[1\]: unknown metric 'nope'; known: .*"
        r"splice_angle",
    ):
        P.splice(body, hand, side="right", metrics=("splice_phase", "nope"))
