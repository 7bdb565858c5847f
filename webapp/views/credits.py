"""Where the open takes come from: each sample's description, licence and credit, and the
no-share warning of pairs whose licence forbids sharing spliced results; the same words
beside the downloads (:func:`share_terms`) and inside the downloaded files
(:func:`file_credit`, :func:`video_caption`).

All text comes from ``sample_data/samples.json`` (and, for the user's own takes, their file
names) and is escaped before it reaches the page; a file's credit is one line without
control characters.
"""

from __future__ import annotations

import html
import re

import panel as pn

from webapp import config, safe_text
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


def _closing(text: str) -> int:
    """Where the ``)`` closing ``text``'s opening ``(`` is (``len(text)`` when unclosed)."""
    depth = 0
    for k, char in enumerate(text):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if depth == 0:
            return k
    return len(text)


def licence_line(text: str) -> str:
    """A samples.json licence as the share terms say it: its name and every caveat the takes
    panel shows with it, only the ``per ...`` clause (where the name was read) left out:
    ``CC BY-NC 4.0 (non-commercial, with credit; see sample_data/README.md for an upstream
    caveat)``, ``CC BY-NC (the majority of the project, per its README)``, ``CC BY-NC 4.0
    (BEAT; the copy's source repository has no licence file)``, ``MIT``. ``"licence not
    stated"`` for an empty one. (Stranger 12: the line said the name alone and dropped them.)"""
    text = " ".join(str(text).split())
    name = _short_licence(text)
    if not name:
        return "licence not stated"
    rest = text[len(name) :].strip()
    if rest.startswith("per "):  # "per the included licence file and the manifest (...)"
        cut = [i for i in (rest.find(" ("), rest.find(";"), rest.find(":")) if i >= 0]
        rest = rest[min(cut) :] if cut else ""
    rest = rest.strip(" ;:,")
    if rest.startswith("("):  # "(inside)" and what follows it: "(BEAT); the copy's ..."
        end = _closing(rest)
        inside, after = rest[1:end], rest[end + 1 :].strip(" ;:,")
        rest = "; ".join(part for part in (inside.strip(), after) if part)
    return f"{name} ({rest})" if rest else name


def _non_commercial(licence: str) -> bool:
    """True for a licence named non-commercial (``CC BY-NC 4.0``, ``CC BY-NC-ND 4.0``)."""
    return "NC" in _short_licence(licence).replace("-", " ").split()


def _pair(session: Session) -> config.SamplePair | None:
    """The open bundled pair, or None for the user's own takes (uploads, ``serve BODY HAND``)."""
    cfg = session.config
    try:
        pair = cfg.sample(session.sample) if session.sample else None
    except KeyError:
        return None
    return None if pair is None or pair.extra.get("local") else pair


def _licences(pair: config.SamplePair, cfg: config.AppConfig) -> tuple[str, bool]:
    """``("body <licence line>, credit: <source>; hand ...", non-commercial)`` of a bundled
    pair's takes (plain text): the one wording of the takes' licences beside the downloads
    and inside them."""
    parts, non_commercial = [], False
    for role, _rel, entry in _take_entries(pair, cfg):
        licence = str(entry.get("licence", ""))
        non_commercial |= _non_commercial(licence)
        source = f", credit: {entry['source']}" if entry.get("source") else ""
        parts.append(f"{role} {licence_line(licence)}{source}")
    return "; ".join(parts), non_commercial


def share_terms_text(session: Session) -> tuple[str, str]:
    """What the open pair's downloads may be used for (plain text; :func:`share_terms` is
    its HTML): ``("warning", NO_SHARE_TEXT)`` for a pair whose licence forbids sharing
    (:func:`webapp.config.no_share`), ``("info", text)`` naming each take's licence (with
    its caveats, :func:`licence_line`) and credit for another bundled pair (non-commercial
    only where a licence is NC), ``("info", OWN_TAKES_TEXT)`` for the user's own takes."""
    cfg = session.config
    pair = _pair(session)
    if pair is None:
        return "info", OWN_TAKES_TEXT
    if config.no_share(pair, cfg.sample_dir):
        return "warning", NO_SHARE_TEXT
    licences, non_commercial = _licences(pair, cfg)
    use = " for non-commercial use only" if non_commercial else ""
    return (
        "info",
        f"Licences: {licences}. Spliced results may be shared{use}, crediting both sources.",
    )


def share_terms(session: Session) -> tuple[str, str]:
    """The open pair's share terms beside the downloads (stranger 10: no plain licence line
    where one shares): :func:`share_terms_text` as escaped HTML ``(alert type, html)``."""
    kind, text = share_terms_text(session)
    return kind, safe_text.html(text)


def _file_words(session: Session) -> tuple[str, str]:
    """``(what, terms)`` a downloaded file says of itself: which takes were spliced, and
    their licences and credits (the page's share terms, :func:`share_terms_text`, word for
    word; a no-share pair's with its takes' licences and credits before the warning; the
    user's own takes said to be theirs, no licence invented)."""
    cfg = session.config
    kind, terms = share_terms_text(session)
    pair = _pair(session)
    if pair is None:
        body, hand = session.body_name, session.hand_name
        if session.sample:  # ``serve BODY HAND``: the files opened from disk
            paths = session.take_paths()
            body, hand = (paths[0].name, paths[1].name) if paths else (body, hand)
        what = (
            f"Spliced with HandSplice from the user's own takes: body {body or 'take'}, "
            f"hand {hand or 'take'} (no licence known to HandSplice)."
        )
        return what, terms
    names = ", ".join(f"{role} {rel}" for role, rel, _ in _take_entries(pair, cfg))
    what = f"Spliced with HandSplice from the sample pair {pair.name} ({names})."
    if kind == "warning":  # the page says the warning alone; the file credits too
        terms = f"Licences: {_licences(pair, cfg)[0]}. {terms}"
    return what, terms


def file_credit(session: Session) -> str:
    """The credit a downloaded file carries inside it (GIF comment, MP4 comment, GLB
    ``asset.copyright``; stranger 12 F7: a colleague given only the file could not tell
    its sources or licence): which takes were spliced and their licences and credits, in
    the page's words (:func:`_file_words`). One line, no control characters (a file
    name's: :func:`webapp.safe_text.one_line`)."""
    return safe_text.one_line(" ".join(_file_words(session)))


def video_caption(session: Session) -> str:
    """The line burned under a preview video's frames (and its MP4 ``copyright`` tag): a
    video is watched, not inspected. A bundled pair's licences and credits (the page's
    share terms, :func:`_file_words`); for the user's own takes, which takes they are."""
    what, terms = _file_words(session)
    return safe_text.one_line(what if _pair(session) is None else terms)


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
