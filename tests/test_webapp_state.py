"""The app's session state without a browser: set parameters, assert results."""

from __future__ import annotations

import json
from urllib.parse import parse_qsl, urlsplit

import numpy as np
import param
import pytest
from conftest import demo_config, demo_pair_uploaded

from engine.base.errors import HandSpliceError
from engine.dtw import constraints as C
from engine.io.session import MatchPoint, SessionError
from webapp import backend, config, uploads
from webapp.state import Session

DEMO = "wave-ok"


@pytest.fixture(scope="module")
def cfg(sample_dir, tmp_path_factory) -> config.AppConfig:
    return demo_config(sample_dir, tmp_path_factory)


@pytest.fixture
def session(cfg) -> Session:
    s = Session(cfg)
    s.load_sample(DEMO)
    assert s.error == ""
    return s


def _path_hits(path: np.ndarray, x: int, y: int, tol: float) -> bool:
    cols = path[path[:, 0] == x, 1]
    return bool(cols.size) and bool(np.all(np.abs(cols - y) <= tol))


def test_samples_json_lists_the_demo_pair(cfg):
    names = [p.name for p in cfg.samples()]
    assert DEMO in names
    assert config.demo_sample_name(cfg.sample_dir) == DEMO
    pair = cfg.sample(DEMO)
    assert pair.body.is_file() and pair.hand.is_file()
    with pytest.raises(KeyError, match="known: .*bye-hello.*wave-hello"):
        cfg.sample("nope")


def test_loading_the_demo_pair_solves_both_passes(session):
    sol = session.solution
    assert session.n == sol.pass1.band.n and session.m == sol.pass1.band.m
    assert 0 in sol.pass1.path[0].tolist()  # open ends: starts on the first row or column
    assert sol.pass1.path[-1][0] == session.n - 1 or sol.pass1.path[-1][1] == session.m - 1
    from engine.splice.pipeline import uses_spin

    if uses_spin(session.prepared.features):  # a hand take without a forearm: pass 2
        assert sol.pass2.band_cells == sol.pass1.band_cells  # compares turning, pass 1's band
    else:
        assert sol.pass2.band_cells < sol.pass1.band_cells  # pass 2 searches a narrower band
    assert sol.warp.shape == (session.n,)
    text = session.status_text()
    assert "pass 1 cost" in text and "band" in text and "ms" in text
    assert session.revision >= 1


def test_band_width_changes_band_and_is_undoable(session):
    cells = session.solution.pass1.band_cells
    session.band = 0.15
    assert session.solution.pass1.band_cells < cells
    assert session.can_undo
    session.undo()
    assert session.band == 0.3 and session.solution.pass1.band_cells == cells
    session.redo()
    assert session.band == 0.15


def test_matching_point_with_tolerance_reshapes_search_and_path(session):
    """Points are in the hand file's frames (40 fps here); the solver gets them on the
    alignment grid (the body's 30 fps)."""
    n = session.n
    x, y = n // 2, session.m_hand // 4  # well off the diagonal, in hand-file frames
    before = session.solution.pass1.path
    session.add_point(x, y, 0)
    ((gx, gy, gt),) = session.constraint_points()
    assert gx == x and gy == round(y * session.fps / session.hand_fps) and gt == 0
    sol = session.solution
    assert _path_hits(sol.pass1.path, x, gy, 0)
    assert _path_hits(sol.pass2.path, x, gy, 0)  # carried over to pass 2
    assert not np.array_equal(before, sol.pass1.path)
    assert abs(session.hand_frame_for(x) - y) <= 3  # in hand-file frames (merged warp)
    # a tolerance loosens the constraint: 4 hand frames = 3 grid columns (rounded up)
    session.set_point_tolerance(0, 4)
    assert session.constraint_points() == [(x, gy, 3.0)]
    band = session.solution.pass1.band
    assert band.lo[x] >= gy - 3 and band.hi[x] <= gy + 3 and band.hi[x] - band.lo[x] > 0
    assert _path_hits(session.solution.pass1.path, x, gy, 3)
    # the global tolerance applies to points without their own
    session.set_point_tolerance(0, None)
    session.tolerance = 2
    assert session.user_points() == [(x, y, 2.0)]
    assert _path_hits(session.solution.pass1.path, x, gy, 2)


def test_infeasible_points_are_rejected_and_leave_state_alone(session):
    session.add_point(40, 20, 0)
    rev, points, undo = session.revision, session.points, session.can_undo
    session.add_point(60, 10, 0)  # after (40, 20) in body frames but before it in hand frames
    assert session.error == (  # what the page's alert says
        "matching point 2 (body 60, hand 10): hand frame 10 is before matching point 1's hand "
        "frame 20; a path cannot go back in time, so hand frames must not decrease while body "
        "frames increase"
    )
    assert session.points == points and session.revision == rev and session.can_undo == undo
    session.add_point(session.n + 5, session.m_hand - 1, 0)
    assert "outside" in session.error and session.points == points


def test_view_edits_round_clip_and_sort(session):
    assert session.set_points_from_view([(80.4, 30.6, float("nan")), (20.2, 5.1, 3.0)])
    assert session.points == (MatchPoint(20, 5, 3.0), MatchPoint(80, 31))
    # dragged past the matrix edge: clipped to the last row; crossing the other point: refused
    assert not session.set_points_from_view([(20, 5, 3.0), (1e9, 2, None)])
    assert session.points == (MatchPoint(20, 5, 3.0), MatchPoint(80, 31))
    assert session.error.startswith(
        f"matching point 2 (body {session.n - 1}, hand 2): hand frame 2 is before matching "
        "point 1's hand frame 5;"
    )


def test_undo_redo_across_points_and_parameters(session):
    session.add_point(50, 20)
    session.move_point(0, 60, 25)
    session.tolerance = 3
    session.delete_point(0)
    assert session.points == ()
    assert session.undo() and session.points == (MatchPoint(60, 25),)
    assert session.undo() and session.tolerance == 0
    assert session.undo() and session.points == (MatchPoint(50, 20),)
    assert session.redo() and session.points == (MatchPoint(60, 25),)
    session.band = 0.2  # a new edit clears the redo stack
    assert not session.can_redo and not session.redo()


def test_undo_and_redo_say_what_they_did(session):
    """Stranger 6, finding 8: the page says what an Undo or Redo did (``history_note``)."""
    session.add_point(50, 20)
    session.move_point(0, 60, 25)
    assert session.history_note == ""
    assert session.undo()
    assert session.history_note == "Undid: matching point 1 moved (body 50 → 60, hand 20 → 25)"
    assert session.redo()
    assert session.history_note == "Redid: matching point 1 moved (body 50 → 60, hand 20 → 25)"
    session.tolerance = 3  # an edit of its own: the words go
    assert session.history_note == ""


def test_json_round_trip_restores_the_same_alignment(session, cfg):
    session.add_point(70, 30, 2)
    session.refine_band = 0.05
    text = session.to_json()
    other = Session(cfg)
    other.from_json(text, source="s.json")
    assert other.points == session.points and other.refine_band == 0.05
    assert other.solution.pass1.cost == pytest.approx(session.solution.pass1.cost)
    assert np.array_equal(other.solution.pass2.path, session.solution.pass2.path)
    with pytest.raises(SessionError) as info:
        other.from_json('{"points": [{"body": 5}]}', source="s.json")
    assert str(info.value) == (
        "s.json: matching point 1 (body 5): expected a hand frame, none was given"
    )


def test_url_round_trip_restores_the_state(session, cfg):
    session.add_point(90, 40, 1.5)
    session.tolerance = 2
    session.matrix = "pass2"
    url = session.share_url("http://127.0.0.1:5006/")
    query = dict(parse_qsl(urlsplit(url).query))
    assert query["sample"] == DEMO and query["pts"] == "90:40:1.5"
    other = Session(cfg)
    other.from_query(query)
    assert other.to_spec() == session.to_spec()
    assert other.solution.pass1.cost == pytest.approx(session.solution.pass1.cost)


def test_view_state_is_saved_and_restored_by_file_and_link(session, cfg):
    """Camera, trails, follow edits and pick mode live in the session: its file and link
    restore them; a file or link without them (made before) gives the defaults."""
    session.param.update(camera="front", trails=True, follow=False, pick=True)
    view = {"camera": "front", "trails": True, "follow": False, "pick": True}
    for restore in (
        lambda s: s.from_json(session.to_json(), source="s.json"),
        lambda s: s.from_query(dict(parse_qsl(urlsplit(session.share_url("/")).query))),
    ):
        other = Session(cfg)
        restore(other)
        assert {k: getattr(other, k) for k in view} == view and not other.error
        assert other.to_spec() == session.to_spec()
    old = json.loads(session.to_json())
    old["view"] = {"matrix": "pass1", "frame": 3}  # a file written before the view state
    other = Session(cfg)
    other.param.update(camera="side", trails=True, follow=False, pick=True)
    other.from_json(json.dumps(old), source="old.json")
    assert (other.camera, other.trails, other.follow, other.pick) == (
        "three-quarter",
        False,
        True,
        False,
    )


def test_bad_view_state_is_refused_and_changes_nothing(session):
    session.param.update(camera="side", trails=True)
    before = _snapshot(session)
    spec = json.loads(session.to_json())
    spec["view"]["camera"] = "<b>top</b>"
    with pytest.raises(SessionError, match=r"^bad.json: view.camera: expected one of"):
        session.from_json(json.dumps(spec), source="bad.json")
    with pytest.raises(SessionError, match=r"^URL: view.trails: expected true or false"):
        session.from_query({"sample": DEMO, "trails": "sometimes"})
    assert _snapshot(session) == before and (session.camera, session.trails) == ("side", True)


def test_preview_and_matrix_widgets_are_the_sessions_view_state(session):
    """The preview's camera, trails and follow boxes and the matrix's click mode read and
    write the session (so a restored session shows in them, and they save with it)."""
    from webapp.views.cost_matrix import CostMatrixView
    from webapp.views.preview import PreviewView

    session.param.update(camera="side", pick=True)
    preview, matrix = PreviewView(session), CostMatrixView(session)
    assert preview.camera.value == "side" and matrix.point_tool.add is False
    preview.trails.value = True
    preview.auto.value = False
    assert session.trails and not session.follow
    assert preview._key()[3:] == ("side", True)
    session.pick = False
    assert matrix.point_tool.add is True
    session.camera = "front"
    assert preview.camera.value == "front"
    session.param.update(camera="side", trails=False)  # together (a session file): one render
    assert preview._key()[3:] == ("side", False)


