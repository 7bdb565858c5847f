"""Changing Bokeh models safely from session watchers.

A Bokeh server session must hold its document lock while models change. Bokeh's
own callbacks (``on_change``, ``on_event``, next-tick and timeout callbacks) hold it,
but Panel may run widget callbacks (a button click, say) on the event loop without
it, a worker thread never holds it, and a model change there raises
``RuntimeError: _pending_writes should be non-None``.

Bokeh has no public way to ask whether the running code holds a document's lock, so
the app keeps that knowledge itself: :func:`next_tick` and :func:`after` schedule a
callback through Bokeh (which runs it under the document's lock) and mark the
document as held while it runs; :class:`Settle` runs a callback once a value has stood
still a while (through :func:`after`). :func:`with_document_lock` runs a change at once when
the running code holds the lock by such a mark (or when there is no server session:
tests, page creation) and otherwise schedules it with :func:`next_tick`. A context the
app did not mark (a Panel widget callback, a worker thread) is treated as unlocked:
the change waits one tick, which is always safe.

The mark is a context variable, so it is the running thread's and task's own (a
worker thread never sees the event loop's mark), and it ends when its callback
returns (an asyncio task started inside one inherits a copy of the variable, but
runs later, when the lock may be another callback's).

The lock that matters is the one of the document the view's models belong to (its
tab's). ``pn.state.curdoc`` names the document of the callback that is running, which
can be another tab's: a change scheduled there ran under that tab's lock, not under the
lock of the document it changed. So the view's own document is looked up first, and a
scheduled change runs only if that document's session is still there (a closed tab's
session is discarded: nobody would see the change).
"""

from __future__ import annotations

import contextvars
import functools
import time
from collections.abc import Callable

import panel as pn
from bokeh.document import Document
from bokeh.model import Model


class _Hold:
    """A running callback's claim that Bokeh runs it under ``doc``'s lock; ``active``
    until the callback returns."""

    __slots__ = ("active", "doc")

    def __init__(self, doc):
        self.doc, self.active = doc, True


# the documents whose lock the running code holds (innermost last)
_HELD: contextvars.ContextVar[tuple[_Hold, ...]] = contextvars.ContextVar(
    "handsplice_document_locks", default=()
)


def under_lock(doc, callback: Callable) -> Callable:
    """``callback``, marked as running under ``doc``'s lock while it runs. Only for a
    callback that Bokeh runs under that lock: use :func:`next_tick` or :func:`after`.

    The document's change events are held while it runs and sent when it returns, repeated
    changes of one property combined into one (Bokeh's ``Document.hold("combine")``): a
    drag's callbacks set some properties several times. They go out through Bokeh's own
    dispatch, one message each, in order. (Panel's ``unlocked`` wrote them as one message
    straight to the websocket: that raced with the messages Bokeh was writing, so a
    message's binary buffers could arrive inside another's and the page failed with
    "Size mismatch" or hung, seen on every upload of a pair: stop 26.)"""

    @functools.wraps(callback)
    def run(*args, **kwargs):
        hold = _Hold(doc)
        token = _HELD.set((*_HELD.get(), hold))
        combine = _hold_events(doc)
        try:
            return callback(*args, **kwargs)
        finally:
            hold.active = False
            _HELD.reset(token)
            if combine:
                doc.unhold()

    return run


def _hold_events(doc) -> bool:
    """Hold ``doc``'s change events (combined) unless they are held already (a callback
    inside another); True if this call holds them (and its caller must ``unhold``)."""
    if not isinstance(doc, Document) or doc.callbacks.hold_value is not None:
        return False  # a test's stand-in document, or held by an outer callback
    doc.hold("combine")
    return True


def next_tick(doc, callback: Callable[[], object]) -> None:
    """Run ``callback`` on ``doc``'s next event-loop tick, under its lock (safe from any
    thread: Bokeh's ``add_next_tick_callback``)."""
    doc.add_next_tick_callback(under_lock(doc, callback))


def after(doc, callback: Callable[[], object], ms: float) -> None:
    """Run ``callback`` ``ms`` milliseconds from now, under ``doc``'s lock."""
    doc.add_timeout_callback(under_lock(doc, callback), ms)


class Settle:
    """Runs ``callback`` once a changing value has stood still ``ms`` milliseconds: each
    :meth:`moved` restarts the quiet time, and one timer at a time waits for it (re-armed
    for the time left when the value moved meanwhile), under ``doc``'s lock
    (:func:`after`). Without a server session (``doc`` None or without a session
    context: tests, scripts, the page being built) ``callback`` runs at once.

    >>> settle = Settle(doc, update_link, 300)   # the link takes the frame once it rests
    >>> session.param.watch(lambda *_: settle.moved(), ["frame"])
    """

    def __init__(self, doc, callback: Callable[[], object], ms: float):
        self.doc, self.callback, self.ms = doc, callback, float(ms)
        self._moved_at = 0.0  # monotonic s of the last move
        self._due = False  # a timer is waiting

    def moved(self) -> None:
        self._moved_at = time.monotonic()
        if self.doc is None or self.doc.session_context is None:
            self.callback()
            return
        if not self._due:
            self._due = True
            after(self.doc, self._stood, self.ms)

    def _stood(self) -> None:
        left_ms = 1000.0 * (self._moved_at - time.monotonic()) + self.ms
        if left_ms > 1.0:  # moved again meanwhile: wait for it to stand
            after(self.doc, self._stood, left_ms)
            return
        self._due = False
        self.callback()


