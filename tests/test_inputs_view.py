"""The takes section (webapp.views.inputs.InputsView) without a browser: uploads go
through its own steps (staged, checked, paired) and each field's tile is read from the
verdicts it was given."""

from __future__ import annotations

import asyncio

import pytest
from conftest import MOCAP, demo_config

from webapp import uploads
from webapp.state import Session
from webapp.views.inputs import InputsView

FINGERS = MOCAP / "gestification" / "fingers-ok.bvh"
HELLO = MOCAP / "gestification" / "hello-world.bvh"
WAVE = MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh"
#: a PNG's first bytes under a .bvh name
PICTURE = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(64)


@pytest.fixture(scope="module")
def cfg(sample_dir, tmp_path_factory):
    return demo_config(sample_dir, tmp_path_factory)


@pytest.fixture
def view(cfg):
    session = Session(cfg)
    session.load_sample("wave-ok")
    inputs = InputsView(session)
    inputs.tiles = {"body": [], "hand": []}  # each field's verdicts, in order
    for which, dropper in inputs._droppers.items():
        dropper.verdict = lambda *a, w=which: inputs.tiles[w].append(a)
    return inputs


def _upload(view: InputsView, which: str, name: str, data: bytes) -> None:
    """``data`` as the file ``name`` in ``which`` field: staged, then checked (and the pair
    opened once both fields hold a checked take), as the page's dropper hands it over."""
    cfg = view.session.config
    view._droppers[which].file_name = name
    staged = uploads.stage_bytes(cfg, name, data)
    asyncio.run(view._check(which, staged, name))


def test_a_refused_file_after_a_refused_pair_keeps_the_other_fields_tile(view):
    """Stranger 11 F4: after a pair was refused (a hand take in the body field), a new
    refused body file emptied both fields while the line still named the hand; the body
    tile turns red "Refused" and the hand's stays "Checked"."""
    _upload(view, "body", "fingers-ok.bvh", FINGERS.read_bytes())
    _upload(view, "hand", "hello-world.bvh", HELLO.read_bytes())
    assert "looks like a hand take" in view.message.object
    assert view.tiles["body"][-1][:3] == ("refused", "fingers-ok.bvh", "Not used")
    assert view.tiles["hand"][-1][:3] == ("ok", "hello-world.bvh", "Checked")
    _upload(view, "body", "picture.bvh", PICTURE)
    assert view.tiles["body"][-1][:3] == ("refused", "picture.bvh", "Refused")
    assert ("clear",) not in view.tiles["hand"], view.tiles["hand"]
    assert view.tiles["hand"][-1][:3] == ("ok", "hello-world.bvh", "Checked")
    line = view.uploaded.object
    assert "hello-world.bvh" in line and "now the other take" in line, line
    assert "binary data" in view.message.object and view.message.visible


def test_a_hand_take_in_the_body_field_says_so_at_once(view):
    """Stranger 11 F10: a hand take uploaded as the body was a green "Checked" and was
    refused only once a hand was added. It is kept (a role override naming its shoulder
    makes it a body), but its tile is amber and the line says at once what will happen;
    a body take in the body field, or a hand take in the hand field, is plain "Checked"."""
    _upload(view, "body", "fingers-ok.bvh", FINGERS.read_bytes())
    assert view.tiles["body"][-1] == ("doubt", "fingers-ok.bvh", "Checked", "245 frames · a hand?")
    line = view.uploaded.object
    assert "looks like a hand take" in line and "role override" in line, line
    assert "now the other take" in line and not view.message.visible
    assert "body" in view._pending  # kept for the pair, not refused
    body = view.session.config.sample("wave-ok").body
    _upload(view, "body", "my-body.bvh", body.read_bytes())
    assert view.tiles["body"][-1][:3] == ("ok", "my-body.bvh", "Checked")
    assert "looks like a hand take" not in view.uploaded.object
    _upload(view, "hand", "fingers-ok.bvh", FINGERS.read_bytes())
    assert view.tiles["hand"][0][:3] == ("ok", "fingers-ok.bvh", "Checked")