def test_two_sessions_are_independent(cfg):
    a, b = Session(cfg), Session(cfg)
    a.load_sample(DEMO)
    b.load_sample(DEMO)
    assert a.prepared is b.prepared  # the per-pair features are shared, read-only
    a.add_point(60, 20, 0)
    a.band = 0.2
    assert b.points == () and b.band == 0.3
    assert b.solution is not a.solution
    assert not _path_hits(b.solution.pass1.path, 60, 20, 0) or _path_hits(
        a.solution.pass1.path, 60, 20, 0
    )
    b.undo()  # nothing to undo in b
    assert a.points == (MatchPoint(60, 20, 0),)


def test_cost_views_at_screen_resolution_and_full_detail(session):
    n, m = session.n, session.m
    full = session.cost_view((-0.5, n - 0.5, -0.5, m - 0.5), 600)
    assert full.stride == (1, 1) and full.image.shape == (n, m)
    assert np.all(np.isfinite(full.image))
    coarse = session.cost_view((-0.5, n - 0.5, -0.5, m - 0.5), 40)
    assert coarse.stride[0] > 1 and coarse.image.shape[0] <= 40 and coarse.image.shape[1] <= 40
    zoom = session.cost_view((50, 70, 10, 20), 40)  # zoomed in: every cell again
    assert (
        zoom.stride == (1, 1)
        and zoom.x0 == 50
        and zoom.image.shape == (zoom.x1 - 50, zoom.y1 - zoom.y0)
    )
    assert np.allclose(zoom.image, full.image[50 : zoom.x1, zoom.y0 : zoom.y1])
    session.matrix = "cumulative1"
    cum = session.cost_view((-0.5, n - 0.5, -0.5, m - 0.5), 600).image
    band = session.solution.pass1.band
    assert np.isnan(cum[0, band.hi[0] + 1 :]).all() and np.isfinite(cum[n - 1, m - 1])
    # open ends: the pass cost is γ at the path's end (its start's skip cost included) plus
    # the skip cost of the frames after the end
    p1 = session.solution.pass1
    i1, j1 = p1.path[-1]
    skipped = ((n - 1 - i1) + (m - 1 - j1)) * p1.alignment.ends.skip
    assert cum[i1, j1] + skipped == pytest.approx(p1.cost, rel=1e-6)


def test_cumulative_view_too_large_is_refused_with_a_message(cfg, monkeypatch):
    from engine.splice import pipeline

    # as for a long pair: no tabulated pass-1 costs and no solver kept (one-shot solves)
    monkeypatch.setattr(backend, "DENSE_PASS1_MAX_CELLS", 0)
    monkeypatch.setattr(backend, "_PREPARED", {})  # not the server-wide cache of prepared pairs
    monkeypatch.setattr(backend, "_PREPARED_ORDER", [])
    monkeypatch.setattr(pipeline, "INCREMENTAL_MAX_CELLS", 0)
    monkeypatch.setattr(pipeline, "CUMULATIVE_MAX_CELLS", 100)
    s = Session(cfg)
    s.load_sample(DEMO)
    assert s.error == "" and s.solution.pass1.band_cells > 100
    s.matrix = "cumulative1"
    assert s.cost_view((-0.5, s.n - 0.5, -0.5, s.m - 0.5), 100) is None
    assert "cumulative-cost view" in s.error and "limit 100" in s.error
    s.matrix = "pass1"  # the local cost still shows
    assert s.cost_view((-0.5, s.n - 0.5, -0.5, s.m - 0.5), 100).image.size > 0


def test_spliced_take_and_downloads(session):
    session.add_point(90, 40, 2)
    motion = session.spliced()
    assert motion.rotations.shape[0] == session.n
    bvh = backend.bvh_bytes(motion).decode()
    assert bvh.startswith("HIERARCHY") and "MOTION" in bvh
    assert session.output_stem() == f"{DEMO}-spliced"
    i, j, k = backend.frame_triplet(session.prepared, session.solution, 90)
    assert i == k == 90 and 0 <= j < session.prepared.features.m_hand


def test_uploads_store_by_hash_and_reject_bad_files(cfg, sample_dir, session):
    pair = cfg.sample(DEMO)
    data = pair.body.read_bytes()
    digest, take = uploads.store(cfg, "my body.bvh", data)
    assert digest == uploads.sha256(data) and uploads.path_for(cfg, digest).is_file()
    assert take.rotations.shape[0] == session.n
    with pytest.raises(uploads.UploadError, match=r"broken\.bvh.*line"):
        uploads.store(cfg, "broken.bvh", b"HIERARCHY\nROOT Hips\n{\n OFFSET 0 0\n")
    with pytest.raises(uploads.UploadError, match="upload limit"):
        uploads.store(cfg, "big.bvh", b"x" * (cfg.max_upload_bytes + 1))
    with pytest.raises(uploads.UploadError, match=r"\.bvh, \.c3d or \.trc"):
        uploads.store(cfg, "notes.txt", b"hello")
    with pytest.raises(uploads.UploadError, match="empty"):
        uploads.store(cfg, "empty.trc", b"")
    for bad in ("../../etc/passwd", "ab" * 31, "AB" * 32):
        with pytest.raises(uploads.UploadError, match="64-digit hex"):
            uploads.path_for(cfg, bad)
    assert not list(cfg.upload_dir.glob(".check-*"))  # no staging files left behind


def test_upload_folder_problems_are_one_line_upload_errors(cfg, tmp_path, monkeypatch):
    import dataclasses

    good = cfg.sample(DEMO).hand.read_bytes()
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("x")
    bad_dir = dataclasses.replace(cfg, upload_dir=blocker / "uploads")
    with pytest.raises(uploads.UploadError) as info:  # mkdir fails (a file is in the way)
        uploads.store(bad_dir, "hand.bvh", good)
    msg = str(info.value)
    assert msg.startswith("hand.bvh: the server cannot store uploads (") and "\n" not in msg
    assert str(tmp_path) not in msg  # no server paths shown to the user

    def denied(path):
        raise PermissionError(13, "Permission denied", str(path))

    other = dataclasses.replace(cfg, upload_dir=tmp_path / "up")
    monkeypatch.setattr(uploads, "_open_staging", denied)
    with pytest.raises(
        uploads.UploadError,
        match=r"^body\.bvh: the server cannot store "
        r"uploads \(permission denied\)$",
    ):
        uploads.store(other, "body.bvh", good)
    assert not list((tmp_path / "up").iterdir())


def test_upload_limit_has_one_source():
    import argparse

    from engine.base.limits import MAX_UPLOAD_BYTES
    from webapp import serve_cli as serve

    assert config.AppConfig().max_upload_bytes == MAX_UPLOAD_BYTES
    parser = argparse.ArgumentParser()
    serve.add_parser(parser.add_subparsers())
    args = parser.parse_args(["serve"])
    assert int(args.max_upload_mb * 2**20) == MAX_UPLOAD_BYTES


def test_w2_is_greyed_out_where_pass_2_compares_the_hand_turning(cfg):
    """A hand take without a forearm (the demo's Leap hand) is timed in pass 2 by how the
    hand turns, inside the whole pass-1 band: W2 changes nothing there, so its controls are
    disabled with the reason beside them and the pass-2 title names that metric. A hand
    take with a forearm (BEAT) keeps W2 and D2."""
    from webapp.state import MATRIX_LABELS, PASS2_SPIN_LABEL
    from webapp.views.controls import parameter_widgets

    s = Session(cfg)
    s.load_sample(DEMO)
    layout = parameter_widgets(s)
    # widths, their notes (W1's: why an open-end band narrows little), the tolerance and
    # the unmatched-end limit with its note
    (w1, _, w1_s, _, w2, _, w2_s, _, _, _), note = layout[0], layout[1]
    s.matrix = "pass2"
    assert s.pass2_turns_hand() and s.matrix_label() == PASS2_SPIN_LABEL
    assert w2.disabled and w2_s.disabled and not w1.disabled and not w1_s.disabled
    assert note.visible and "W2 is not used" in note.object
    before = s.solution.warp.copy()
    assert s.set_constraints(refine_band=0.5)
    assert np.array_equal(s.solution.warp, before)  # what the note says: W2 changes nothing
    s.load_sample("beat-self")
    assert not s.pass2_turns_hand() and s.matrix_label() == MATRIX_LABELS["pass2"]
    assert not w2.disabled and not w2_s.disabled and not note.visible


def test_widths_typed_in_seconds_are_checked_edits(session):
    """The seconds fields go through the session's rules: a value out of range (or not a
    number) is refused in one line, the width in force stays and the field keeps what was
    typed, to be corrected; a value in range greys out its fraction slider; emptied, the
    fraction is in force again."""
    from webapp.views.controls import parameter_widgets

    (w1, _, w1_s, *_), *_ = parameter_widgets(session)  # slider, its note, seconds
    before, fraction = session.to_spec(), session.band
    w1_s.value = "1e9"
    assert session.error.startswith("W1 in seconds: expected seconds from")
    assert w1_s.value == "1e9" and session.band_s is None and session.to_spec() == before
    w1_s.value = "abc"
    assert session.error.startswith("W1 in seconds: ") and "got 'abc'" in session.error
    assert w1_s.value == "abc" and session.band_s is None
    w1_s.value = "2"
    assert session.error == "" and session.band_s == 2.0 and w1.disabled
    w1_s.value = "2.50s"
    assert session.band_s == 2.5 and w1_s.value == "2.5"
    w1_s.value = ""
    assert session.band_s is None and not w1.disabled and session.band == fraction


def test_the_status_names_body_frames_left_without_a_hand_match(session):
    """Open ends leave the demo's first and last body frames unmatched (its hand take is
    shorter than the wave): the status line says which, as the CLI does."""
    from engine.splice.report import unmatched_summary

    ranges = session.solution.cache["engine"].unmatched_body
    assert ranges and ranges[0][0] == 0
    text = unmatched_summary(ranges, session.fps, front="page")
    assert text.startswith(f"body frames {ranges[0][0]}-{ranges[0][1]}")
    assert text in session.status_text()
    # sample_data/README.md says what the demo does (it said the hand stays still on
    # 'about 1 %' of body frames while 53 of 187 have no hand match)
    import re

    from conftest import ROOT

    readme = (ROOT / "sample_data" / "README.md").read_text()
    quoted = re.search(r"`(body frames [^`]* have no hand match)`", readme)
    assert quoted and quoted.group(1) in session.status_text(), quoted
    frames = sum(b - a + 1 for a, b in ranges)
    share = re.search(r"\((\d+) of (\d+), [\d.]+ s, (\d+) %\)", readme)
    assert share and (int(share.group(1)), int(share.group(2))) == (frames, session.n)
    assert int(share.group(3)) == round(100 * frames / session.n)
    # neither end reached the open-end limit: the data cut them
    limit = session.solution.cache["engine"].unmatched_limit(session.fps)
    assert limit and all(b - a + 1 < limit for a, b in ranges)
    assert "open-end limit" not in session.status_text()


