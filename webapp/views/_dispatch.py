"""Changing Bokeh models safely from session watchers.

A Bokeh server session must hold its document lock while models change. Bokeh's
own callbacks (``on_change``, ``on_event``, next-tick callbacks) hold it, but Panel
may run widget callbacks (a button click, say) on the event loop without it, and a
model change there raises ``RuntimeError: _pending_writes should be non-None``.
:func:`with_document_lock` runs a change at once when the lock is held (or when
there is no server session: tests, page creation) and otherwise schedules it as a
next-tick callback, which Bokeh runs under the lock.

The lock that matters is the one of the document the view's models belong to (its
tab's). ``pn.state.curdoc`` names the document of the callback that is running, which
can be another tab's: a change scheduled there ran under that tab's lock, not under the
lock of the document it changed. So the view's own document is looked up first, and a
scheduled change runs only if that document's session is still there and holds its
lock (a closed tab's session is discarded: nobody would see the change).
"""

from __future__ import annotations

import functools

import panel as pn
from bokeh.model import Model


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
    """True when ``doc``'s server session holds its document lock, or has none to hold."""
    session = _session_of(doc)
    if session is None:  # no server session, or the page is being built: nothing to lock
        return True
    # bokeh keeps a list of pending writes exactly while the lock is held
    return session._pending_writes is not None


def _still_served(doc) -> bool:
    """True while ``doc``'s server session is alive and holds its lock (a next-tick
    callback's state); False once the tab's session is discarded."""
    session = _session_of(doc)
    return session is not None and not session.destroyed and session._pending_writes is not None


def with_document_lock(method):
    """Decorator for view methods that change Bokeh models (see the module docstring)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        doc = (_view_document(args[0]) if args else None) or pn.state.curdoc
        if doc is None or _lock_held(doc):
            return method(*args, **kwargs)

        def later():
            if _still_served(doc):
                method(*args, **kwargs)

        doc.add_next_tick_callback(later)
        return None

    return wrapper
