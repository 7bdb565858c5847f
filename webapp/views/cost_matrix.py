"""The DTW cost matrix: local or cumulative cost image, band, optimal path, matching points.

x is the body frame (matrix row i), y the hand frame in the hand file's own numbering,
so a matching point (body frame, hand frame) sits at (x, y), as the table, the preview
caption, the session file and ``--match`` count it. The solver's columns are the
alignment grid (the hand take at the body's rate); column j is drawn at hand frame
j × hand_scale (hand fps / body fps), so band, path and image sit where the hand
file's frames are. Axes and hover also give seconds.

Editing: with the point tool active (the default) a click adds a matching point,
a drag moves one, Backspace deletes the selected one. The page never waits for the
server: each click, drag end or delete becomes a numbered edit (the point list
before and after it) in a queue the page sends whole until the server has answered
(``hs-edit-queue``). The server applies the new edits one by one, in order, as what
they did (add, move, delete) to the session's points; then it sends the session's
points back with the number of the last edit they include (``hs-server-points``),
and the page adopts them only when no newer edit of its own is still unanswered.
So quick clicks all arrive, an old answer never overwrites a newer click, and a
refused edit disappears with the reason shown. Only the band, path and point
sources change, so the page does not re-render the figure.

Large matrices: the image is a view of at most ``max_pixels`` cells per axis of the
visible range, fetched again (throttled) when the visible range changes, so a
10,000 x 10,000 matrix costs the page no more than a small one and zooming in shows
full detail. So are the lines (band edges, both paths, the uncertain region, the
wrist-speed strips): thinned to the plot's screen columns of the visible range
(``webapp.views.decimate``, drawn the same), so an edit of a 10-minute take sends a few
thousand vertices, not one per frame, and a zoom brings every frame in view.
"""

from __future__ import annotations

import numpy as np
import panel as pn
from bokeh.events import DoubleTap, PanEnd, PanStart, RangesUpdate, Tap
from bokeh.models import (
    BoxZoomTool,
    ColorBar,
    ColumnDataSource,
    CustomJS,
    CustomJSHover,
    CustomJSTickFormatter,
    HoverTool,
    LinearColorMapper,
    PointDrawTool,
    Range1d,
)
from bokeh.palettes import Viridis256
from bokeh.plotting import figure

from engine.base.json_text import JsonTextError, parse_json
from webapp.matrix_frames import JS_VIEW_FRAME
from webapp.state import Session
from webapp.views import decimate, page_js
from webapp.views._dispatch import after, after_path, next_tick, with_document_lock

PATH_COLOR = "#ff3b30"
OTHER_PATH_COLOR = "#ffffff"
BAND_COLOR = "#4fc3f7"
POINT_COLOR = "#ffd60a"
#: the ring of the selected matching point (the one Backspace deletes): magenta, unlike
#: the matrix's colours, the path, the band and the points' yellow
SELECTED_POINT_RING = "#e040fb"
#: a matching point's marker, pixels across, and how near (pixels from its centre) the
#: pointer shows the point's tooltip instead of the cell's
POINT_SIZE = 13
#: pixels across of the area round a point where a click selects (or drags) the point
#: instead of adding one beside it (stranger 8: a click 10 px off a 13 px point added a
#: near-duplicate point); the point's tooltip shows over the same area
POINT_HIT_SIZE = 24
POINT_HOVER_PX = POINT_HIT_SIZE / 2
AXIS_SIGNAL_SIZE = 90
#: pixels right of the matrix's frame, for its colour bar (labels up to 5 digits) and its
#: toolbar: reserved, so that the frame's width never depends on the colour bar's labels
MATRIX_RIGHT_BORDER = 105


#: after the box zoom's gesture (its PanEnd), the matching-point tool is the active one again
#: (once the zoom has applied its box: the next tick)
_JS_ZOOM_ONCE = "if (zoom.active) setTimeout(() => { tool.active = true }, 0)"


def _phase_quads(labels: np.ndarray | None, colors: dict) -> dict:
    """Runs of equal phase labels as quads (start, stop, colour)."""
    if labels is None or len(labels) == 0:
        return {"start": [], "stop": [], "color": [], "phase": []}
    labels = np.asarray(labels)
    cut = np.flatnonzero(np.diff(labels)) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(labels)]])
    vals = labels[starts]
    return {
        "start": starts - 0.5,
        "stop": stops - 0.5,
        "color": [colors.get(int(v), "#cccccc") for v in vals],
        "phase": [_phase_name(int(v)) for v in vals],
    }


def _phase_name(code: int) -> str:
    try:
        from engine.gesture.phases import Phase

        return Phase(code).name.lower()
    except (ImportError, ValueError):
        return str(code)


def _phase_colors() -> dict:
    try:
        from engine.gesture.phases import PHASE_COLORS

        return {int(k): v for k, v in PHASE_COLORS.items()}
    except ImportError:
        return {}


def _rates(session: Session) -> dict:
    """The page's ``hs-rates``: both frame rates (times beside frames), both takes' frame
    counts (the frame under a position: ``webapp.matrix_frames``), the global tolerance."""
    return {
        "fps": [session.fps],
        "hand_fps": [session.hand_fps],
        "n": [session.n],
        "m_hand": [session.m_hand],
        "tol": [session.tolerance],
    }


def _fresh_edits(text, acked: int) -> list[dict]:
    """The page's queued point edits (a JSON list of ``{"seq", "before", "after"}``) newer
    than ``acked``, oldest first; text that is not such a list (a client other than the
    page's own script can send anything) gives none."""
    try:
        queue = parse_json(str(text))
    except JsonTextError:
        return []
    if not isinstance(queue, list):
        return []
    fresh = [
        e for e in queue if isinstance(e, dict) and type(e.get("seq")) is int and e["seq"] > acked
    ]
    return sorted(fresh, key=lambda e: e["seq"])