def test_an_unmatched_end_cut_by_the_open_end_limit_says_so():
    """An end as long as the default limit (for the body take: the length difference
    plus half the shorter take; a 33 s 120 fps hand is 1000 grid frames at 30 fps) was
    cut by the limit, not the data, and the sentence names the rule."""
    from engine.splice.pipeline import unmatched_limits
    from engine.splice.report import unmatched_summary

    assert unmatched_limits(4587, 1000, 30.0, None) == (4087, 500)
    ranges = [(0, 499), (4087, 4586)]
    text = unmatched_summary(ranges, 30.0, 500)
    assert text.startswith("body frames 0-499, 4087-4586 (33.3 s) have no hand match")
    assert (
        "500 frames (16.7 s) at an end is the open-end limit (half the shorter take, "
        "plus the length difference for the longer one)" in text
    )
    assert "--max-unmatched SECONDS" in text
    assert "limit" not in unmatched_summary([(0, 120)], 30.0, 500)
    assert "(--max-unmatched)" in unmatched_summary([(0, 14)], 30.0, 15, limit_given=True)


def test_the_printed_url_of_a_pair_opened_from_disk_opens_it(tmp_path):
    """``serve BODY HAND --show-url`` prints a link whose ``sample`` is the pair's name
    ("BODY + HAND", spaces and a plus sign) as the page reads it back."""
    from urllib.parse import parse_qs

    from conftest import MOCAP

    from webapp import serve_cli as serve

    pair = config.local_pair(
        MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh",
        MOCAP / "gestification" / "fingers-ok.bvh",
        "right",
    )
    assert " + " in pair.name
    link = serve.sample_url("http://127.0.0.1:5006/", pair.name)
    assert " " not in link
    assert parse_qs(urlsplit(link).query)["sample"] == [pair.name]


def test_session_on_uploaded_files(cfg):
    s, body, hand = demo_pair_uploaded(cfg)
    query = s.to_query()
    assert query["body"] == body and "sample" not in query
    other = Session(cfg)
    other.from_query(query)
    assert other.solution.pass1.cost == pytest.approx(s.solution.pass1.cost)
    missing = Session(cfg)
    with pytest.raises(uploads.UploadError, match="no such file"):
        missing.from_query({"body": "0" * 64, "hand": hand})
    assert missing.solution is None and missing.body_sha256 is None


def _snapshot(s: Session) -> tuple:
    return (
        s.to_spec(),
        s.solution,
        s.prepared,
        s.n,
        s.m,
        s.revision,
        s.inputs_revision,
        s.can_undo,
    )


def test_bad_session_file_or_link_leaves_the_working_session_alone(session, cfg):
    """Everything is resolved and solved before anything changes: a bad file or link raises
    and the working session (takes, parameters, points, path, undo) is untouched."""
    session.add_point(50, 20, 1)
    session.band = 0.25
    before = _snapshot(session)
    good_hand, _ = uploads.store(cfg, "hand.bvh", cfg.sample(DEMO).hand.read_bytes())
    files = [
        ({"inputs": {"sample": "nope"}, "band": 0.5}, "nope"),
        ({"inputs": {"body": {"sha256": "0" * 64}, "hand": {"sha256": good_hand}}}, "no such file"),
        ({"inputs": {"body": {"sha256": good_hand}}}, "inputs.hand"),
        ({"inputs": {"sample": "wave-hello"}, "points": [{"body": 5000, "hand": 3}]}, "outside"),
        (
            {"inputs": {"sample": "wave-hello"}, "roles": {"body": {"right.wrist": "NoSuchJoint"}}},
            "NoSuchJoint",
        ),
        ({"inputs": {"sample": DEMO}, "side": "both"}, "right or left"),
    ]
    for data, message in files:
        with pytest.raises((HandSpliceError, KeyError, ValueError), match=message):
            session.from_json(json.dumps(data), source="bad.json")
        assert _snapshot(session) == before, data
    for query, message in [
        ({"sample": "nope", "band": "0.5"}, "nope"),
        ({"body": "0" * 64, "hand": "1" * 64, "pts": "1:2"}, "no such file"),
        ({"pts": "5000:3"}, "outside"),
    ]:
        with pytest.raises((HandSpliceError, KeyError, ValueError), match=message):
            session.from_query(query)
        assert _snapshot(session) == before, query
    # parameters without inputs apply to the takes already open
    session.from_query({"band": "0.4", "pts": "30:10", "frames": "hand"})
    assert session.sample == DEMO and session.band == 0.4
    assert session.points == (MatchPoint(30, 10),) and not session.can_undo
    assert _path_hits(session.solution.pass1.path, 30, session.constraint_points()[0][1], 0)


def test_a_bad_link_opens_the_demo_and_says_why(cfg):
    from webapp import app

    s = Session(cfg)
    app._initial_state(s, {"sample": "nope", "pts": "1:2"})
    assert s.sample == DEMO and s.solution is not None and s.points == ()
    assert s.error.startswith("shared link:") and "nope" in s.error
    assert "nope" not in s.share_url() and "pts" not in s.to_query()  # the link shows the demo
    ok = Session(cfg)
    app._initial_state(ok, {"sample": "wave-hello", "pts": "30:10:2", "frames": "hand"})
    assert ok.sample == "wave-hello" and ok.points == (MatchPoint(30, 10, 2.0),) and not ok.error
    # a link made before hand frames were the hand file's own: grid column 10 at 30 fps is
    # hand frame 12 of the 37 fps hand file (tolerance likewise)
    old = Session(cfg)
    app._initial_state(old, {"sample": "wave-hello", "pts": "30:10:2"})
    assert old.points == (MatchPoint(30, 12, 2.469),) and not old.error
    # and said (stranger 14 F5: a hand-written 40:7 became 40:9 silently)
    assert "no frames=hand" in old.link_notice and "frames=hand" not in ok.link_notice


def test_a_link_without_takes_means_one_thing_on_every_front(cfg):
    """A link of parameters only (``?frame=75``) opens the default pair with them whether the
    page opens it (app._initial_state) or a caller gives it to a fresh Session (open_link,
    from_query) or a session file has no inputs; with takes open it applies to them; with
    neither takes nor a default pair it is refused in one line."""
    from dataclasses import replace

    from engine.io.session import SessionSpec, format_session
    from webapp import app

    query = {"frame": "75", "band": "0.4", "pts": "30:10", "frames": "hand"}
    page = Session(cfg)
    app._initial_state(page, dict(query))
    linked, parsed, filed = Session(cfg), Session(cfg), Session(cfg)
    linked.open_link(dict(query))
    parsed.from_query(dict(query))
    filed.from_json(
        format_session(SessionSpec(band=0.4, points=((30, 10),), view={"frame": 75})),
        source="params.json",
    )
    for s in (page, linked, parsed, filed):
        assert (s.sample, s.frame, s.band, s.points) == (DEMO, 75, 0.4, (MatchPoint(30, 10),))
        assert not s.error and s.solution is not None
        assert s.to_query() == page.to_query()
    # takes already open: the link's values apply to them
    other = Session(cfg)
    other.load_sample("wave-hello")
    other.open_link(dict(query))
    assert (other.sample, other.frame, other.band) == ("wave-hello", 75, 0.4)
    # no takes and no default pair: nothing to apply them to
    bare = Session(replace(cfg, default_sample=None))
    with pytest.raises(SessionError, match=r"^inputs: expected a sample .*none are open"):
        bare.from_query(dict(query))
    assert bare.solution is None and bare.sample is None


def test_opening_a_bad_session_file_in_the_page_keeps_the_session(session, cfg):
    from webapp.views.inputs import InputsView
    from webapp.views.sharing import SharingView

    inputs = InputsView(session)
    view = SharingView(session)
    session.add_point(40, 20, 0)
    before = _snapshot(session)
    view.open_session.filename = "bad.json"
    view.open_session.value = b'{"inputs": {"sample": "nope"}, "band": 0.5}'
    assert view.message.visible and "session file: " in view.message.object
    assert "nope" in view.message.object and _snapshot(session) == before
    other = Session(cfg)
    other.load_sample("wave-hello")
    other.add_point(30, 10, 2)
    view.open_session.filename = "good.json"
    view.open_session.value = other.to_json().encode()
    assert not view.message.visible and session.to_spec() == other.to_spec()
    assert inputs.sample.value == "wave-hello" and "wave-hello" in view.link.value


def test_a_finished_downloads_line_goes_with_its_pair(session):
    """Stranger 11: "spliced BVH: ... handed to your browser" stayed under another pair's
    buttons after the Sample pair changed; it goes with its pair."""
    import asyncio

    from webapp.views.sharing import SENT, SharingView

    view = SharingView(session)
    data = asyncio.run(view._bvh())  # the BVH button's own coroutine
    assert data is not None and data.size > 0
    assert view.prepare_text.visible and SENT in view.prepare_text.object
    session.add_point(40, 20, 0)  # an edit of the same pair keeps it
    assert view.prepare_text.visible
    session.load_sample("wave-hello")
    assert not view.prepare_text.visible


def test_the_link_follows_the_preview_frame(session):
    """Stranger R4-5: the frame moved (the preview's slider writes ``frame``) is in the
    link field at once (without a server; a page's link follows it
    once the frame rests, tests/test_browser_links.py)."""
    from webapp.views.preview import PreviewView
    from webapp.views.sharing import SharingView

    preview, view = PreviewView(session), SharingView(session)
    assert "frame=0" in view.link.value
    preview.slider.value = 57  # the slider, as a person moves it
    assert session.frame == 57 and "frame=57" in view.link.value, view.link.value
    assert dict(parse_qsl(urlsplit(view.link.value).query))["frame"] == "57"


def test_session_json_with_paths_is_refused_by_the_app(cfg):
    s = Session(cfg)
    with pytest.raises(SessionError, match="inputs.body"):
        s.from_json('{"inputs": {"body": {"path": "/etc/passwd"}, "hand": {"path": "x"}}}')


def test_create_app_builds_a_page_with_the_css_hooks(cfg, monkeypatch):
    from bokeh.document import Document

    from webapp import app

    monkeypatch.setattr(config, "_CONFIG", cfg)
    page = app.create_app()
    assert page.session.sample == DEMO and page.session.solution is not None
    root = page.get_root(Document())
    classes = set()
    for model in root.references():
        classes.update(getattr(model, "css_classes", None) or [])
    assert {"hs-cost-matrix", "hs-status", "hs-points"} <= classes


