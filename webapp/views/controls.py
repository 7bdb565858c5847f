"""Parameter widgets, the matching-points table and the status line of one session."""

from __future__ import annotations

import pandas as pd
import panel as pn
from bokeh.models import CustomJS

from engine.dtw import constraints as C
from webapp import safe_text
from webapp.state import PASS2_SPIN_NOTE, Session
from webapp.views import page_js
from webapp.views._dispatch import after_path, with_document_lock
from webapp.views.refusal import refusal_box

MATRIX_CHOICES = {
    "Pass 1": "pass1",
    "Pass 2": "pass2",
    "Cumulative 1": "cumulative1",
    "Cumulative 2": "cumulative2",
}


def parameter_widgets(session: Session) -> pn.viewable.Viewable:
    """Band widths (sliders for fractions, fields for seconds) and global tolerance (recompute
    on release: throttled), the W2 note and the matrix choice. The first column holds the
    width and tolerance controls in page order, each fraction slider followed by its note
    (shown when a width in seconds overrides it) and its seconds field."""
    params = pn.Param(
        session.param,
        parameters=["band", "refine_band", "tolerance"],
        show_name=False,
        widgets={
            "band": {
                "type": pn.widgets.FloatSlider,
                "throttled": True,
                "label": "Pass-1 band width W1 (fraction of body frames)",
                # no tooltip above the handle: it covered the label while dragging; the
                # label itself says the value as it moves (Panel's show_value)
                "tooltips": False,
                "step": 0.01,
            },
            "refine_band": {
                "type": pn.widgets.FloatSlider,
                "throttled": True,
                "label": "Pass-2 band width W2 around the pass-1 path",
                "tooltips": False,
                "step": 0.01,
            },
            "tolerance": {
                "type": pn.widgets.FloatSlider,
                "throttled": True,
                "end": 60.0,
                "label": "Global tolerance T (hand frames)",
                "tooltips": False,
                "step": 1.0,
            },
        },
        sizing_mode="stretch_width",
    )
    # a width in seconds wins over the fraction; empty = use the fraction. Typed values go
    # through Session.set_constraints (engine.dtw.constraints' ranges and one-line refusal,
    # as for links and session files); a refused value gives way to the one in force
    seconds = {
        "band": _seconds_input(session, "band", f"{C.BAND.seconds_label} (empty: fraction)"),
        "refine_band": _seconds_input(
            session, "refine_band", f"{C.REFINE_BAND.seconds_label} (empty: fraction)"
        ),
    }

    # a slider whose width is overridden by seconds is greyed out, and a line under it
    # says why (a long take opens with a width in seconds: the slider's fraction is not used)
    overridden = {
        name: pn.pane.Markdown(
            "",
            css_classes=[f"hs-{name}-fraction-unused"],
            visible=False,
            margin=(0, 10),
            styles={"color": "#666", "font-size": "12px"},
        )
        for name in ("band", "refine_band")
    }

    def fraction_in_force(*_):
        for name, label in (("band", "W1"), ("refine_band", "W2")):
            value = getattr(session, f"{name}_s")
            off = value is not None or (name == "refine_band" and session.pass2_turns_hand())
            slider = params._widgets[name]
            slider.disabled = off
            slider.styles = {"opacity": "0.4" if off else "1"}
            note = overridden[name]
            unused = name == "refine_band" and session.pass2_turns_hand()  # said below
            note.visible = value is not None and not unused
            if note.visible and name in session.automatic:  # not set: each pair's own
                note.object = (
                    f"The fraction above is not used: the seconds field below sets {label} "
                    f"to {value:g} seconds, the default for these takes (another pair gets "
                    "its own until you set a width; empty the field to use the fraction)."
                )
            elif note.visible:
                note.object = (
                    f"The fraction above is not used: the seconds field below sets {label} "
                    f"to {value:g} seconds (empty it to use the fraction)."
                )

    session.param.watch(fraction_in_force, ["band_s", "refine_band_s", "inputs_revision"])
    matrix = pn.widgets.RadioButtonGroup(
        label="Matrix",
        options=MATRIX_CHOICES,
        value=session.matrix,
        color="default",
        css_classes=["hs-matrix-choice"],
    )
    matrix.link(session, value="matrix")
    session.param.watch(lambda e: setattr(matrix, "value", e.new), ["matrix"])
    # W2 greyed out, and why, when pass 2 does not use it (a hand take without a forearm)
    unused = pn.pane.Markdown(
        PASS2_SPIN_NOTE, css_classes=["hs-w2-unused"], visible=False, margin=(0, 10)
    )

    def w2_in_use(*_):
        spin = session.pass2_turns_hand()
        seconds["refine_band"].disabled = spin
        unused.visible = spin
        fraction_in_force()

    session.param.watch(w2_in_use, ["inputs_revision"])
    w2_in_use()
    fraction_in_force()
    # takes of different lengths with open ends: the band also holds every place of the
    # shorter take inside the longer one, which W1 does not narrow (said under W1)
    placement = pn.pane.Markdown(
        "",
        css_classes=["hs-band-placement"],
        visible=False,
        margin=(0, 10),
        styles={"color": "#666", "font-size": "12px"},
    )
    # the open-end limit (the CLI's --max-unmatched): range, default and refusal are
    # engine.dtw.constraints'; empty = the default for these takes, said below the field
    unmatched = _unmatched_input(session)
    unmatched_note = pn.pane.Markdown(
        "",
        css_classes=["hs-unmatched-note"],
        margin=(0, 10),
        styles={"color": "#666", "font-size": "12px"},
    )

    def open_end_notes(*_):
        text = session.band_placement_note()
        placement.object, placement.visible = text, bool(text)
        unmatched_note.object = session.unmatched_note()

    session.param.watch(open_end_notes, ["inputs_revision", "max_unmatched_s"])
    doc = pn.state.curdoc
    session.param.watch(  # an edit's: after its path is in the page (``after_path``)
        lambda *_: after_path(session, ("open-end-notes", id(placement)), open_end_notes, doc),
        ["revision"],
    )
    open_end_notes()
    widgets = params._widgets  # linked to the session by pn.Param; laid out here
    return pn.Column(
        pn.Column(
            widgets["band"],
            overridden["band"],
            seconds["band"],
            placement,
            widgets["refine_band"],
            overridden["refine_band"],
            seconds["refine_band"],
            widgets["tolerance"],
            unmatched,
            unmatched_note,
            sizing_mode="stretch_width",
            css_classes=["hs-params"],
        ),
        unused,
        pn.pane.Markdown("**Matrix shown**", margin=(0, 10)),
        matrix,
        sizing_mode="stretch_width",
    )


