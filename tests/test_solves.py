"""Off-loop solving (webapp.solves): jobs run on a worker, results come back through the
document's next-tick callbacks, the newest edit wins (issue 13)."""

from __future__ import annotations

import threading
import time

import pytest

from webapp import config
from webapp.solves import Job, SolveRunner
from webapp.state import Session


class FakeDoc:
    """Stands in for a Bokeh document: next-tick callbacks are queued (from any thread)
    and run by :meth:`pump` on the test's thread, as the server's event loop would."""

    def __init__(self):
        self._lock = threading.Lock()
        self.callbacks: list = []
        self.loop_thread = threading.get_ident()

    def add_next_tick_callback(self, callback):
        with self._lock:
            self.callbacks.append(callback)

    def pump(self, until, timeout: float = 120.0) -> None:
        deadline = time.monotonic() + timeout
        while not until():
            with self._lock:
                todo, self.callbacks = self.callbacks, []
            for callback in todo:
                callback()
            if not todo:
                assert time.monotonic() < deadline, "the worker never answered"
                time.sleep(0.005)


def _job(kind, name, log, gate=None, fail=False):
    def work(progress):
        log.append(("ran", name, threading.get_ident()))
        progress("pass 1", 0.0)
        if gate is not None:
            assert gate.wait(30)
        if fail:
            raise ValueError(f"{name} refused")
        return name

    return Job(
        kind,
        name,
        work,
        done=lambda result: log.append(("done", result, threading.get_ident())),
        failed=lambda exc: log.append(("failed", str(exc), threading.get_ident())),
        dropped=lambda: log.append(("dropped", name, threading.get_ident())),
    )


def test_newest_solve_wins_and_results_come_back_on_the_loop():
    doc, log = FakeDoc(), []
    busy = []
    runner = SolveRunner(doc, on_busy=busy.append)
    gate = threading.Event()
    runner.submit(_job("solve", "first", log, gate))
    runner.submit(_job("solve", "second", log))  # queued, then replaced by the third
    runner.submit(_job("solve", "third", log))
    assert runner.busy and busy[0] == "first"
    gate.set()
    doc.pump(lambda: not runner.busy)
    ran = [name for what, name, _ in log if what == "ran"]
    assert ran == ["first", "third"]  # the second was never computed
    assert [(w, n) for w, n, _ in log if w in ("done", "failed")] == [("done", "third")]
    assert {n for w, n, _ in log if w == "dropped"} == {"first", "second"}
    # work ran on a worker thread; done and dropped on the loop's
    assert all(t != doc.loop_thread for w, _, t in log if w == "ran")
    assert all(t == doc.loop_thread for w, _, t in log if w != "ran")
    assert busy[-1] == ""


def test_a_refused_newest_solve_reports_and_an_opening_drops_old_solves():
    doc, log = FakeDoc(), []
    runner = SolveRunner(doc)
    gate = threading.Event()
    runner.submit(_job("inputs", "open", log, gate))
    assert not runner.submit(_job("solve", "edit of the old pair", log))  # dropped at once
    gate.set()
    doc.pump(lambda: not runner.busy)
    runner.submit(_job("solve", "bad", log, fail=True))
    doc.pump(lambda: not runner.busy)
    events = [(w, n) for w, n, _ in log if w != "ran"]
    assert events == [
        ("dropped", "edit of the old pair"),
        ("done", "open"),
        ("failed", "bad refused"),
    ]


@pytest.fixture(scope="module")
def cfg():
    return config.configure()


def test_session_off_the_loop_opens_solves_and_keeps_only_the_newest_edit(cfg):
    doc = FakeDoc()
    s = Session(cfg)
    s.compute_off_loop(doc)
    s.load_sample(cfg.default_sample)
    assert s.busy and s.solution is None  # nothing computed on the caller's thread
    doc.pump(lambda: s.solution is not None and not s.busy)
    assert s.revision == 1 and not s.error
    path = s.solution.pass1.path
    x = s.n // 2
    y = int(path[path[:, 0] == x, 1][0])
    # three quick edits: the page shows each at once, only the last is solved and drawn
    s.add_point(x, y)
    s.move_point(0, x, y + 2)
    s.move_point(0, x, y + 4)
    assert s.busy and s.revision == 1 and s.points[0].hand == y + 4
    doc.pump(lambda: not s.busy)
    assert s.revision in (
        2,
        3,
    )  # the first edit may have been running already; never the middle one
    assert s.solution.points == tuple(s.constraint_points())
    assert len(s._undo) == 3 and s.can_undo
    # the same edits at once (no runner) give the same path
    ref = Session(cfg)
    ref.load_sample(cfg.default_sample)
    ref.set_points(s.points)
    assert (ref.solution.pass1.path == s.solution.pass1.path).all()
    assert (ref.solution.pass2.path == s.solution.pass2.path).all()


def test_a_link_without_takes_opens_the_default_pair_off_the_loop(cfg):
    """The page's link of parameters only (``?frame=75``) opened off the loop: the page says
    which pair opens (the default one) and ends with the session a caller's open_link of
    the same link gives."""
    from webapp import app

    query = {"frame": "75", "band": "0.4", "pts": "30:10", "frames": "hand"}
    doc = FakeDoc()
    s = Session(cfg)
    s.compute_off_loop(doc)
    app._initial_state(s, dict(query))
    assert s.opening == cfg.default_sample and s.solution is None
    doc.pump(lambda: s.solution is not None and not s.busy)
    ref = Session(cfg)
    ref.open_link(dict(query))
    assert not s.error and not s.opening and s.frame == 75
    assert s.to_query() == ref.to_query() and s.sample == cfg.default_sample