def test_role_overrides_reprepare_and_travel_with_the_session(cfg):
    s = Session(cfg)
    s.load_sample(DEMO)
    cost = s.solution.pass1.cost
    assert s.set_roles({"body": {"right.wrist": "Hand_R", "right.elbow": "LowerArm_R"}})
    assert s.error == "" and s.solution.pass1.cost == pytest.approx(cost)  # same joints
    assert s.to_spec().roles == {"body": {"right.wrist": "Hand_R", "right.elbow": "LowerArm_R"}}
    other = Session(cfg)
    other.from_query(s.to_query())
    assert other.roles == s.roles
    # a joint name the take does not have: the reason is shown, the alignment is kept
    assert not s.set_roles({"body": {"right.wrist": "NoSuchJoint"}})
    assert "NoSuchJoint" in s.error and s.solution is not None
    assert not s.set_roles({"body": {"right.wirst": "Hand_R"}})
    assert "right.wirst" in s.error
    assert s.roles == {"body": {"right.wrist": "Hand_R", "right.elbow": "LowerArm_R"}}


def test_matrix_view_refetches_the_visible_range_at_full_detail(session):
    from webapp.views.cost_matrix import CostMatrixView

    view = CostMatrixView(session, max_pixels=40)
    img = view.image_source.data["image"][0]
    assert img.shape[0] <= 40 and img.shape[1] <= 40  # whole matrix, downsampled
    assert "1 pixel" in view.title.object

    class Ranges:  # what Bokeh's RangesUpdate carries
        x0, x1, y0, y1 = 100.0, 120.0, 20.0, 35.0

    view._on_range(Ranges())  # outside a server: fetched at once
    data = view.image_source.data
    rows = round(data["dh"][0] / session.hand_scale)  # dh in hand-file frames
    assert data["image"][0].shape == (rows, data["dw"][0])  # one pixel per cell
    assert data["x"][0] == pytest.approx(99.5) and "1 pixel" not in view.title.object
    # band, path and points follow the session
    session.add_point(90, 40, 2)
    assert list(view.points_source.data["x"]) == [90]
    # the red line is the alignment used (pipeline.alignment_pass): pass 1 or pass 2
    used = session.solution.pass1 if view._used_pass() == 1 else session.solution.pass2
    assert len(view.path_source.data["x"]) == len(used.path)
    r = session.hand_scale  # drawn in hand-file frames
    assert np.allclose(view.band_source.data["lo"], (session.solution.pass1.band.lo - 0.5) * r)
    session.matrix = "pass2"
    assert len(view.path_source.data["x"]) == len(session.solution.pass2.path)


def _served_document(*roots):
    """A Bokeh document holding ``roots``, served by a real (connection-less) server
    session."""
    import weakref

    from bokeh.document import Document
    from bokeh.server.contexts import BokehSessionContext
    from bokeh.server.session import ServerSession

    doc = Document()
    for root in roots:
        doc.add_root(root)
    session = ServerSession("s", doc, io_loop=None)
    context = BokehSessionContext("s", None, doc)
    context._set_session(session)
    doc._session_context = weakref.ref(context)
    doc._hs_context = context  # kept alive with the document
    return doc, session


@pytest.fixture
def two_tabs(monkeypatch):
    """A view whose ``draw`` changes a model under the document lock, its tab (``tab``,
    ``tab_session``) and another tab (``other``, ``other_session``), both served by real
    (connection-less) server sessions; each tab's next-tick callbacks are collected in
    ``ticks[id(doc)]`` instead of being run."""
    from types import SimpleNamespace

    from bokeh.models import ColumnDataSource

    from webapp.views._dispatch import with_document_lock

    class View:
        def __init__(self):
            self.source = ColumnDataSource({"x": [0]})

        @with_document_lock
        def draw(self, x):
            self.source.data = {"x": [x]}

    view = View()
    tab, tab_session = _served_document(view.source)  # the view's tab
    other, other_session = _served_document()
    ticks = {id(tab): [], id(other): []}
    for d in (tab, other):
        monkeypatch.setattr(d, "add_next_tick_callback", ticks[id(d)].append)
    return SimpleNamespace(
        view=view,
        tab=tab,
        tab_session=tab_session,
        other=other,
        other_session=other_session,
        ticks=ticks,
    )


def test_model_changes_wait_for_the_document_lock(two_tabs, monkeypatch):
    """Outside Bokeh's document lock (a Panel widget callback run on the event loop) a view's
    model change is deferred to a next-tick callback of the view's own document (not of the
    document whose callback is running: another tab's) and runs under that document's lock;
    once that tab's session is discarded the change is dropped. Inside the lock it runs at
    once."""
    import asyncio

    import panel as pn

    from webapp.views._dispatch import next_tick

    view, tab, tab_session = two_tabs.view, two_tabs.tab, two_tabs.tab_session
    other, scheduled = two_tabs.other, two_tabs.ticks  # other: the tab whose callback runs
    monkeypatch.setattr(type(pn.state), "curdoc", property(lambda self: other))

    view.draw(1)  # no lock held: deferred to the view's document
    assert view.source.data["x"] == [0] and not scheduled[id(other)]
    (later,) = scheduled[id(tab)]
    asyncio.run(tab_session.with_document_locked(later))  # as bokeh runs a next tick
    assert view.source.data["x"] == [1]

    next_tick(tab, lambda: view.draw(2))  # a callback the app scheduled on the tab
    asyncio.run(tab_session.with_document_locked(scheduled[id(tab)][-1]))  # lock held: at once
    assert view.source.data["x"] == [2] and len(scheduled[id(tab)]) == 2

    view.draw(3)  # deferred; then the tab closes before the next tick
    later = scheduled[id(tab)][-1]
    tab_session.destroy()
    later()  # dropped without an error: nobody is there to see it


def test_only_code_that_holds_the_lock_changes_models_at_once(two_tabs):
    """The run-now-or-defer decision follows who holds the lock, not whether somebody does:
    a worker thread, an asyncio task outliving the callback that started it and a callback
    holding another tab's lock all defer the change (made at once there, Bokeh would send
    it from outside the lock, or raise); the deferred change then runs under the tab's
    lock, accepted by Bokeh's real session."""
    import asyncio

    from webapp.views._dispatch import next_tick

    view, tab, tab_session = two_tabs.view, two_tabs.tab, two_tabs.tab_session
    other, other_session, ticks = two_tabs.other, two_tabs.other_session, two_tabs.ticks

    def run_ticks(doc, session):  # as Bokeh runs next-tick callbacks: one by one, locked
        while ticks[id(doc)]:
            asyncio.run(session.with_document_locked(ticks[id(doc)].pop(0)))

    # 1. a worker thread, while a callback on the loop holds the tab's lock and waits for it
    async def holds_the_lock_meanwhile():
        await asyncio.get_running_loop().run_in_executor(None, view.draw, 1)

    asyncio.run(tab_session.with_document_locked(holds_the_lock_meanwhile))
    assert view.source.data["x"] == [0] and len(ticks[id(tab)]) == 1
    run_ticks(tab, tab_session)
    assert view.source.data["x"] == [1]

    # 2. a task started by a locked callback runs after it, when the lock is released
    async def starts_a_task():
        tasks = []

        async def task():
            view.draw(2)

        next_tick(tab, lambda: tasks.append(asyncio.get_running_loop().create_task(task())))
        await tab_session.with_document_locked(ticks[id(tab)].pop())
        await tasks[0]

    asyncio.run(starts_a_task())
    assert view.source.data["x"] == [1] and len(ticks[id(tab)]) == 1
    run_ticks(tab, tab_session)
    assert view.source.data["x"] == [2]

    # 3. a callback holding another tab's lock
    next_tick(other, lambda: view.draw(3))
    run_ticks(other, other_session)
    assert view.source.data["x"] == [2] and len(ticks[id(tab)]) == 1
    run_ticks(tab, tab_session)
    assert view.source.data["x"] == [3]

    # a callback holding the tab's own lock: at once (nothing deferred), accepted
    next_tick(tab, lambda: view.draw(4))
    asyncio.run(tab_session.with_document_locked(ticks[id(tab)].pop()))
    assert view.source.data["x"] == [4] and not ticks[id(tab)]


def test_teaching_example_steps_through_the_recurrence():
    from webapp.views.teaching import TeachingModel, TeachingView

    model = TeachingModel()
    assert model.cost.shape == (12, 10) and model.current() is None
    model.step = len(model.order)  # the last cell
    g, d = model.gamma, model.cost
    for i, j in model.order[1:]:  # eq. 2 holds in every band cell the solver filled
        preds = [
            g[a, b]
            for a, b in ((i - 1, j - 1), (i - 1, j), (i, j - 1))
            if a >= 0 and b >= 0 and np.isfinite(g[a, b])
        ]
        assert g[i, j] == pytest.approx(d[i, j] + min(preds))
    assert g[11, 9] == pytest.approx(model.alignment.cost) and model.finished
    model.step = 5
    i, j = model.current()
    assert f"γ({i}, {j}) = D({i}, {j}) + min(" in model.explain()
    # a narrower band searches fewer cells; a matching point pins the path
    cells = model.band.area
    model.width = 0.3
    assert model.band.area < cells
    model.param.update(use_point=True, point_body=6, point_hand=3, point_tol=0)
    path = model.alignment.path
    assert path[path[:, 0] == 6, 1].tolist() == [3]
    assert "T = 0" in model.band_text()
    # value- and sign-based costs give different alignments of the amplitude-shrunk hand
    model.use_point = False
    sign_path = model.alignment.path
    model.metric = "value"
    assert not np.array_equal(sign_path, model.alignment.path)
    view = TeachingView(model)
    assert len(view.cells.data["i"]) == 120


def test_video_export_runs_off_the_event_loop_with_progress(session, monkeypatch):
    """The GIF renders on a worker thread: the event loop (every session's) keeps ticking,
    the page's progress bar moves, and the bytes are a real GIF."""
    import asyncio
    import time

    import imageio.v3 as iio

    from webapp.views import sharing

    real = backend.preview_video
    threads = set()

    def short_video(*args, **kwargs):  # a real export, fewer frames (test time)
        import threading

        threads.add(threading.current_thread().name)
        time.sleep(0.3)  # long enough for the page to show progress
        return real(*args, max_frames=12, **kwargs)

    monkeypatch.setattr(backend, "preview_video", short_video)
    monkeypatch.setattr(sharing, "PROGRESS_INTERVAL", 0.05)
    view = sharing.SharingView(session)

    async def export():
        gaps, shown, stop = [], set(), []

        async def tick():
            last = time.perf_counter()
            while not stop:
                await asyncio.sleep(0.01)
                now = time.perf_counter()
                gaps.append(now - last)
                last = now
                if view.progress.visible:
                    shown.add((view.gif.disabled, view.progress_text.object.split("…")[0]))

        ticker = asyncio.create_task(tick())
        t0 = time.perf_counter()
        data = await view._gif()
        took = time.perf_counter() - t0
        stop.append(True)
        await ticker
        return data, gaps, shown, took

    data, gaps, shown, took = asyncio.run(export())
    assert threads and all(name.startswith("hs-export") for name in threads)
    # the loop ran all along: an export on the loop would stall it once for the whole
    # export (>= took); a loaded machine stretches every gap, hence the relative bound
    assert len(gaps) > 10 and max(gaps) < max(0.5, 0.5 * took), (max(gaps), took)
    # buttons off, progress text on, naming the frames and their rate (every frame: 30 fps)
    # (this test renders 12 of them; the text names the frames a real export renders)
    assert (
        True,
        "preview GIF (body frames 0–186 at 30 fps, three-quarter camera): rendering",
    ) in shown, shown
    frames = iio.imread(data.getvalue(), index=None)
    assert frames.shape[0] >= 10 and not view.gif.disabled
    assert view.progress.value == 100 and "KiB" in view.progress_text.object
    assert view.gif.filename == f"{DEMO}-spliced.gif"


