"""One rule set for every front: the same band widths, tolerances and matching points fed
to the CLI flags, the batch manifest, the session file, the app's link and the app's
Session are accepted by all (with the same spliced BVH) or refused by all with the same
one-line text from engine.dtw.constraints, with only the front's source in front of it
(``--match 80:20: matching point 2 (body 80, hand 20): ...``).

The pair (Bandai wave body, BEAT hand) shares one frame rate (30 fps), so the hand file's
frames and the app's alignment grid coincide and every front reads the same numbers.
"""

from __future__ import annotations

import json
import shutil

import pytest
from conftest import MOCAP

from engine.cli import main
from engine.dtw import constraints as C

BODY = MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh"
HAND = MOCAP / "beat" / "1_wayne_0_1_1.bvh"

# (band, refine_band, points as (body, hand, tolerance or None)); tolerance None = global 0
CASES = {
    "paper fractions, tolerance 200": ("0.25", "0.08", [(40, 30, 200), (120, 150, 2)]),
    "equal hand frames (a hold)": ("0.3", "0.1", [(40, 30, None), (80, 30, None)]),
    "widths in seconds": ("3s", "0.5s", [(60, 50, 2)]),
    "defaults": (None, None, []),
    "band below its range": ("0.01", None, []),
    "refine band below its range": (None, "0.001", []),
    "seconds past the range": ("4000s", None, []),
    "tolerance past the range": (None, None, [(40, 30, 1000)]),
    "points crossing": (None, None, [(40, 30, None), (80, 20, None)]),
    "the third point crosses the second": (None, None, [(20, 10, 1), (40, 30, None), (80, 20, 2)]),
    "body frames out of order": (None, None, [(80, 30, None), (40, 50, None)]),
    "point outside the takes": (None, None, [(40, 30, None), (5000, 60, None)]),
    "consecutive body frames too far apart": (None, None, [(40, 30, None), (41, 60, None)]),
    "a point on the first body frame, off the corner (open ends)": (None, None, [(0, 30, None)]),
    "a hand frame that is not a whole number": (None, None, [(40, 12.5, None)]),
    "a body frame that is not a whole number": (None, None, [(40.5, 30, None)]),
}


def _expected(band, refine, points, n, m, grid_scale):
    """None (accepted) or the ConstraintError every front must show and where it is found:
    ``"read"`` (the values alone) or ``"takes"`` (the points against the takes; points in
    the files' own frames, ``grid_scale`` body fps / hand fps)."""
    try:
        C.BAND.parse(band)
        C.REFINE_BAND.parse(refine)
        pts = C.parse_points([p for p in points])
    except C.ConstraintError as exc:
        return exc, "read"
    try:
        C.check_points(
            [p.resolved(0.0) for p in pts],
            n,
            m,
            open_ends=C.DEFAULT_ENDS == "open",
            grid_scale=grid_scale,
        )
    except C.ConstraintError as exc:
        return exc, "takes"
    return None, None


def _source(front, refusal, found, points) -> str:
    """What ``front`` puts in front of engine.dtw.constraints' text: its source only (the
    flag and the point as typed, the file, the manifest's line and column)."""
    point = refusal.index is not None
    if front == "cli":
        typed = _point_text(points)[refusal.index] if point else ""
        return "handsplice: error: " + (f"--match {typed}: " if point else "")
    if front == "manifest":  # read with the manifest; against the takes when its pair runs
        if not point:
            return "m.csv line 2: "
        return "m.csv line 2, column match: " if found == "read" else "line 2, column match: "
    if front == "session file":
        return "handsplice: error: s.json: "
    if front == "link":  # the page says "shared link: " in front of this
        return "URL: " if found == "read" else ""
    return ""


#: each front's own name of a field where it is not the field's (stranger R4-6: the CLI
#: named ``max_unmatched_s``, not the flag typed)
_FRONT_NAMES = {
    "cli": {"band": "--band", "refine_band": "--refine-band"},
    "link": {"refine_band": "refine"},
}


def _named(front, refusal) -> str:
    """engine.dtw.constraints' text as ``front`` shows it: the field by the front's name
    for it (the flag, the link's key); a matching point in its own words."""
    if refusal.index is not None:
        return str(refusal)
    label = _FRONT_NAMES.get(front, {}).get(refusal.field, refusal.label)
    return f"{label}: {refusal.detail}"


