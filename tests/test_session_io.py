"""Session JSON (engine/io/session.py): round trips, field-naming errors, URL query."""

from __future__ import annotations

import hashlib
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.io.session import (
    VIEW_DEFAULTS,
    MatchPoint,
    SessionError,
    SessionSpec,
    TakeRef,
    format_session,
    from_dict,
    from_query,
    parse_session,
    read_query,
    read_session,
    to_dict,
    to_query,
    write_session,
)

HASH = "ab" * 32


def _spec(**kw) -> SessionSpec:
    base = dict(
        sample="demo",
        side="left",
        band=0.25,
        refine_band=0.08,
        tolerance=3,
        points=(MatchPoint(10, 12), MatchPoint(40, 35, 0.0), MatchPoint(90, 99, 7.5)),
        view={"matrix": "pass2", "frame": 17},
    )
    base.update(kw)
    return SessionSpec(**base)


def test_json_round_trip_file(tmp_path):
    spec = _spec()
    path = tmp_path / "s.json"
    write_session(spec, path)
    back = read_session(path)
    assert back == spec
    assert back.constraint_points() == [(10, 12, 3.0), (40, 35, 0.0), (90, 99, 7.5)]
    data = json.loads(path.read_text())
    assert data["format"] == "handsplice-session" and data["version"] == 2
    assert data["points"][0] == {"body": 10, "hand": 12, "tolerance": None}


def test_version_1_files_stay_readable_with_grid_hand_frames(tmp_path):
    """Files written before hand frames were the hand file's own (version 1) still open,
    marked as alignment-grid frames; written back they keep saying so."""
    data = json.loads(format_session(_spec()))
    data["version"] = 1
    old = from_dict(data, source="old.json")
    assert old.hand_frames == "grid" and old.points == _spec().points
    assert to_dict(old)["version"] == 1
    assert _spec().hand_frames == "file" and to_dict(_spec())["version"] == 2
    # links: made before, no frames=hand (grid); made now, frames=hand
    q = to_query(_spec())
    assert q["frames"] == "hand" and from_query(q).hand_frames == "file"
    del q["frames"]
    assert from_query(q).hand_frames == "grid"


def test_uploaded_inputs_round_trip():
    spec = _spec(
        sample=None,
        body=TakeRef(sha256=HASH, name="walk.bvh"),
        hand=TakeRef(sha256="cd" * 32, name="h.bvh"),
    )
    assert parse_session(format_session(spec)) == spec


def test_cli_paths_and_roles_round_trip():
    spec = SessionSpec(
        body=TakeRef(path="body.bvh"),
        hand=TakeRef(path="sub/hand.bvh"),
        roles={"body": {"right.wrist": "RHand"}, "hand": {"left.index1": None}},
    )
    assert from_dict(to_dict(spec)) == spec
    nested = from_dict({"roles": {"body": {"right": {"wrist": "RHand"}}}})
    assert nested.roles == {"body": {"right.wrist": "RHand"}}


def test_defaults_from_empty_object():
    spec = parse_session("{}")
    assert (spec.side, spec.band, spec.refine_band, spec.tolerance, spec.points) == (
        "right",
        None,
        None,
        0.0,
        (),
    )  # no width: the default for the take (constraints)


