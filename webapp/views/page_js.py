"""A view's script that runs once in the page, whenever the view comes into it.

Some views set the page up with a script (the upload fields' kind check, the
keyboard's undo keys, the matrix's long-press setting). Bokeh runs a document's
``document_ready`` callbacks once, when the page first renders; the app's page is a
light shell first and its sections come afterwards (:mod:`webapp.app`), so a view built
then would never run its script that way. :func:`run_once` covers both: the script is
a ``document_ready`` callback (a page built whole) and also runs as soon as the view's
model is in the browser (a change of the model's ``tags`` made on the next tick, after
the model itself was sent). A guard in the page runs it once per model either way.
"""

from __future__ import annotations

import panel as pn
from bokeh.model import Model
from bokeh.models import CustomJS

from webapp.views._dispatch import after, next_tick

#: the tag :func:`run_once` adds to a model to have its script run in the page
RUN_TAG = "hs-page-js"

#: :func:`run_once` looks this often (ms), this many times, for its model in the page
RETRY_MS, RETRIES = 50, 200

_GUARD = """
const ran = (window.__hs_page_js ??= new Set());
if (ran.has(__hs_key)) return;
ran.add(__hs_key);
"""


def run_once(model: Model, code: str, args: dict | None = None, doc=None) -> None:
    """Run the JavaScript function body ``code`` (with ``args``, as ``CustomJS``) once in
    the page of ``doc`` (default: the current document), once ``model`` (a Bokeh model
    being put into that page) is there. Without a document (a page built in a test or
    script) nothing runs."""
    doc = doc if doc is not None else pn.state.curdoc
    if doc is None:
        return
    js = CustomJS(args={**(args or {}), "__hs_key": f"{model.id}:{hash(code)}"}, code=_GUARD + code)
    doc.js_on_event("document_ready", js)
    if doc.session_context is None:
        return
    model.js_on_change("tags", js)

    def tag(tries: int = 0):  # a change the browser applies to the model sent before it
        if model.document is None:  # not in the page yet: its view is added later
            if tries < RETRIES:
                after(doc, lambda: tag(tries + 1), RETRY_MS)
            return
        if RUN_TAG not in model.tags:
            model.tags = [*model.tags, RUN_TAG]

    next_tick(doc, tag)