def _bvh_text(motion) -> str:
    from engine.io.bvh import format_bvh

    return format_bvh(motion)


def _point_text(points) -> list[str]:
    return [C.MatchPoint(b, h, t).text() for b, h, t in points]


# ---------------------------------------------------------------- the five fronts
# each returns ("ok", BVH text) or ("refused", the one line shown)


def _cli(tmp, band, refine, points, capsys):
    out = tmp / "cli.bvh"
    argv = ["splice", str(BODY), str(HAND), "-o", str(out), "--side", "right", "--quiet"]
    argv += ["--band", band] if band is not None else []
    argv += ["--refine-band", refine] if refine is not None else []
    for text in _point_text(points):
        argv += ["--match", text]
    capsys.readouterr()
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    if code != 0:
        assert code == 2 and len(err) == 1
        return "refused", err[0]
    return "ok", out.read_text()


def _manifest(tmp, band, refine, points, capsys):
    from engine.base.errors import HandSpliceError
    from engine.io import load_take
    from engine.jobs import batch

    text = "body,hand,side,band,refine_band,match\n" + ",".join(
        [str(BODY), str(HAND), "right", band or "", refine or "", ";".join(_point_text(points))]
    )
    try:
        (job,) = batch.parse_manifest(text + "\n", tmp / "m.csv")
        if job.refused:  # a bad cell fails its row (with the same one line), never run
            return "refused", job.refused
        motion, _ = batch.splice_pair(load_take(job.body), load_take(job.hand), job)
    except HandSpliceError as exc:
        return "refused", batch.one_line(exc)
    return "ok", _bvh_text(motion)