def _seconds_text(value: float | None) -> str:
    return "" if value is None else f"{value:g}"


def _seconds_input(session: Session, name: str, label: str) -> pn.widgets.TextInput:
    """A band width in seconds for ``name`` ("band" or "refine_band"), kept in step with the
    session both ways; what the person types (``2``, ``2s``, empty for the fraction) is an
    edit the session checks (a text field: a number field shows "NaN" for what it cannot
    read, and nothing at all for a value out of range)."""
    field = f"{name}_s"
    widget = pn.widgets.TextInput(
        label=label,
        value=_seconds_text(getattr(session, field)),
        placeholder="empty: the fraction above",
        css_classes=[f"hs-{name}-s"],
    )
    syncing = [False]

    def show(*_):
        syncing[0] = True
        try:
            widget.value = _seconds_text(getattr(session, field))
        finally:
            syncing[0] = False

    def typed(event):
        if syncing[0]:
            return
        text = str(event.new or "").strip()
        if text == _seconds_text(getattr(session, field)):
            return  # what is in force (the page echoing a value shown): no edit
        # emptied: the fraction is in force again; a refusal speaks of this field
        # ("W1 in seconds: ...", engine.dtw.constraints), showing the text as typed
        ok = session.set_constraints(**{field: text})
        if ok:
            show()  # normalised: show what is in force
        # refused: the text stays as typed, to be corrected (the error line says why and
        # the width in force is unchanged)

    widget.param.watch(typed, "value")
    session.param.watch(show, [field])
    return widget


def hand_rate_note(session: Session) -> pn.viewable.Viewable:
    """Under the matching points' heading: a hand take faster than the body snaps a point's
    hand frame to the body's rate (``Session.hand_rate_note``), said before anyone asks why
    the preview names another hand frame."""
    pane = pn.pane.Markdown(
        "",
        css_classes=["hs-hand-rate-note"],
        visible=False,
        margin=(0, 10),
        styles={"color": "#666", "font-size": "12px"},
    )

    def update(*_):
        text = session.hand_rate_note()
        pane.object, pane.visible = text, bool(text)

    session.param.watch(update, ["inputs_revision"])
    update()
    return pane


