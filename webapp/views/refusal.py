"""The page's red refusal box: hidden until something is refused, then says why."""

from __future__ import annotations

import panel as pn


def refusal_box(css_class: str, **layout) -> pn.pane.Alert:
    """A hidden red ``Alert`` with the CSS hook ``css_class`` (tests and styles find it
    there); its owner sets ``object`` (escaped text) and ``visible``. ``layout``: Panel's
    sizing and margin options."""
    return pn.pane.Alert("", alert_type="danger", visible=False, css_classes=[css_class], **layout)
