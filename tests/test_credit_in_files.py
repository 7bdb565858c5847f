"""Stranger 12 F7: the files the page downloads carry the takes' credit inside them (GIF
comment, MP4 comment and copyright tags, GLB ``asset.copyright``), in the page's words, and
a preview video shows it under its frames; the BVH (no comment syntax) keeps the command
line's bytes. The page's licence line keeps the caveats the takes panel shows."""

from __future__ import annotations

import asyncio
import io
import json
import re
import struct
import subprocess

import numpy as np
import pytest
from conftest import open_demo_session

from engine.io.bvh import format_bvh
from webapp import backend, uploads
from webapp.state import Session

#: what the demo pair's files must name: both sources and both licences
DEMO_CREDIT = (
    "Bandai-Namco-Research-Motiondataset",
    "CC BY-NC 4.0",
    "jaanga/gestification",
    "MIT",
    "non-commercial use only",
)


@pytest.fixture
def session(tmp_path) -> Session:
    return open_demo_session(tmp_path / "uploads")


@pytest.fixture
def renders(monkeypatch) -> None:
    """Cheap frames instead of OpenGL renders (tests/test_video_reuse.py's stand-ins): a
    black frame with one grey pixel per body frame, and a black close-up."""

    def frame(prepared, solution, body_frame, camera, trails, size):
        image = np.zeros((size[1], size[0], 3), np.uint8)
        image[0, body_frame % size[0]] = 128
        return image

    def closeup(prepared, solution, body_frame, size):
        return np.zeros((size[1], size[0], 3), np.uint8)

    monkeypatch.setattr(backend, "render_frame", frame)
    monkeypatch.setattr(backend, "render_closeup", closeup)


def _short(session: Session) -> Session:
    """The pair with the shortest body take (59 frames): a quick video."""
    session.load_sample("raise-pointing")
    assert session.error == "" and session.solution is not None, session.error
    return session


def _glb_json(data: bytes) -> dict:
    """The JSON chunk of a GLB file."""
    magic, version, _ = struct.unpack_from("<III", data, 0)
    length, kind = struct.unpack_from("<II", data, 12)
    assert (magic, version, kind) == (0x46546C67, 2, 0x4E4F534A)
    return json.loads(data[20 : 20 + length])


def _mp4_tags(path) -> dict[str, str]:
    """The container tags of an MP4 (ffmpeg's own ``-f ffmetadata`` dump: imageio-ffmpeg
    bundles ffmpeg, not ffprobe), unescaped."""
    import imageio_ffmpeg

    out = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path), "-f", "ffmetadata", "-"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    tags = {}
    for line in out.splitlines()[1:]:
        key, _, value = line.partition("=")
        tags[key] = re.sub(r"\\(.)", r"\1", value)
    return tags


def test_the_licence_line_keeps_every_caveat_the_takes_panel_shows(session):
    from webapp.views.credits import credits_html, licence_line, share_terms

    # the name alone dropped these (the takes panel showed them)
    assert licence_line("CC BY-NC (the majority of the project, per its README)") == (
        "CC BY-NC (the majority of the project, per its README)"
    )
    assert licence_line(
        "CC BY-NC 4.0 (BEAT); the copy's source repository has no licence file"
    ) == ("CC BY-NC 4.0 (BEAT; the copy's source repository has no licence file)")
    # only the clause saying where the name was read goes
    assert licence_line("CC BY-NC 4.0 per the licence file (non-commercial; see X)") == (
        "CC BY-NC 4.0 (non-commercial; see X)"
    )
    assert licence_line("MIT") == "MIT" and licence_line("") == "licence not stated"
    for sample, caveats in (
        ("wave-ok", ["see sample_data/README.md for an upstream caveat"]),
        ("wave-both-mug", ["upstream caveat", "the majority of the project"]),
        ("beat-self", ["the copy&#x27;s source repository has no licence file"]),
    ):
        session.load_sample(sample)
        kind, line = share_terms(session)
        assert kind == "info"
        for caveat in caveats:
            assert caveat in line and caveat in credits_html(session), (sample, caveat)


