"""The page never asks the internet for its stylesheets (the README: nothing downloads).

Panel gives a component its CDN's stylesheet URLs unless the document already names a
local ``dist_url``; it rewrote them only for the models in the page when the page's HTML
was rendered. Under load, widgets made before that moment but shown later (the upload
boxes, the points table) kept the CDN's URLs and a user offline saw them unstyled.
``webapp.app.create_app`` names the local URL first, so every model is born local.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from bokeh.document import Document
from bokeh.models import ImportedStyleSheet

pytest.importorskip("panel")


def _served_page(doc: Document):
    """``create_app``'s page in ``doc`` with every section: the shell the server answers
    with, and the sections it adds once the browser has the shell (its ``onload``)."""
    from webapp import app

    page = app.create_app()
    sections, rest = app._work_sections(page.session)
    page.extend(sections)
    rest()
    page.extend(app._later_sections(page.session))
    return page.get_root(doc)


def _served_doc() -> Document:
    """A document as a Bokeh server session has it, before its page is rendered."""
    doc = Document()
    request = SimpleNamespace(
        arguments={}, headers={}, cookies={}, uri="/", path="/", host="127.0.0.1", protocol="http"
    )
    doc._session_context = lambda: SimpleNamespace(id="t", server_context=None, request=request)
    return doc


def test_every_stylesheet_of_a_new_session_is_served_locally():
    from panel.io.state import set_curdoc

    from webapp import config

    config.configure()
    doc = _served_doc()
    with set_curdoc(doc):
        root = _served_page(doc)
    urls = {str(m.url) for m in root.references() if isinstance(m, ImportedStyleSheet)}
    assert any("filepond" in u for u in urls) and any("tabulator" in u for u in urls), urls
    remote = sorted(u for u in urls if "://" in u)
    assert not remote, remote
    assert all(u.startswith("static/extensions/panel/") for u in urls), sorted(urls)


def test_the_page_layout_passes_bokehs_own_checks():
    """Bokeh validates every document it serves and logs what it finds (W-1005: a 'fixed'
    column without a height); a page that passes its checks keeps the server log quiet."""
    from bokeh.core.validation.check import check_integrity
    from panel.io.state import set_curdoc

    from webapp import config

    config.configure()
    doc = _served_doc()
    with set_curdoc(doc):
        root = _served_page(doc)
    issues = check_integrity(list(root.references()))
    found = [f"{w.code} {w.name}: {w.text}" for w in issues.warning + issues.error]
    assert not found, found