def _view_document(view):
    """The Bokeh document of the first of ``view``'s own Bokeh models that is in one
    (None: none is, e.g. the page is being built or the view holds only Panel objects)."""
    for value in vars(view).values() if hasattr(view, "__dict__") else ():
        if isinstance(value, Model) and value.document is not None:
            return value.document
    return None


def _session_of(doc):
    """The server session serving ``doc`` (None: no server session, or page creation)."""
    ctx = doc.session_context
    return getattr(ctx, "session", None)  # None too for a context without one (a test's)


def _lock_held(doc) -> bool:
    """True when the running code holds ``doc``'s lock (marked by :func:`under_lock`),
    or ``doc`` has no server session whose lock it could need."""
    if _session_of(doc) is None:  # no server session, or the page is being built
        return True
    return any(hold.active and hold.doc is doc for hold in _HELD.get())


def with_document_lock(method):
    """Decorator for view methods that change Bokeh models (see the module docstring)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        doc = (_view_document(args[0]) if args else None) or pn.state.curdoc
        if doc is None or _lock_held(doc):
            return method(*args, **kwargs)

        def later():  # a next-tick callback: Bokeh skips it once the session is destroyed
            session = _session_of(doc)
            if session is not None and not session.destroyed:
                method(*args, **kwargs)

        next_tick(doc, later)
        return None

    return wrapper


#: ms of quiet after an edit's path before the rest of that edit's work (points table,
#: status line, link, trust layers, the other pass's path) starts: the next edit of a drag
#: usually arrives within it, and is then solved and drawn first (the rest waits for its path)
AFTER_PATH_MS = 250


class _AfterPath:
    """One session's views' work that waits until an edit's path is in the page."""

    def __init__(self, session, doc):
        self.session, self.doc = session, doc
        self.due: dict = {}  # key -> callback, first asked first run
        self.armed = False
        #: bumped by every arming: a timer of an older arming runs nothing
        self._generation = 0
        session.param.watch(lambda *_: self._arm(), ["busy"])

    def add(self, key, callback: Callable[[], object]) -> None:
        self.due[key] = callback
        self._arm()

    def _solving(self) -> bool:
        runner = getattr(self.session, "runner", None)
        return runner is not None and runner.solving()

    def _arm(self) -> None:
        if self.armed or not self.due or self._solving():
            return
        self.armed = True
        self._generation += 1
        generation = self._generation
        after(self.doc, lambda: self._run(generation), AFTER_PATH_MS)

    def _alive(self) -> bool:
        session = _session_of(self.doc)
        if session is None or session.destroyed:
            self.due.clear()
            return False
        return True

    def _run(self, generation: int) -> None:
        """One callback a tick, the first asked first, while no newer edit is being
        solved: an edit that arrives meanwhile is handled between them (its solve starts,
        and the rest waits for its path: ``busy`` re-arms)."""
        if generation != self._generation:
            return
        if self._solving() or not self._alive():
            self.armed = False
            return
        if not self.due:
            self.armed = False
            return
        key = next(iter(self.due))
        callback = self.due.pop(key)
        try:
            callback()
        finally:
            if self.due:
                next_tick(self.doc, lambda: self._run(generation))
            else:
                self.armed = False


def after_path(session, key, callback: Callable[[], object], doc=None) -> None:
    """Run ``callback`` once the page has the newest path: the work an edit causes besides
    its band and path (the points table, the status line, the link, the trust layers).

    A Bokeh server sends a callback's model changes when the callback returns, and the
    browser applies them in order, so work done in the tick that draws an edit's path
    (or while its solve runs, delaying that tick) delays the path: on a 2-core machine
    the table, status line, link and trust took ~0.4 s of the loop per edit and their
    widget changes hundreds of ms of the page's. Here it runs :data:`AFTER_PATH_MS` after
    the path, once no solve is running or queued (an edit during a drag supersedes it;
    only the last state's work is done), one callback a tick (an edit arriving meanwhile
    goes first), ``key`` coalescing repeats. Without a server session (tests,
    scripts, the page being built) ``callback`` runs at once.
    """
    doc = doc if doc is not None else pn.state.curdoc
    if doc is None or _session_of(doc) is None:
        callback()
        return
    waiting = getattr(session, "_hs_after_path", None)
    if waiting is None or waiting.doc is not doc:
        waiting = _AfterPath(session, doc)
        session._hs_after_path = waiting
    waiting.add(key, callback)
