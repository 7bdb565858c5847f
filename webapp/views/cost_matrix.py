"""The DTW cost matrix: local or cumulative cost image, band, optimal path, matching points.

x is the body frame (matrix row i), y the hand frame (column j), so a matching
point (body frame, hand frame) sits at (x, y) and the band of row i is the vertical
stretch [lo_i, hi_i] above x = i.

Editing: with the point tool active (the default) a click adds a matching point,
a drag moves one, Backspace deletes the selected one. The browser only sends the
edited point list when a drag ends; the session validates it, recomputes band and
path, and pushes the new band and path back (only those sources change, so the
page does not re-render the figure).

Large matrices: the image is a view of at most ``max_pixels`` cells per axis of the
visible range, fetched again (throttled) when the visible range changes, so a
10,000 x 10,000 matrix costs the page no more than a small one and zooming in shows
full detail.
"""

from __future__ import annotations

import numpy as np
import panel as pn
from bokeh.events import DoubleTap, RangesUpdate, Tap
from bokeh.models import (
    ColorBar,
    ColumnDataSource,
    HoverTool,
    LinearColorMapper,
    PointDrawTool,
    Range1d,
)
from bokeh.palettes import Viridis256
from bokeh.plotting import figure

from webapp.state import MATRIX_LABELS, Session
from webapp.views._dispatch import with_document_lock

PATH_COLOR = "#ff3b30"
OTHER_PATH_COLOR = "#ffffff"
BAND_COLOR = "#4fc3f7"
POINT_COLOR = "#ffd60a"
AXIS_SIGNAL_SIZE = 90


def _phase_quads(labels: np.ndarray | None, colors: dict) -> dict:
    """Runs of equal phase labels as quads (start, stop, colour)."""
    if labels is None or len(labels) == 0:
        return {"start": [], "stop": [], "color": [], "phase": []}
    labels = np.asarray(labels)
    cut = np.flatnonzero(np.diff(labels)) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(labels)]])
    vals = labels[starts]
    return {"start": starts - 0.5, "stop": stops - 0.5,
            "color": [colors.get(int(v), "#cccccc") for v in vals],
            "phase": [_phase_name(int(v)) for v in vals]}


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