def test_a_body_take_in_the_hand_field_says_so_at_once(view, tmp_path):
    """The mirror of stranger 11 F10: a body take without fingers dropped into the hand
    field was said only once the pair was complete ("has no finger joints"). Its tile is
    amber at once and the line says why (``Roles.looks_like_body_take``); the pair is then
    refused for it, as said. A body with fingers (BEAT) in the hand field, or a hand take,
    is plain "Checked": its fingers can be spliced."""
    from conftest import cropped_bvh

    body = view.session.config.sample("wave-ok").body
    _upload(view, "hand", "my-body.bvh", body.read_bytes())
    state, tile, title, words = view.tiles["hand"][-1]
    assert (state, tile, title) == ("doubt", "my-body.bvh", "Checked")
    assert words.endswith(" frames · a body?"), words
    line = view.uploaded.object
    assert "no finger joints (it looks like a body take)" in line and "role override" in line
    assert "now the other take" in line and not view.message.visible
    assert "hand" in view._pending  # kept for the pair, not refused
    walk = MOCAP / "bandai-namco" / "dataset-1_bye_normal_001.bvh"
    _upload(view, "body", "my-walk.bvh", walk.read_bytes())
    assert "my\\-body\\.bvh has no finger joints" in view.message.object  # escaped
    assert "looks like a body take" not in view.uploaded.object  # the refusal says it now
    beat = cropped_bvh(view.session.config.sample("beat-self").body, tmp_path / "wayne.bvh", 60)
    _upload(view, "hand", "wayne.bvh", beat.read_bytes())
    assert view.tiles["hand"][-1][:3] == ("ok", "wayne.bvh", "Checked")
    _upload(view, "hand", "fingers-ok.bvh", FINGERS.read_bytes())
    assert view.tiles["hand"][-1][:3] == ("ok", "fingers-ok.bvh", "Checked")


def test_a_new_take_waits_for_the_other_fields_file_on_its_way(view):
    """Stranger 14 F8: with a pair of uploads open, a new body dropped with a new hand
    opened first with the previous hand (a wasted alignment of a long take) while the
    new hand was still coming; the pair now opens once the file on its way is checked."""
    from webapp.views.dropper import Receipt

    opened = []
    view._open_pair = _recorder(opened, view._open_pair)
    _upload(view, "body", "wave.bvh", WAVE.read_bytes())
    _upload(view, "hand", "hello-world.bvh", HELLO.read_bytes())
    assert len(opened) == 1 and view._open
    # a new hand is coming (its first chunk is in) when a new body has been checked
    view._on_progress("hand", Receipt("hand2.bvh", "hand2.bvh", 10, 100, 1, 10, 0.1))
    _upload(view, "body", "wave2.bvh", cropped_bytes(WAVE, 150))
    assert len(opened) == 1, "opened with the previous hand"
    _upload(view, "hand", "hand2.bvh", cropped_bytes(HELLO, 70))
    assert len(opened) == 2
    assert {k: v.name for k, v in view._open.items()} == {"body": "wave2.bvh", "hand": "hand2.bvh"}
    # the file on its way refused: the new body opens with the open pair's hand
    view._on_progress("hand", Receipt("pic.bvh", "pic.bvh", 10, 100, 1, 10, 0.1))
    _upload(view, "body", "wave3.bvh", cropped_bytes(WAVE, 140))
    assert len(opened) == 2
    _upload(view, "hand", "pic.bvh", PICTURE)
    assert len(opened) == 3
    assert {k: v.name for k, v in view._open.items()} == {"body": "wave3.bvh", "hand": "hand2.bvh"}


def _recorder(calls: list, fn):
    async def wrapped():
        calls.append(1)
        return await fn()

    return wrapped


def cropped_bytes(path, frames: int) -> bytes:
    """The BVH at ``path`` cut to its first ``frames`` frames (other bytes: another take)."""
    text = path.read_text()
    head, _, rows = text.partition("MOTION")
    lines = rows.strip().splitlines()
    body = [ln for ln in lines if not ln.startswith(("Frames:", "Frame Time:"))]
    time = next(ln for ln in lines if ln.startswith("Frame Time:"))
    return (f"{head}MOTION\nFrames: {frames}\n{time}\n" + "\n".join(body[:frames]) + "\n").encode()