def _rows(cols) -> list[tuple[float, float, float]]:
    """The page's ``{"x": [...], "y": [...], "tol": [...]}`` as ``(x, y, tol)`` rows."""
    if not isinstance(cols, dict):
        return []
    xs, ys, tols = (cols.get(k) if isinstance(cols.get(k), list) else [] for k in ("x", "y", "tol"))
    tols = tols + [None] * (len(xs) - len(tols))

    def num(v):
        if not isinstance(v, int | float) or isinstance(v, bool):
            return None
        try:
            return float(v)
        except OverflowError:  # an integer past float's range
            return None

    return [(num(x), num(y), num(t)) for x, y, t in zip(xs, ys, tols)]


#: the page side of the edit queue (see ``CostMatrixView``): every change of the points the
#: user makes (click, drag end, Backspace) becomes a numbered edit {seq, before, after}; all
#: edits the server has not answered yet are sent together, so none is lost or reordered
_JS_STATE = """
const cols = (d) => ({x: Array.from(d.x ?? []), y: Array.from(d.y ?? []),
                      tol: Array.from(d.tol ?? []).map(v => (v == null || Number.isNaN(v)) ? null : v)});
const st = (src._hs ??= {seq: 0, pending: [], syncing: false, shown: cols(server.data)});
const dragging = () => {
  const view = Bokeh.index.find_one(fig);
  const tool_view = view?.tool_views?.get(tool);
  return tool_view != null && tool_view._basepoint != null;
};
const adopt = () => {  // show the session's points once every edit sent is answered
  const acked = server.tags[0] ?? 0;
  st.pending = st.pending.filter(e => e.seq > acked);
  if (st.pending.length || dragging()) return;  // a drag in progress adopts when it ends
  const d = server.data;
  if (JSON.stringify(cols(d)) === JSON.stringify(cols(src.data))) {  // as shown: no change
    st.shown = cols(src.data);  // (one message fewer for the server while it solves)
    return;
  }
  st.syncing = true;
  try {
    src.data = {x: Array.from(d.x ?? []), y: Array.from(d.y ?? []),
                tol: Array.from(d.tol ?? []).map(v => v == null ? NaN : v)};
  } finally {
    st.syncing = false;
  }
  st.shown = cols(src.data);
};
"""

_JS_SEND_EDIT = (
    _JS_STATE
    + """
if (st.syncing) return;
const after = cols(src.data);
const before = st.shown;
if (JSON.stringify(before) !== JSON.stringify(after)) {
  st.seq = Math.max(st.seq, server.tags[0] ?? 0) + 1;
  st.pending.push({seq: st.seq, before: before, after: after});
  st.shown = after;
  queue.data = {edits: [JSON.stringify(st.pending)]};
  // the views that show the edit's result are stale from now on (the status line dims)
  document.dispatchEvent(new CustomEvent('hs-edit-sent', {detail: st.seq}));
}
adopt();
"""
)

#: Bokeh reports a second click within 300 ms as a double tap, which the point tool ignores:
#: quick clicks were lost in the page itself. A double tap is handed to the tool as a tap.
_JS_DOUBLE_TAP_IS_A_TAP = """
const view = Bokeh.index.find_one(fig);
const tool_view = view?.tool_views?.get(tool);
if (tool_view == null || tool_view._doubletap != null || tool.active === false) return;
tool_view._tap({type: "tap", sx: cb_obj.sx, sy: cb_obj.sy,
                modifiers: cb_obj.modifiers ?? {shift: false, ctrl: false, alt: false}});
"""

#: Bokeh turns a pointer held still for 300 ms into a "press", after which moves are ignored:
#: a point pressed a moment before it is dragged (or a drag started while the page is busy
#: drawing the previous answer) stayed put. Nothing here uses presses, so they wait a minute.
_JS_NO_PRESS = """
const gestures = Bokeh.require("core/ui_gestures").UIGestures;
gestures.press_threshold = 60000;
"""

#: a drag of a matching point begins (the point tool has taken hold of the selected point:
#: Bokeh's tool drags the selection) or ends: the page tells the server at once
#: (``hs-drag-press``), so the previous edit's follow-up work (preview, trust) gives way
#: before the drag's edit arrives on release (``Session.edit_coming``)
_JS_DRAG_PRESS = """
const view = Bokeh.index.find_one(fig);
const tool_view = view?.tool_views?.get(tool);
const held = tool_view != null && tool_view._basepoint != null && src.selected.indices.length > 0;
const down = on && held ? 1 : 0;
if ((press.data.down ?? [0])[0] !== down) press.data = {down: [down]};
"""

#: the page adopts the session's points once the server has answered every edit it sent;
#: an answer with no solve to follow (``hs-server-points``' second tag 0: the edit was
#: refused, or changed nothing) ends the edit's wait at once (``hs-edit-answered``)
_JS_RECONCILE = (
    _JS_STATE
    + """
const [acked, solving] = server.tags;
if ((acked ?? 0) > (st.answered ?? 0)) {
  st.answered = acked;
  if (!solving && acked >= st.seq)
    document.dispatchEvent(new CustomEvent('hs-edit-answered', {detail: acked}));
}
adopt();
"""
)