def test_a_video_export_stops_when_its_page_closes(session, monkeypatch):
    """Stranger 7: an MP4 kept rendering (and ffmpeg encoding) for minutes after its tab
    was closed. Now the rendering stops at the next frame once the page has closed."""
    import asyncio

    from webapp.views import sharing

    rendered = []
    real = backend.render_frame

    def counted(*args, **kwargs):
        rendered.append(1)
        if len(rendered) == 3:  # the tab closes while the third frame renders
            session.page_closed()
        return real(*args, **kwargs)

    monkeypatch.setattr(backend, "render_frame", counted)
    view = sharing.SharingView(session)
    data = asyncio.run(view._mp4())
    assert data is None and len(rendered) == 3  # given up, not the 186 frames of the take
    assert not view.mp4.disabled  # the next export may start


def test_the_video_export_uses_the_preview_camera_hands_close_up(session, monkeypatch):
    """Stranger R5-6: the app's GIF/MP4 had no close-up of the spliced fingers. The preview's
    camera (``hands`` too, as ``handsplice render --camera hands``) is the video's: its
    frames are the preview's pictures with that camera, and the page says which camera."""
    import asyncio

    import imageio.v3 as iio

    from webapp.views import sharing

    real = backend.preview_video
    monkeypatch.setattr(
        backend, "preview_video", lambda *a, **k: real(*a, **{**k, "max_frames": 2})
    )
    session.camera = "hands"  # as the preview's Camera select sets it
    view = sharing.SharingView(session)
    data = asyncio.run(view._gif())
    assert data is not None, view.message.object
    # the views: above the credit's caption strip (stranger 12 F7, tests/test_credit_in_files)
    first = iio.imread(data.getvalue(), index=0)[: backend.VIDEO_SIZE[1], :, :3].astype(float)
    prepared, solution = session.prepared, session.solution

    def rendered(camera):
        image = backend.render_frame(prepared, solution, 0, camera, False, backend.VIDEO_SIZE)
        return image[..., :3].astype(float)

    close, far = rendered("hands"), rendered(backend.VIDEO_CAMERA)
    assert np.abs(first - close).mean() < 0.5 * np.abs(first - far).mean()
    assert "hands camera" in view.progress_text.object
    # stranger 7: on the default camera the spliced fingers were a few pixels of a whole
    # body; the video now shows, right of the three views, the spliced hands close up
    session.camera = backend.VIDEO_CAMERA
    data = asyncio.run(view._gif())
    assert data is not None, view.message.object
    first = iio.imread(data.getvalue(), index=0)[..., :3].astype(float)
    w, h = backend.VIDEO_SIZE
    assert first.shape[1] == w + backend.VIDEO_CLOSEUP_WIDTH and first.shape[0] > h, first.shape
    first = first[:h]  # the views, above the caption
    assert np.abs(first[:, :w] - far).mean() < 3.0  # the three views (GIF colours)
    near = backend.render_closeup(prepared, solution, 0, (backend.VIDEO_CLOSEUP_WIDTH, h))
    right = first[:, w + 2 :]
    assert (
        np.abs(right - near[:, 2:, :3]).mean()
        < 0.5 * np.abs(right - far[:, -right.shape[1] :]).mean()
    )


def test_failed_exports_download_nothing_and_say_why(session, monkeypatch):
    """A failing BVH or GIF export sends no file to the browser (no empty download);
    the page shows the error. Drives Panel's own transfer paths (sync and async)."""
    import asyncio

    from webapp.views import sharing

    view = sharing.SharingView(session)
    view.bvh._clicks += 1  # a working download first: the page gets the file's address
    assert view.bvh.links == 1 and view.bvh.served.size > 1000
    assert view.bvh._transfers == 0 and view.bvh.data is None  # no base64 copy in the page
    first = view.bvh.served

    def broken(*args, **kwargs):
        raise RuntimeError("renderer exploded")

    monkeypatch.setattr(backend, "served_file", broken)
    monkeypatch.setattr(backend, "preview_video", broken)
    view.bvh._clicks += 1  # the button's click, as the browser sends it
    assert view.bvh.links == 1 and view.bvh.served is first  # nothing new was sent
    assert view.message.visible and "spliced BVH: " in view.message.object
    assert "renderer exploded" in view.message.object

    view.message.visible = False
    asyncio.run(view.gif._async_sync_data())  # Panel's path for a coroutine callback
    assert view.gif._transfers == 0 and view.gif.data is None
    assert view.message.visible and "preview GIF: " in view.message.object
    assert "renderer exploded" in view.message.object
    assert not view.progress.visible and not view.gif.disabled and not view.mp4.disabled


def test_command_line_uses_the_session_file_then_explicit_flags(session):
    from webapp.views import sharing

    session.add_point(40, 20, 0)
    view = sharing.SharingView(session)
    where, first, second = view.command.object.split("<br>", 2)
    assert "run in your HandSplice folder" in where and ".venv/bin/handsplice" in where
    assert first == (
        f"$ .venv/bin/handsplice splice {session.take_paths()[0].name} "
        f"{session.take_paths()[1].name} -o spliced.bvh "
        f"--session {sharing.SESSION_FILENAME}"
    )
    assert "--match" not in first
    assert "explicit flags" in second and "$ .venv/bin/handsplice splice " in second
    # the automatic band widths are the command's own default: left out (R4-8); set, given
    assert "--match 40:" in second and "--band" not in second and "--refine-band" not in second
    session.band = 0.25
    second = view.command.object.split("<br>", 2)[2]
    assert "--band 0.25" in second and "--refine-band" not in second


def test_a_run_of_one_slider_is_one_undo_step(session, monkeypatch):
    """Arrow-key steps (each a release) of one slider within the run window undo at once;
    another parameter, or a pause, starts a new step."""
    from webapp import state

    session.tolerance = 1
    session.tolerance = 2
    session.tolerance = 3
    session.band = 0.25
    session.undo()
    assert session.band == 0.3 and session.tolerance == 3
    session.undo()
    assert session.tolerance == 0  # the three steps were one
    monkeypatch.setattr(state, "SLIDER_RUN_S", 0.0)  # every step is a pause
    session.tolerance = 1
    session.tolerance = 2
    session.undo()
    assert session.tolerance == 1


def test_lesson_next_row_finishes_the_current_row():
    from webapp.views.teaching import TeachingModel, example_signals, local_costs, short_number

    mdl = TeachingModel()
    rows = [sum(1 for i, _ in mdl.order if i == r) for r in range(mdl.n)]
    assert mdl.next_row_step() == rows[0]  # from the start: all of row 0
    mdl.step = 2  # part of row 0 done: the rest of it, not row 1
    assert mdl.next_row_step() == rows[0]
    mdl.step = rows[0]
    assert mdl.next_row_step() == rows[0] + rows[1]
    mdl.metric = "value"
    mdl.step = len(mdl.order)
    texts = [short_number(g) for g in mdl.gamma[np.isfinite(mdl.gamma)].ravel()]
    assert texts and max(map(len, texts)) <= 4
    # value costs in cm²: every cell's label a plain number a class can read (stranger 7 saw
    # "2e-3" in the cells), as are the γ of this example
    costs = local_costs(*example_signals(), "value")
    labels = [short_number(c, 3) for c in costs.ravel()] + texts
    assert all("e" not in t for t in labels), [t for t in labels if "e" in t]
    assert [short_number(x) for x in (0, 0.1234, 3.5, 12.34, 340.2, 2345, 23456, 0.004)] == [
        "0",
        "0.12",
        "3.5",
        "12.3",
        "340",
        "2345",
        "2e4",
        "4e-3",
    ]


def test_points_table_shows_whole_frames_times_and_the_global_tolerance(session):
    from webapp.views.controls import _points_frame

    session.add_point(60, 80)
    session.add_point(120, 170, 3)
    frame = _points_frame(session)
    assert frame["body frame"].tolist() == [60, 120] and str(frame["hand frame"].dtype) == "int64"
    assert frame["tolerance"].tolist() == ["", "3"]
    assert frame["effective"].tolist() == ["0 (global)", "3"]
    assert frame["seconds"][0] == f"{60 / session.fps:.2f} s · {80 / session.hand_fps:.2f} s"


def test_page_errors_use_the_pages_words():
    from engine.base.errors import RoleError

    text = backend.one_line(
        RoleError("h.bvh has no left hand (hands found: right); try --side right")
    )
    assert "--side" not in text and "choose side right in the page" in text