@pytest.mark.parametrize(
    ("data", "field", "words"),
    [
        (
            {"points": [{"body": 1, "hand": 2}, {"body": 5, "hand": 9, "tolerance": -1}]},
            "points[1].tolerance",
            "matching point 2 (body 5, hand 9): expected a tolerance from 0 to 500 frames, got -1",
        ),
        (
            {"points": [{"body": 10, "hand": 2}, {"body": 5, "hand": 9}]},
            "points[1]",
            "matching point 2 (body 5, hand 9): body frame 5 is not after matching point 1's "
            "body frame 10;",
        ),
        (
            {"points": [{"body": 1.5, "hand": 2}]},
            "points[0].body",
            "matching point 1 (body 1.5, hand 2): expected a whole body frame number >= 0, got 1.5",
        ),
        (
            {"points": [{"hand": 2}]},
            "points[0].body",
            "matching point 1 (hand 2): expected a body frame, none was given",
        ),
        ({"band": 0}, "band", "from 0.02 to 1"),
        ({"band": 0.01}, "band", "from 0.02 to 1"),
        ({"band": "wide"}, "band", "expected a fraction of the body take"),
        ({"band": "0.3"}, "band", "expected a fraction of the body take"),
        ({"tolerance": 1000}, "tolerance", "from 0 to 500"),
        ({"refine_band": 1.5}, "refine_band", "from 0.01 to 1"),
        ({"refine_band": 0.001}, "refine_band", "from 0.01 to 1"),
        ({"side": "middle"}, "side", "right, left, both"),
        ({"inputs": {"body": {"sha256": "xyz"}}}, "inputs.body.sha256", "64"),
        ({"inputs": {"sample": "a", "body": {"path": "x"}}}, "inputs", "not both"),
        ({"colour": 1}, "colour", "unknown field"),
        ({"version": 3}, "version", "expected 1 or 2"),
        ({"view": {"matrix": "pass3"}}, "view.matrix", "pass1"),
        ({"version": [2]}, "version", "expected 1 or 2"),  # unhashable: found by the fuzz bench
        ({"version": {"v": 2}}, "version", "expected 1 or 2"),
        ({"view": {"matrix": ["pass1"]}}, "view.matrix", "pass1"),
        ({"view": {"camera": "top"}}, "view.camera", "three-quarter, front, side"),
        ({"view": {"camera": ["front"]}}, "view.camera", "three-quarter, front, side"),
        ({"view": {"trails": "yes"}}, "view.trails", 'expected true or false, got "yes"'),
        ({"view": {"follow": 1}}, "view.follow", "expected true or false, got 1"),
        ({"view": {"pick": None}}, "view.pick", "expected true or false, got null"),
        ({"view": {"orbit": 30}}, "view.orbit", "unknown field (known: matrix, frame, camera"),
        # a misspelt key gets the field it may have meant, as a link's does (stranger 14 F9)
        ({"tolerence": 2}, "tolerence", "unknown field (did you mean 'tolerance'? known: band,"),
        ({"view": {"camra": "front"}}, "view.camra", "(did you mean 'camera'? known: matrix"),
        ({"inputs": {"hnad": {"path": "h.bvh"}}}, "inputs.hnad", "(did you mean 'hand'?"),
        ({"inputs": {"body": {"nmae": "b"}}}, "inputs.body.nmae", "(did you mean 'name'?"),
        ({"roles": {"body": {"right.wrist": 3}}}, "", "roles.body: right.wrist"),
        ({"roles": {"body": {"right.wirst": "R"}}}, "", "did you mean right.wrist"),
        ({"roles": {"right": {"wrist": "R"}}}, "roles.right", "body, hand"),
    ],
)
def test_errors_name_the_field(data, field, words):
    with pytest.raises(SessionError) as info:
        from_dict(data, source="s.json")
    assert info.value.field == field
    if field.startswith("points["):  # a matching point is named as a user counts it
        assert str(info.value).startswith(f"s.json: {words}")
        assert "points[" not in str(info.value)
    else:
        assert str(info.value).startswith(f"s.json: {field}: " if field else "s.json: ")
    assert words in str(info.value)


@pytest.mark.parametrize(
    "text", ["", "[1, 2]", "{", '{"band": NaN}', '{"band": Infinity}', b"\xff\xfe", "[" * 100000]
)
def test_malformed_text_is_one_clear_error(text):
    with pytest.raises(SessionError):
        parse_session(text, source="bad.json")


def test_query_round_trip():
    spec = _spec()
    q = to_query(spec)
    assert q["pts"] == "10:12,40:35:0,90:99:7.5"
    assert from_query(q) == spec
    up = _spec(
        sample=None,
        body=TakeRef(sha256=HASH),
        hand=TakeRef(sha256="cd" * 32),
        view={},
        roles={"hand": {"right.wrist": "rHand"}},
    )
    assert from_query(to_query(up)) == up


def test_query_errors():
    with pytest.raises(SessionError, match=r"^URL: matching point 1: expected BODY:HAND or "):
        from_query({"pts": "1:2:3:4"})
    with pytest.raises(SessionError, match="band"):
        from_query({"band": "x"})
    with pytest.raises(SessionError, match=r"^URL: matching point 2 \(body 3, hand 9\): body"):
        from_query({"pts": "5:5,3:9"})
    with pytest.raises(SessionError, match="roles"):
        from_query({"roles": "{not json"})


