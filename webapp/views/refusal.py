"""The page's red refusal box: hidden until something is refused, then says why."""

from __future__ import annotations

import panel as pn

#: the browser scrolls a shown box to the middle of the window (it may sit at the screen's
#: edge, below the control that was used)
_INTO_VIEW = (
    "setTimeout(() => { const v = Bokeh.index.find_one(source);"
    " if (v && v.el && source.visible) v.el.scrollIntoView({block: 'center'}); }, 100)"
)


def refusal_box(css_class: str, into_view: bool = False, **layout) -> pn.pane.Alert:
    """A hidden red ``Alert`` with the CSS hook ``css_class`` (tests and styles find it
    there); its owner sets ``object`` (escaped text) and ``visible``. ``into_view``: the
    page scrolls the box into view whenever it is shown or its text changes. ``layout``:
    Panel's sizing and margin options."""
    box = pn.pane.Alert("", alert_type="danger", visible=False, css_classes=[css_class], **layout)
    if into_view:
        box.jscallback(object=_INTO_VIEW, visible=_INTO_VIEW)
    return box