def test_the_page_shows_the_constraints_one_text(session, cfg):
    """Every refusal of a matching point the page shows is engine.dtw.constraints' one text
    (``matching point K (body B, hand H): ...``, K as the table lists the points), with
    only a source in front (a shared link's); the page words none of it itself."""
    from webapp import app

    n, m = session.n, session.m_hand

    def check(edit, begins):
        edit(session)
        refusal = session.refusal()
        assert refusal is not None and session.error == str(refusal), session.error
        assert session.error.startswith(begins), session.error
        assert "points[" not in session.error

    session.add_point(40, 20, 1)
    check(  # crosses (the order rule)
        lambda s: s.add_point(60, 10, 2),
        "matching point 2 (body 60, hand 10): hand frame 10 is before matching point 1's hand "
        "frame 20; a path cannot go back in time",
    )
    check(  # the same body frame
        lambda s: s.add_point(40, 25),
        "matching point 2 (body 40, hand 25): on the same body frame as matching point 1 "
        "(body 40, hand 20); expected one point per body frame",
    )
    check(  # outside the takes (check_points)
        lambda s: s.add_point(n + 5, m - 1, 0),
        f"matching point 2 (body {n + 5}, hand {m - 1}): outside the takes; expected body "
        f"frames 0 to {n - 1} and hand frames 0 to {m - 1}",
    )
    check(  # a neighbour too far away (check_points)
        lambda s: s.add_point(41, 60, 0),
        "matching point 2 (body 41, hand 60): on the body frame after matching point 1 (body "
        "40, hand 20), but their hand frames 20 and 60 are more than one",
    )
    check(  # a tolerance out of range
        lambda s: s.set_point_tolerance(0, 900),
        "matching point 1 (body 40, hand 20): expected a tolerance from 0 to 500 frames, got 900",
    )
    check(lambda s: s.set_constraints(band=5), "band: expected a fraction")
    check(  # typed out of order
        lambda s: s.set_constraints(points="10:5 8:9"),
        "matching point 2 (body 8, hand 9): body frame 8 is not after matching point 1's body "
        "frame 10; body frames must increase from one point to the next",
    )
    refusal = session.refusal()
    assert (refusal.field, refusal.index, refusal.point, refusal.value) == (
        "points[1]",
        1,
        (8, 9),
        MatchPoint(8, 9),
    )
    linked = Session(cfg)
    app._initial_state(linked, {"sample": DEMO, "pts": "60:10,40:20:1"})
    assert linked.error == (
        "shared link: URL: matching point 2 (body 40, hand 20): body frame 40 is not after "
        "matching point 1's body frame 60; body frames must increase from one point to the next"
    )
    assert linked.error.endswith(str(linked.refusal()))
    session.error = "h.bvh line 12:30: a message that is no constraint's"
    assert session.refusal() is None


def test_sample_credits_and_the_no_share_warning(session):
    from webapp.views.credits import (
        NO_SHARE_TEXT,
        OWN_TAKES_TEXT,
        credits_html,
        share_terms,
        share_terms_alert,
    )

    text = credits_html(session)
    assert "wave-ok" in text and "CC BY-NC 4.0" in text and "MIT" in text
    assert "jaanga/gestification" in text and NO_SHARE_TEXT not in text
    alert = share_terms_alert(session)
    # Bandai dataset-2 (CC BY-NC) + a Leap hand (MIT): shareable, non-commercially, with
    # credit; said in one plain line beside the downloads (stranger 10)
    assert alert.visible and alert.alert_type == "info"
    # the licence's name with the caveats the takes panel shows (stranger 12 F7)
    assert alert.object.startswith(
        "Licences: body CC BY-NC 4.0 (non-commercial, with credit; see sample_data/README.md "
        "for an upstream caveat), credit: Bandai-Namco"
    )
    assert "; hand MIT, credit: jaanga/gestification" in alert.object
    assert "may be shared for non-commercial use only, crediting both sources" in alert.object
    # one rule, the takes' own licences: every pair with a dataset-1 body (CC BY-NC-ND per
    # the data set's manifest) carries the warning in its credits and by the downloads
    # alike, whatever its description says (stranger 8: bye-ok had none)
    for name in ("bye-hello", "bye-ok"):
        session.load_sample(name)
        assert alert.visible and alert.alert_type == "warning", name
        assert alert.object == NO_SHARE_TEXT and NO_SHARE_TEXT in credits_html(session)
        assert "CC BY-NC-ND 4.0" in credits_html(session)
    session.load_sample("dab-swiping")  # MIT body and hand: no non-commercial clause
    assert NO_SHARE_TEXT not in credits_html(session)
    assert alert.alert_type == "info" and "non-commercial" not in alert.object
    assert alert.object.endswith("Spliced results may be shared, crediting both sources.")
    demo_pair_uploaded(session.config, session)  # the user's own takes: theirs to check
    assert alert.visible and alert.alert_type == "info" and alert.object == OWN_TAKES_TEXT
    session.load_sample("beat-self")  # BEAT's "CC BY-NC 4.0 (BEAT); ..." read to its name
    assert share_terms(session)[1].count("CC BY-NC 4.0") >= 1
    assert "non-commercial use only" in share_terms(session)[1]


def test_a_new_pair_drops_the_old_pairs_matching_points(cfg, session):
    """Points name frames of the takes they were placed on: another sample or an upload
    starts without them; a refused upload or a side change keeps them."""
    session.add_point(40, 20, 2)
    session.side = "left" if session.side == "right" else "right"  # same takes: kept
    assert [(p.body, p.hand) for p in session.points] == [(40, 20)]
    session.side = cfg.sample(DEMO).side
    bad, _ = uploads.store(cfg, "other.bvh", cfg.sample("wave-hello").hand.read_bytes())
    session.load_uploads("0" * 64, bad, "missing.bvh", "other.bvh")  # refused: kept
    assert session.error and [(p.body, p.hand) for p in session.points] == [(40, 20)]
    session.load_sample("wave-hello")
    assert session.error == "" and session.points == ()
    session.add_point(30, 10, 2)
    demo_pair_uploaded(cfg, session)
    assert session.points == ()


def test_a_hand_take_uploaded_as_the_body_is_refused_and_the_pair_stays(cfg, session):
    hand_bytes = cfg.sample(DEMO).hand.read_bytes()
    hand, _ = uploads.store(cfg, "fingers.bvh", hand_bytes)
    before = session.to_spec()
    session.load_uploads(hand, hand, "fingers.bvh", "fingers.bvh")
    assert "looks like a hand take" in session.error and "\n" not in session.error
    assert session.to_spec() == before and session.solution is not None


def test_a_refused_upload_names_the_persons_files_not_their_kept_hashes(cfg, session):
    """Stranger R3-11: a swapped pair's refusal named the hand by the server's kept file
    (``9a285b…d73.bvh has no finger joints``); it names the uploaded file's own name."""
    body_bytes = cfg.sample(DEMO).body.read_bytes()
    body, _ = uploads.store(cfg, "my-body.bvh", body_bytes)
    session.load_uploads(body, body, "my-body.bvh", "my-hand.bvh")
    assert session.error and "\n" not in session.error
    assert "my-hand.bvh" in session.error or "my-body.bvh" in session.error, session.error
    assert body not in session.error, session.error


def test_the_explicit_flags_line_names_the_points_as_the_table_does_and_replays(session, tmp_path):
    """The page's ``--match`` shows each point in the hand file's frames with the
    tolerance typed in the table (a round trip through the alignment grid used to
    show another hand frame), and the command still gives the page's spliced BVH."""
    import html
    import shlex

    from engine.cli import main
    from webapp.views import sharing

    assert session.hand_fps != session.fps  # the demo's takes differ in rate (30 vs 40 fps)
    session.add_point(40, 26, 4)  # through the grid and back: hand frame 27
    view = sharing.SharingView(session)
    flags = html.unescape(view.command.object.split("<br>")[-1].removeprefix("$ "))
    argv = shlex.split(flags)
    assert argv[argv.index("--match") + 1] == "40:26:4", flags
    body, hand = session.take_paths()
    argv = [str(body), str(hand)] + argv[4:]  # the page names the files; run on their paths
    out = argv.index("-o") + 1
    argv[out] = str(tmp_path / "cli.bvh")
    assert main(["splice", *argv, "--quiet"]) == 0
    app_bytes = backend.bvh_bytes(backend.splice(session.prepared, session.solution))
    assert (tmp_path / "cli.bvh").read_bytes() == app_bytes
    # the file the page's button serves (written by the download child) is the same
    served = backend.served_file(session.prepared, session.solution, "bvh", "x.bvh")
    assert served.path.read_bytes() == app_bytes


def test_a_link_of_an_uploaded_pair_keeps_the_file_names(cfg):
    """The names travel in the link: the reopened session names its takes in downloads,
    the session file and the CLI line as the sharer's did (not the server's hash files)."""
    pair = cfg.sample(DEMO)
    body, _ = uploads.store(cfg, "walk 1.bvh", pair.body.read_bytes())
    hand, _ = uploads.store(cfg, "<b>hand</b>.bvh", pair.hand.read_bytes())
    s = Session(cfg)
    s.load_uploads(body, hand, "walk 1.bvh", "<b>hand</b>.bvh")
    other = Session(cfg)
    other.open_link(dict(parse_qsl(urlsplit(s.share_url("/")).query)))
    assert not other.error
    assert (other.body_name, other.hand_name) == ("walk 1.bvh", "<b>hand</b>.bvh")
    assert other.output_stem() == "walk_1-spliced"
    inputs = json.loads(other.to_json())["inputs"]
    assert inputs["body"] == {"sha256": body, "name": "walk 1.bvh"}
    assert inputs["hand"] == {"sha256": hand, "name": "<b>hand</b>.bvh"}


@pytest.mark.parametrize(
    ("bad", "words"),
    [
        ({"band": "99"}, "URL: band: expected a fraction of the body take from 0.02 to 1"),
        (
            {"pts": "abc:1"},
            "URL: matching point 1 (hand 1): expected a whole body frame number >= 0, got 'abc'",
        ),
    ],
)
def test_a_link_with_one_bad_value_opens_its_takes_and_good_values(cfg, bad, words):
    """One bad parameter refuses only itself (the page's one-line error, shown after the
    link's solve); the link's own takes open (not the default pair) with its good values."""
    link = {
        "sample": "bye-hello",
        "side": "right",
        "band": "0.4",
        "refine": "0.1",
        "tol": "0",
        "pts": "30:20:3,60:50",
        "frames": "hand",
        "view": "pass2",
        "frame": "40",
    }
    s = Session(cfg)
    s.load_sample(DEMO)
    s.open_link({**link, **bad})
    assert s.sample == "bye-hello" and s.matrix == "pass2" and s.frame == 40
    if "band" in bad:
        assert s.band == pytest.approx(0.3)  # the default, not 99
        assert [(p.body, p.hand, p.tolerance) for p in s.points] == [(30, 20, 3), (60, 50, None)]
    else:
        assert s.band == pytest.approx(0.4) and s.points == ()
    assert s.error.startswith("shared link: " + words) and "\n" not in s.error
    with pytest.raises(SessionError) as strict:  # the same words as a whole refusal
        Session(cfg).from_query({**link, **bad})
    assert s.error == f"shared link: {backend.one_line(strict.value)}"