def test_the_gif_carries_the_credit_and_shows_its_caption(session, renders):
    from PIL import Image

    from webapp.views import sharing

    view = sharing.SharingView(_short(session))
    data = asyncio.run(view._gif()).getvalue()
    with Image.open(io.BytesIO(data)) as gif:
        comment = gif.info["comment"].decode("utf-8")
        gif.seek(0)
        first = np.asarray(gif.convert("RGB"))
    assert "raise-pointing" in comment and "Bandai" in comment
    for words in ("CC BY-NC 4.0", "jaanga/gestification", "MIT", "upstream caveat"):
        assert words in comment, words
    from webapp.views.credits import file_credit, video_caption

    assert comment == file_credit(session)
    # the caption: a strip of its own under the panels (the panels keep their size)
    from engine.render.offscreen import caption_strip

    width = backend.VIDEO_SIZE[0] + backend.VIDEO_CLOSEUP_WIDTH
    strip = caption_strip(video_caption(session), width)
    assert 20 <= strip.shape[0] <= 80, strip.shape  # two to four lines of 12 px
    assert first.shape == (backend.VIDEO_SIZE[1] + strip.shape[0], width, 3)
    below = first[backend.VIDEO_SIZE[1] :].astype(int)
    assert (below > 200).mean() > 0.8 and (below < 100).any()  # dark text on white
    assert np.abs(below - strip).mean() < 2  # the caption (a GIF's palette: near enough)
    panels = backend.video_frame(session.prepared, session.solution, 0)
    assert np.abs(first[: backend.VIDEO_SIZE[1]].astype(int) - panels).mean() < 2  # as before


def test_the_mp4_carries_the_credit_in_its_tags(session, renders, tmp_path):
    from webapp.views import sharing

    view = sharing.SharingView(_short(session))
    path = tmp_path / "preview.mp4"
    path.write_bytes(asyncio.run(view._mp4()).getvalue())
    tags = _mp4_tags(path)
    for words in DEMO_CREDIT[:-1]:
        assert words in tags.get("comment", ""), (words, tags)
        assert words in tags.get("copyright", ""), (words, tags)
    from webapp.views.credits import file_credit, video_caption

    assert tags["comment"] == file_credit(session)
    assert tags["copyright"] == video_caption(session)


def test_the_glb_carries_the_credit_and_the_bvh_keeps_the_clis_bytes(session):
    from webapp.views import sharing

    view = sharing.SharingView(session)
    glb = asyncio.run(view._glb())
    asset = _glb_json(glb.path.read_bytes())["asset"]
    assert asset["generator"] == "HandSplice" and asset["version"] == "2.0"
    for words in DEMO_CREDIT:
        assert words in asset.get("copyright", ""), (words, asset)
    bvh = asyncio.run(view._bvh())
    spliced = backend.splice(session.prepared, session.solution)
    assert bvh.path.read_bytes() == format_bvh(spliced).encode("utf-8")  # no credit: BVH
    from webapp.views.credits import file_credit

    assert asset["copyright"] == file_credit(session)


def test_a_no_share_pairs_files_credit_its_takes_and_warn(session):
    from webapp.views.credits import NO_SHARE_TEXT, file_credit, share_terms

    session.load_sample("bye-ok")
    assert share_terms(session) == ("warning", NO_SHARE_TEXT)  # the page: the warning
    credit = file_credit(session)  # the file: the takes' credits, then the warning
    assert "CC BY-NC-ND 4.0" in credit and "Bandai-Namco-Research-Motiondataset" in credit
    assert "jaanga/gestification" in credit and credit.endswith(NO_SHARE_TEXT)


def test_own_takes_are_said_to_be_the_users_with_no_licence_invented(session, tmp_path):
    from webapp.views.credits import credits_html, file_credit, video_caption

    cfg = session.config
    pair = cfg.sample("wave-ok")
    body, _ = uploads.store(cfg, "b.bvh", pair.body.read_bytes())
    hand, _ = uploads.store(cfg, "h.bvh", pair.hand.read_bytes())
    session.load_uploads(body, hand, "my\nbody\x1b[31m.bvh", "<b>hand</b>.bvh")
    assert session.error == "", session.error
    credit = file_credit(session)
    assert credit.startswith("Spliced with HandSplice from the user's own takes: body my body")
    assert "<b>hand</b>.bvh" in credit and "no licence known" in credit
    assert not re.search(r"[\x00-\x1f\x7f]", credit)
    assert "CC BY" not in credit and "MIT" not in credit and "Licences" not in credit
    assert video_caption(session) in credit
    assert "&lt;b&gt;hand&lt;/b&gt;" in credits_html(session)  # the page: escaped
