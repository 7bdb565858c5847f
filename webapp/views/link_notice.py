"""The page's top notice for a shared link that did not open as it was sent."""

from __future__ import annotations

from urllib.parse import urlencode

import panel as pn

from engine.io.session import QUERY_NAMES
from webapp import safe_text
from webapp.state import Session


def link_notice(session: Session, args: dict[str, str]) -> pn.viewable.Viewable:
    """A notice at the page's top, hidden until ``session.link_notice`` says what of the
    page's shared link ``args`` (its decoded query) was left out; it quotes the link as
    sent (the address bar then shows the pair that is open, so the sent link would be
    lost) and stays until its Close button. Every text is escaped (``safe_text``)."""
    alert = pn.pane.Alert(
        "", alert_type="warning", css_classes=["hs-link-notice"], sizing_mode="stretch_width"
    )
    close = pn.widgets.Button(label="Close", width=80, css_classes=["hs-link-notice-close"])
    box = pn.Row(alert, close, visible=False, sizing_mode="stretch_width", margin=(0, 10))
    sent = "?" + urlencode(args)
    # the files a link of uploads names: what to ask its sender for (stranger 9)
    named = ", ".join(f"{args[key]} ({role})" for role, key in QUERY_NAMES.items() if args.get(key))

    def update(*_):
        text = session.link_notice
        # what to ask the sender for only while the link waits for takes this server
        # lacks (stranger 12: said with both files open here); once they are open, what
        # is left to say is only what of it was left out
        link_takes = tuple(str(args.get(k, "")).lower() for k in ("body", "hand"))
        wanted = (
            named
            and session.link_waits_for(*link_takes)
            and (session.body_sha256, session.hand_sha256) != link_takes
        )
        if text:
            alert.object = (
                "**This page's link did not open as it was sent:** "
                + safe_text.markdown(text)
                + (
                    "<br>The files it names: "
                    + safe_text.markdown(named)
                    + ". Ask its sender for them and upload them below (Body take, Hand"
                    " take): uploading them applies the link, its matching points and"
                    " bands, to those files."
                    if wanted
                    else ""
                )
                + "<br>The link as sent: <code style='word-break: break-all'>"
                + safe_text.markdown(sent)
                + "</code>"
            )
        box.visible = bool(text)

    def closed(_):
        box.visible = False

    close.on_click(closed)
    session.param.watch(update, ["link_notice"])
    update()
    return box