def test_a_link_with_points_outside_its_takes_opens_the_takes_without_them(cfg):
    link = {"sample": "bye-hello", "band": "0.4", "pts": "30:20,900:50", "frames": "hand"}
    s = Session(cfg)
    s.load_sample(DEMO)
    s.open_link(link)
    assert s.sample == "bye-hello" and s.band == pytest.approx(0.4) and s.points == ()
    assert s.solution is not None and "\n" not in s.error
    assert s.error.startswith(
        "shared link: matching point 2 (body 900, hand 50): outside the takes; expected body "
        f"frames 0 to {s.n - 1} and hand frames 0 to "
    )
    assert s.refusal() is not None and s.refusal().field == "points[1]"
    # a frame past the take shows the last one and says so (stranger 11: silently clamped)
    s.open_link({"sample": "bye-hello", "frame": "9999"})
    assert s.frame == s.n - 1 and s.error == (
        f"shared link: URL: frame: 9999 is past the body take's last frame, {s.n - 1}: "
        f"{s.n - 1} is shown"
    )
    assert "9999 is past" in s.link_notice and "the rest of the link opened" in s.link_notice
    # both at once: the points' refusal and the frame's, each said (one was dropped)
    s.open_link({**link, "frame": "9999"})
    assert s.points == () and s.frame == s.n - 1
    assert "matching point 2 (body 900, hand 50): outside the takes" in s.error
    assert s.error.endswith(
        f"9999 is past the body take's last frame, {s.n - 1}: {s.n - 1} is shown"
    )
    assert s.refusal() is not None and s.refusal().field == "points[1]"


def test_points_table_refuses_a_fraction_of_a_frame_with_the_rules_one_text(session):
    """A hand frame of 12.5 typed in the table (a slip while typing 125) was truncated to
    12: it is refused, the point kept, with engine.dtw.constraints' text; the tolerance
    cell's refusals ('abc', 1000) say one range in one wording, as every front does."""
    from types import SimpleNamespace

    from engine.dtw import constraints as C
    from webapp.views.controls import PointsTable

    table = PointsTable(session)
    session.add_point(60, 80)
    before = session.points

    def edit(column, value):
        table._on_edit(SimpleNamespace(row=0, column=column, value=value))
        return session.error

    assert edit("hand frame", 12.5) == (
        "matching point 1 (body 60, hand 12.5): expected a whole hand frame number >= 0, got 12.5"
    )
    assert session.points == before
    assert edit("body frame", 12.5) == (
        "matching point 1 (body 12.5, hand 80): expected a whole body frame number >= 0, got 12.5"
    )
    assert session.points == before
    with pytest.raises(C.ConstraintError) as info:  # the same text as every front's
        C.parse_point("60:12.5")
    assert str(info.value) == (
        "matching point 1 (body 60, hand 12.5): expected a whole hand frame number >= 0, got 12.5"
    )
    # the session's own point API refuses it too (never int() truncation)
    session.move_point(0, 60, 12.5)
    assert session.points == before and session.error == str(info.value)
    tol_texts = [edit("tolerance", v) for v in ("abc", "1000", "-3")]
    assert session.points == before
    assert tol_texts == [
        f"matching point 1 (body 60, hand 80): expected a tolerance from 0 to 500 frames, got {v}"
        for v in ("'abc'", "1000", "-3")
    ]
    edit("hand frame", "125")
    assert session.points[0].hand == 125 and session.error == ""


def test_a_refused_table_edit_is_said_once_beside_the_table(session):
    """Stranger 13 F3: -5 typed into a point's hand cell showed the same red box twice,
    under the matrix legend and above the table. The table's box says it (where it was
    typed), the page's error line does not; also when the edit's solve is refused later,
    off the loop. A refusal of another front (a click on the matrix: the session's own
    point API) is said on the page's line only."""
    from types import SimpleNamespace

    from engine.base.errors import HandSpliceError
    from webapp.views.controls import PointsTable, error_alert

    table, alert = PointsTable(session), error_alert(session)
    session.add_point(51, 80)
    table._on_edit(SimpleNamespace(row=0, column="hand frame", value=-5))
    assert session.error == (
        "matching point 1 (body 51, hand -5): expected a whole hand frame number >= 0, got -5"
    )
    assert table.refusal.visible and "hand frame number" in table.refusal.object
    assert not alert.visible
    # the edit is taken, its solve refused on the worker: the table's refusal still
    jobs = []
    session.runner = SimpleNamespace(submit=jobs.append, solving=lambda: False)
    try:
        table._on_edit(SimpleNamespace(row=0, column="hand frame", value=90))
        assert session.error == "" and not table.refusal.visible
        (job,) = [j for j in jobs if j.kind == "solve"]
        job.failed(HandSpliceError("no alignment fits these matching points"))
    finally:
        session.runner = None
    assert session.error == "no alignment fits these matching points"
    assert table.refusal.visible and not alert.visible
    assert session.points[0].hand == 80  # back to the path on screen
    # a click on the matrix out of order: the page's line, not the table's box
    session.add_point(60, 10)
    assert session.error.startswith("matching point 2 (body 60, hand 10): hand frame 10 is")
    assert alert.visible and not table.refusal.visible
    # an accepted table edit clears the line too
    table._on_edit(SimpleNamespace(row=0, column="hand frame", value=81))
    assert session.error == "" and not alert.visible and not table.refusal.visible


def test_a_refused_seconds_entry_speaks_of_its_field(session):
    """What is typed into a width's field in seconds is refused in that field's words
    (``W1 in seconds``, seconds only, the text as typed), not as ``band`` with its
    fractions; empty text puts the fraction back in force."""
    assert session.set_constraints(band_s="2") and session.band_s == 2.0
    for typed in ("abc", "0s", "1.5x"):
        assert not session.set_constraints(band_s=typed)
        assert session.error == (
            f"W1 in seconds: expected seconds from 0.1 to 3600 (like 10 or 10s), got {typed!r}"
        )
        assert "fraction" not in session.error and session.band_s == 2.0
        assert session.refusal().field == "band_s"
    assert not session.set_constraints(refine_band_s="0")
    assert session.error.startswith("W2 in seconds: expected seconds from 0.05 to 3600")
    assert session.set_constraints(band_s="3 s") and session.band_s == 3.0
    assert session.set_constraints(band_s="") and session.band_s is None
    assert session.widths()[0] == C.Width(session.band)


def test_the_pages_command_line_runs_the_program_the_readme_installs(session):
    """The Share section's command lines name the program as the README's "Command line"
    section runs it (``make demo`` puts it in the clone's .venv, not on PATH), and say
    where to run them."""
    import html
    import re
    import shlex

    from conftest import ROOT

    from webapp.views import sharing

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split("## Command line", 1)[1].split("```sh", 1)[1].split("```", 1)[0]
    programs = {line.split()[0] for line in block.strip().splitlines()}
    assert len(programs) == 1, programs
    view = sharing.SharingView(session)
    lines = [html.unescape(re.sub("<[^>]+>", "", ln)) for ln in view.command.object.split("<br>")]
    commands = [shlex.split(ln.removeprefix("$ ")) for ln in lines if ln.startswith("$ ")]
    assert len(commands) == 2
    assert {argv[0] for argv in commands} == programs
    assert lines[0].startswith("# run in your HandSplice folder")


def test_the_unmatched_end_limit_is_an_edit_the_file_link_and_command_line_carry(
    session, tmp_path, capsys
):
    """The page's open-end limit (the CLI's --max-unmatched) is an undoable edit checked by
    engine.dtw.constraints (its refusal names the page's field), and the session file, the
    link and the command line carry it: the CLI replays the page's splice byte for byte."""
    from engine.cli import main
    from engine.io import session as session_io

    cells = session.solution.pass1.band_cells
    assert not session.set_constraints(max_unmatched_s="-1")
    assert session.error == (
        "Unmatched ends at most (seconds): expected a number of seconds from 0 to 3600, got -1"
    )
    assert session.set_constraints(max_unmatched_s="0.5")
    assert session.solution.cache["engine"].max_unmatched_s == 0.5
    assert session.solution.pass1.band_cells < cells
    assert "0.5 s unmatched at each end (the limit set above)" in session.unmatched_note()
    spec = session_io.parse_session(session.to_json())
    assert spec.max_unmatched_s == 0.5
    assert session_io.from_query(session.to_query()).max_unmatched_s == 0.5
    body, hand = session.take_paths()
    flags = backend.cli_command(
        body.name, hand.name, "right", *session.widths(), [], None, session.max_unmatched_s
    )
    assert "--max-unmatched 0.5" in flags
    file = tmp_path / "s.json"
    file.write_text(session.to_json(), encoding="utf-8")
    out = tmp_path / "cli.bvh"
    assert main(["splice", str(body), str(hand), "-o", str(out), "--session", str(file)]) == 0
    capsys.readouterr()
    assert out.read_bytes() == backend.bvh_bytes(session.spliced())
    session.undo()
    assert session.max_unmatched_s is None and session.solution.pass1.band_cells == cells


def test_every_number_of_the_status_says_what_it_is(session):
    """R5-3: the solve time stood bare ("2166.0 ms") beside the desync meter's milliseconds;
    it is now "solved in N ms", and no number of the line is left without its word."""
    import re

    text = session.status_text()
    assert re.search(r"solved in [\d,]+ ms", text), text
    costs_and_time = text.split(" · ")[:4]
    assert [part.split()[0] for part in costs_and_time] == ["pass", "pass", "solved", "band"]


def test_the_status_of_a_page_whose_first_pair_is_opening_says_so(cfg):
    """Stranger 7: while a page's first pair opened, its status line said "no takes loaded"
    under the first matrix already drawn."""
    s = Session(cfg)
    assert s.solution is None
    s.opening = "walk.bvh + mug1_rightHand.bvh"
    assert s.status_text() == "opening walk.bvh + mug1_rightHand.bvh: no alignment yet"
    s.opening = ""
    assert s.status_text() == "no takes loaded"


def test_a_link_that_did_not_open_is_said_at_the_top_with_its_files_escaped(session):
    """The page's top notice (stranger 8, 9): the reason, the files a link of uploads names
    (what to ask its sender for) and the link as sent, all escaped; Close hides it."""
    from webapp import app, safe_text
    from webapp.views.link_notice import link_notice

    args = {
        "body": "ab" * 32,
        "bname": "<b>their</b>_body.bvh",
        "hand": "cd" * 32,
        "hname": "hand.bvh",
    }
    box = link_notice(session, args)
    assert not box.visible
    try:
        app._initial_state(session, dict(args))  # not on this server: the link waits
        assert session.link_waiting
        # each missing take is named (stranger 12: only the body was)
        assert "upload ababababab" in session.link_notice
        assert "upload cdcdcdcdcd" in session.link_notice
        alert, close = box.objects
        assert box.visible and "did not open as it was sent" in alert.object
        named = safe_text.markdown("<b>their</b>_body.bvh (body), hand.bvh (hand)")
        assert "&lt;b&gt;their&lt;/b&gt;" in named and named in alert.object
        # and what its receiver does next (stranger 10): ask, upload, which applies the link
        assert "Ask its sender for them" in alert.object
        assert "uploading them applies the link" in alert.object
        assert "<b>their" not in alert.object and "bname=%3Cb%3Etheir" in alert.object
        close.clicks += 1
        assert not box.visible
    finally:
        session.link_notice = ""


