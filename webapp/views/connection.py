"""A "connection lost" notice: the page says so when its websocket to the server drops.

Without it a dropped connection is silent: clicks keep drawing points that never
reach the server. When Bokeh reports ``connection_lost`` the page shows a red bar
across the top with a *Reload* button (the address bar holds the session's link, so
a reload restores what the server last knew). Built with DOM calls and
``textContent`` only (no HTML strings).
"""

from __future__ import annotations

from bokeh.models import CustomJS

NOTICE_ID = "hs-connection-lost"
TEXT = (
    "Connection to the server lost: what you do now is not sent to the server. "
    "Reload the page to continue (the link in the address bar keeps the session)."
)

_JS = """
if (window.__hs_connection_watch) { return; }
window.__hs_connection_watch = true;
const show = () => {
  if (document.getElementById(ID)) { return; }
  const bar = document.createElement('div');
  bar.id = ID;
  bar.className = ID;
  bar.setAttribute('role', 'alert');
  bar.style.cssText = 'position:fixed;top:0;left:0;right:0;z-index:100000;display:flex;' +
    'gap:16px;align-items:center;justify-content:center;padding:10px 16px;' +
    'background:#b71c1c;color:#fff;font:15px Helvetica,Arial,sans-serif;' +
    'box-shadow:0 2px 6px rgba(0,0,0,0.3)';
  const text = document.createElement('span');
  text.textContent = TEXT;
  const button = document.createElement('button');
  button.textContent = 'Reload';
  button.className = ID + '-reload';
  button.style.cssText = 'font:600 14px Helvetica,Arial,sans-serif;padding:5px 16px;' +
    'border:0;border-radius:4px;background:#fff;color:#b71c1c;cursor:pointer';
  button.addEventListener('click', () => window.location.reload());
  bar.append(text, button);
  document.body.append(bar);
};
for (const doc of Bokeh.documents) {
  doc.on_event('connection_lost', show);
}
"""


def install(doc) -> None:
    """Watch the page's connection (``doc``: the session's Bokeh document)."""
    if doc is None:
        return
    doc.js_on_event("document_ready", CustomJS(args={"ID": NOTICE_ID, "TEXT": TEXT}, code=_JS))