#: hover and axis texts: frames with their times (``rates`` holds both frame rates)
#: the frame under a position is the one rule's (``webapp.matrix_frames``), as stored
_JS_BODY_FRAME = (
    JS_VIEW_FRAME
    + """
const i = view_frame(value, rates.data.n[0]);
return `${i} · ${(i / rates.data.fps[0]).toFixed(2)} s`;
"""
)
_JS_HAND_FRAME = (
    JS_VIEW_FRAME
    + """
const h = view_frame(value, rates.data.m_hand[0]);
return `${h} · ${(h / rates.data.hand_fps[0]).toFixed(2)} s`;
"""
)
#: a matching point's frames in its tooltip (during a drag too): the same rule
_JS_POINT_FRAME = JS_VIEW_FRAME + "return `${view_frame(value, rates.data[count][0])}`;"
_JS_IN_BAND = (
    JS_VIEW_FRAME
    + """
// the band's vertices are thinned to the screen's columns: its edges at x are
// interpolated between the nearest two (exact where the view shows every frame)
const x = view_frame(special_vars.x, rates.data.n[0]), y = special_vars.y;
const xs = band.data.x, n = xs.length;
if (n === 0 || x < xs[0] || x > xs[n - 1]) return "outside (no band)";
let a = 0, b = n - 1;
while (b - a > 1) { const c = (a + b) >> 1; if (xs[c] <= x) a = c; else b = c; }
if (xs[b] === x) a = b;
const at = (col) => {
  const v = band.data[col];
  if (xs[a] === x || b === a) return v[a];
  return v[a] + (v[b] - v[a]) * (x - xs[a]) / (xs[b] - xs[a]);
};
return (at("lo") <= y && y <= at("hi")) ? "inside (searched)" : "outside (never searched)";
"""
)
#: the cell hover's filter: false (no cell tooltip) within ``radius`` pixels of a matching
#: point, where the point's own tooltip shows
_JS_NOT_ON_A_POINT = """
const view = Bokeh.index.find_one(fig);
if (view == null) return true;
const xs = view.frame.x_scale, ys = view.frame.y_scale;
const d = src.data, sx = cb_data.vars.sx, sy = cb_data.vars.sy;
for (let k = 0; k < d.x.length; k++) {
  if (Math.hypot(xs.compute(d.x[k]) - sx, ys.compute(d.y[k]) - sy) <= radius) return false;
}
return true;
"""
_JS_TOL = """
value = src.data.tol[value];  // by row: Bokeh prints a NaN field without formatting it
if (value == null || !Number.isFinite(Number(value)))
  return `global (${rates.data.tol[0]} hand frames)`;
return `${value} hand frames`;
"""
_JS_TICK = """
const fps = rates.data[key][0];
return `${tick}\n${(tick / fps).toFixed(1)} s`;
"""


#: what the matrix's colour is, per view shown (the legend follows the view)
MATRIX_COLOUR = {
    "pass1": "local cost D1 (colour bar at the right; dark = the two frames move alike)",
    "pass2": "local cost D2 (colour bar at the right; dark = the two frames move alike)",
    "cumulative1": "pass-1 cumulative cost γ, the cheapest path's cost from the first cell "
    "(colour bar at the right; grows along the path)",
    "cumulative2": "pass-2 cumulative cost γ, the cheapest path's cost from the first cell "
    "(colour bar at the right; grows along the path)",
}


def phase_legend_html(colors: dict, matrix: str = "pass1", used: int = 2) -> str:
    """The legend of the strips along the axes (wrist speed curves, phase colour bars) and
    of the matrix (its colour for the view ``matrix`` shown, band, the path of pass ``used``
    that the splice follows in red, the other pass's path dashed, points)."""
    names = [
        (1, "P", "preparation"),
        (2, "S", "stroke"),
        (3, "H", "hold"),
        (4, "R", "retraction"),
        (0, "–", "rest"),
    ]
    swatches = "".join(
        f'<span class="hs-phase-key" data-phase="{letter}" '
        f'style="margin-right:10px;white-space:nowrap">'
        f'<span style="display:inline-block;width:12px;height:10px;background:'
        f'{colors.get(code, "#cccccc")};margin-right:3px;vertical-align:-1px"></span>'
        f"<b>{letter}</b> {name}</span>"
        for code, letter, name in names
    )
    return (
        '<div class="hs-legend" style="font-size:12px;color:#333;line-height:1.7">'
        '<div><span style="display:inline-block;width:18px;border-top:2px solid #333;'
        'vertical-align:3px;margin-right:4px"></span>wrist speed of each take along its '
        "axis (scaled to its fastest moment) · colour bars: gesture phases "
        f"{swatches}</div>"
        f'<div class="hs-matrix-colour" data-matrix="{matrix}">Matrix colour: '
        f"{MATRIX_COLOUR.get(matrix, MATRIX_COLOUR['pass1'])} · "
        '<span style="color:#4fc3f7">■</span> band edges, outside dimmed · '
        f'<span class="hs-used-path" data-pass="{used}"><span style="color:#ff3b30">━</span> '
        f"<b>alignment used</b>: pass {used}'s optimal path, which the splice, the preview "
        "and the status line follow (in every view)</span> · "
        f'<span class="hs-other-path-key" data-pass="{3 - used}">╌ pass {3 - used}\'s path'
        "</span> · "
        '<span style="color:#ffd60a">●</span> matching points</div></div>'
    )