_json = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(
            st.sampled_from(
                [
                    "inputs",
                    "points",
                    "band",
                    "side",
                    "body",
                    "hand",
                    "tolerance",
                    "sample",
                    "sha256",
                    "view",
                    "roles",
                    "x",
                ]
            ),
            inner,
            max_size=4,
        )
    ),
    max_leaves=20,
)


@settings(max_examples=300, deadline=None)
@given(_json)
def test_any_json_is_valid_or_session_error(data):
    try:
        spec = from_dict(data)
    except SessionError as exc:
        assert str(exc)
    else:
        assert from_dict(to_dict(spec)) == spec


def test_view_state_round_trips_through_file_and_link(tmp_path):
    """The app's view state (preview camera, hand trails, follow edits, pick mode) is saved
    and read back by the file and the link; the link carries only what is not the default."""
    view = {
        "matrix": "pass1",
        "frame": 5,
        "camera": "side",
        "trails": True,
        "follow": False,
        "pick": True,
    }
    spec = _spec(view=view)
    write_session(spec, tmp_path / "s.json")
    assert read_session(tmp_path / "s.json").view == view
    q = to_query(spec)
    assert (q["camera"], q["trails"], q["follow"], q["pick"]) == ("side", "1", "0", "1")
    assert from_query(q).view == view
    default = to_query(_spec(view={"frame": 0, **VIEW_DEFAULTS}))
    assert not set(VIEW_DEFAULTS) & set(default)  # links of default views read as before


@pytest.mark.parametrize(
    ("query", "field", "words"),
    [
        ({"camera": "top"}, "view.camera", "expected one of three-quarter, front, side"),
        ({"trails": "maybe"}, "view.trails", 'expected true or false, got "maybe"'),
        ({"pick": "2"}, "view.pick", 'expected true or false, got "2"'),
    ],
)
def test_bad_view_state_in_a_link_names_the_field(query, field, words):
    with pytest.raises(SessionError) as info:
        from_query({"sample": "demo", **query})
    assert info.value.field == field and str(info.value).startswith(f"URL: {field}: ")
    assert words in str(info.value)


def test_a_link_keeps_the_uploaded_files_names():
    """A link of an uploaded pair carries the files' names (``bname``, ``hname``), so the
    page, the CLI line, downloads and the session file name them as the sharer's did."""
    up = _spec(
        sample=None,
        body=TakeRef(sha256=HASH, name="walk <b>1</b>.bvh"),
        hand=TakeRef(sha256="cd" * 32, name="hand & co.bvh"),
        view={},
    )
    q = to_query(up)
    assert (q["bname"], q["hname"]) == ("walk <b>1</b>.bvh", "hand & co.bvh")
    assert from_query(q) == up
    # a bad name loses only the name: the take still opens by its hash
    spec, problems = read_query({**q, "bname": "x\x00y"})
    assert spec.body == TakeRef(sha256=HASH) and spec.hand == up.hand
    assert [p.field for p in problems] == ["bname"]  # the link's own key
    # a bad hash is said once, by its link key (stranger 8 read each twice, as
    # "inputs.body.sha256"); its name is not read
    spec, problems = read_query({**q, "body": "deadbeef", "hand": "00"})
    assert spec.body is None and spec.hand is None
    assert [str(p) for p in problems] == [
        'URL: body: expected 64 lowercase hex digits, got "deadbeef"',
        'URL: hand: expected 64 lowercase hex digits, got "00"',
    ]


