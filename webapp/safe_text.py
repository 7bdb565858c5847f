"""Outside text made safe for the page (and for files' metadata): the one place that escapes it.

Text that comes from a file (joint names, reader errors), a file name, a link or a
session file may hold HTML or Markdown. Before it reaches a pane it goes through
:func:`html` (for ``pn.pane.HTML``) or :func:`markdown` (for ``pn.pane.Markdown`` and
``pn.pane.Alert``, which render Markdown *and* inline HTML), so the page shows it
literally and never runs it.
"""

from __future__ import annotations

import html as _html
import re

#: characters Markdown gives a meaning to (backslash-escaped so they show literally)
_MARKDOWN_SPECIALS = re.compile(r"([\\`*_{}\[\]()#+\-.!|~>])")
#: control characters other than tab: dropped (they have no place in a one-line message)
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f]")


def html(text: object) -> str:
    """``text`` as HTML text content: ``&``, ``<``, ``>`` and both quotes escaped."""
    return _html.escape(_CONTROL.sub("", str(text)), quote=True)


def markdown(text: object) -> str:
    """``text`` for a Markdown pane: shown literally (no markup, no HTML, no links).

    HTML's ``&``, ``<``, ``>`` become entities first; then every character Markdown
    reads as markup gets a backslash (``*``, ``_``, ``[``, ``(``, ``#``...), so
    ``[x](javascript:...)`` is text, not a link.
    """
    escaped = _html.escape(_CONTROL.sub(" ", str(text)), quote=False)
    # entities (&amp; &lt; &gt;) hold no Markdown specials, so this cannot break them
    return _MARKDOWN_SPECIALS.sub(r"\\\1", escaped)


def one_line(text: object) -> str:
    """``text`` for a file's metadata (a GIF comment, an MP4 tag, a GLB's ``asset``): one
    line, every control character (line breaks and tabs included) a space, runs of spaces
    one (a file name's control characters never reach a file a viewer shows)."""
    return " ".join(_CONTROL.sub(" ", str(text)).replace("\t", " ").split())
