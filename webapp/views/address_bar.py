"""The browser's address bar carries the link of the state shown, without history entries.

Every edit, frame and view change gives a new link (:meth:`Session.share_url`); the
address bar takes it by ``history.replaceState``, not as a new history entry. Panel's
``pn.state.location`` pushes one entry per change (``pushState``), and the page did not
follow the browser's Back button to them: Back changed the address bar's ``frame=`` while
the page stayed (stranger 13 F4), so the address bar no longer said what was shown. In an
animation tool scrubbing frames and placing keys are not places to go back to: they have
their own Undo (Ctrl+Z, :class:`webapp.state.Session`'s history), so the address bar
always says what is shown (a reload or a copied address opens it) and Back leaves the app,
to the page before it, as it does on any other single page.
"""

from __future__ import annotations

import panel as pn

from webapp.views import page_js

#: the page's script: the current history entry gets the carrier's query (``source``)
_REPLACE = """
const query = source.value;
if (query && window.location.search !== query) {
  window.history.replaceState(
    window.history.state, '', window.location.pathname + query + window.location.hash);
}
"""


class _Carrier(pn.widgets.TextInput):
    """The hidden field that brings the query to the page: its script runs when the value
    changes and once when the field comes into the page (its first value is no change)."""

    def _get_model(self, doc, root=None, parent=None, comm=None):
        model = super()._get_model(doc, root, parent, comm)
        page_js.run_once(model, _REPLACE, args={"source": model}, doc=doc)
        return model


class AddressBar:
    """The address bar's query (``?sample=...&frame=40``): set :meth:`show` and the page's
    current history entry gets it (no new entry)."""

    def __init__(self):
        self.query = _Carrier(value="", visible=False, css_classes=["hs-address"])
        self.query.jscallback(value=_REPLACE)

    def show(self, query: str) -> None:
        """The address bar's query from now on (``query``: '?' and the link's parameters)."""
        self.query.value = query

    def panel(self) -> pn.viewable.Viewable:
        return self.query