def _unmatched_input(session: Session) -> pn.widgets.TextInput:
    """The open-end limit in seconds (``Session.max_unmatched_s``, the CLI's
    --max-unmatched), kept in step with the session both ways; what is typed is an edit the
    session checks (engine.dtw.constraints' range and refusal, naming this field); empty
    text is the default limit. A refused entry stays as typed, to be corrected."""
    widget = pn.widgets.TextInput(
        label=f"{C.MAX_UNMATCHED_LABEL}, each end of each take",
        value=_seconds_text(session.max_unmatched_s),
        placeholder="empty: the default (said below)",
        css_classes=["hs-max-unmatched"],
    )
    syncing = [False]

    def show(*_):
        syncing[0] = True
        try:
            widget.value = _seconds_text(session.max_unmatched_s)
        finally:
            syncing[0] = False

    def typed(event):
        if syncing[0]:
            return
        text = str(event.new or "").strip()
        if text == _seconds_text(session.max_unmatched_s):
            return
        if session.set_constraints(max_unmatched_s=text):
            show()

    widget.param.watch(typed, "value")
    session.param.watch(show, ["max_unmatched_s"])
    return widget


#: points table: pixels per digit of a frame number and the rest of a frame cell (padding)
_DIGIT_PX, _CELL_PX = 9, 16


def _frame_column_width(frames: int) -> int:
    """Pixels of a points-table column of frame numbers up to ``frames - 1`` (at least 4
    digits: 52 px)."""
    return _CELL_PX + _DIGIT_PX * max(4, len(str(max(int(frames) - 1, 0))))


def _column_widths(body_frames: int, hand_frames: int) -> dict[str, int]:
    """The points table's column widths for takes of ``body_frames`` and ``hand_frames``:
    frame numbers never cut off, the whole table as wide as for 4-digit takes."""
    body, hand = _frame_column_width(body_frames), _frame_column_width(hand_frames)
    extra = body + hand - 2 * _frame_column_width(0)
    return {
        "body frame": body,
        "hand frame": hand,
        "seconds": 112 - extra,  # wraps: "367.10 s ·" / "16.65 s"
        "tolerance": 44,
        "effective": 92,
    }


def _points_frame(session: Session) -> pd.DataFrame:
    """The table's rows: frames in each file's numbering (whole numbers), their times, the
    point's own tolerance (empty = global) and the tolerance in use, as text."""
    pts = session.points
    fps, hand_fps = session.fps or 1.0, session.hand_fps or 1.0
    return pd.DataFrame(
        {
            "body frame": pd.Series([p.body for p in pts], dtype="int64"),
            "hand frame": pd.Series([p.hand for p in pts], dtype="int64"),
            "seconds": [f"{p.body / fps:.2f} s · {p.hand / hand_fps:.2f} s" for p in pts],
            "tolerance": ["" if p.tolerance is None else f"{p.tolerance:g}" for p in pts],
            "effective": [
                f"{session.tolerance:g} (global)" if p.tolerance is None else f"{p.tolerance:g}"
                for p in pts
            ],
        },
        columns=["body frame", "hand frame", "seconds", "tolerance", "effective"],
    )


#: the page side of :class:`PointsTabulator`: Panel's table view drops a change of its
#: rows that arrives while Tabulator still builds the table (``setData`` returns at once
#: while ``_initializing``), so the rows a shared link restores a moment after the page
#: loads never showed. A dropped change is shown here once the table is ready.
_JS_SHOW_LATE_ROWS = """
const busy = v => v == null || v.tabulator == null || !v.tabulator.initialized
  || v._initializing || v._building;
if (!busy(Bokeh.index.find_one(table))) return;  // Panel's own handler shows the rows
const serial = (table.__hs_rows = (table.__hs_rows ?? 0) + 1);
let tries = 0;
const again = () => {
  if (table.__hs_rows !== serial) return;  // a newer change took over
  const view = Bokeh.index.find_one(table);
  if (view == null) return;  // drawn later from the source as it is then
  if (busy(view)) {
    if (++tries < 600) setTimeout(again, 100);
    return;
  }
  void view.setData();
};
setTimeout(again, 100);
"""