@pytest.mark.parametrize(
    ("bad", "field"),
    [
        ({"band": "99"}, "band"),
        ({"refine": "-1"}, "refine_band"),
        ({"tol": "x"}, "tolerance"),
        ({"pts": "abc:1"}, "points[0].body"),
        ({"view": "<b>"}, "view.matrix"),
        ({"frame": "x"}, "frame"),
        ({"camera": "top"}, "view.camera"),
        ({"side": "middle"}, "side"),
        ({"roles": "{not json"}, "roles"),
    ],
)
def test_a_bad_link_value_is_left_out_and_the_rest_kept(bad, field):
    """One bad parameter refuses only itself, with the strict reader's one-line error; the
    takes and every good value are kept."""
    good = {
        "sample": "demo",
        "side": "left",
        "band": "0.4",
        "refine": "2s",
        "tol": "2",
        "pts": "10:12,40:35:1",
        "frames": "hand",
        "view": "pass2",
        "frame": "7",
        "camera": "front",
        "roles": '{"hand":{"right.wrist":"rHand"}}',
    }
    whole = from_query(good)
    spec, problems = read_query({**good, **bad})
    with pytest.raises(SessionError) as strict:
        from_query({**good, **bad})
    assert [str(p) for p in problems] == [str(strict.value)]
    assert problems[0].field == field
    if field == "points[0].body":
        assert str(problems[0]) == (
            "URL: matching point 1 (hand 1): expected a whole body frame number >= 0, got 'abc'"
        )
    assert spec.sample == "demo"
    key = {"band": "band", "refine_band": "refine_band", "tolerance": "tolerance"}
    kept = {
        "side": spec.side != whole.side,
        "band": spec.band != whole.band,
        "refine_band": spec.refine_band != whole.refine_band,
        "tolerance": spec.tolerance != whole.tolerance,
        "points[0].body": spec.points != whole.points,
        "view.matrix": spec.view.get("matrix") != whole.view["matrix"],
        "frame": spec.view.get("frame") != whole.view["frame"],
        "view.camera": spec.view.get("camera") != whole.view["camera"],
        "roles": spec.roles != whole.roles,
    }
    # only the bad value differs from the good link's (it takes its default)
    assert [k for k, differs in kept.items() if differs] == [key.get(field, field)]


def test_a_links_bad_point_leaves_out_only_itself_and_a_typo_key_is_said():
    """Stranger 11: ``pts=59:95,124:abc`` said point 2 was left out but dropped point 1 too;
    ``camra=hands`` (for camera) was dropped in silence."""
    spec, problems = read_query({"sample": "demo", "pts": "59:95,124:abc,130:140:2"})
    assert [(p.body, p.hand, p.tolerance) for p in spec.points] == [(59, 95, None), (130, 140, 2)]
    assert [str(p) for p in problems] == [
        "URL: matching point 2 (body 124): expected a whole hand frame number >= 0, got 'abc'"
    ]
    # the kept points still keep the order rules: one out of order is left out alone
    spec, problems = read_query({"sample": "demo", "pts": "59:95,x:1,40:20"})
    assert spec.points == (MatchPoint(59, 95),) and len(problems) == 2
    assert "matching point 3 (body 40, hand 20): body frame 40 is not after" in str(problems[1])
    spec, problems = read_query({"sample": "demo", "camra": "hands", "frame": "50"})
    assert spec.sample == "demo" and spec.view == {"frame": 50}
    assert len(problems) == 1 and str(problems[0]).startswith(
        "URL: camra: not a link parameter (did you mean 'camera'? known: sample, body, hand,"
    )
    with pytest.raises(SessionError, match="camra"):
        from_query({"sample": "demo", "camra": "hands"})
    # every key a link is made with is known
    full = SessionSpec(
        body=TakeRef(sha256=HASH, name="b.bvh"),
        hand=TakeRef(sha256=HASH, name="h.bvh"),
        tolerance=1.0,
        points=(MatchPoint(1, 2, 0),),
        roles={"hand": {"right.wrist": "rHand"}},
        view={"matrix": "pass2", "frame": 3, "camera": "front", "trails": True, "pick": True},
        max_unmatched_s=2.0,
    )
    query = to_query(full)
    assert {"bname", "hname", "unmatched", "frames", "pick", "trails"} <= set(query)
    assert read_query(query)[1] == ()


def test_a_links_point_out_of_order_leaves_out_only_itself():
    """Stranger 12: ``pts=649:1149,429:1799`` said point 2 was left out and dropped point 1
    too; each point is checked against the last one kept and named by its own number."""
    spec, problems = read_query({"sample": "demo", "pts": "649:1149,429:1799"})
    assert spec.points == (MatchPoint(649, 1149),)
    assert [str(p) for p in problems] == [
        "URL: matching point 2 (body 429, hand 1799): body frame 429 is not after matching "
        "point 1's body frame 649; body frames must increase from one point to the next"
    ]
    spec, problems = read_query({"sample": "demo", "pts": "1:1,5:5,3:3,7:7:2"})
    assert spec.points == (MatchPoint(1, 1), MatchPoint(5, 5), MatchPoint(7, 7, 2.0))
    assert [p.field for p in problems] == ["points[2]"]
    assert "matching point 2's body frame 5" in str(problems[0])
    assert to_query(spec)["pts"] == "1:1,5:5,7:7:2"


