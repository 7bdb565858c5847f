"""The page's checkbox: its words toggle it, as on most web pages.

Bokeh 3.9 draws a checkbox's label as a ``div`` beside the ``input`` (not a ``<label>``
around it), so a click on the words did nothing (stranger R5-8: "Hand trails"). Every
checkbox of the page is a :class:`Checkbox`; the first one in the page brings a script
(:data:`_JS_LABEL_CLICKS`, once per page) that turns a click on a checkbox's words into a
click on its box (the box's own ``change`` then updates the widget, as a click on the box
does). A disabled box stays as it is.
"""

from __future__ import annotations

import panel as pn

from webapp.views import page_js

_JS_LABEL_CLICKS = """
if (window.__hsCheckboxLabels) return;
window.__hsCheckboxLabels = true;
document.addEventListener('click', (ev) => {
  const words = ev.composedPath()[0];
  if (!(words instanceof Element) || !words.classList.contains('bk-label')) return;
  const root = words.getRootNode();
  const box = root instanceof ShadowRoot ? root.querySelector('input[type=checkbox]') : null;
  if (box && !box.disabled) box.click();
});
"""

#: the words look like what they do: a hand pointer, no text selection on a double click
_STYLE = ".bk-label { cursor: pointer; user-select: none; }"


class Checkbox(pn.widgets.Checkbox):
    """``pn.widgets.Checkbox`` whose words (its ``name``) toggle it too."""

    def __init__(self, **params):
        params["stylesheets"] = [*params.get("stylesheets", []), _STYLE]
        super().__init__(**params)

    def _get_model(self, doc, root=None, parent=None, comm=None):
        model = super()._get_model(doc, root, parent, comm)
        page_js.run_once(model, _JS_LABEL_CLICKS, doc=doc)
        return model
