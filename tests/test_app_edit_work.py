"""What an edit in the app recomputes besides its solve (issue 13: edits cost what they
change). The preview after an edit keeps the views and mannequins of the pair's previous
preview: rebuilding the body's and the hand take's (and the spliced take's mesh) took much
of the server's CPU after each edit, beside the next edit's solve; an edit's trust assessment waits until the session's solves are done
(benchmarks/RESULTS.md, section app)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import open_demo_session

from webapp import backend
from webapp.state import Session


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> Session:
    return open_demo_session(tmp_path_factory.mktemp("uploads"))


def test_an_edit_keeps_the_preview_meshes_it_does_not_change(session):
    prepared = session.prepared
    before = backend.preview_for(prepared, session.solution)
    body, hand = prepared.body, prepared.hand
    session.add_point(session.n // 2, session.hand_frame_for(session.n // 2) + 3, 1)
    after = backend.preview_for(prepared, session.solution)
    assert after is not before and [v.motion for v in after.views[:2]] == [body, hand]
    # the body and the hand take did not change: their views (joints, meshes, framing) are
    # not built again
    assert all(a is b for a, b in zip(after.views[:2], before.views[:2], strict=True))
    spliced = backend.splice(prepared, session.solution)
    assert after.views[2] is not before.views[2] and after.views[2].motion is spliced
    # the spliced take changed, its skeleton did not: its mannequin is kept
    assert after.views[2].mesh is before.views[2].mesh


class _LoopDoc:
    """A served document's callbacks, run by the test as the event loop would run them."""

    session_context = object()  # a served page: the trust view defers its assessments

    def __init__(self):
        self.callbacks: list = []

    def add_timeout_callback(self, callback, ms):
        self.callbacks.append(callback)

    def add_next_tick_callback(self, callback):
        self.callbacks.append(callback)

    def run(self) -> None:
        while self.callbacks:
            todo, self.callbacks = self.callbacks, []
            for callback in todo:
                callback()


class _AtOnce:
    """A pool that runs each job when it is submitted (the test's thread is the worker)."""

    @staticmethod
    def submit(fn, *args):
        from concurrent.futures import Future

        future = Future()
        try:
            future.set_result(fn(*args))
        except Exception as exc:  # as a pool does: the future holds it
            future.set_exception(exc)
        return future


def _nudge(session) -> None:
    """One edit: a matching point added near the path, or the first one moved."""
    if not session.points:
        x = session.n // 2
        session.add_point(x, session.hand_frame_for(x), 2)
    else:
        p = session.points[0]
        session.move_point(0, p.body, p.hand + 2)


def test_trust_is_assessed_once_edits_pause_never_beside_a_solve(session, monkeypatch):
    """An edit's assessment (about four solves) waits while the session solves and runs one
    at a time per page, for the newest edit: assessments of every edit of a drag ran beside
    its solves and slowed them (benchmarks/RESULTS.md, section app)."""
    from webapp.views import trust as trust_view
    from webapp.views.cost_matrix import CostMatrixView

    monkeypatch.setattr(trust_view, "DEBOUNCE_MS", 0)
    monkeypatch.setattr(trust_view, "_POOL", _AtOnce())
    view = trust_view.TrustView(session, CostMatrixView(session))
    doc = _LoopDoc()
    view._doc = doc
    assessed: list[int] = []
    real = session.assess
    monkeypatch.setattr(session, "assess", lambda *a: assessed.append(session.revision) or real(*a))

    session.busy = "aligning"  # the solve of a next edit is running
    _nudge(session)
    doc.run()
    assert assessed == [] and session.trust is None  # nothing beside the solve
    session.busy = ""  # solved and drawn: the newest edit is assessed, once
    doc.run()
    assert assessed == [session.revision] and session.trust is not None
    # two edits while an assessment runs: no second one beside it, then one of the newest
    view._running = True
    _nudge(session)
    _nudge(session)
    doc.run()
    assert len(assessed) == 1 and session.trust is None
    view._running = False
    view._schedule(0)
    doc.run()
    assert assessed[1:] == [session.revision] and session.trust is not None


def test_the_desync_line_says_the_first_assessment_is_running(session, monkeypatch):
    """Until a pair's first trust assessment is drawn, its line says one is running: a
    10-minute pair's took minutes, and the empty line looked finished with nothing to say
    (benchmarks/RESULTS.md, section app_tenmin)."""
    from webapp.views import trust as trust_view
    from webapp.views.cost_matrix import CostMatrixView

    real = session.update_trust
    session.param.update(trust=None)  # the module's earlier tests assessed this alignment
    monkeypatch.setattr(session, "update_trust", lambda *a, **k: False)  # still running
    view = trust_view.TrustView(session, CostMatrixView(session))
    assert trust_view.ASSESSING in view.summary.object
    assert all(b.disabled or not b.visible for b in view.buttons)
    real()  # the assessment arrives: the line is its summary
    assert "Desync meter" in view.summary.object
    assert trust_view.ASSESSING not in view.summary.object