class CostMatrixView:
    """Bokeh figures of one session's cost matrix, kept in sync with the session."""

    def __init__(self, session: Session, size: int = 560, max_pixels: int = 600):
        self.session = session
        self.max_pixels = max_pixels
        self._syncing = False
        self._pending_range: tuple[float, float, float, float] | None = None
        self._range_timer = False
        self._image_key = None
        self._colors = _phase_colors()
        n, m = max(session.n, 1), max(session.m, 1)

        self.x_range = Range1d(-0.5, n - 0.5, bounds=(-0.5, n - 0.5), name="hs-x-range")
        self.y_range = Range1d(-0.5, m - 0.5, bounds=(-0.5, m - 0.5), name="hs-y-range")
        fig = figure(
            frame_width=size, frame_height=size, x_range=self.x_range, y_range=self.y_range,
            tools="pan,wheel_zoom,box_zoom,reset,save", toolbar_location="right",
            x_axis_label="body frame", y_axis_label="hand frame",
            name="hs-cost-figure", output_backend="canvas",
        )
        fig.css_classes = ["hs-cost-matrix"]
        fig.min_border_left, fig.min_border_top, fig.min_border_bottom = 10, 6, 6
        fig.xaxis.visible = False  # the signal strips below and left carry the axes
        fig.yaxis.visible = False
        fig.grid.visible = False
        fig.background_fill_color = "#202020"
        self.mapper = LinearColorMapper(palette=Viridis256, nan_color="rgba(0,0,0,0)")
        self.image_source = ColumnDataSource(
            {"image": [np.zeros((1, 1), dtype=np.float32)], "x": [-0.5], "y": [-0.5],
             "dw": [1.0], "dh": [1.0]}, name="hs-image-source")
        fig.image(image="image", x="x", y="y", dw="dw", dh="dh", source=self.image_source,
                  color_mapper=self.mapper, level="image")
        # the band: cells outside it dimmed, its edges drawn
        self.band_source = ColumnDataSource({"x": [], "lo": [], "hi": []}, name="hs-band-source")
        fig.varea(x="x", y1=-0.5, y2="lo", source=self.band_source, fill_color="black",
                  fill_alpha=0.55, name="hs-band-below")
        self._above = fig.varea(x="x", y1="hi", y2=m - 0.5, source=self.band_source,
                                fill_color="black",
                  fill_alpha=0.55, name="hs-band-above")
        fig.line(x="x", y="lo", source=self.band_source, color=BAND_COLOR, line_width=1.5,
                 name="hs-band-lo")
        fig.line(x="x", y="hi", source=self.band_source, color=BAND_COLOR, line_width=1.5,
                 name="hs-band-hi")
        # open ends: frames of either take outside the path's overlap, lightly shaded
        self.unmatched_source = ColumnDataSource(
            {"left": [], "right": [], "bottom": [], "top": []}, name="hs-unmatched-source")
        fig.quad(left="left", right="right", bottom="bottom", top="top",
                 source=self.unmatched_source, fill_color="white", fill_alpha=0.14,
                 line_alpha=0, name="hs-unmatched")
        self.other_path_source = ColumnDataSource({"x": [], "y": []}, name="hs-other-path")
        fig.line(x="x", y="y", source=self.other_path_source, color=OTHER_PATH_COLOR,
                 line_width=1.2, line_alpha=0.7, line_dash="dashed")
        self.path_source = ColumnDataSource({"x": [], "y": []}, name="hs-path-source")
        fig.line(x="x", y="y", source=self.path_source, color=PATH_COLOR, line_width=2.2,
                 name="hs-path")
        self.tol_source = ColumnDataSource({"x": [], "y0": [], "y1": []}, name="hs-tol-source")
        fig.segment(x0="x", y0="y0", x1="x", y1="y1", source=self.tol_source,
                    color=POINT_COLOR, line_width=3, line_alpha=0.8)
        self.frame_source = ColumnDataSource({"x": [0], "y": [0]}, name="hs-frame-source")
        fig.scatter(x="x", y="y", source=self.frame_source, size=11, marker="circle_cross",
                    fill_alpha=0, line_color="white", line_width=2)
        self.points_source = ColumnDataSource({"x": [], "y": [], "tol": []},
                                              name="hs-points-source")
        points = fig.scatter(x="x", y="y", source=self.points_source, size=13,
                             fill_color=POINT_COLOR, line_color="black", line_width=1.5,
                             name="hs-points-glyph")
        self.point_tool = PointDrawTool(renderers=[points], add=True, drag=True,
                                        default_overrides={"tol": float("nan")},
                                        name="hs-point-tool",
                                        description="Matching points: click adds, drag moves, "
                                                    "Backspace deletes")
        fig.add_tools(self.point_tool)
        fig.toolbar.active_drag = self.point_tool
        fig.toolbar.active_tap = self.point_tool
        fig.add_tools(HoverTool(renderers=[points], tooltips=[
            ("body frame", "@x{0}"), ("hand frame", "@y{0}"), ("tolerance", "@tol")]))
        fig.add_layout(ColorBar(color_mapper=self.mapper, width=8, padding=2,
                                major_label_text_font_size="8pt"), "right")
        self.figure = fig
        self.title = pn.pane.HTML("", css_classes=["hs-matrix-title"], margin=(0, 10, 0, 100),
                                  styles={"font-size": "13px"})

        # signals along the axes: body below (shares x), hand at the left (shares y)
        self.body_signal_source = ColumnDataSource({"x": [], "y": []})
        self.hand_signal_source = ColumnDataSource({"x": [], "y": []})
        self.body_phase_source = ColumnDataSource(_phase_quads(None, {}))
        self.hand_phase_source = ColumnDataSource(_phase_quads(None, {}))
        body = figure(frame_width=size, frame_height=AXIS_SIGNAL_SIZE - 40, x_range=self.x_range,
                      y_range=Range1d(-0.35, 1.05), tools="", toolbar_location=None,
                      x_axis_label="body frame", name="hs-body-signal")
        body.quad(left="start", right="stop", bottom=-0.32, top=-0.08,
                  color="color", source=self.body_phase_source)
        body.line(x="x", y="y", source=self.body_signal_source, color="#333333")
        body.yaxis.visible = False
        body.ygrid.visible = False
        hand = figure(width=AXIS_SIGNAL_SIZE, frame_height=size, y_range=self.y_range,
                      x_range=Range1d(1.05, -0.35), tools="", toolbar_location=None,
                      y_axis_label="hand frame", name="hs-hand-signal")
        hand.quad(bottom="start", top="stop", left=-0.32, right=-0.08,
                  color="color", source=self.hand_phase_source)
        hand.line(x="x", y="y", source=self.hand_signal_source, color="#333333")
        hand.xaxis.visible = False
        hand.xgrid.visible = False
        for f in (body, hand):
            f.outline_line_color = None
        body.min_border_left, body.min_border_top, body.min_border_right = 10, 2, 60
        hand.min_border_top, hand.min_border_bottom, hand.min_border_right = 6, 6, 2
        self.body_figure, self.hand_figure = body, hand

        self.points_source.on_change("data", self._on_points_edited)
        fig.on_event(RangesUpdate, self._on_range)
        fig.on_event(Tap, self._on_tap)
        fig.on_event(DoubleTap, self._on_tap)
        session.param.watch(self._on_result, ["revision"])
        session.param.watch(self._on_matrix, ["matrix"])
        session.param.watch(self._on_frame, ["frame"])
        session.param.watch(self._on_inputs, ["inputs_revision"])
        self._on_inputs()

    # ------------------------------------------------------------ session -> page

    @with_document_lock
    def _on_inputs(self, *_):
        s = self.session
        n, m = max(s.n, 1), max(s.m, 1)
        self.x_range.update(bounds=(-0.5, n - 0.5), start=-0.5, end=n - 0.5)
        self.y_range.update(bounds=(-0.5, m - 0.5), start=-0.5, end=m - 0.5)
        self._above.glyph.y2 = m - 0.5
        body, hand = s.axis_signals()
        self.body_signal_source.data = {"x": np.arange(len(body)), "y": body}
        self.hand_signal_source.data = {"x": hand, "y": np.arange(len(hand))}
        body_phases, hand_phases = s.axis_phases()
        self.body_phase_source.data = _phase_quads(body_phases, self._colors)
        self.hand_phase_source.data = _phase_quads(hand_phases, self._colors)
        self._image_key = None
        self._update_image((-0.5, n - 0.5, -0.5, m - 0.5))
        self._on_result()

    @with_document_lock
    def _on_result(self, *_):
        s = self.session
        sol = s.solution
        self._sync_points()
        if sol is None:
            self.band_source.data = {"x": [], "lo": [], "hi": []}
            self.path_source.data = {"x": [], "y": []}
            self.other_path_source.data = {"x": [], "y": []}
            self.unmatched_source.data = _unmatched_quads(None, 0, 0)
            return
        shown, other = (sol.pass2, sol.pass1) if s.matrix in ("pass2", "cumulative2") \
            else (sol.pass1, sol.pass2)
        # the path first: it is what a drag is waiting for; compact dtypes keep messages small
        self.path_source.data = {"x": shown.path[:, 0].astype(np.int32),
                                 "y": shown.path[:, 1].astype(np.int32)}
        lo, hi = shown.band.lo, shown.band.hi
        self.band_source.data = {"x": np.arange(len(lo), dtype=np.int32),
                                 "lo": (lo - 0.5).astype(np.float32),
                                 "hi": (hi + 0.5).astype(np.float32)}
        self.other_path_source.data = {"x": other.path[:, 0].astype(np.int32),
                                       "y": other.path[:, 1].astype(np.int32)}
        self.unmatched_source.data = _unmatched_quads(shown.path, len(lo), shown.band.m)
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
        tol = [self.session.tolerance if p.tolerance is None else p.tolerance for p in pts]
        self._syncing = True
        try:
            self.points_source.data = {"x": [p.body for p in pts], "y": [p.hand for p in pts],
                                       "tol": [None if p.tolerance is None else p.tolerance
                                               for p in pts]}
            self.tol_source.data = {"x": [p.body for p in pts],
                                    "y0": [p.hand - t - 0.5 for p, t in zip(pts, tol)],
                                    "y1": [p.hand + t + 0.5 for p, t in zip(pts, tol)]}
        finally:
            self._syncing = False

    def _visible(self) -> tuple[float, float, float, float]:
        return (self.x_range.start, self.x_range.end, self.y_range.start, self.y_range.end)

    @with_document_lock
    def _update_image(self, ranges):
        s = self.session
        if s.n == 0 or s.m == 0:
            return
        view = s.cost_view(ranges, self.max_pixels)
        if view is None:
            return
        key = (s.matrix, view.x0, view.x1, view.y0, view.y1, view.image.shape, s.revision
               if s.matrix.startswith("cumulative") else 0)
        if key == self._image_key:
            return
        self._image_key = key
        img = np.ascontiguousarray(view.image.T, dtype=np.float32)  # rows = hand frames (y)
        finite = img[np.isfinite(img)]
        if finite.size:
            lo, hi = np.percentile(finite, [1, 99]) if finite.size > 100 else \
                (finite.min(), finite.max())
            self.mapper.update(low=float(lo), high=float(hi if hi > lo else lo + 1))
        self.image_source.data = {"image": [img], "x": [view.x0 - 0.5], "y": [view.y0 - 0.5],
                                  "dw": [float(view.x1 - view.x0)],
                                  "dh": [float(view.y1 - view.y0)]}
        self.title.object = "<b>" + MATRIX_LABELS[s.matrix] + "</b>" + (
            "" if view.stride == (1, 1) else f"  ·  1 pixel = {view.stride[0]}×{view.stride[1]} cells")

    # ------------------------------------------------------------ page -> session

    def _on_points_edited(self, attr, old, new):
        if self._syncing:
            return
        xs, ys = list(new.get("x", [])), list(new.get("y", []))
        tols = list(new.get("tol", [])) + [None] * (len(xs) - len(new.get("tol", [])))
        edited = [(x, y, t) for x, y, t in zip(xs, ys, tols)]
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            self._apply_edit(edited)
        else:  # after Bokeh has finished applying the browser's patch: changes go out at once
            doc.add_next_tick_callback(lambda: self._apply_edit(edited))

    def _apply_edit(self, edited) -> None:
        if not self.session.set_points_from_view(edited):
            self._sync_points()  # rejected: put the points back where the session has them

    def _on_range(self, event):
        self._pending_range = (event.x0, event.x1, event.y0, event.y1)
        if self._range_timer:
            return
        self._range_timer = True
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            self._flush_range()
        else:
            doc.add_timeout_callback(self._flush_range, 120)

    def _flush_range(self):
        self._range_timer = False
        if self._pending_range is not None:
            ranges, self._pending_range = self._pending_range, None
            self._update_image(ranges)

    def _on_tap(self, event):
        if event.x is None or self.point_tool.add:
            return
        self.session.pick_cell(event.x, event.y)

    @with_document_lock
    def set_pick_mode(self, pick: bool) -> None:
        """Pick mode: a click chooses the previewed frame pair instead of adding a point."""
        self.point_tool.add = not pick

    def panel(self) -> pn.viewable.Viewable:
        size = self.figure.frame_width + 70
        return pn.Column(
            self.title,
            pn.Row(pn.pane.Bokeh(self.hand_figure, sizing_mode="fixed", margin=0),
                   pn.pane.Bokeh(self.figure, sizing_mode="fixed", margin=0),
                   sizing_mode=None, width=size + AXIS_SIGNAL_SIZE, margin=0),
            pn.Row(pn.Spacer(width=AXIS_SIGNAL_SIZE, margin=0),
                   pn.pane.Bokeh(self.body_figure, sizing_mode="fixed", margin=0),
                   sizing_mode=None, width=size + AXIS_SIGNAL_SIZE, margin=0),
            sizing_mode=None, width=size + AXIS_SIGNAL_SIZE, margin=(0, 10))


def _unmatched_quads(path, n: int, m: int) -> dict:
    """Quads over the body rows and hand columns an open-end ``path`` leaves unmatched."""
    q = {"left": [], "right": [], "bottom": [], "top": []}
    if path is None or len(path) == 0:
        return q
    (i0, j0), (i1, j1) = path[0], path[-1]
    for left, right, bottom, top in ((-0.5, i0 - 0.5, -0.5, m - 0.5),
                                     (i1 + 0.5, n - 0.5, -0.5, m - 0.5),
                                     (-0.5, n - 0.5, -0.5, j0 - 0.5),
                                     (-0.5, n - 0.5, j1 + 0.5, m - 0.5)):
        if right > left and top > bottom:
            for k, v in zip(("left", "right", "bottom", "top"), (left, right, bottom, top),
                            strict=True):
                q[k].append(float(v))
    return q
