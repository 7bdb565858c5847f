"""drag150 (issue 13): the work an edit causes besides its path waits for quiet after the
path and never runs while a newer edit is being solved; it runs one callback a tick, so an
edit arriving meanwhile is handled between them (webapp.views._dispatch.after_path)."""

from __future__ import annotations

from types import SimpleNamespace

import param

from webapp.views import _dispatch
from webapp.views._dispatch import AFTER_PATH_MS, after_path


class _Session(param.Parameterized):
    busy = param.String(default="")

    def __init__(self):
        super().__init__()
        self.runner = SimpleNamespace(solving=lambda: bool(self.busy))


class _Doc:
    """A served document: timeouts and next ticks are queued; the test runs them one by one."""

    def __init__(self):
        self.session_context = SimpleNamespace(session=SimpleNamespace(destroyed=False))
        self.queue: list = []  # (kind, ms, callback)

    def add_timeout_callback(self, callback, ms):
        self.queue.append(("timeout", ms, callback))

    def add_next_tick_callback(self, callback):
        self.queue.append(("tick", 0, callback))

    def step(self):
        kind, ms, callback = self.queue.pop(0)
        callback()
        return kind, ms


def test_the_rest_of_an_edit_waits_for_quiet_and_yields_to_a_newer_edit():
    session, doc, ran = _Session(), _Doc(), []
    session.busy = "aligning"  # the edit's solve runs: nothing is armed
    after_path(session, "table", lambda: ran.append("table"), doc)
    after_path(session, "status", lambda: ran.append("status"), doc)
    after_path(session, "table", lambda: ran.append("table 2"), doc)  # coalesced: the newest
    assert doc.queue == [] and ran == []
    session.busy = ""  # the path is drawn: the rest is due after a quiet pause
    assert [(k, ms) for k, ms, _ in doc.queue] == [("timeout", AFTER_PATH_MS)]
    assert AFTER_PATH_MS >= 100
    assert doc.step() == ("timeout", AFTER_PATH_MS) and ran == ["table 2"]  # one a tick
    # the next drag's edit arrives between two of them: the rest waits for its path
    session.busy = "aligning"
    doc.step()
    assert ran == ["table 2"] and doc.queue == []
    session.busy = ""
    assert [(k, ms) for k, ms, _ in doc.queue] == [("timeout", AFTER_PATH_MS)]
    doc.step()
    assert ran == ["table 2", "status"] and doc.queue == []


def test_a_timer_of_an_earlier_arming_runs_nothing_and_closed_tabs_run_nothing():
    session, doc, ran = _Session(), _Doc(), []
    after_path(session, "a", lambda: ran.append("a"), doc)
    first = doc.queue.pop(0)[2]
    session.busy = "aligning"
    first()  # ran while solving: disarmed, nothing done
    assert ran == []
    session.busy = ""  # re-armed
    assert len(doc.queue) == 1
    doc.session_context.session.destroyed = True
    doc.step()
    assert ran == [] and session._hs_after_path.due == {}


def test_without_a_server_the_work_runs_at_once():
    ran = []
    after_path(_Session(), "a", lambda: ran.append("a"), SimpleNamespace(session_context=None))
    assert ran == ["a"]
    assert _dispatch._session_of(SimpleNamespace(session_context=None)) is None


def test_settle_runs_once_the_value_has_stood_still(monkeypatch):
    """``Settle`` (the link's frame): one timer at a time; a move while it waits re-arms
    it for the time left; the callback runs once, after the last move's quiet time."""
    clock = [100.0]
    monkeypatch.setattr(_dispatch.time, "monotonic", lambda: clock[0])
    doc, ran = _Doc(), []
    settle = _dispatch.Settle(doc, lambda: ran.append("link"), 300)
    settle.moved()
    clock[0] += 0.2
    settle.moved()  # moved again 200 ms later: still one timer
    assert [(k, ms) for k, ms, _ in doc.queue] == [("timeout", 300)]
    clock[0] += 0.1
    doc.step()  # 100 ms after the last move: 200 ms left
    assert ran == [] and [(k, round(ms)) for k, ms, _ in doc.queue] == [("timeout", 200)]
    clock[0] += 0.2
    doc.step()
    assert ran == ["link"] and doc.queue == []
    at_once = _dispatch.Settle(None, lambda: ran.append("at once"), 300)
    at_once.moved()  # no server session: at once
    assert ran == ["link", "at once"]