class PointsTabulator(pn.widgets.Tabulator):
    """Panel's Tabulator whose rows also show when they change while the page's table is
    still being built (see ``_JS_SHOW_LATE_ROWS``)."""

    def _get_model(self, doc, root=None, parent=None, comm=None):
        model = super()._get_model(doc, root, parent, comm)
        model.source.js_on_change("data", CustomJS(args={"table": model}, code=_JS_SHOW_LATE_ROWS))
        return model


#: the points table as the front of an edit (``Session.edit_from``): its refusal is said in
#: the table's own box, not on the page's error line
TABLE_FRONT = "table"


class PointsTable:
    """Tabulator of the matching points: edit frames and per-point tolerance, delete rows.

    An empty ``tolerance`` cell means "use the global tolerance" (``effective`` shows it).
    """

    def __init__(self, session: Session):
        self.session = session
        self._syncing = False
        self.table = self._make_table()
        #: a new pair (a link, a session file) gets a new table, drawn with its rows: a
        #: change of rows that reaches the page while its table is still being built (a
        #: link's solve back before a loaded tab drew the page) was lost
        self._holder = pn.Column(self.table, margin=0, sizing_mode="stretch_width")
        #: a refused edit of the table is said here, where it was typed (the page's error
        #: line sits above the matrix, often scrolled out of view)
        self.refusal = refusal_box(
            "hs-table-error", into_view=True, sizing_mode="stretch_width", margin=(4, 10)
        )
        # after the edit's path is in the page (``after_path``): re-rendering the table in
        # the tick that draws the path, or while its solve runs, delayed the path
        doc = pn.state.curdoc
        session.param.watch(
            lambda *_: after_path(session, ("points-table", id(self)), self._refresh, doc),
            ["points", "tolerance", "revision"],
        )
        session.param.watch(self._new_table, ["inputs_revision"])
        session.param.watch(self._on_error, ["error"])

    def _make_table(self) -> pn.widgets.Tabulator:
        table = PointsTabulator(
            _points_frame(self.session),
            show_index=False,
            sizing_mode="stretch_width",
            height=180,
            titles={
                "body frame": "body",
                "hand frame": "hand",
                "seconds": "times",
                "tolerance": "tol.",
                "effective": "tol. in use",
            },
            # with the delete column (about 40 px) all columns fit the side panel's 400 px:
            # nothing is cut off or scrolled sideways; the frame columns are as wide as the
            # takes' largest frame numbers (5 digits on a long take), the times (which wrap)
            # give up what they take beyond 4 digits
            widths=_column_widths(self.session.n, self.session.m_hand),
            header_align="center",
            header_tooltips={
                "body frame": "body frame (body file's numbering)",
                "hand frame": "hand frame (hand file's numbering)",
                "seconds": "body time · hand time",
                "tolerance": "this point's tolerance in hand frames; empty = the global tolerance",
                "effective": "the tolerance this point uses, hand frames",
            },
            formatters={
                "body frame": {"type": "plaintext"},
                "hand frame": {"type": "plaintext"},
                # wraps (not cut) when a long take's times do not fit: "152.87 s · 33.00 s"
                "seconds": {"type": "textarea"},
                "tolerance": {"type": "plaintext"},
                "effective": {"type": "plaintext"},
            },
            editors={
                "effective": None,
                "seconds": None,
                # a value typed into a cell replaces the one there (stranger 12: "40" typed
                # over 25 became 2540): the editor opens with its text selected
                "tolerance": {"type": "input", "selectContents": True},
                "body frame": {"type": "number", "min": 0, "step": 1, "selectContents": True},
                "hand frame": {"type": "number", "min": 0, "step": 1, "selectContents": True},
            },
            text_align={"tolerance": "right"},
            buttons={"delete": '<span title="delete this point" style="color:#c62828">✕</span>'},
            css_classes=["hs-points"],
            selectable=False,
            layout="fit_data_table",
            configuration={"columnDefaults": {"headerSort": False}},
        )
        table.on_edit(self._on_edit)
        table.on_click(self._on_click)
        return table

    @with_document_lock
    def _new_table(self, *_):
        self.table = self._make_table()
        self._holder.objects = [self.table]

    def _refresh(self, *_):
        frame = _points_frame(self.session)
        if frame.equals(self.table.value):
            return  # unchanged: do not re-render the table (an open editor would close)
        self._syncing = True
        try:
            self.table.value = frame
        finally:
            self._syncing = False

    def _on_edit(self, event):
        if self._syncing:
            return
        k, column, value = event.row, event.column, event.value
        s = self.session
        if not 0 <= k < len(s.points):
            return
        # the rules and their one text are engine.dtw.constraints' (as for every front):
        # a fraction of a frame (12.5) is refused, never truncated
        s.error = ""  # a new edit: only its own refusal is shown
        with s.edit_from(TABLE_FRONT):  # its refusal is said here (even from its solve)
            self._edit(k, column, value)
        self._refresh()
        self._on_error()

    def _edit(self, k: int, column: str, value) -> None:
        """Point ``k``'s ``column`` set to ``value`` as typed; a refusal said by the session."""
        s = self.session
        try:
            if column == "tolerance":
                text = "" if value is None else str(value).strip()
                tol = None if text in ("", "global", "nan") else text
                s.set_point_tolerance(k, tol)
            elif column in ("body frame", "hand frame"):
                p = s.points[k]
                key = "body" if column == "body frame" else "hand"
                frame = C.parse_point_frame(
                    value, k, key, *((value, p.hand) if key == "body" else (p.body, value))
                )
                s.move_point(
                    k,
                    frame if key == "body" else p.body,
                    frame if key == "hand" else p.hand,
                )
        except C.ConstraintError as exc:
            s.refuse(exc, str(exc))

    def _on_error(self, *_):
        """The refusal of an edit typed in this table is said here, and only here (stranger
        13 F3: the page's error line under the matrix said it too); another's is not."""
        s = self.session
        if s.error and s.refused_from == TABLE_FRONT:
            self.refusal.object = safe_text.markdown(s.error)
            self.refusal.visible = True
        else:
            self.refusal.visible = False

    def _on_click(self, event):
        if getattr(event, "column", None) == "delete" and 0 <= event.row < len(self.session.points):
            self.session.delete_point(event.row)

    def panel(self) -> pn.viewable.Viewable:
        # the refusal above the rows: in view while a cell is edited
        return pn.Column(self.refusal, self._holder, margin=0, sizing_mode="stretch_width")


