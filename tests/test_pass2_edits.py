"""Edits in the app cost what they change in pass 2 too (issue 13), and give the splice a
fresh solve gives.

An app edit calls ``align_passes`` with the previous result: pass 2 reuses its rows when the
headings stay, and both pass-2 solves (the open-ends probe that sizes the skip, and the
final one) are incremental ``Aligner`` re-solves while the rounded skip stays.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.split import make_case
from engine.splice import pipeline as P


@pytest.fixture(scope="module")
def feats():
    case = make_case("lafan1", 2, crop_s=20.0)
    return P.prepare(case.body, case.hand)


def _points(feats, path, shift=0):
    xs = [round(feats.n * (k + 1) / 6) for k in range(5)]
    pts = [[x, int(path[np.searchsorted(path[:, 0], x), 1]), 2] for x in xs]
    pts[2][1] += shift
    return [tuple(p) for p in pts]


def test_skip_step_rounds_down_by_at_most_three_percent():
    for v in (1e-3, 0.2168, 0.5, 1.0, 3.7, 1234.5):
        q = P.skip_step(v)
        assert v * (1 - 1 / 32) <= q <= v
        assert P.skip_step(q) == q
    assert P.skip_step(0.0) == 0.0 and P.skip_step(float("nan")) == 0.0


def test_dragging_a_point_equals_a_fresh_solve_and_recomputes_a_part(feats):
    """After each drag: pass 1 costs what a fresh solve costs (its sign costs tie, so the
    path may be another of equal cost), and pass 2 is exactly what a fresh one-shot pass 2
    gives on the same band (path, cost, ends)."""
    ref = P.align_passes(feats)
    res = P.align_passes(feats, points=_points(feats, ref.pass2.path), incremental=True)
    reused = partial = 0
    for k, shift in enumerate((6, -6, 9, -9)):
        pts = _points(feats, ref.pass2.path, shift)
        before = res
        res = P.align_passes(feats, points=pts, previous=res, incremental=True)
        fresh = P.align_passes(feats, points=pts, incremental=False)
        assert res.pass1.cost == pytest.approx(fresh.pass1.cost, rel=1e-12)
        al, _, ends, _ = P._solve_pass2(res.pass2.rows, res.pass2.band, None, False, res.pass1.ends)
        assert np.array_equal(res.pass2.path, al.path), f"edit {k}"
        assert res.pass2.cost == pytest.approx(al.cost, rel=1e-12)
        assert res.pass2.ends == ends
        if np.array_equal(before.body_heading, res.body_heading):
            assert res.pass2.rows[0] is before.pass2.rows[0]  # rows reused
            reused += 1
        if res.pass2.ends == before.pass2.ends:
            # the final pass-2 solve recomputed only the rows the edit touched
            assert res.pass2.solver.last_stats.fraction < 0.7
            partial += 1
    assert reused >= 3 and partial >= 3


def test_an_edit_that_keeps_pass_2_rows_does_not_sample_their_chance_cost_again(feats, monkeypatch):
    """Pass 2's chance cost (its open ends' skip) is kept with the rows it was sampled
    from: an edit that keeps the rows reads it, and gives a fresh solve's pass 2."""
    ref = P.align_passes(feats)
    res = P.align_passes(feats, points=_points(feats, ref.pass2.path), incremental=True)
    calls = []
    chance = P.chance_cost
    monkeypatch.setattr(P, "chance_cost", lambda *a, **k: calls.append(1) or chance(*a, **k))
    pts = _points(feats, ref.pass2.path, 3)
    res2 = P.align_passes(feats, points=pts, previous=res, incremental=True)
    assert res2.pass2.rows[0] is res.pass2.rows[0]  # the headings stayed: the same rows
    assert calls == []
    monkeypatch.setattr(P, "chance_cost", chance)
    feats.params.pop("_chance2")
    fresh = P.align_passes(feats, points=pts, incremental=False)
    assert np.array_equal(res2.pass2.path, fresh.pass2.path)
    assert res2.pass2.ends == fresh.pass2.ends and res2.pass2.cost == pytest.approx(
        fresh.pass2.cost
    )
