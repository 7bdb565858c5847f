"""Tabs of one server share a pair's work (issue 13, openlong): the first alignment at
the same settings is solved once (``backend.first_solution``), and a session's edits from
it run on copies of its solvers, so they give what a fresh solve gives and never change
what another tab starts from. Also the BVH reader's number parser
(``engine.io.numbers.parse_rows``): the value ``float()`` reads, bit for bit."""

from __future__ import annotations

from urllib.parse import parse_qsl, urlsplit

import numpy as np
import pytest
from conftest import demo_config, demo_pair_uploaded

from engine.io.numbers import parse_rows
from webapp import backend, config
from webapp.state import Session

DEMO = "wave-ok"


@pytest.fixture(scope="module")
def cfg(sample_dir, tmp_path_factory) -> config.AppConfig:
    return demo_config(sample_dir, tmp_path_factory)


def _open(cfg) -> Session:
    s = Session(cfg)
    s.load_sample(DEMO)
    assert s.error == "" and s.solution is not None
    return s


def _mid_point(s: Session, shift: int) -> tuple[int, int]:
    """A body frame at mid-take and the hand-file frame the path gives it, moved by ``shift``."""
    body = s.n // 2
    return body, s.hand_frame_for(body) + shift


def test_a_second_session_on_a_pair_shows_the_first_alignment_without_solving(cfg):
    first = _open(cfg)
    solved = backend.FIRST_STATS["solved"]
    second = _open(cfg)
    assert backend.FIRST_STATS["solved"] == solved  # not solved again
    assert second.solution is first.solution
    assert not second.aligned_here()
    # another setting is another alignment: solved for the session that asks
    second.band = 0.25
    assert second.solution is not first.solution and second.aligned_here()


def test_edits_from_the_shared_alignment_stay_in_their_session(cfg):
    a, b = _open(cfg), _open(cfg)
    shared = a.solution
    assert b.solution is shared
    prepared = a.prepared
    band, refine = a.widths()
    p_a, p_b = _mid_point(a, 6), _mid_point(b, -6)
    a.add_point(*p_a)
    b.add_point(*p_b)
    assert a.error == "" and b.error == "" and len(a.points) == len(b.points) == 1
    for s in (a, b):
        fresh = backend.solve(prepared, band, refine, s.constraint_points())
        assert np.array_equal(s.solution.pass2.path, fresh.pass2.path)
        np.testing.assert_array_equal(s.solution.warp, fresh.warp)
    # the shared alignment's solvers were never run: a third session starts from the same
    # rows, and its own edit equals a fresh solve too
    c = _open(cfg)
    assert c.solution is shared
    c.add_point(*p_a)
    np.testing.assert_array_equal(c.solution.warp, a.solution.warp)
    assert shared.cache["engine"].pass1.solver.band == shared.pass1.band


def _query(s: Session) -> dict:
    return dict(parse_qsl(urlsplit(s.share_url("/")).query))


def test_an_uploaded_pair_reopened_by_its_link_shows_its_alignment_without_solving(cfg):
    """Stranger R5-2: a tab opening an uploaded pair's share link solved both passes again
    (the link's opening called ``backend.solve``, never the shared first alignment)."""
    s, body, hand = demo_pair_uploaded(cfg)
    solved = backend.FIRST_STATS["solved"]
    other = Session(cfg)
    other.open_link(_query(s))
    assert other.error == "" and backend.FIRST_STATS["solved"] == solved
    assert other.solution is s.solution and not other.aligned_here()
    # an edit of the reopened tab is its own and what a fresh solve gives
    other.add_point(*_mid_point(other, 6))
    assert other.error == "" and s.solution is not other.solution
    band, refine = other.widths()
    fresh = backend.solve(other.prepared, band, refine, other.constraint_points())
    np.testing.assert_array_equal(other.solution.warp, fresh.warp)
    # a link with points is solved for the tab that opens it, as before
    third = Session(cfg)
    third.open_link(_query(other))
    assert third.error == "" and third.aligned_here()
    np.testing.assert_array_equal(third.solution.warp, fresh.warp)


def test_copied_solvers_hold_their_own_rows(cfg):
    s = _open(cfg)
    result = s.solution.cache["engine"]
    with s.prepared.lock:
        own = backend._own(result)
    for part in ("pass1", "pass2"):
        a, b = getattr(result, part).solver, getattr(own, part).solver
        if a is None or not hasattr(a, "_fwd"):
            continue
        assert b is not a and b._problem is a._problem
        for side in ("_fwd", "_bwd"):
            x, y = getattr(a, side), getattr(b, side)
            assert x.bp is not y.bp and x.has is not y.has
            assert np.array_equal(x.has, y.has) and x.valid == y.valid


# ------------------------------------------------------------------ number parser


def _bits(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).view(np.int64)


def test_parsed_values_are_what_float_reads_bit_for_bit():
    rng = np.random.default_rng(7)
    texts = []
    for _ in range(4000):
        v = float(rng.normal() * 10.0 ** rng.integers(-30, 30))
        fmt = ["%.6f", "%.17g", "%g", "%.3e", "%.20f", "%.1f"][int(rng.integers(6))]
        texts.append(fmt % v)
    texts += [
        "1.",
        ".5",
        "+.5e-3",
        "-0.000000",
        "00012.50",
        "1e22",
        "1e23",
        "9007199254740993",
        "123456789012345678",
        "0.1234567890123456789",
        "5e-324",
        "1e-400",
        "1E+05",
        "0." + "0" * 30 + "1",
        "-180.000000",
        "359.999999",
    ]
    rows = [" ".join(texts[k : k + 4]) for k in range(0, len(texts) - len(texts) % 4, 4)]
    got = parse_rows("\n".join(rows), len(rows), 4)
    want = [float(t) for r in rows for t in r.split()]
    assert got is not None and got.shape == (len(rows), 4)
    assert np.array_equal(_bits(got.ravel()), _bits(want))


@pytest.mark.parametrize(
    "text",
    [
        "1e",
        "e5",
        ".",
        "-",
        "+-1",
        "1-2",
        "1.2.3",
        "1..2",
        "--1",
        "1e+",
        "nan",
        "inf",
        "1_0",
        "\u0663",
        "\u00a01",
        "0x10",
        "1e5.",
        "",
        "  ",
    ],
)
def test_text_that_is_not_one_clean_number_is_left_to_the_caller(text):
    assert parse_rows(text, 1, 1) is None


def test_rows_must_hold_their_count_of_values():
    assert parse_rows(" 1\t2 \r\n3 4", 2, 2).tolist() == [[1, 2], [3, 4]]
    assert parse_rows("1 2\n3", 2, 2) is None
    assert parse_rows("1 2 3\n4", 2, 2) is None
    assert parse_rows("1 2\n3 4\n5 6", 2, 2) is None