#: the status line's height: two lines of its text, so that an edit whose line wraps to a
#: second line (unmatched body frames named) does not move the matrix below it, px
STATUS_MIN_PX = 48
#: the status line's opacity while it is stale (an edit sent, its line not back yet)
STALE_OPACITY = 0.45

#: the page dims the status line from the moment the matrix sends an edit (the page event
#: ``hs-edit-sent``: ``webapp.views.cost_matrix``) until the line is written again, or
#: the server answers that no solve follows the edit (``hs-edit-answered``: a refused or
#: empty edit); no message to or from the server (stranger 11 F6: on a long pair the line
#: said the old points for seconds, and nothing said work was under way)
_JS_STALE = """
const mark = (on) => {
  const view = Bokeh.index.find_one(status);
  if (view == null) return;
  // the text's own box inside the pane: the pane's styles (the veil's greying while a
  // new pair opens: webapp.views.veil) are the element's, and stay as they are
  const text = view.container ?? view.el;
  text.style.opacity = on ? String(opacity) : '';
  text.style.transition = 'opacity 0.15s';
  if (on) view.el.dataset.hsStale = '1'; else delete view.el.dataset.hsStale;
};
document.addEventListener('hs-edit-sent', () => mark(true));
document.addEventListener('hs-edit-answered', () => mark(false));
status.properties.text.change.connect(() => mark(false));
"""


class _StatusPane(pn.pane.HTML):
    """The status line's pane: an HTML pane that the page dims while it is stale
    (:data:`_JS_STALE`). Never chosen by ``pn.panel`` for a text (``priority`` 0)."""

    priority = 0

    def _get_model(self, doc, root=None, parent=None, comm=None):
        model = super()._get_model(doc, root, parent, comm)
        if doc is not None:
            args = {"status": model, "opacity": STALE_OPACITY}
            page_js.run_once(model, _JS_STALE, args, doc=doc)
        return model


