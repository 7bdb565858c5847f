"""Changing Bokeh models safely from session watchers.

A Bokeh server session must hold its document lock while models change. Bokeh's
own callbacks (``on_change``, ``on_event``, next-tick callbacks) hold it, but Panel
may run widget callbacks (a button click, say) on the event loop without it, and a
model change there raises ``RuntimeError: _pending_writes should be non-None``.
:func:`with_document_lock` runs a change at once when the lock is held (or when
there is no server session: tests, page creation) and otherwise schedules it as a
next-tick callback, which Bokeh runs under the lock.
"""

from __future__ import annotations

import functools

import panel as pn


def _lock_held(doc) -> bool:
    ctx = getattr(doc, "session_context", None)
    session = getattr(ctx, "_session", None) if ctx is not None else None
    if session is None:  # no server session, or the page is being built: nothing to lock
        return True
    return getattr(session, "_pending_writes", None) is not None


def with_document_lock(method):
    """Decorator for view methods that change Bokeh models (see the module docstring)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        doc = pn.state.curdoc
        if doc is None or _lock_held(doc):
            return method(*args, **kwargs)

        def later():
            try:
                method(*args, **kwargs)
            except RuntimeError as exc:
                # the tab closed between scheduling and running: its session has no
                # pending writes any more and nobody will see this change
                if "_pending_writes" not in str(exc):
                    raise

        doc.add_next_tick_callback(later)
        return None

    return wrapper
