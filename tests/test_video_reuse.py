"""A second click on the preview GIF with nothing changed downloads the file made before
(no second render); an edit of the alignment renders a new one."""

from __future__ import annotations

import asyncio
import io

import numpy as np
import pytest
from conftest import open_demo_session

from webapp import backend
from webapp.state import Session


@pytest.fixture
def session(tmp_path) -> Session:
    return open_demo_session(tmp_path / "uploads")


@pytest.fixture
def renders(monkeypatch) -> list[int]:
    """Body frames rendered by ``backend.render_frame`` (each gives a small image that
    depends on the frame and the alignment's hand frame there, so files can be compared
    without the minutes of real renders on a loaded machine)."""
    seen: list[int] = []

    def counted(prepared, solution, body_frame, camera, trails, size):
        seen.append(body_frame)
        hand = backend.frame_triplet(prepared, solution, body_frame)[1]
        image = np.zeros((size[1], size[0], 3), np.uint8)
        image[..., 0], image[..., 1] = body_frame % 256, hand % 256
        return image

    def closeup(prepared, solution, body_frame, size):  # the videos' close-up: as cheap
        return np.full((size[1], size[0], 3), body_frame % 256, np.uint8)

    monkeypatch.setattr(backend, "render_frame", counted)
    monkeypatch.setattr(backend, "render_closeup", closeup)
    return seen


def test_a_second_gif_click_reuses_the_file_until_an_edit(session, renders):
    from webapp.views import sharing

    view = sharing.SharingView(session)
    first = asyncio.run(view._gif())
    assert first is not None and renders, "the first click renders the frames"
    shown, _ = backend.video_frames(session.prepared.n, float(session.prepared.body.fps))
    assert renders == list(shown)
    assert "unchanged" not in view.progress_text.object

    renders.clear()
    second = asyncio.run(view._gif())  # nothing changed: the same file, no render
    assert renders == []
    assert second.getvalue() == first.getvalue()
    assert "unchanged since it was made" in view.progress_text.object
    assert not view.message.visible and not view.gif.disabled

    session.add_point(40, 26, 4)  # an edit: a new alignment, a new file
    third = asyncio.run(view._gif())
    assert renders == list(shown)
    assert third.getvalue() != first.getvalue()
    assert "unchanged" not in view.progress_text.object


class _Stream(io.StringIO):
    def __init__(self, terminal: bool):
        super().__init__()
        self._terminal = terminal

    def isatty(self) -> bool:
        return self._terminal


def test_progress_in_a_log_is_plain_lines_and_on_a_terminal_one_redrawn_bar():
    """R5-5: a preview's progress written to a log (stderr not a terminal) was one line of
    hundreds of carriage-return updates; now a plain line every few seconds and the last one.
    On a terminal it stays a bar redrawn in place."""
    from engine.render.video import progress_printer

    log = _Stream(terminal=False)
    report = progress_printer("preview out.gif", stream=log, log_interval=0.0)
    for done in range(1, 6):
        report(done, 5)
    text = log.getvalue()
    assert "\r" not in text and "#" not in text
    lines = text.splitlines()
    assert len(lines) == 5 and lines[-1].startswith("preview out.gif: 5/5 ")
    quiet = _Stream(terminal=False)
    report = progress_printer("p", stream=quiet)  # the default: one line per 10 s at most
    for done in range(1, 188):
        report(done, 187)
    assert quiet.getvalue().count("\n") == 1 and quiet.getvalue().startswith("p: 187/187")
    tty = _Stream(terminal=True)
    report = progress_printer("p", stream=tty, min_interval=0.0)
    for done in range(1, 4):
        report(done, 3)
    assert tty.getvalue().count("\r") == 3 and tty.getvalue().endswith("\n")
    assert tty.getvalue().count("\n") == 1 and "[" in tty.getvalue()