class CostMatrixView:
    """Bokeh figures of one session's cost matrix, kept in sync with the session."""

    def __init__(self, session: Session, size: int = 560, max_pixels: int = 600):
        self.session = session
        self.max_pixels = max_pixels
        self._syncing = False
        self._pending_range: tuple[float, float, float, float] | None = None
        self._range_timer = False
        self._image_key = None
        self._doc = pn.state.curdoc  # the tab's document (``after_path``)
        #: the lines drawn thinned to the screen (``show_line``): source name -> (source,
        #: x, {column: values}, axis) at full resolution, thinned again when the view moves
        self._lines: dict[str, tuple] = {}
        self._colors = _phase_colors()
        n = max(session.n, 1)
        lo, hi = self._hand_extent()
        # frame rates for the axes and hover (seconds next to frames)
        self.rates = ColumnDataSource(
            _rates(session),
            name="hs-rates",
        )

        self.x_range = Range1d(-0.5, n - 0.5, bounds=(-0.5, n - 0.5), name="hs-x-range")
        self.y_range = Range1d(lo, hi, bounds=(lo, hi), name="hs-y-range")
        fig = self._matrix_figure(size)
        image = self._add_image(fig)
        self._add_band(fig, hi)
        self._add_paths(fig)
        points = self._add_points(fig)
        self._add_hovers(fig, image, points)
        self._add_color_bar(fig)
        self.figure = fig
        self.title = pn.pane.HTML(
            "",
            css_classes=["hs-matrix-title"],
            margin=(0, 10, 0, 100),
            styles={"font-size": "13px"},
        )

        self.body_figure, self.hand_figure = self._axis_figures(size)
        self._edit_queue(fig)
        self._watch(session, fig)
        self._on_inputs()

    # ------------------------------------------------------------ building the figures

    def _matrix_figure(self, size: int):
        """The matrix's figure (its axes are the signal strips'), on the shared ranges."""
        fig = figure(
            frame_width=size,
            frame_height=size,
            x_range=self.x_range,
            y_range=self.y_range,
            tools="pan,wheel_zoom,box_zoom,reset,save",
            toolbar_location="right",
            x_axis_label="body frame",
            y_axis_label="hand frame",
            name="hs-cost-figure",
            output_backend="canvas",
        )
        fig.css_classes = ["hs-cost-matrix"]
        fig.min_border_left, fig.min_border_top, fig.min_border_bottom = 10, 6, 6
        fig.min_border_right = MATRIX_RIGHT_BORDER
        _sized_by_frame(fig)
        fig.xaxis.visible = False  # the signal strips below and left carry the axes
        fig.yaxis.visible = False
        fig.grid.visible = False
        fig.background_fill_color = "#202020"
        return fig

    def _add_image(self, fig):
        """The cost image (a view of the visible range: ``_update_image``), its colours."""
        self.mapper = LinearColorMapper(palette=Viridis256, nan_color="rgba(0,0,0,0)")
        self.image_source = ColumnDataSource(
            {
                "image": [np.zeros((1, 1), dtype=np.float32)],
                "x": [-0.5],
                "y": [-0.5],
                "dw": [1.0],
                "dh": [1.0],
            },
            name="hs-image-source",
        )
        image = fig.image(
            image="image",
            x="x",
            y="y",
            dw="dw",
            dh="dh",
            source=self.image_source,
            color_mapper=self.mapper,
            level="image",
        )
        return image

    def _add_band(self, fig, hi: float) -> None:
        """The band: cells outside it dimmed, its edges drawn (``hi``: the hand axis's top)."""
        self.band_source = ColumnDataSource({"x": [], "lo": [], "hi": []}, name="hs-band-source")
        fig.varea(
            x="x",
            y1=-0.5,
            y2="lo",
            source=self.band_source,
            fill_color="black",
            fill_alpha=0.55,
            name="hs-band-below",
        )
        self._above = fig.varea(
            x="x",
            y1="hi",
            y2=hi,
            source=self.band_source,
            fill_color="black",
            fill_alpha=0.55,
            name="hs-band-above",
        )
        fig.line(
            x="x",
            y="lo",
            source=self.band_source,
            color=BAND_COLOR,
            line_width=1.5,
            name="hs-band-lo",
        )
        fig.line(
            x="x",
            y="hi",
            source=self.band_source,
            color=BAND_COLOR,
            line_width=1.5,
            name="hs-band-hi",
        )

    def _add_paths(self, fig) -> None:
        """Open ends, both passes' paths, the points' tolerance bars, the frame marker."""
        # open ends: frames of either take outside the path's overlap, lightly shaded
        self.unmatched_source = ColumnDataSource(
            {"left": [], "right": [], "bottom": [], "top": []}, name="hs-unmatched-source"
        )
        fig.quad(
            left="left",
            right="right",
            bottom="bottom",
            top="top",
            source=self.unmatched_source,
            fill_color="white",
            fill_alpha=0.14,
            line_alpha=0,
            name="hs-unmatched",
        )
        self.other_path_source = ColumnDataSource({"x": [], "y": []}, name="hs-other-path")
        fig.line(
            x="x",
            y="y",
            source=self.other_path_source,
            color=OTHER_PATH_COLOR,
            line_width=1.2,
            line_alpha=0.7,
            line_dash="dashed",
        )
        self.path_source = ColumnDataSource({"x": [], "y": []}, name="hs-path-source")
        fig.line(
            x="x", y="y", source=self.path_source, color=PATH_COLOR, line_width=2.2, name="hs-path"
        )
        self.tol_source = ColumnDataSource({"x": [], "y0": [], "y1": []}, name="hs-tol-source")
        fig.segment(
            x0="x",
            y0="y0",
            x1="x",
            y1="y1",
            source=self.tol_source,
            color=POINT_COLOR,
            line_width=3,
            line_alpha=0.8,
        )
        self.frame_source = ColumnDataSource({"x": [0], "y": [0]}, name="hs-frame-source")
        fig.scatter(
            x="x",
            y="y",
            source=self.frame_source,
            size=11,
            marker="circle_cross",
            fill_alpha=0,
            line_color="white",
            line_width=2,
        )

    def _add_points(self, fig):
        """The matching points and the tool that adds, drags and deletes them; returns the
        renderer a click hits (larger than the points drawn: ``POINT_HIT_SIZE``)."""
        self.points_source = ColumnDataSource(
            {"x": [], "y": [], "tol": []}, name="hs-points-source"
        )
        fig.scatter(
            x="x",
            y="y",
            source=self.points_source,
            size=POINT_SIZE,
            fill_color=POINT_COLOR,
            line_color="black",
            line_width=1.5,
            # the point a click selected (what Backspace deletes) has a thick magenta ring; the
            # others stay as they are (Bokeh would fade them)
            selection_line_color=SELECTED_POINT_RING,
            selection_line_width=4,
            nonselection_fill_alpha=1.0,
            nonselection_line_alpha=1.0,
            name="hs-points-glyph",
        )
        # the tool's own renderer: the same points, drawn invisibly larger (what a click
        # hits); the visible points above follow the same source and its selection
        hit = fig.scatter(
            x="x",
            y="y",
            source=self.points_source,
            size=POINT_HIT_SIZE,
            fill_alpha=0,
            line_alpha=0,
            selection_fill_alpha=0,
            selection_line_alpha=0,
            nonselection_fill_alpha=0,
            nonselection_line_alpha=0,
            name="hs-points-hit",
        )
        self.point_tool = PointDrawTool(
            renderers=[hit],
            add=not self.session.pick,
            drag=True,
            default_overrides={"tol": float("nan")},
            name="hs-point-tool",
            description="Matching points: click adds, drag moves, Backspace deletes",
        )
        fig.add_tools(self.point_tool)
        fig.toolbar.active_drag = self.point_tool
        fig.toolbar.active_tap = self.point_tool
        # a box zoom is one gesture: once its box is drawn the point tool is back, so the
        # next click adds a point again (stranger 7: after a zoom, clicks silently added
        # nothing until the toolbar's point icon was chosen again)
        box_zoom = fig.select_one(BoxZoomTool)
        if box_zoom is not None:
            fig.js_on_event(
                PanEnd,
                CustomJS(args={"zoom": box_zoom, "tool": self.point_tool}, code=_JS_ZOOM_ONCE),
            )
        return hit

    def _add_hovers(self, fig, image, points) -> None:
        """Tooltips: a matching point's own, else the cell's (frames, times, cost, band)."""
        fig.add_tools(
            HoverTool(
                renderers=[points],
                name="hs-point-hover",
                tooltips=[
                    ("matching point", "body frame @x{custom} · hand frame @y{custom}"),
                    ("tolerance", "$index{custom}"),
                ],
                formatters={
                    "$index": CustomJSHover(
                        args={"rates": self.rates, "src": self.points_source}, code=_JS_TOL
                    ),
                    **{
                        f"@{axis}": CustomJSHover(
                            args={"rates": self.rates, "count": count}, code=_JS_POINT_FRAME
                        )
                        for axis, count in (("x", "n"), ("y", "m_hand"))
                    },
                },
            )
        )
        # every cell: both frames with their times, the local cost, inside the band or not;
        # over a matching point only the point's own tooltip (one box, not two overlapping)
        fig.add_tools(
            HoverTool(
                renderers=[image],
                name="hs-cell-hover",
                filters={
                    "$sx": CustomJS(
                        args={"fig": fig, "src": self.points_source, "radius": POINT_HOVER_PX},
                        code=_JS_NOT_ON_A_POINT,
                    )
                },
                tooltips=[
                    ("body frame", "$x{body}"),
                    ("hand frame", "$y{hand}"),
                    ("cost", "@image{0.000}"),
                    ("band", "$sx{band}"),
                ],
                formatters={
                    "$x": CustomJSHover(args={"rates": self.rates}, code=_JS_BODY_FRAME),
                    "$y": CustomJSHover(args={"rates": self.rates}, code=_JS_HAND_FRAME),
                    "$sx": CustomJSHover(
                        args={"band": self.band_source, "rates": self.rates}, code=_JS_IN_BAND
                    ),
                },
            )
        )

    def _add_color_bar(self, fig) -> None:
        fig.add_layout(
            ColorBar(
                color_mapper=self.mapper,
                width=8,
                padding=2,
                major_label_text_font_size="8pt",
                name="hs-colorbar",
                title="cost",
                title_text_font_size="8pt",
                title_standoff=4,
            ),
            "right",
        )

    def _axis_figures(self, size: int):
        """``(body strip, hand strip)``: the takes' wrist speed and gesture phases along the
        matrix's axes (body below, sharing x; hand at the left, sharing y)."""
        self.body_signal_source = ColumnDataSource({"x": [], "y": []}, name="hs-body-signal-source")
        self.hand_signal_source = ColumnDataSource({"x": [], "y": []}, name="hs-hand-signal-source")
        self.body_phase_source = ColumnDataSource(_phase_quads(None, {}))
        self.hand_phase_source = ColumnDataSource(_phase_quads(None, {}))
        body = figure(
            frame_width=size,
            frame_height=AXIS_SIGNAL_SIZE - 40,
            x_range=self.x_range,
            y_range=Range1d(-0.35, 1.05),
            tools="",
            toolbar_location=None,
            x_axis_label="body frame (and seconds)",
            name="hs-body-signal",
        )
        body.xaxis.formatter = CustomJSTickFormatter(
            args={"rates": self.rates, "key": "fps"}, code=_JS_TICK
        )
        body.quad(
            left="start",
            right="stop",
            bottom=-0.32,
            top=-0.08,
            color="color",
            source=self.body_phase_source,
        )
        body.line(x="x", y="y", source=self.body_signal_source, color="#333333")
        body.yaxis.visible = False
        body.ygrid.visible = False
        hand = figure(
            width=AXIS_SIGNAL_SIZE,
            frame_height=size,
            y_range=self.y_range,
            x_range=Range1d(1.05, -0.35),
            tools="",
            toolbar_location=None,
            y_axis_label="hand frame, hand file's numbering (and seconds)",
            name="hs-hand-signal",
        )
        hand.yaxis.formatter = CustomJSTickFormatter(
            args={"rates": self.rates, "key": "hand_fps"}, code=_JS_TICK
        )
        hand.yaxis.axis_label_text_font_size = "9pt"
        hand.quad(
            bottom="start",
            top="stop",
            left=-0.32,
            right=-0.08,
            color="color",
            source=self.hand_phase_source,
        )
        hand.line(x="x", y="y", source=self.hand_signal_source, color="#333333")
        hand.xaxis.visible = False
        hand.xgrid.visible = False
        for f in (body, hand):
            f.outline_line_color = None
        body.min_border_left, body.min_border_top, body.min_border_right = 10, 2, 60
        hand.min_border_top, hand.min_border_bottom, hand.min_border_right = 6, 6, 2
        _sized_by_frame(body)
        _sized_by_frame(hand)
        return body, hand

    def _edit_queue(self, fig) -> None:
        """The page's side of the matching-point edits (``_JS_SEND_EDIT``) and the server's
        answer (``hs-server-points``): see the class docstring."""
        # the edit queue: the page numbers its edits and sends every unanswered one; the
        # session's points come back in ``server_points`` with the last edit they include
        self.edit_source = ColumnDataSource({"edits": ["[]"]}, name="hs-edit-queue")
        self.server_points = ColumnDataSource(
            {"x": [], "y": [], "tol": []}, tags=[0], name="hs-server-points"
        )
        self._acked = 0
        self._sent_points = None  # (points, acked edit, tolerance bars) last sent (_sync_points)
        self._page_up = False
        if pn.state.curdoc is not None and pn.state.curdoc.session_context is not None:
            pn.state.onload(lambda: setattr(self, "_page_up", True))
        args = {
            "src": self.points_source,
            "queue": self.edit_source,
            "server": self.server_points,
            "fig": fig,
            "tool": self.point_tool,
        }
        self.points_source.js_on_change("data", CustomJS(args=args, code=_JS_SEND_EDIT))
        reconcile = CustomJS(args=args, code=_JS_RECONCILE)
        fig.js_on_event(DoubleTap, CustomJS(args=args, code=_JS_NO_PRESS + _JS_DOUBLE_TAP_IS_A_TAP))
        page_js.run_once(fig, _JS_NO_PRESS)
        self.server_points.js_on_change("data", reconcile)
        self.server_points.js_on_change("tags", reconcile)
        self.edit_source.on_change("data", self._on_edits)
        # a drag under way (``_JS_DRAG_PRESS``): 1 from the drag's start to its release
        self.press_source = ColumnDataSource({"down": [0]}, name="hs-drag-press")
        for event, on in ((PanStart, True), (PanEnd, False)):
            press = {
                "press": self.press_source,
                "src": self.points_source,
                "fig": fig,
                "tool": self.point_tool,
                "on": on,
            }
            fig.js_on_event(event, CustomJS(args=press, code=_JS_DRAG_PRESS))
        self.press_source.on_change("data", self._on_press)

    def _watch(self, session: Session, fig) -> None:
        """Page events (visible range, clicks) and session changes this view follows."""
        fig.on_event(RangesUpdate, self._on_range)
        fig.on_event(Tap, self._on_tap)
        fig.on_event(DoubleTap, self._on_tap)
        session.param.watch(lambda *_: self._on_result(rest_later=True), ["revision"])
        # points set by the session (an edit solved off the loop, or put back when its solve
        # was refused) show at once; the path follows with the next revision
        session.param.watch(lambda *_: self._sync_points(), ["points", "tolerance"])
        session.param.watch(self._on_matrix, ["matrix"])
        self.legend = pn.pane.HTML(
            phase_legend_html(self._colors, session.matrix, self._used_pass()),
            css_classes=["hs-legends"],
            width=400,  # set by panel()
            margin=(4, 0),
        )
        session.param.watch(lambda *_: self._show_legend(), ["matrix"])
        session.param.watch(self._on_frame, ["frame"])
        session.param.watch(self._on_inputs, ["inputs_revision"])
        session.param.watch(lambda *_: self.set_pick_mode(self.session.pick), ["pick"])

    # ------------------------------------------------------------ session -> page

    def _hand_extent(self) -> tuple[float, float]:
        """The hand axis's extent in hand-file frames (the grid's columns, scaled)."""
        r, m = self.session.hand_scale, max(self.session.m, 1)
        return -0.5 * r, (m - 0.5) * r

    @with_document_lock
    def _on_inputs(self, *_):
        s = self.session
        n = max(s.n, 1)
        r = s.hand_scale
        lo, hi = self._hand_extent()
        self.rates.data = _rates(s)
        # the toolbar's reset shows the whole matrix of these takes (not the empty one the
        # page began with when the pair was opened off the loop)
        self.x_range.update(
            bounds=(-0.5, n - 0.5), start=-0.5, end=n - 0.5, reset_start=-0.5, reset_end=n - 0.5
        )
        self.y_range.update(bounds=(lo, hi), start=lo, end=hi, reset_start=lo, reset_end=hi)
        self._above.glyph.y2 = hi
        body, hand = s.axis_signals()
        # the wrist speeds: thinned to the strips' screen columns like the matrix's lines
        self.show_line(
            self.body_signal_source,
            np.arange(len(body), dtype=np.int32),
            {"y": np.asarray(body, dtype=np.float32)},
        )
        self.show_line(
            self.hand_signal_source,
            (np.arange(len(hand)) * r).astype(np.float32),
            {"x": np.asarray(hand, dtype=np.float32)},
            axis="y",
        )
        body_phases, hand_phases = s.axis_phases()
        self.body_phase_source.data = _phase_quads(body_phases, self._colors)
        quads = _phase_quads(hand_phases, self._colors)
        quads["start"] = list(np.asarray(quads["start"], dtype=float) * r)
        quads["stop"] = list(np.asarray(quads["stop"], dtype=float) * r)
        self.hand_phase_source.data = quads
        self._image_key = None
        self._update_image((-0.5, n - 0.5, lo, hi))
        self._on_result()

    def _used_pass(self) -> int:
        """The pass whose path the splice follows (``pipeline.alignment_pass``)."""
        from engine.splice.pipeline import alignment_pass

        prepared = self.session.prepared
        return 2 if prepared is None else alignment_pass(prepared.features)

    def _show_legend(self) -> None:
        if getattr(self, "legend", None) is None:  # not built yet (__init__)
            return
        html = phase_legend_html(self._colors, self.session.matrix, self._used_pass())
        if self.legend.object != html:
            self.legend.object = html

    @with_document_lock
    def _on_result(self, *_, rest_later: bool = False):
        """Draw the session's solution: the red path and the band at once; the other
        pass's path, the unmatched ends, the frame marker and the legend with them, or
        (``rest_later``: a new edit's solution) once its path is in the page
        (``after_path``): the tick that draws a drag's path sends its messages when it
        returns, so it holds only what the drag waits for."""
        s = self.session
        sol = s.solution
        self._sync_points()
        if sol is None:
            for source in (self.band_source, self.path_source, self.other_path_source):
                self.show_line(
                    source, np.zeros(0, np.int32), {k: [] for k in source.data if k != "x"}
                )
            self.unmatched_source.data = _unmatched_quads(None, 0, 0)
            return
        # the red path is the alignment used (the splice, preview and status follow it) in
        # every view; the band is the shown pass's; the other pass's path is dashed
        shown = sol.pass2 if s.matrix in ("pass2", "cumulative2") else sol.pass1
        used = sol.pass1 if self._used_pass() == 1 else sol.pass2
        r = s.hand_scale  # grid columns -> hand-file frames
        # the path first: it is what a drag is waiting for; compact dtypes keep messages small,
        # and every line is thinned to the screen's columns (``decimate``)
        self.show_line(
            self.path_source,
            used.path[:, 0].astype(np.int32),
            {"y": (used.path[:, 1] * r).astype(np.float32)},
        )
        lo, hi = shown.band.lo, shown.band.hi
        self.show_line(
            self.band_source,
            np.arange(len(lo), dtype=np.int32),
            {"lo": ((lo - 0.5) * r).astype(np.float32), "hi": ((hi + 0.5) * r).astype(np.float32)},
        )
        if rest_later:
            after_path(s, ("matrix-rest", id(self)), self._draw_rest, self._doc)
        else:
            self._draw_rest()

    @with_document_lock
    def _draw_rest(self) -> None:
        """The solution's lines besides the red path and the band (see ``_on_result``), of
        the session's solution as it is now."""
        s = self.session
        sol = s.solution
        if sol is None:
            return
        shown = sol.pass2 if s.matrix in ("pass2", "cumulative2") else sol.pass1
        used, other = (sol.pass1, sol.pass2) if self._used_pass() == 1 else (sol.pass2, sol.pass1)
        r = s.hand_scale
        self.show_line(
            self.other_path_source,
            other.path[:, 0].astype(np.int32),
            {"y": (other.path[:, 1] * r).astype(np.float32)},
        )
        quads = _unmatched_quads(used.path, len(shown.band.lo), shown.band.m)
        quads["bottom"] = [v * r for v in quads["bottom"]]
        quads["top"] = [v * r for v in quads["top"]]
        self.unmatched_source.data = quads
        self._show_legend()
        self._on_frame()
        if s.matrix.startswith("cumulative"):  # the cumulative cost depends on band and points
            self._image_key = None
            self._update_image(self._visible())

    @with_document_lock
    def _on_matrix(self, *_):
        self._image_key = None
        self._on_result()
        self._update_image(self._visible())

    @with_document_lock
    def _on_frame(self, *_):
        pair = self.session.frame_pair()
        self.frame_source.data = {"x": [pair[0]], "y": [pair[1]]}

    @with_document_lock
    def _sync_points(self):
        pts = self.session.points
        if self.rates.data["tol"] != [self.session.tolerance]:
            self.rates.data = {**self.rates.data, "tol": [self.session.tolerance]}
        tol = [self.session.tolerance if p.tolerance is None else p.tolerance for p in pts]
        data = {
            "x": [p.body for p in pts],
            "y": [p.hand for p in pts],
            "tol": [None if p.tolerance is None else p.tolerance for p in pts],
        }
        bars = {
            "x": [p.body for p in pts],
            "y0": [p.hand - t - 0.5 for p, t in zip(pts, tol)],
            "y1": [p.hand + t + 0.5 for p, t in zip(pts, tol)],
        }
        # an edit calls this up to three times (points set, edits answered, path drawn):
        # only what changed is sent, each message being one more for the page to apply
        # before the path it waits for
        if self._sent_points == (data, self._acked, bars) and self._page_up:
            return
        # data first, then the answered edit number: the page adopts the session's points
        # once nothing it sent is still unanswered (a newer click is never overwritten)
        if self._sent_points is None or self._sent_points[0] != data:
            self.server_points.data = data
        # and whether a solve follows (the page's status line waits for it, or not)
        runner = self.session.runner
        tags = [self._acked, int(runner is not None and runner.solving())]
        if self.server_points.tags != tags:
            self.server_points.tags = tags
        if not self._page_up:  # the page is not up yet: its first points are the session's
            self.points_source.data = dict(data)
        if self._sent_points is None or self._sent_points[2] != bars:
            self.tol_source.data = bars
        self._sent_points = (data, self._acked, bars)

    @with_document_lock
    def show_line(self, source: ColumnDataSource, x, ys: dict, axis: str = "x") -> None:
        """Draw the polylines ``(x, ys[k])`` in ``source`` thinned to the screen's columns
        of the visible range (``webapp.views.decimate``: drawn the same); the view's moves
        thin them again (``_flush_range``).

        ``x``: the non-decreasing coordinate along ``axis``: body frames along the matrix's
        x axis (``"x"``), or hand-file frames along its y axis (``"y"``: the hand take's
        strip, whose line runs up the page; ``source`` then holds ``x`` as its ``y``)."""
        x = np.asarray(x)
        self._lines[source.name] = (source, x, ys, axis)
        source.data = self._thinned(x, ys, axis)

    def _thinned(self, x, ys: dict, axis: str, visible=None) -> dict:
        along = "x" if axis == "x" else "y"
        if len(x) > 2:
            rng = self.x_range if axis == "x" else self.y_range
            if visible is None:
                visible = (rng.start, rng.end)
            lo, hi = rng.bounds
            pixels = self.figure.frame_width if axis == "x" else self.figure.frame_height
            keep = decimate.kept(x, list(ys.values()), visible, hi - lo, pixels)
            x, ys = x[keep], {k: np.asarray(v)[keep] for k, v in ys.items()}
        return {along: x, **ys}

    def _rethin(self, ranges: tuple[float, float, float, float]) -> None:
        """Thin the drawn lines again for the visible ``ranges`` (x0, x1, y0, y1): a zoom
        shows every frame once a screen column is narrower than a frame; lines that go
        whole at the whole take's resolution are left as they are."""
        for source, x, ys, axis in self._lines.values():
            rng = self.x_range if axis == "x" else self.y_range
            along = "x" if axis == "x" else "y"
            whole = len(x) <= 2 or len(self._thinned(x, ys, axis, rng.bounds)[along]) == len(x)
            if not whole:
                visible = ranges[:2] if axis == "x" else ranges[2:]
                if any(v is None for v in visible):  # the event lacks it: the model's
                    visible = (rng.start, rng.end)
                source.data = self._thinned(x, ys, axis, visible)

    def _visible(self) -> tuple[float, float, float, float]:
        return (self.x_range.start, self.x_range.end, self.y_range.start, self.y_range.end)

    @with_document_lock
    def _update_image(self, ranges):
        """Show the part of the matrix in ``ranges`` (x0, x1 body frames, y0, y1 hand-file
        frames)."""
        s = self.session
        if s.n == 0 or s.m == 0:
            return
        r = s.hand_scale
        x0, x1, y0, y1 = ranges
        view = s.cost_view((x0, x1, y0 / r, y1 / r), self.max_pixels)
        if view is None:
            return
        key = (
            s.matrix,
            view.x0,
            view.x1,
            view.y0,
            view.y1,
            view.image.shape,
            s.revision if s.matrix.startswith("cumulative") else 0,
        )
        if key == self._image_key:
            return
        self._image_key = key
        img = np.ascontiguousarray(view.image.T, dtype=np.float32)  # rows = hand frames (y)
        finite = img[np.isfinite(img)]
        if finite.size:
            lo, hi = (
                np.percentile(finite, [1, 99])
                if finite.size > 100
                else (finite.min(), finite.max())
            )
            self.mapper.update(low=float(lo), high=float(hi if hi > lo else lo + 1))
        self.image_source.data = {
            "image": [img],
            "x": [view.x0 - 0.5],
            "y": [(view.y0 - 0.5) * r],
            "dw": [float(view.x1 - view.x0)],
            "dh": [float(view.y1 - view.y0) * r],
        }
        self.title.object = (
            "<b>"
            + s.matrix_label()
            + "</b>"
            + (
                ""
                if view.stride == (1, 1)
                else f"  ·  1 pixel = {view.stride[0]}×{view.stride[1]} cells"
            )
        )

    # ------------------------------------------------------------ page -> session

    def _on_edits(self, attr, old, new):
        """The page's queue of unanswered edits changed: apply the new ones in order (after
        Bokeh has applied the browser's patch, so the answers go out at once)."""
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            self._apply_edits()
        else:
            next_tick(doc, self._apply_edits)

    def _on_press(self, attr, old, new) -> None:
        """A drag of a matching point began or ended in the page (``Session.dragging``).
        Its end is taken after the edit queued with it (the release sends the edit first):
        the edit's solve is then already submitted, so the follow-up work never starts in
        between."""
        down = bool((new.get("down") or [0])[0])
        doc = pn.state.curdoc
        if down or doc is None or doc.session_context is None:
            self.session.dragging = down
        else:
            next_tick(
                doc,
                lambda: setattr(self.session, "dragging", bool(self.press_source.data["down"][0])),
            )

    def _apply_edits(self) -> None:
        fresh = _fresh_edits((self.edit_source.data.get("edits") or ["[]"])[0], self._acked)
        if not fresh:
            return
        for edit in fresh:  # one at a time: each is solved before the next is merged
            self.session.apply_view_edits([(_rows(edit.get("before")), _rows(edit.get("after")))])
            self._acked = int(edit["seq"])
        self._sync_points()

    def _on_range(self, event):
        self._pending_range = (event.x0, event.x1, event.y0, event.y1)
        if self._range_timer:
            return
        self._range_timer = True
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            self._flush_range()
        else:
            after(doc, self._flush_range, 120)

    def _flush_range(self):
        self._range_timer = False
        if self._pending_range is not None:
            ranges, self._pending_range = self._pending_range, None
            self._update_image(ranges)
            self._rethin(ranges)

    def _on_tap(self, event):
        if event.x is None or self.point_tool.add:
            return
        self.session.pick_cell(event.x, event.y)

    @with_document_lock
    def set_pick_mode(self, pick: bool) -> None:
        """Pick mode: a click chooses the previewed frame pair instead of adding a point."""
        self.point_tool.add = not pick

    @property
    def panel_width(self) -> int:
        """Pixels of :meth:`panel`'s content: hand strip, matrix with its colour bar and tools."""
        fig = self.figure
        return fig.min_border_left + fig.frame_width + MATRIX_RIGHT_BORDER + AXIS_SIGNAL_SIZE

    def panel(self) -> pn.viewable.Viewable:
        size = self.panel_width - AXIS_SIGNAL_SIZE
        self.legend.width = size + AXIS_SIGNAL_SIZE
        return pn.Column(
            self.title,
            pn.Row(
                pn.pane.Bokeh(self.hand_figure, sizing_mode="fixed", margin=0),
                pn.pane.Bokeh(self.figure, sizing_mode="fixed", margin=0),
                sizing_mode=None,
                width=size + AXIS_SIGNAL_SIZE,
                margin=0,
            ),
            pn.Row(
                pn.Spacer(width=AXIS_SIGNAL_SIZE, margin=0),
                pn.pane.Bokeh(self.body_figure, sizing_mode="fixed", margin=0),
                sizing_mode=None,
                width=size + AXIS_SIGNAL_SIZE,
                margin=0,
            ),
            self.legend,
            sizing_mode=None,
            width=size + AXIS_SIGNAL_SIZE,
            margin=(0, 10),
        )