def test_a_link_of_uploads_opens_on_a_server_started_on_the_same_files(cfg, tmp_path):
    """Stranger 12: a link (or session file) of an uploaded pair, opened on a server started
    with ``serve BODY HAND`` on the very same files, said "no such file on this server" and
    showed the pair without the link's points. The server's files with the link's bytes
    open it (``uploads.file_for``): points, tolerance and view, no notice, nothing copied."""
    from webapp import app
    from webapp.views.inputs import UPLOADED, InputsView
    from webapp.views.link_notice import link_notice

    s, body, hand = demo_pair_uploaded(cfg)
    s.add_point(40, 20, 2)
    s.tolerance = 1
    s.matrix, s.frame = "pass2", 40
    link = dict(parse_qsl(urlsplit(s.share_url("/")).query))
    pair = cfg.sample(DEMO)
    disk, empty = tmp_path / "disk", tmp_path / "uploads"
    disk.mkdir(), empty.mkdir()
    (disk / "my body.bvh").write_bytes(pair.body.read_bytes())
    (disk / "my hand.bvh").write_bytes(pair.hand.read_bytes())
    local = config.local_pair(disk / "my body.bvh", disk / "my hand.bvh", "right")
    served = config.AppConfig(
        sample_dir=cfg.sample_dir, upload_dir=empty, default_sample=local.name, local=local
    )
    other = Session(served)
    box, inputs = link_notice(other, link), InputsView(other)
    app._initial_state(other, dict(link))
    assert other.error == "" and other.link_notice == "" and not box.visible
    # said as what they are: not "kept on this server from an earlier upload"
    assert "this server's own files with these contents, opened from disk" in (
        inputs.uploaded.object
    )
    assert (other.sample, other.body_sha256, other.hand_sha256) == (None, body, hand)
    assert other.take_paths() == (local.body, local.hand)
    # the Sample pair menu names the disk pair as a plain load does (stranger 13 F2: it
    # said "(your uploaded pair)" over the line "opened from disk"), and picks nothing
    assert inputs.sample.value == local.name and UPLOADED not in inputs.sample.options
    assert other.sample is None and other.body_sha256 == body
    assert other.points == s.points and other.points[0].tolerance == 2
    assert (other.tolerance, other.matrix, other.frame) == (1, "pass2", 40)
    assert not other.link_waiting
    assert other.solution.pass1.cost == pytest.approx(s.solution.pass1.cost)
    # the session file the same (Open a session file)
    from_file = Session(served)
    from_file.load_sample(local.name)
    file_inputs = InputsView(from_file)
    from_file.from_json(s.to_json(), "handsplice-session.json")
    assert from_file.error == "" and from_file.points == s.points
    assert (from_file.sample, file_inputs.sample.value) == (None, local.name)
    assert list(file_inputs.sample.options) == [p.name for p in served.samples()]
    assert list(empty.iterdir()) == []  # read where it is: nothing uploaded
    # bytes no file here has: each missing take named, as before
    with pytest.raises(uploads.UploadError) as missing:
        uploads.files_for(served, (("0" * 64, "x.bvh"), (hand, None), ("1" * 64, None)))
    assert str(missing.value).startswith(
        "upload 000000000000... (x.bvh) and upload 111111111111...: no such file on this server"
    )


def test_a_links_bad_side_takes_the_side_the_hand_files_name_says(cfg, tmp_path):
    """Stranger 12: ``side=middle`` in a link of a ``...leftHand`` take fell back to right;
    left out, the side is the one an upload of that hand takes (its name's). Both takes are
    open here, so the notice does not tell the colleague to ask for them and upload them."""
    from conftest import cropped_bvh

    from webapp.views.link_notice import link_notice

    take = cropped_bvh(cfg.sample("beat-self").body, tmp_path / "wayne.bvh", 120).read_bytes()
    digest, _ = uploads.store(cfg, "wayne.bvh", take)
    link = {
        "body": digest,
        "bname": "wayne.bvh",
        "hand": digest,
        "hname": "wayne_leftHand.bvh",
        "side": "middle",
        "frame": "5",
    }
    s = Session(cfg)
    s.load_sample(DEMO)
    box = link_notice(s, link)
    s.open_link(link)
    assert (s.body_sha256, s.side, s.frame) == (digest, "left", 5)
    assert s.error == 'shared link: URL: side: expected right or left, got "middle"'
    alert = box.objects[0].object
    assert box.visible and "middle" in alert and "Ask its sender" not in alert


def test_a_link_waiting_for_its_uploads_opens_once_they_are_uploaded(cfg, tmp_path):
    """A shared link of uploads this server lacks opens the demo and waits (the notice at
    the top names the files); uploading other files opens them plainly, and the link still
    waits; uploading the link's own bytes opens the link on them: its points, bands,
    tolerance, view, no undo back to the demo's edits, and the notice goes. A link's point
    outside the uploaded takes is left out with its one-line refusal, the rest opens."""
    from conftest import MOCAP, cropped_bvh

    from webapp import app
    from webapp.views.link_notice import link_notice

    body = (MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh").read_bytes()
    hand = cropped_bvh(
        MOCAP / "gestification" / "hello-world.bvh", tmp_path / "their-hand.bvh", 70
    ).read_bytes()
    body_sha, hand_sha = uploads.sha256(body), uploads.sha256(hand)
    with pytest.raises(uploads.UploadError, match="no such file"):
        uploads.path_for(cfg, hand_sha)  # not on this server (yet)
    link = {
        "body": body_sha,
        "bname": "their-body.bvh",
        "hand": hand_sha,
        "hname": "their-hand.bvh",
        "side": "right",
        "band": "0.4",
        "tol": "1",
        "pts": "30:10:2,60:40",
        "frames": "hand",
        "view": "pass2",
        "frame": "50",
    }
    s = Session(cfg)
    box = link_notice(s, link)
    app._initial_state(s, dict(link))
    assert s.sample == DEMO and s.points == () and "no such file" in s.link_notice
    assert "(their-hand.bvh)" in s.link_notice and s.link_waiting  # named as sent
    alert = box.objects[0]
    assert box.visible and "uploading them applies the link" in alert.object
    assert "open the link again" not in alert.object
    assert s.link_waits_for(body_sha, hand_sha)
    # other files uploaded: opened plainly, without the link's values; the link still waits
    s.add_point(40, 20, 0)
    other, _ = uploads.store(cfg, "other-hand.bvh", cfg.sample(DEMO).hand.read_bytes())
    stored_body, _ = uploads.store(cfg, "their-body.bvh", body)
    s.load_uploads(stored_body, other, "their-body.bvh", "other-hand.bvh")
    assert (s.hand_sha256, s.points, s.tolerance, s.link_applied) == (other, (), 0.0, False)
    assert s.link_waits_for(body_sha, hand_sha) and box.visible
    # the link's own files uploaded (the same bytes, so the same sha256): the link opens
    s.add_point(40, 20, 0)
    assert s.can_undo
    stored_hand, _ = uploads.store(cfg, "hand-from-sender.bvh", hand)
    s.load_uploads(stored_body, stored_hand, "their-body.bvh", "hand-from-sender.bvh")
    assert (s.body_sha256, s.hand_sha256) == (body_sha, hand_sha) and s.link_applied
    assert s.points == (MatchPoint(30, 10, 2.0), MatchPoint(60, 40))
    assert (s.band, s.tolerance, s.matrix, s.frame) == (0.4, 1.0, "pass2", 50)
    assert s.hand_name == "hand-from-sender.bvh"  # the name it was uploaded under
    assert not s.can_undo and not s.error and s.solution is not None
    assert _path_hits(s.solution.pass1.path, 60, s.constraint_points()[1][1], 1)
    assert s.link_notice == "" and not box.visible
    assert not s.link_waits_for(body_sha, hand_sha)  # opened once: a new upload is plain

    # a link's point outside the uploaded takes: left out, said in one line, the rest opens
    missing = cropped_bvh(MOCAP / "gestification" / "hello-world.bvh", tmp_path / "h.bvh", 60)
    late_sha = uploads.sha256(missing.read_bytes())
    late_link = {**link, "hand": late_sha, "pts": "30:10,60:75"}
    late = Session(cfg)
    lbox = link_notice(late, late_link)
    app._initial_state(late, dict(late_link))
    assert late.sample == DEMO and late.link_waits_for(body_sha, late_sha)
    late_hand, _ = uploads.store(cfg, "h.bvh", missing.read_bytes())
    late.load_uploads(stored_body, late_hand, "their-body.bvh", "h.bvh")
    assert late.hand_sha256 == late_sha and late.points == () and late.band == 0.4
    assert "outside" in late.error and "\n" not in late.error
    assert "left out; the rest of the link opened" in late.link_notice and lbox.visible
    assert "uploading them applies" not in lbox.objects[0].object  # its takes are open now

    # a link that cannot open on its uploaded takes (a side they lack): they open plainly,
    # the notice says why, naming the files as uploaded, and the link waits no more
    right = cropped_bvh(MOCAP / "gestification" / "hello-world.bvh", tmp_path / "r.bvh", 64)
    right_sha = uploads.sha256(right.read_bytes())
    wrong = Session(cfg)
    app._initial_state(wrong, {**link, "hand": right_sha, "side": "left"})
    right_hand, _ = uploads.store(cfg, "r.bvh", right.read_bytes())
    wrong.load_uploads(stored_body, right_hand, "their-body.bvh", "hand-from-sender.bvh")
    assert (wrong.hand_sha256, wrong.side, wrong.points) == (right_sha, "right", ())
    assert wrong.link_notice == (
        "hand-from-sender.bvh has no left hand (hands found: right); choose side right in "
        "the page (your uploads opened without the link's values)"
    )
    assert not wrong.link_applied and not wrong.link_waits_for(body_sha, right_sha)


def test_the_hand_rate_note_fits_the_rates(session):
    """Under the points' heading: a hand take much faster than the body says its step in
    hand frames; one barely faster says a frame may be one off, not "1 frames per body
    frame ... up to 0.501" (stranger 12, a 120 fps hand on a 119.875 fps body); the same
    rate says nothing."""
    assert "(40 vs 30 fps)" in session.hand_rate_note()
    assert "1.33 frames per body frame" in session.hand_rate_note()
    with param.edit_constant(session):
        session.param.update(fps=119.875, hand_fps=120.0)
        slight = session.hand_rate_note()
        session.param.update(fps=120.0, hand_fps=120.0)
        same = session.hand_rate_note()
    assert slight == (
        "The hand take runs a little faster than the body (120 vs 119.875 fps) and is aligned "
        "at the body's rate: the preview at a point's body frame may name a hand frame one off "
        "the table's."
    )
    assert same == ""
