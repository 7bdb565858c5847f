"""A marker body (C3D/TRC) with a BVH hand: the command lines the page shows under
"the command line below redoes the same splice offline" give the page's "Spliced BVH"
(the hand take retimed to the body), byte for byte."""

from __future__ import annotations

import html
import shlex

import pytest

from engine.cli import main
from tests.conftest import MOCAP
from webapp import backend, config, uploads
from webapp.state import Session

BODY_C3D = MOCAP / "pyomeca" / "markers_analogs.c3d"
HAND_BVH = MOCAP / "gestification" / "gesture-pointing.bvh"


@pytest.fixture(scope="module")
def marker_session(sample_dir, tmp_path_factory):
    cfg = config.AppConfig(
        sample_dir=sample_dir.resolve(),
        upload_dir=tmp_path_factory.mktemp("uploads"),
        default_sample="wave-ok",
        max_upload_bytes=8 * 1024 * 1024,
    )
    s = Session(cfg)
    body, _ = uploads.store(cfg, BODY_C3D.name, BODY_C3D.read_bytes())
    hand, _ = uploads.store(cfg, HAND_BVH.name, HAND_BVH.read_bytes())
    s.load_uploads(body, hand, BODY_C3D.name, HAND_BVH.name)
    assert s.error == "" and s.solution is not None
    assert backend.marker_body(s.prepared)
    s.add_point(200, 60, 3)
    return s


def _shown_commands(session) -> list[list[str]]:
    from webapp.views import sharing

    view = sharing.SharingView(session)
    lines = [ln for ln in view.command.object.split("<br>") if ln.startswith("$ ")]
    assert len(lines) == 2, view.command.object
    return [shlex.split(html.unescape(ln.removeprefix("$ "))) for ln in lines]


@pytest.mark.parametrize("which", ["session file", "flags"])
def test_the_pages_command_redoes_a_marker_body_splice(marker_session, tmp_path, capsys, which):
    s = marker_session
    session_argv, flags_argv = _shown_commands(s)
    argv = session_argv if which == "session file" else flags_argv
    assert argv[:2] == [".venv/bin/handsplice", "splice"]  # as the README installs it
    assert argv[2:4] == [BODY_C3D.name, HAND_BVH.name]
    rest = argv[4:]
    rest[rest.index("-o") + 1] = str(tmp_path / "cli.bvh")
    if "--session" in rest:
        session_file = tmp_path / "handsplice-session.json"
        session_file.write_text(s.to_json(), encoding="utf-8")  # the page's download
        rest[rest.index("--session") + 1] = str(session_file)
    code = main(["splice", str(BODY_C3D), str(HAND_BVH), *rest])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "retimed" in err
    app_bytes = backend.bvh_bytes(backend.splice(s.prepared, s.solution))
    assert (tmp_path / "cli.bvh").read_bytes() == app_bytes


def test_a_marker_hand_is_still_refused(tmp_path, capsys):
    code = main(["splice", str(BODY_C3D), str(BODY_C3D), "-o", str(tmp_path / "o.bvh")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "the hand take must be a skeletal take" in err[0]


def test_a_marker_bodys_status_does_not_speak_of_its_fingers(marker_session):
    """A marker body has no fingers: where it has no hand match, the status says what the
    download does there (the retimed hand holds its nearest matched frame)."""
    from engine.splice.report import unmatched_summary

    text = unmatched_summary([(0, 29)], 100.0, retimed=True)
    assert "the retimed hand take holds its nearest matched frame" in text
    assert "fingers" not in text
    assert "the fingers hold the nearest matched pose" in unmatched_summary([(0, 29)], 100.0)
    status = marker_session.status_text()
    assert "no hand match" in status, status  # this pair has an unmatched start
    assert "retimed hand take holds" in status and "fingers hold" not in status, status


def test_the_pages_glb_of_a_marker_body_is_the_retimed_hand_in_3d(marker_session, tmp_path):
    """The "Spliced GLB (3D)" button of a marker body gives what its BVH gives, in 3D: the
    hand take retimed to the body (one key per body frame at the body's rate), named so
    (it was named as a splice of the body)."""
    import asyncio

    import pygltflib

    from webapp.views import sharing

    s = marker_session
    view = sharing.SharingView(s)
    asyncio.run(view.glb._async_sync_data())  # the button's click, as Panel runs it
    assert not view.message.visible, view.message.object
    assert view.glb.filename == "markers_analogs-spliced-hand-retimed.glb"
    path = tmp_path / view.glb.filename
    path.write_bytes(view.glb.served.path.read_bytes())  # the file the page fetches over HTTP
    doc = pygltflib.GLTF2().load_binary(str(path))
    retimed = backend.splice(s.prepared, s.solution)
    assert {node.name for node in doc.nodes} >= set(retimed.skeleton.names)
    times = doc.accessors[doc.animations[0].samplers[0].input]
    assert times.count == s.n == retimed.n_frames
    assert times.max[0] == pytest.approx((s.n - 1) / s.fps, abs=1e-3)