def _sized_by_frame(fig) -> None:
    """Lay ``fig`` out at its own size: its ``frame_width``/``frame_height`` where set, else
    its ``width``/``height``. Bokeh's default fits a plot with a frame size to its parent,
    so the matrix's frame lost what its colour bar took (21 px at 560) and no longer lined
    up with the strips' frames of the same ``frame_width``: a body frame read off the
    strip's axis was a few frames off in the matrix."""
    for side in ("width", "height"):
        if getattr(fig, f"frame_{side}") is not None:
            # "min": the frame plus what its axes, colour bar and toolbar take (BokehJS
            # sizes "fixed" without a size the same way, but Bokeh's checks refuse that)
            setattr(fig, f"{side}_policy", "min")
            setattr(fig, side, None)
        else:
            setattr(fig, f"{side}_policy", "fixed")


def _unmatched_quads(path, n: int, m: int) -> dict:
    """Quads over the body rows and hand columns an open-end ``path`` leaves unmatched."""
    q = {"left": [], "right": [], "bottom": [], "top": []}
    if path is None or len(path) == 0:
        return q
    (i0, j0), (i1, j1) = path[0], path[-1]
    for left, right, bottom, top in (
        (-0.5, i0 - 0.5, -0.5, m - 0.5),
        (i1 + 0.5, n - 0.5, -0.5, m - 0.5),
        (-0.5, n - 0.5, -0.5, j0 - 0.5),
        (-0.5, n - 0.5, j1 + 0.5, m - 0.5),
    ):
        if right > left and top > bottom:
            for k, v in zip(
                ("left", "right", "bottom", "top"), (left, right, bottom, top), strict=True
            ):
                q[k].append(float(v))
    return q
