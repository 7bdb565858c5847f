"""Where the open takes come from: each sample's description, licence and credit, and the
no-share warning of pairs whose licence forbids sharing spliced results.

All text comes from ``sample_data/samples.json`` and is escaped before it reaches the page.
"""

from __future__ import annotations

import html
import re

import panel as pn

from webapp import config
from webapp.state import Session

#: the share terms of the user's own takes (stranger 11: silence read as "no restriction")
OWN_TAKES_TEXT = (
    "Your own takes: their licences are yours to check before you share spliced results."
)
NO_SHARE_TEXT = (
    "Do not share spliced results of this pair: its licence forbids adapted "
    "material (CC BY-NC-ND). Downloads are for your own use."
)


def _take_entries(pair: config.SamplePair, cfg: config.AppConfig) -> list[tuple[str, str, dict]]:
    """``(role, samples.json name, its entry)`` of the pair's body and hand takes (an empty
    entry for a file samples.json does not list): what the credits and share terms read."""
    files = config.file_credits(cfg.sample_dir)
    out = []
    for role, path in (("body", pair.body), ("hand", pair.hand)):
        rel = config.sample_path(path, cfg.sample_dir) or path.name
        out.append((role, rel, files.get(rel, {})))
    return out


def credits_html(session: Session) -> str:
    """The open pair's description and, per take, its file, source and licence (HTML)."""
    cfg = session.config
    if not session.sample:
        return (
            "<div class='hs-credits' style='font-size:12px;color:#444'>Your own takes: "
            f"{html.escape(session.body_name or 'body')} and "
            f"{html.escape(session.hand_name or 'hand')}.</div>"
        )
    try:
        pair = cfg.sample(session.sample)
    except KeyError:
        return ""
    if pair.extra.get("local"):  # ``handsplice serve BODY HAND``: the user's own files
        return (
            "<div class='hs-credits' style='font-size:12px;color:#444'>Your own takes, "
            f"opened from disk: {html.escape(pair.body.name)} and "
            f"{html.escape(pair.hand.name)}.</div>"
        )
    rows = []
    for role, rel, entry in _take_entries(pair, cfg):
        rows.append(
            f"<li><b>{role}</b> <code>{html.escape(rel)}</code>"
            + (f" — {html.escape(str(entry['description']))}" if entry.get("description") else "")
            + (
                f"<br><span style='color:#555'>credit: {html.escape(str(entry['source']))}"
                if entry.get("source")
                else "<br><span style='color:#555'>"
            )
            + (f" · licence: {html.escape(str(entry['licence']))}" if entry.get("licence") else "")
            + "</span></li>"
        )
    warning = (
        f"<div class='hs-no-share' style='color:#b71c1c;font-weight:600'>"
        f"{html.escape(NO_SHARE_TEXT)}</div>"
        if config.no_share(pair, cfg.sample_dir)
        else ""
    )
    return (
        f"<div class='hs-credits' style='font-size:12px;color:#333'>"
        f"<b>{html.escape(pair.name)}</b>: {html.escape(pair.description)}"
        f"<ul style='margin:4px 0 0 0;padding-left:18px'>{''.join(rows)}</ul>{warning}</div>"
    )


def credits_pane(session: Session) -> pn.viewable.Viewable:
    """The credits of the open takes, following the session's inputs."""
    pane = pn.pane.HTML(
        credits_html(session), css_classes=["hs-credits-pane"], sizing_mode="stretch_width"
    )

    def update(*_):
        pane.object = credits_html(session)

    # names too: the same takes uploaded again under other names (Session.rename_takes)
    session.param.watch(update, ["inputs_revision", "sample", "body_name", "hand_name"])
    return pane


def _short_licence(text: str) -> str:
    """A samples.json licence's name alone (``CC BY-NC 4.0`` of ``CC BY-NC 4.0 per the
    included licence file ...``)."""
    return re.split(r" per | \(|;", text, maxsplit=1)[0].strip()


def share_terms(session: Session) -> tuple[str, str]:
    """What the open pair's downloads may be used for, said beside them (stranger 10: no
    plain licence line where one shares): ``("warning", NO_SHARE_TEXT)`` for a pair whose
    licence forbids sharing (:func:`webapp.config.no_share`), ``("info", text)`` naming each
    take's licence and credit for another bundled pair (non-commercial only where a
    licence is NC), ``("info", OWN_TAKES_TEXT)`` for the user's own takes (uploads, or
    ``serve BODY HAND``). ``text`` is escaped HTML."""
    cfg = session.config
    try:
        pair = cfg.sample(session.sample) if session.sample else None
    except KeyError:
        pair = None
    if pair is None or pair.extra.get("local"):
        return "info", html.escape(OWN_TAKES_TEXT)
    if config.no_share(pair, cfg.sample_dir):
        return "warning", html.escape(NO_SHARE_TEXT)
    parts, non_commercial = [], False
    for role, _rel, entry in _take_entries(pair, cfg):
        licence = _short_licence(str(entry.get("licence", ""))) or "licence not stated"
        non_commercial |= "NC" in licence.replace("-", " ").split()  # CC BY-NC 4.0
        source = f", credit: {entry['source']}" if entry.get("source") else ""
        parts.append(html.escape(f"{role} {licence}{source}"))
    use = " for non-commercial use only" if non_commercial else ""
    return (
        "info",
        f"Licences: {'; '.join(parts)}. Spliced results may be shared{use}, crediting both sources.",
    )


def share_terms_alert(session: Session) -> pn.viewable.Viewable:
    """The pair's share terms beside the downloads (:func:`share_terms`): a warning for a
    no-share pair, a plain licence line for other bundled pairs and for own takes."""
    alert = pn.pane.Alert(
        "",
        alert_type="info",
        css_classes=["hs-share-terms"],
        sizing_mode="stretch_width",
    )

    def update(*_):
        alert.alert_type, alert.object = share_terms(session)

    session.param.watch(update, ["inputs_revision", "sample"])
    update()
    return alert