def test_a_shared_alignment_no_page_shows_lets_go_of_its_spliced_take_and_preview(session):
    """The pair's shared first alignment is kept for later tabs; its spliced take and
    preview (0.14 GB at 10 minutes) only while a page shows it (issue 13, app memory)."""
    import gc

    class Page:  # a page as the registry sees it (a Session in the app)
        pass

    prepared, edited = session.prepared, session.solution
    shared = backend.solve(prepared, edited.band, edited.refine_band, [])
    shared.cache["shared"] = True  # as backend.first_solution marks it
    a, b = Page(), Page()
    backend.showing(a, shared)
    backend.showing(b, shared)
    preview = backend.preview_for(prepared, shared)
    spliced = backend.splice(prepared, shared)
    backend.showing(a, edited)  # one page moved on, the other still shows it
    assert shared.cache["preview"] is preview and shared.cache["spliced"] is spliced
    backend.showing(b, None)  # that page closed: nobody shows it
    assert "preview" not in shared.cache and "spliced" not in shared.cache
    assert all(p is not preview for p in backend._PREVIEWS.values())
    # a render asked for it meanwhile (a job queued before the page moved on): not kept
    again = backend.render_frame(prepared, shared, 3, "front", False, size=(96, 64))
    assert again.shape == (64, 96, 3) and "preview" not in shared.cache
    assert "spliced" not in shared.cache
    backend.showing(a, shared)  # shown again: made again and kept while shown
    backend.render_frame(prepared, shared, 3, "front", False, size=(96, 64))
    assert "preview" in shared.cache and "spliced" in shared.cache
    backend.showing(a, None)
    assert "preview" not in shared.cache
    # an alignment of one page only goes with the page when it closes
    backend.preview_for(prepared, edited)
    backend.showing(a, edited)
    backend.showing(a, None)
    assert "preview" in edited.cache
    # and lets go of its spliced take and preview when its page moves on to an edit (during
    # drags the render worker or a trust being given up could still hold it: tenmin2)
    mine, newer = (backend.solve(prepared, edited.band, edited.refine_band, []) for _ in "ab")
    backend.showing(a, mine)
    backend.preview_for(prepared, mine)
    backend.showing(a, newer)
    assert "preview" not in mine.cache and "spliced" not in mine.cache
    backend.splice(prepared, mine)  # a render queued before the move: not kept
    assert "spliced" not in mine.cache
    backend.showing(a, None)
    # the session tells the registry what it shows after every edit
    session.add_point(session.n // 3, session.hand_frame_for(session.n // 3), 1)
    gc.collect()
    assert backend._SHOWN.get(session) is session.solution is not edited
    # the page closes: it shows nothing, even when a solve begun before lands afterwards
    session.page_closed()
    assert session not in backend._SHOWN
    session.solution = edited
    assert session not in backend._SHOWN


class _Runner:
    """The session's solve runner as the trust view sees it: ``solving()`` is set by the test."""

    def __init__(self):
        self.now = False

    def solving(self) -> bool:
        return self.now


def test_an_assessment_is_given_up_when_a_newer_edit_is_being_solved(session, monkeypatch):
    """drag150: an assessment (about four solves) that runs when the next drag's edit arrives
    stops at its next look (between its γ sweeps) instead of taking a core from that edit's
    solve; the newer edit is assessed once it is drawn and edits pause."""
    from webapp.views import trust as trust_view
    from webapp.views.cost_matrix import CostMatrixView

    monkeypatch.setattr(trust_view, "DEBOUNCE_MS", 0)
    monkeypatch.setattr(trust_view, "_POOL", _AtOnce())
    runner = _Runner()
    view = trust_view.TrustView(session, CostMatrixView(session))
    doc = _LoopDoc()
    view._doc = doc
    looks: list[bool] = []
    real = session.assess

    def assess(cancelled=None):
        def look():  # the next drag's edit arrives after the assessment's first look
            looks.append(runner.now)
            stop = cancelled()
            runner.now = True
            return stop

        return real(look)

    monkeypatch.setattr(session, "assess", assess)
    # the module's earlier trust views (built without a served page) would assess at once
    real_update = session.update_trust
    monkeypatch.setattr(
        session,
        "update_trust",
        lambda assessment=None, revision=None: (
            assessment is not None and real_update(assessment, revision)
        ),
    )
    _nudge(session)  # solved at once (no runner); its assessment is due
    monkeypatch.setattr(session, "runner", runner)
    doc.run()
    assert looks[:2] == [False, True] and len(looks) == 2  # stopped at its second look
    assert view.cancelled == 1 and session.trust is None
    # the newer edit is solved and drawn: it is assessed (the stopped one is not "failed")
    runner.now = False
    monkeypatch.setattr(session, "assess", real)
    monkeypatch.setattr(session, "runner", None)
    _nudge(session)
    monkeypatch.setattr(session, "runner", runner)
    doc.run()
    assert session.trust is not None and view._failed != session.revision


def test_an_edit_is_solved_while_a_preview_splices_the_previous_alignment(session, monkeypatch):
    """A drag's solve does not wait for the splice of the previous alignment (the preview's
    or a download's: 0.2-0.9 s on a 2-minute pair): they hold different locks."""
    import threading

    from engine.splice import pipeline

    inside, release = threading.Event(), threading.Event()
    transfer = pipeline.transfer

    def slow_transfer(*args, **kwargs):
        inside.set()
        release.wait(60)
        return transfer(*args, **kwargs)

    monkeypatch.setattr(pipeline, "transfer", slow_transfer)
    prepared, previous = session.prepared, session.solution
    previous.cache.pop("spliced", None)
    splicer = threading.Thread(target=backend.splice, args=(prepared, previous))
    splicer.start()
    try:
        assert inside.wait(60)
        x = session.n // 2
        points = [(x, int(previous.cache["engine"].warp[x]) + 2, 1.0)]
        band, refine = session.widths()
        solved = []
        solver = threading.Thread(
            target=lambda: solved.append(
                backend.solve(prepared, band, refine, points, previous=previous)
            )
        )
        solver.start()
        solver.join(60)
        assert solved, "the edit's solve waited for the splice"
        fresh = backend.solve(prepared, band, refine, points)
        assert np.array_equal(solved[0].pass2.path, fresh.pass2.path)
        np.testing.assert_array_equal(solved[0].warp, fresh.warp)
    finally:
        release.set()
        splicer.join(60)


def test_a_splice_that_starts_while_a_solve_runs_waits_for_it(session):
    """The other way round, the solve goes first: a preview's splice asked for while a
    drag's solve runs (it holds the pair's lock) starts once the solve is done, instead
    of sharing the CPU with it."""
    import threading

    prepared, solution = session.prepared, session.solution
    solution.cache.pop("spliced", None)
    splicer = threading.Thread(target=backend.splice, args=(prepared, solution))
    with prepared.lock:  # a solve running
        splicer.start()
        splicer.join(0.5)
        assert splicer.is_alive() and "spliced" not in solution.cache
    splicer.join(60)
    assert not splicer.is_alive() and "spliced" in solution.cache


def test_a_preview_splice_is_given_up_between_blocks_once_a_newer_edit_is_solved(
    session, monkeypatch
):
    """drag11: the preview's splice of the whole take (0.7 s of CPU at 72,000 frames) is
    given up at its next block of frames once a newer edit is being solved, instead of
    running beside that edit's solve to the end (it had no look inside: the drags it
    overlapped on the 10-minute pair took 3.4-3.9 s instead of 1.1-2.4 s); nothing is
    kept, and a splice that is still wanted makes the whole take."""
    from engine.base.errors import Cancelled
    from engine.splice import transfer as TR
    from webapp.views import preview

    prepared, solution = session.prepared, session.solution
    monkeypatch.setattr(TR, "TRANSFER_CHUNK", 32)
    assert session.n > 3 * 32
    blocks: list[int] = []
    block = TR._transfer_block
    monkeypatch.setattr(TR, "_transfer_block", lambda *a: (blocks.append(a[5]), block(*a))[1])
    rendered: list[int] = []
    monkeypatch.setattr(backend, "render_frame", lambda *a, **k: rendered.append(1))

    def stale() -> bool:  # the next drag's edit arrives during the splice's first block
        return len(blocks) >= 1

    solution.cache.pop("spliced", None)
    with pytest.raises(Cancelled):
        preview._render_images(prepared, solution, 0, "front", False, (64, 64), (64, 64), stale)
    assert blocks == [0] and not rendered and "spliced" not in solution.cache
    blocks.clear()
    whole = backend.splice(prepared, solution, cancelled=lambda: False)
    assert blocks == list(range(0, session.n, 32)) and whole.n_frames == session.n
    assert backend.splice(prepared, solution) is whole  # kept: the downloads' take


def test_a_given_up_preview_keeps_no_spliced_arrays_while_its_future_lives(session, monkeypatch):
    """mem29: a worker's future keeps the exception it ended with, and the exception every
    frame it passed through: a preview's splice given up mid-way kept its spliced take's
    rotations (81 MB at 10 minutes) alive while the page held the future (until the next
    edit's path is drawn: under that edit's solve). Run as the page runs it
    (``run_cancellable``), the future's Cancelled holds none of them."""
    import concurrent.futures
    import weakref

    from engine.base.errors import Cancelled, run_cancellable
    from engine.splice import transfer as TR
    from webapp.views import preview

    prepared, solution = session.prepared, session.solution
    monkeypatch.setattr(TR, "TRANSFER_CHUNK", 32)
    made: list = []
    block = TR._transfer_block
    monkeypatch.setattr(
        TR, "_transfer_block", lambda *a: (made.append(weakref.ref(a[7].base)), block(*a))[1]
    )
    job = (prepared, solution, 0, "front", False, (64, 64), (64, 64), lambda: len(made) >= 1)
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        for wrap, kept in ((False, True), (True, False)):
            made.clear()
            solution.cache.pop("spliced", None)
            future = (
                pool.submit(run_cancellable, preview._render_images, *job)
                if wrap
                else pool.submit(preview._render_images, *job)
            )
            with pytest.raises(Cancelled):
                future.result()
            assert made and (made[0]() is not None) is kept  # the rotations (n, J, 4)
            del future


def test_a_preview_of_a_new_alignment_is_given_up_while_its_view_is_posed(session, monkeypatch):
    """drag11: the preview's view of an edit's spliced take (every frame posed for the
    framing: 0.75 s of CPU at 72,000 frames) is given up at its next block once a newer
    edit is being solved; no preview is kept, and the next render builds it whole."""
    from engine.base.errors import Cancelled
    from engine.render import scene
    from webapp.views import preview

    prepared = session.prepared
    _nudge(session)  # a new alignment: its spliced take's view is built by the next render
    solution = session.solution
    backend.splice(prepared, solution)  # made already (the step before the view)
    monkeypatch.setattr(scene, "BLOCK_FRAMES", 32)
    posed: list = []
    fk = scene.forward_kinematics
    monkeypatch.setattr(scene, "forward_kinematics", lambda *a: (posed.append(a[1]), fk(*a))[1])

    def stale() -> bool:  # the next drag's edit arrives while the first block is posed
        return len(posed) >= 2  # the bind frame, then the first block

    with pytest.raises(Cancelled):
        preview._render_images(prepared, solution, 0, "front", False, (64, 64), (64, 64), stale)
    assert len(posed) == 2 and "preview" not in solution.cache
    png, close_png, _frames, _ms = preview._render_images(
        prepared, solution, 0, "front", False, (64, 64), (64, 64), lambda: False
    )
    assert png and close_png and solution.cache["preview"].views[2].n_frames == session.n


def test_a_drag_under_way_holds_back_the_previous_edits_assessment(session, monkeypatch):
    """drag11: from the moment the page says a matching point is being dragged
    (``hs-drag-press``; its edit comes on release) the previous edit's assessment does not
    start, and one running stops at its next look; the preview's renders are stale
    meanwhile (``edit_coming``). Once the drag ends the assessment goes on."""
    from webapp.views import trust as trust_view
    from webapp.views.cost_matrix import CostMatrixView

    monkeypatch.setattr(trust_view, "DEBOUNCE_MS", 0)
    monkeypatch.setattr(trust_view, "_POOL", _AtOnce())
    matrix = CostMatrixView(session)
    view = trust_view.TrustView(session, matrix)
    doc = _LoopDoc()
    view._doc = doc
    real = session.assess
    looks: list[bool] = []

    def assess(cancelled=None):
        def look():  # the drag begins after the assessment's first look
            looks.append(session.dragging)
            stop = cancelled()
            matrix.press_source.data = {"down": [1]}
            return stop

        return real(look)

    monkeypatch.setattr(session, "assess", assess)
    # the module's earlier trust views (built without a served page) would assess at once
    real_update = session.update_trust
    monkeypatch.setattr(
        session,
        "update_trust",
        lambda assessment=None, revision=None: (
            assessment is not None and real_update(assessment, revision)
        ),
    )
    _nudge(session)  # an edit, solved and drawn: its assessment is due
    doc.run()
    assert looks[:2] == [False, True] and len(looks) == 2 and view.cancelled == 1
    assert session.dragging and session.edit_coming() and session.trust is None
    doc.run()  # nothing starts while the drag is under way
    assert len(looks) == 2
    monkeypatch.setattr(session, "assess", real)
    matrix.press_source.data = {"down": [0]}  # released without moving the point
    assert not session.dragging and not session.edit_coming()
    doc.run()
    assert session.trust is not None