def status_line(session: Session) -> pn.viewable.Viewable:
    """One line: path costs, compute time, band cells, points; the error when one is set.
    It keeps the height of two lines (:data:`STATUS_MIN_PX`), so the matrix under it stays
    where it is under the pointer. The page dims it while an edit it sent is not yet in it
    (:data:`_JS_STALE`)."""
    pane = _StatusPane(
        "",
        css_classes=["hs-status"],
        sizing_mode="stretch_width",
        styles={
            "font-family": "monospace",
            "font-size": "13px",
            "line-height": "17px",
            "box-sizing": "border-box",
            "min-height": f"{STATUS_MIN_PX}px",
            "padding": "6px 10px",
            "background": "#f3f5f7",
            "border-radius": "4px",
            "border": "1px solid #dde2e6",
        },
    )

    def update(*_):
        text = session.status_text()
        if session.waiting:
            text = f"{session.waiting} · the views below still show the pair open before: {text}"
        # data-aligned: "here" (solved for this tab) or "shared" (the pair's first
        # alignment, solved once for every tab of the server)
        aligned = "here" if session.aligned_here() else "shared"
        pane.object = (
            f'<span data-revision="{session.revision}" data-aligned="{aligned}">'
            f"{safe_text.html(text)}</span>"
        )

    doc = pn.state.curdoc
    session.param.watch(  # after the edit's path is in the page (``after_path``)
        lambda *_: after_path(session, ("status", id(pane)), update, doc),
        ["revision", "compute_ms", "error", "waiting", "opening"],
    )
    update()
    return pane


def error_alert(session: Session) -> pn.viewable.Viewable:
    """A dismissible alert showing ``session.error`` (never a traceback)."""
    alert = refusal_box("hs-error", sizing_mode="stretch_width")

    def update(*_):
        alert.object = safe_text.markdown(session.error)
        # a refused side is shown under the Side control (webapp.views.inputs), a refused
        # edit of the points table above the table (PointsTable): one refusal, one box
        alert.visible = (
            bool(session.error)
            and "side" not in session.refused_inputs
            and session.refused_from != TABLE_FRONT
        )

    session.param.watch(update, ["error"])
    update()
    return alert


class _UndoButton(pn.widgets.Button):
    """The Undo button; it brings the page's undo keys (:data:`_JS_UNDO_KEYS`) with it."""

    def _get_model(self, doc, root=None, parent=None, comm=None):
        model = super()._get_model(doc, root, parent, comm)
        page_js.run_once(model, _JS_UNDO_KEYS, doc=doc)
        return model


#: the history buttons' tooltips
UNDO_TIP = "Undo the last edit: a matching point added, moved or deleted, a band width, a tolerance (Ctrl+Z)"
REDO_TIP = "Redo the edit last undone (Ctrl+Shift+Z or Ctrl+Y)"
CLEAR_TIP = "Delete every matching point (one edit: Undo brings them back)"


def undo_redo(session: Session) -> pn.viewable.Viewable:
    """Undo, Redo and Clear points, with the words of what the last Undo or Redo did
    (``Session.history_note``, a line of its own under the buttons)."""
    undo = _UndoButton(
        label="↶ Undo",
        disabled=not session.can_undo,
        width=90,
        css_classes=["hs-undo"],
        description=UNDO_TIP,
    )
    redo = pn.widgets.Button(
        label="↷ Redo",
        disabled=not session.can_redo,
        width=90,
        css_classes=["hs-redo"],
        description=REDO_TIP,
    )
    clear = pn.widgets.Button(
        label="Clear points", width=110, css_classes=["hs-clear"], description=CLEAR_TIP
    )
    undo.on_click(lambda e: session.undo())
    redo.on_click(lambda e: session.redo())
    clear.on_click(lambda e: session.set_points([]))
    note = pn.pane.HTML(
        "",
        css_classes=["hs-history-note"],
        styles={"font-size": "12px", "color": "#444"},
        margin=(0, 10),
        min_height=18,  # the line is there empty too: its words never move the page below
        sizing_mode="stretch_width",
    )

    def flags(*_):
        undo.disabled = not session.can_undo
        redo.disabled = not session.can_redo

    def words(*_):
        note.object = safe_text.html(session.history_note)

    session.param.watch(flags, ["can_undo", "can_redo"])
    session.param.watch(words, ["history_note"])
    return pn.Column(pn.Row(undo, redo, clear), note, sizing_mode="stretch_width")