@pytest.mark.parametrize("bad", ["middle", "both"])
def test_a_links_bad_side_is_left_out_for_the_app_to_choose(bad):
    """Stranger 12: ``side=middle`` became right, and its message offered "both", which the
    page's Side control cannot show. Left out (like a missing side): the spec's side is
    None, the app's to choose (``Session._side_for``); a link without one names none."""
    spec, problems = read_query({"sample": "demo", "side": bad, "frame": "3"})
    assert spec.side is None and spec.view == {"frame": 3} and spec.sample == "demo"
    assert [str(p) for p in problems] == [f'URL: side: expected right or left, got "{bad}"']
    assert "side" not in to_query(spec) and "side" not in to_dict(spec)
    assert read_query({"sample": "demo"})[0].side is None
    assert read_query({"sample": "demo", "side": "left"})[0].side == "left"


def test_a_truncated_file_says_where_it_ends_in_a_whole_sentence():
    """Stranger 8 read "line 1: not valid JSON (Unterminated string starting at)"."""
    with pytest.raises(SessionError) as err:
        parse_session('{"format": "handsplice-sess', "cut.json")
    text = str(err.value)
    assert "cut.json" in text and "\n" not in text
    assert text.endswith("line 1, column 12: not valid JSON (unterminated string starting)")


def test_foreign_takes_is_the_one_rule_of_whose_session_this_is(tmp_path):
    """A session names its takes by sha256 (the app) or path; played on other files it is
    said, naming the take, the session's file and the given one (stranger 14 F3)."""
    from engine.io.session import TakeRef, foreign_takes, foreign_takes_warning

    wave, call, hello = (tmp_path / n for n in ("wave.bvh", "call.bvh", "hello.bvh"))
    for f in (wave, call, hello):
        f.write_text(f"not a take, only bytes of {f.name}\n")
    sha = {f: hashlib.sha256(f.read_bytes()).hexdigest() for f in (wave, call, hello)}
    app = SessionSpec(
        body=TakeRef(sha256=sha[wave], name="wave.bvh"),
        hand=TakeRef(sha256=sha[hello], name="hello.bvh"),
    )
    assert foreign_takes(app, wave, hello) == ()
    copy = tmp_path / "renamed.bvh"  # the same bytes under another name belong
    copy.write_bytes(wave.read_bytes())
    assert foreign_takes(app, copy, hello) == ()
    assert foreign_takes(app, call, hello) == (("body", "wave.bvh", "call.bvh"),)
    assert foreign_takes(app, call, wave) == (
        ("body", "wave.bvh", "call.bvh"),
        ("hand", "hello.bvh", "wave.bvh"),
    )
    text = foreign_takes_warning("s.json", foreign_takes(app, call, hello), points_used=True)
    assert text == (
        "s.json was made on body take wave.bvh, not call.bvh: "
        "its matching points were placed on that take"
    )
    both = foreign_takes_warning("s.json", foreign_takes(app, call, wave), points_used=False)
    assert both.endswith("not call.bvh and wave.bvh: its settings were tuned on those takes")
    assert foreign_takes_warning("s.json", (), points_used=True) is None
    # paths (relative to the session file's folder): the same file, the same bytes, or by name
    cli = SessionSpec(body=TakeRef(path="wave.bvh"), hand=TakeRef(path="gone/hello.bvh"))
    assert foreign_takes(cli, wave, hello, tmp_path) == ()
    assert foreign_takes(cli, copy, hello, tmp_path) == ()
    assert foreign_takes(cli, call, call, tmp_path) == (
        ("body", "wave.bvh", "call.bvh"),
        ("hand", "gone/hello.bvh", "call.bvh"),
    )
    # a sample pair's session, or one naming no takes: nothing to compare
    assert foreign_takes(SessionSpec(sample="wave-ok"), call, call) == ()
    assert foreign_takes(SessionSpec(), call, call) == ()
    # a name from the file stays on one line
    odd = SessionSpec(body=TakeRef(sha256=sha[wave], name="a\nb.bvh"))
    assert "\n" not in foreign_takes_warning("s.json", foreign_takes(odd, call, hello), True)