def _session_file(tmp, band, refine, points, capsys):
    data = {
        "format": "handsplice-session",
        "version": 2,
        "side": "right",
        "points": [{"body": b, "hand": h, "tolerance": t} for b, h, t in points],
    }
    for key, value in (("band", band), ("refine_band", refine)):
        if value is not None:  # JSON: a fraction is a number, seconds a text ("3s")
            data[key] = value if value.endswith("s") else float(value)
    path = tmp / "s.json"
    path.write_text(json.dumps(data))
    out = tmp / "session.bvh"
    capsys.readouterr()
    code = main(["splice", str(BODY), str(HAND), "-o", str(out), "--session", str(path), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    if code != 0:
        assert code == 2 and len(err) == 1
        return "refused", err[0]
    return "ok", out.read_text()


def _link(tmp, band, refine, points, capsys, app):
    from webapp import backend

    query = {"sample": "pair", "side": "right"}
    if band is not None:
        query["band"] = band
    if refine is not None:
        query["refine"] = refine
    if points:
        query["pts"] = ",".join(_point_text(points))
    before = app.to_spec()
    try:
        app.from_query(query)
    except (backend.HandSpliceError, ValueError, KeyError) as exc:
        assert app.to_spec() == before  # a refused link changes nothing
        return "refused", backend.one_line(exc)
    return "ok", _bvh_text(app.spliced())


def _session(tmp, band, refine, points, capsys, app):
    before = app.to_spec()
    ok = app.set_constraints(
        band=band, refine_band=refine, tolerance=0, points=[list(p) for p in points]
    )
    if not ok:
        assert app.to_spec() == before
        return "refused", app.error
    return "ok", _bvh_text(app.spliced())


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    from webapp import config
    from webapp.state import Session

    samples = tmp_path_factory.mktemp("samples")
    shutil.copy(BODY, samples / BODY.name)
    shutil.copy(HAND, samples / HAND.name)
    (samples / "samples.json").write_text(
        json.dumps(
            {
                "format": "handsplice-samples",
                "version": 1,
                "pairs": [{"name": "pair", "body": BODY.name, "hand": HAND.name, "side": "right"}],
            }
        )
    )
    cfg = config.AppConfig(sample_dir=samples, upload_dir=samples / "up")
    return Session(cfg)


def _fresh(app):
    """The app on the pair with default constraints (each case starts from here)."""
    app.load_sample("pair")
    app.from_query({"sample": "pair", "side": "right", "band": "0.3", "refine": "0.1", "tol": "0"})
    return app


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_every_front_accepts_or_refuses_alike(case, tmp_path, capsys, app):
    band, refine, points = CASES[case]
    app = _fresh(app)
    expected, found = _expected(band, refine, points, app.n, app.m_hand, app.fps / app.hand_fps)
    results = {
        "cli": _cli(tmp_path, band, refine, points, capsys),
        "manifest": _manifest(tmp_path, band, refine, points, capsys),
        "session file": _session_file(tmp_path, band, refine, points, capsys),
        "link": _link(tmp_path, band, refine, points, capsys, _fresh(app)),
        "session": _session(tmp_path, band, refine, points, capsys, _fresh(app)),
    }
    if expected is None:
        assert {k: v[0] for k, v in results.items()} == dict.fromkeys(results, "ok"), results
        texts = {k: v[1] for k, v in results.items()}
        assert len(set(texts.values())) == 1, [k for k in texts if texts[k] != texts["cli"]]
    else:
        text = str(expected)
        if expected.index is not None:  # a point is named as a user counts and reads it
            b, h = points[expected.index][:2]
            assert text.startswith(
                f"matching point {expected.index + 1} (body {b:g}, hand {h:g}): "
            )
            assert "points[" not in text
        for front, (status, message) in results.items():
            assert status == "refused", (front, message)
            assert "\n" not in message
            # the same text; only the source in front, and the front's name of the field
            # (a flag, the link's key), differ
            shown = _source(front, expected, found, points) + _named(front, expected)
            assert message == shown, (front, message)


def test_defaults_are_the_papers_fractions_on_short_takes_and_seconds_on_long():
    assert C.BAND.default_for(187, 30.0) == C.Width(0.30)
    assert C.REFINE_BAND.default_for(187, 30.0) == C.Width(0.10)
    two_minutes, ten_minutes = 120 * 120, 600 * 120
    assert C.BAND.default_for(two_minutes, 120.0) == C.Width(16.4, C.SECONDS)
    # 1.5 s x sqrt(600) = 36.7 s would be 439 M cells: capped to fit the engine's limit
    assert C.BAND.default_for(ten_minutes, 120.0) == C.Width(14.7, C.SECONDS)
    assert C.BAND.long_take_seconds(600.0) == 36.7
    assert C.REFINE_BAND.default_for(two_minutes, 120.0) == C.Width(2.0, C.SECONDS)
    # the default band of any long take fits the engine's cell limit (open ends included)
    from engine.base.limits import MAX_BAND_CELLS
    from engine.dtw import Band

    for minutes, fps in ((10, 120.0), (30, 60.0), (5, 240.0)):
        n = int(minutes * 60 * fps)
        fraction = C.BAND.default_for(n, fps).fraction(n, fps)
        area = Band.from_constraints(n, n, fraction, [], open_ends=True).area
        assert MAX_BAND_CELLS * 0.8 < area <= MAX_BAND_CELLS, (minutes, fps, area)
    # the rule is continuous: the switch (25 s for W1) is where both give the same width
    for n in (24 * 30, 26 * 30):
        width = C.BAND.default_for(n, 30.0)
        assert width.unit == (C.FRACTION if n < 25 * 30 else C.SECONDS)
        assert width.frames(n, 30.0) == pytest.approx(0.3 * 25 * 30, rel=0.05)


@pytest.mark.parametrize(
    ("text", "width"),
    [
        ("0.3", C.Width(0.3)),
        ("10s", C.Width(10.0, "s")),
        (" 2.5 s ", C.Width(2.5, "s")),
        ("4 seconds", C.Width(4.0, "s")),
        (0.25, C.Width(0.25)),
        (C.Width(5, "s"), C.Width(5, "s")),
    ],
)
def test_width_text_forms(text, width):
    assert C.BAND.parse(text) == width
    assert C.BAND.parse(width.text()) == width  # the text a front writes reads back


@pytest.mark.parametrize(
    "text", ["0", "1.5", "-1", "nan", "inf", "wide", "3 m", "0.05s", "1e400", True]
)
def test_width_refusals_name_the_field_and_range(text):
    with pytest.raises(C.ConstraintError) as info:
        C.BAND.parse(text)
    assert info.value.field == "band"
    assert str(info.value).startswith(
        "band: expected a fraction of the body take from 0.02 to 1 or seconds like 10s"
    )


def test_ends_and_open_end_limit():
    assert C.parse_ends(None) == C.DEFAULT_ENDS == "open"  # as the pipeline (issue 12)
    assert C.parse_ends("Open") == "open"
    with pytest.raises(C.ConstraintError, match="ends: expected fixed or open"):
        C.parse_ends("loose")
    assert C.parse_max_unmatched(None) is None
    assert C.parse_max_unmatched("2.5s") == 2.5
    with pytest.raises(
        C.ConstraintError, match="max_unmatched_s: expected a number of seconds from 0 to 3600"
    ):
        C.parse_max_unmatched(-1)
    # default: half of the shorter take (alignment-grid frames)
    assert C.unmatched_limits(300, 200, 30.0, None) == (200, 100)
    assert C.unmatched_limits(300, 200, 30.0, 2.0) == (60, 60)


def test_shared_command_line_replays_the_apps_tolerance_exactly():
    """The app's tolerance in grid frames -> the shared --match in hand-file frames -> back:
    the same whole number of grid frames (a tolerance of 200 at 30 vs 40 fps gave 201)."""
    for body_fps, hand_fps in ((30.0, 40.0), (30.0, 37.037037), (120.0, 30.0), (30.0, 120.0)):
        for tol in (0, 1, 2, 7, 200, 499):
            ((_, _, t_hand),) = C.points_to_hand([(10, 5, tol)], body_fps, hand_fps, 10_000)
            if t_hand > C.TOLERANCE.hi:  # past the range in the hand file's frames
                continue
            text = C.MatchPoint(10, 5, t_hand or None).text()
            ((_, _, back),) = C.points_to_grid(
                [C.parse_point(text).resolved()], body_fps, hand_fps, 10_000
            )
            assert back == tol, (body_fps, hand_fps, tol, text)


def test_a_refusal_carries_field_value_and_expected():
    """A ConstraintError's structured fields (for code) and its one text (for people)."""
    with pytest.raises(C.ConstraintError) as info:
        C.BAND.parse("5")
    err = info.value
    assert (err.field, err.value, err.expected, err.index) == ("band", 5.0, C.BAND.expected, None)
    assert str(err) == f"band: expected {C.BAND.expected}, got 5"
    with pytest.raises(C.ConstraintError) as info:
        C.parse_point_tolerance(-2, 3, 40, 30)
    err = info.value
    assert (err.field, err.value, err.index) == ("points[3].tolerance", -2.0, 3)
    assert (
        str(err)
        == "matching point 4 (body 40, hand 30): expected a tolerance from 0 to 500 frames, got -2"
    )

    with pytest.raises(C.ConstraintError) as info:
        C.parse_points("10:5:2 8:9")
    err = info.value
    assert (err.field, err.value, err.point, err.index) == (
        "points[1]",
        C.MatchPoint(8, 9),
        (8, 9),
        1,
    )
    assert err.others == (C.MatchPoint(10, 5, 2.0),) and err.expected is None
    assert str(err) == (
        "matching point 2 (body 8, hand 9): body frame 8 is not after matching point 1's body "
        "frame 10; body frames must increase from one point to the next"
    )

    with pytest.raises(C.ConstraintError) as info:  # against the matrix (the engine's calls)
        C.check_points([(3, 50, 0)], 10, 20)
    err = info.value
    assert (err.point, err.value, err.index) == ((3, 50), (3.0, 50.0, 0.0), 0)
    assert str(err) == (
        "matching point 1 (body 3, hand 50): outside the 10 x 20 matrix; expected body frames "
        "0 to 9 and hand frames 0 to 19"
    )
    with pytest.raises(C.ConstraintError) as info:  # a malformed point is not "placed"
        C.check_points([(3.5, 5, 0)], 10, 20)
    assert info.value.point is None and str(info.value) == (
        "matching point 1 (body 3.5, hand 5): expected whole body and hand frame numbers"
    )


@pytest.mark.parametrize(
    ("items", "text"),
    [
        (
            "12",
            "matching point 1: expected BODY:HAND or BODY:HAND:TOL (frames >= 0, tolerance "
            "in frames), got '12'",
        ),
        ("40:30 a:b", "matching point 2: expected a whole body frame number >= 0, got 'a'"),
        (
            "40:30 80:12.5",
            "matching point 2 (body 80, hand 12.5): expected a whole hand frame "
            "number >= 0, got 12.5",
        ),
        ([{"hand": 2}], "matching point 1 (hand 2): expected a body frame, none was given"),
        (
            [{"body": 1, "hand": 2, "tol": 3}],
            "matching point 1 (body 1, hand 2): unknown field 'tol' (known: body, hand, tolerance)",
        ),
        (
            "20:10 40:30 80:20",
            "matching point 3 (body 80, hand 20): hand frame 20 is before "
            "matching point 2's hand frame 30; a path cannot go back in time, so hand frames must "
            "not decrease while body frames increase",
        ),
    ],
)
def test_a_point_is_named_one_based_in_the_order_given(items, text):
    """Every refusal of a matching point says which one as a user counts them (1-based, in
    the order given) and where it is, never the programmer's ``points[0]``."""
    with pytest.raises(C.ConstraintError) as info:
        C.parse_points(items)
    assert str(info.value) == text


def test_a_refusal_against_the_takes_names_both_points():
    """Same body frame, duplicate, fixed-end corners: the point and the one it meets."""
    cases = [
        (
            [(40, 30), (40, 60)],
            {},
            "matching point 2 (body 40, hand 60): on the same body frame "
            "as matching point 1 (body 40, hand 30); expected one point per body frame (a larger "
            "tolerance covers a range of hand frames)",
        ),
        (
            [(40, 30), (40, 30)],
            {},
            "matching point 2 (body 40, hand 30): the same frames as "
            "matching point 1 (body 40, hand 30); give each point once",
        ),
        (
            [(0, 30)],
            {"open_ends": False},
            "matching point 1 (body 0, hand 30): with fixed ends "
            "every path starts at (0, 0), so on body frame 0 it covers hand frame 0; expected a "
            "tolerance of at least 30",
        ),
        (
            [(99, 30, 2)],
            {"open_ends": False},
            "matching point 1 (body 99, hand 30): with fixed "
            "ends every path ends at (99, 199), so on body frame 99 it covers hand frame 199; "
            "expected a tolerance of at least 169",
        ),
    ]
    for points, options, text in cases:
        with pytest.raises(C.ConstraintError) as info:
            C.check_points(points, 100, 200, grid_scale=1.0, **options)
        assert str(info.value) == text


def test_consecutive_points_are_judged_at_the_takes_frame_rates():
    """Two points on consecutive body frames: a 120 fps hand may advance 4 of its frames
    per 30 fps body frame, a 30 fps hand not even one per 120 fps body frame; the refusal
    names both points in the files' own frames, the other one as a structured point."""
    C.check_points([(100, 2000), (101, 2004)], 200, 4000, grid_scale=30 / 120)
    with pytest.raises(C.ConstraintError) as info:
        C.check_points([(100, 2000), (101, 2010)], 200, 4000, grid_scale=30 / 120)
    err = info.value
    assert str(err) == (
        "matching point 2 (body 101, hand 2010): on the body frame after matching point 1 "
        "(body 100, hand 2000), but their hand frames 2000 and 2010 are more than one body "
        "frame's worth apart after tolerances (0 and 0); increase a tolerance or move a point"
    )
    assert err.point == (101, 2010) and err.others == ((100, 2000, 0.0),)
    with pytest.raises(C.ConstraintError, match="one body frame's worth"):
        C.check_points([(100, 50), (101, 51)], 400, 100, grid_scale=120 / 30)
    # the same pair of points on one rate: one step apart is joinable
    C.check_points([(100, 50), (101, 51)], 400, 100, grid_scale=1.0)
    # a tolerance in hand frames widens the reach on the grid
    C.check_points([(100, 2000), (101, 2010, 6)], 200, 4000, grid_scale=30 / 120)


def test_a_refusal_names_the_key_each_front_holds():
    """The session file names its key (``max_unmatched``), the link its own (``unmatched``,
    ``refine``, ``tol``), not the engine's field names (``max_unmatched_s``,
    ``refine_band``); a matching point keeps its own words."""
    from engine.io import session as session_io

    with pytest.raises(session_io.SessionError) as info:
        session_io.parse_session('{"max_unmatched": -1}', source="s.json")
    assert str(info.value) == (
        "s.json: max_unmatched: expected a number of seconds from 0 to 3600, got -1"
    )
    assert info.value.constraint.field == "max_unmatched_s"  # for code, as before
    _, problems = session_io.read_query(
        {"sample": "demo", "unmatched": "-1", "refine": "5", "tol": "999", "pts": "5:x"}
    )
    texts = [str(p) for p in problems]
    assert texts[0].startswith("URL: refine: expected a fraction"), texts
    assert texts[1].startswith("URL: tol: expected a number of frames"), texts
    assert texts[2].startswith("URL: unmatched: expected a number of seconds"), texts
    assert texts[3].startswith("URL: matching point 1 (body 5): expected"), texts
