"""An app edit of a hand take without a forearm (ManipNet, Leap: the bench_app pair, the demo
pair) costs what it changes and gives the splice a fresh solve gives (issue 13's drag goal,
issue 16's app benchmark).

Such a pair's alignment rests on pass 1, whose sign costs tie often; its edits used to solve
both passes afresh (a re-solve's junction may break exact ties another way), with the
phase row kernel instead of the app's pass-1 cost table. Now both passes keep their solvers
and re-solve forward only (``Aligner.solve(forward_only=True)``): the rows before the first
edited row are kept, the path is traced back from the end as a full solve traces it.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.base.errors import ParameterError
from engine.dtw import Aligner, Band, align
from engine.dtw.align import Ends
from engine.splice import pipeline as P
from webapp import backend

PAIR = ("bandai-namco/dataset-2_wave-both-hands_normal_001.bvh", "manipnet/mug1_rightHand.bvh")


def _tied_costs(rng, n: int, m: int) -> np.ndarray:
    return np.round(rng.random((n, m)) * 2)  # 0, 1 or 2: many paths of equal cost


def test_forward_only_re_solves_give_a_full_solves_path_ties_included():
    rng = np.random.default_rng(3)
    checked = partial = 0
    for trial in range(40):
        n, m = int(rng.integers(30, 90)), int(rng.integers(30, 90))
        cost = _tied_costs(rng, n, m)
        ends = Ends(n // 4, m // 4, 0.5) if trial % 2 else Ends()
        solver = Aligner.from_cost(cost)
        x = int(rng.integers(n // 2, n - 2))
        for k in range(4):
            y = int(np.clip(round(x * m / n) + int(rng.integers(-4, 5)), 0, m - 1))
            try:
                band = Band.from_constraints(n, m, 0.5, [(x, y, 1)], open_ends=not ends.fixed)
                full = align(cost, band, ends)
            except (ParameterError, ValueError):
                continue
            got = solver.solve(band, ends, forward_only=True)
            assert np.array_equal(got.path, full.path), f"trial {trial}, edit {k}"
            assert got.cost == full.cost
            stats = solver.last_stats
            assert stats.backward_rows[0] == stats.backward_rows[1]  # no backward rows
            assert stats.cells_computed <= band.area
            partial += stats.cells_computed < band.area
            checked += 1
    assert checked > 60 and partial > 10  # the rows before an edit were kept


@pytest.fixture(scope="module")
def prepared(sample_dir):
    body, hand = (sample_dir / p for p in PAIR)
    prep = backend.prepare(body, hand, "right")
    assert P.hand_lacks_forearm(prep.features) and P.uses_spin(prep.features)
    assert prep.pass1_cost is not None  # the app's pass-1 table
    return prep


def _drag(prepared) -> list[list[tuple[int, int, float]]]:
    """Grid points of drags: a point mid-take moved up and down, then a second point
    before it added and the later one moved (its edits leave the rows before the first
    point as they were), then the earlier one moved (the rows after the later one
    settle: ``engine.dtw.fixed``)."""
    n, m = prepared.n, prepared.features.m
    x, y = n // 2, m // 2
    edits = [[(x, y + dy, 0.0)] for dy in (0, 12, -12, 6)]
    edits += [[(n // 4, m // 4, 2.0), (x, y + dy, 0.0)] for dy in (6, -6, 0, 9)]
    # the earlier point moved before the later one: the rows after the later point settle
    edits += [[(n // 4, m // 4 + dy, 2.0), (x, y + 9, 0.0)] for dy in (4, 0, 4)]
    return edits


def test_app_edits_of_a_forearmless_pair_equal_fresh_solves_and_reuse_both_passes(prepared):
    sol = backend.solve(prepared, None, None, [])
    reused_partly = 0
    settled = {True: 0, False: 0}  # pass 1's solver, pass 2's
    for k, points in enumerate(_drag(prepared)):
        before = sol.cache["engine"]
        sol = backend.solve(prepared, None, None, points, previous=sol)
        got = sol.cache["engine"]
        fresh = P.align_passes(prepared.features, points=points)  # the CLI's solve
        for name in ("pass1", "pass2"):
            a, b = getattr(got, name), getattr(fresh, name)
            assert np.array_equal(a.path, b.path), f"edit {k}: {name} path"
            assert a.cost == b.cost and a.ends == b.ends
        assert np.array_equal(got.warp, fresh.warp) and np.array_equal(got.map, fresh.map)
        assert np.array_equal(got.hand_heading, fresh.hand_heading)
        # the solvers are the previous edit's (the pass-1 one over the app's cost table),
        # re-solving forward only: never more than the band, no backward rows
        assert got.pass1.solver is before.pass1.solver
        # pass 2 with open ends keeps two solvers (the probe and the one of the rounded
        # skip): the edit's is one of the previous edit's, or new only when the skip changed
        kept2 = (before.pass2.solver, before.pass2.probe)
        assert any(got.pass2.solver is s for s in kept2) or got.pass2.ends != before.pass2.ends
        for solver, band in (
            (got.pass1.solver, got.pass1.band),
            (got.pass2.solver, got.pass2.band),
        ):
            stats = solver.last_stats
            assert stats.cells_computed <= band.area
            assert stats.backward_rows[0] == stats.backward_rows[1]
        reused_partly += got.pass1.solver.last_stats.cells_computed < got.pass1.band.area
        # both passes' costs are exact (sign costs, fixed-point spin costs): a solver stops
        # at the first settled row after the edit, and still gives the fresh solve's path
        for solver in (got.pass1.solver, got.pass2.solver, got.pass2.probe):
            if solver is not None and solver.last_stats.settled_row < solver.n:
                settled[solver is got.pass1.solver] += 1
    assert reused_partly >= 2
    assert settled[True] >= 2 and settled[False] >= 1  # pass 1's and pass 2's


def test_headings_from_remembered_cell_thetas_equal_the_fresh_ones(prepared):
    """Pass 2's heading along pass 1's path computes θ only at cells no earlier path had."""
    feats = prepared.features
    path = P.align_passes(feats).pass1.path
    # a point a few frames off the path at mid-take: the paths share cells away from it
    mid = feats.n // 2
    on_path = int(path[path[:, 0] == mid][0, 1])
    other = P.align_passes(feats, points=[(mid, on_path + 4, 0.0)]).pass1.path
    feats.params.pop("_theta_cells", None)
    P._cells_theta(feats, other)
    kept = feats.params["_theta_cells"][0]
    assert len(np.intersect1d(kept, path[:, 0] * feats.m + path[:, 1])) > 0
    want = P.M.cell_theta_window(feats.body_phase, feats.hand_phase, path[:, 0], path[:, 1])
    assert np.array_equal(P._cells_theta(feats, path), want)


def test_trust_reads_the_apps_pass1_table_and_gives_the_same_assessment(prepared, monkeypatch):
    """The app's assessment of an edit (pass-1 spread over the tabulated costs) equals the
    CLI's (the sign metric per cell), without one metric call per band row (about 0.3 s CPU
    per assessment at 2,000 x 2,000, beside the next edit's solve)."""
    from engine.dtw.align import Problem
    from engine.trust import assess_splice

    points = _drag(prepared)[1]
    sol = backend.solve(prepared, None, None, points)
    cli = assess_splice(prepared.features, sol.cache["engine"], body_phases=prepared.body_phases)
    rows = []
    real = Problem.cost_row
    monkeypatch.setattr(
        Problem, "cost_row", lambda self, *a: rows.append(self.kind) or real(self, *a)
    )
    app = backend.assess(prepared, sol)
    assert "metric" not in rows  # no per-row pass-1 metric calls
    assert np.array_equal(app.uncertainty.ms, cli.uncertainty.ms)
    assert np.array_equal(app.uncertainty.pass1_ms, cli.uncertainty.pass1_ms)
    assert app.suggestions == cli.suggestions
