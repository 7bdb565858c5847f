"""The one rule that turns a position on the cost matrix into a whole frame.

The page holds a matching point, or the pointer over the matrix, at a position in floats:
x in body frames, y in hand frames of the hand file's numbering. The frame it means is the
nearest whole frame, a half going up, kept within the take (``count`` frames):
:func:`view_frame`. The page says it with :data:`JS_VIEW_FRAME`, the same rule in the
page's language: the cell's and the point's tooltips, and a dragged or clicked point as it
is sent; the session stores a point from the page by :func:`view_frame`. So the hand frame
a tooltip shows during a drag is the one the table lists after it (stranger 11 F7: the
tooltip rounded a half up, the session to the even frame, and neither agreed outside the
take).
"""

from __future__ import annotations

import math


def view_frame(value: float, count: int) -> int:
    """The whole frame at matrix position ``value`` (frames, float): the nearest, a half
    going up, within ``0 .. count - 1``."""
    return int(min(max(math.floor(value + 0.5), 0), max(count - 1, 0)))


#: :func:`view_frame` in the page: ``view_frame(v, count)``, put before code that uses it
JS_VIEW_FRAME = (
    "const view_frame = (v, count) =>"
    " Math.min(Math.max(Math.floor(v + 0.5), 0), Math.max(count - 1, 0));\n"
)
