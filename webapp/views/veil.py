"""The open pair's views go inactive while a new pair opens.

While :attr:`webapp.state.Session.opening` is set (a new sample, uploads, a link or a
session file being opened off the event loop, until its first path is in: seconds on a
long take or a marker take) the status line, the matrix, its controls, the trust layers
with their suggested points and the preview still show the previous pair. They are
greyed and take no pointer input (the session refuses edits meanwhile too), and the
page's progress line (:mod:`webapp.views.progress`) says which pair is opening. Once it
is shown, the preview and the suggestions say they are still being made for the new
pair rather than show the previous pair's.
"""

from __future__ import annotations

import panel as pn

from webapp.state import Session

#: the look of a view of the previous pair while the new one opens
INACTIVE = {"opacity": "0.35", "filter": "grayscale(0.8)", "pointer-events": "none"}
#: and once the new pair is shown (explicit values: a style left out of a later update
#: is not removed from the page's element)
ACTIVE = {"opacity": "1", "filter": "none", "pointer-events": "auto"}


class Veil:
    """Greys ``views`` (and blocks their pointer input) while ``session.opening``."""

    def __init__(self, session: Session, *views: pn.viewable.Viewable):
        self.session = session
        self.views = views
        self._styles = [dict(v.styles or {}) for v in views]
        session.param.watch(self._update, ["opening"])
        self._update()

    def _update(self, *_):
        opening = bool(self.session.opening)
        for view, styles in zip(self.views, self._styles, strict=True):
            view.styles = {**styles, **(INACTIVE if opening else ACTIVE)}
            view.css_classes = [c for c in view.css_classes if c != "hs-inactive"] + (
                ["hs-inactive"] if opening else []
            )