#: The page's keyboard handling. Ctrl+Z undoes, Ctrl+Shift+Z and Ctrl+Y redo (Cmd on a
#: Mac), anywhere in the page except while typing in a text field (where the field's own
#: undo applies): they press the page's Undo and Redo buttons, so keyboard and mouse do
#: the same thing. Backspace and Delete delete the selected matching point, likewise from
#: anywhere but a text field (stranger 6: only with the pointer over the matrix before). While a new pair opens (the old pair's views veiled, ``.hs-inactive``:
#: webapp.views.veil, which blocks the mouse) the keyboard is inert there too: no key
#: reaches a veiled view (a focused slider, table cell or field), and no edit shortcut
#: (undo, redo, Delete/Backspace on the matrix's points) acts, before the server would
#: refuse it.
_JS_UNDO_KEYS = """
if (window.__hsUndoKeys) return;
window.__hsUndoKeys = true;
const find = (sel, root = document) => {
  const hit = root.querySelector(sel);
  if (hit) return hit;
  for (const el of root.querySelectorAll('*')) {
    if (el.shadowRoot) { const f = find(sel, el.shadowRoot); if (f) return f; }
  }
  return null;
};
const typing = (t) => t && (t.tagName === 'INPUT' && !['range', 'checkbox', 'radio', 'button']
  .includes(t.type) || t.tagName === 'TEXTAREA' || t.isContentEditable);
const opening = () => find('.hs-inactive') !== null;
const veiled = (ev) => ev.composedPath().some((n) => n.classList && n.classList.contains('hs-inactive'));
const editKey = (ev) => ((ev.ctrlKey || ev.metaKey) && !ev.altKey
    && ['z', 'y'].includes(ev.key.toLowerCase()))
  || (['Delete', 'Backspace'].includes(ev.key) && !typing(ev.composedPath()[0]));
for (const type of ['keydown', 'keypress', 'keyup']) {  // before any other listener
  window.addEventListener(type, (ev) => {
    if ((veiled(ev) || editKey(ev)) && opening()) {
      ev.stopImmediatePropagation();
      ev.preventDefault();
    }
  }, true);
}
document.addEventListener('keydown', (ev) => {
  if (!(ev.ctrlKey || ev.metaKey) || ev.altKey) return;
  const key = ev.key.toLowerCase();
  const redo = (key === 'z' && ev.shiftKey) || (key === 'y' && !ev.shiftKey);
  const undo = key === 'z' && !ev.shiftKey;
  if (!undo && !redo) return;
  const target = ev.composedPath()[0];
  if (target && (target.tagName === 'INPUT' && !['range', 'checkbox', 'radio', 'button']
      .includes(target.type) || target.tagName === 'TEXTAREA' || target.isContentEditable)) return;
  ev.preventDefault();
  // presses are queued and done in order; a button still disabled may be waiting for the
  // server's answer to the edit before (a redo re-enables Undo): each waits up to 10 s
  queue.push(redo ? '.hs-redo' : '.hs-undo');
  if (queue.length === 1) next(100);
}, true);
// Backspace and Delete delete the selected matching point (the one with the magenta ring)
// wherever the pointer is (Bokeh's point tool does it only while the pointer is over the
// matrix, and then finds none left to delete), never while typing in a field
window.addEventListener('keyup', (ev) => {
  if (!['Delete', 'Backspace'].includes(ev.key) || ev.ctrlKey || ev.metaKey || ev.altKey
      || typing(ev.composedPath()[0]) || opening()) return;
  const src = window.Bokeh?.documents[0]?.get_model_by_name('hs-points-source');
  const picked = src == null ? [] : Array.from(src.selected.indices);
  if (!picked.length) return;
  ev.stopImmediatePropagation();
  ev.preventDefault();
  const kept = (k) => Array.from(src.data[k] ?? []).filter((_, i) => !picked.includes(i));
  const data = Object.fromEntries(Object.keys(src.data).map((k) => [k, kept(k)]));
  src.selected.indices = [];
  src.data = data;  // the matrix's edit queue sends it as one edit (a delete), as a tool's
}, true);
const queue = [];
const next = (tries) => {
  if (opening()) queue.length = 0;  // a press queued before a new pair began to open
  if (!queue.length) return;
  const host = find(queue[0]);
  const button = host && (host.shadowRoot ?? host).querySelector('button');
  if (button && !button.disabled) {
    button.click();
    queue.shift();
    setTimeout(() => next(100), 50);
  } else if (tries > 0) {
    setTimeout(() => next(tries - 1), 100);
  } else {
    queue.shift();
    next(100);
  }
};
"""
