"""Teaching mode: DTW on a 12 x 10 example, one cell at a time.

The learner steps through the recurrence (eqs. 1-2) cell by cell and sees the
values that make each γ; changes the band width and adds a matching point with a
tolerance to see how they reshape the search (eqs. 3-5); and compares a
value-based local cost with the paper's sign-based one on takes that differ in
amplitude (as Majkowska et al.'s Figure 3 does).

All numbers come from the engine: local costs from ``engine.align.metrics``, the band
from ``Band.from_constraints``, the path and γ from the DTW solver. The view only
reveals them in the order the recurrence fills them.
"""

from __future__ import annotations

import math

import numpy as np
import panel as pn
import param
from bokeh.models import ColumnDataSource, Range1d
from bokeh.plotting import figure

from engine.align import metrics
from engine.base.errors import HandSpliceError
from engine.dtw import Aligner, Band
from engine.dtw.views import local_cost_image
from webapp.views._dispatch import with_document_lock
from webapp.views.checkbox import Checkbox

EXAMPLE_FPS = 10.0
#: centimetres per unit of the example's wrist heights (a stroke rises about 30 cm): the
#: value-based costs are squared differences in cm² (0-900), whole numbers a cell can show,
#: not the 0.002-0.9 of unit heights (stranger 7: "2e-3" in a teaching grid)
HEIGHT_CM = 30.0


def _gesture(t: np.ndarray, amplitude: float, offset: float) -> np.ndarray:
    """Two strokes with a hold between them (a smooth made-up wrist height)."""
    stroke1 = np.exp(-(((t - 0.25) / 0.09) ** 2))
    stroke2 = 0.8 * np.exp(-(((t - 0.7) / 0.11) ** 2))
    return offset + amplitude * (stroke1 + stroke2)


def example_signals(n: int = 12, m: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Body (n,) and hand (m,) wrist heights: the hand take is smaller, lower and re-timed."""
    tb = np.linspace(0.0, 1.0, n)
    warp = np.linspace(0.0, 1.0, m) ** 1.35  # the hand performer is slower at first
    return _gesture(tb, 1.0, 0.0), _gesture(warp, 0.45, 0.3)


def local_costs(body: np.ndarray, hand: np.ndarray, metric: str) -> np.ndarray:
    """(n, m) local cost of the example: ``"value"`` squared difference of heights, or
    ``"sign"`` eq. 6 on this one coordinate (signs of velocity and acceleration). Value
    costs are in cm² (heights × ``HEIGHT_CM``)."""
    n, m = len(body), len(hand)
    if metric == "value":
        body_cm, hand_cm = body[:, None] * HEIGHT_CM, hand[:, None] * HEIGHT_CM
        return local_cost_image(body_cm, hand_cm, "sqeuclidean", (n, m)).image
    codes = []
    for x in (body, hand):
        v, a = metrics.derivatives(x[:, None], EXAMPLE_FPS, window_s=0.3)
        zone = metrics.dead_zone(v[:, :, None], a[:, :, None])
        codes.append(
            np.concatenate(
                [
                    metrics.sign_dead_zone(v, zone.velocity),
                    metrics.sign_dead_zone(a, zone.acceleration),
                ],
                axis=1,
            )
        )
    return local_cost_image(
        codes[0].astype(float), codes[1].astype(float), "sqeuclidean", (n, m)
    ).image


def short_number(x: float, width: int = 4) -> str:
    """``x`` in at most ``width`` characters (so it fits a lesson cell): 0, 0.12, 3.5, 12,
    340, 2e3."""
    x = float(x)
    if x == 0:
        return "0"
    for digits in (2, 1, 0):
        text = f"{x:.{digits}f}"
        if len(text) <= width and float(text) != 0:
            return text.rstrip("0").rstrip(".") if "." in text else text
    text = f"{x:.0e}".replace("e+0", "e").replace("e-0", "e-").replace("e+", "e")
    return text


class TeachingModel(param.Parameterized):
    """The example's state: metric, band, optional matching point, current step."""

    metric = param.Selector(default="sign", objects=["sign", "value"])
    width = param.Number(default=0.6, bounds=(0.05, 1.5), step=0.05)
    use_point = param.Boolean(default=False)
    point_body = param.Integer(default=6, bounds=(1, 10))
    point_hand = param.Integer(default=3, bounds=(1, 8))
    point_tol = param.Integer(default=0, bounds=(0, 4))
    step = param.Integer(default=0, bounds=(0, None))
    error = param.String(default="")
    revision = param.Integer(default=0)

    def __init__(self, n: int = 12, m: int = 10, **params):
        super().__init__(**params)
        self.n, self.m = n, m
        self.body, self.hand = example_signals(n, m)
        self.solve()
        self.param.watch(
            lambda e: self.solve(),
            ["metric", "width", "use_point", "point_body", "point_hand", "point_tol"],
        )

    def points(self) -> list[tuple[int, int, int]]:
        return [(self.point_body, self.point_hand, self.point_tol)] if self.use_point else []

    def solve(self) -> None:
        try:
            band = Band.from_constraints(self.n, self.m, self.width, self.points())
        except (HandSpliceError, ValueError) as exc:
            self.error = str(exc).splitlines()[0]
            return
        self.error = ""
        self.cost = local_costs(self.body, self.hand, self.metric)
        solver = Aligner.from_cost(self.cost)
        self.alignment = solver.solve(band)
        self.band = band
        self.gamma = solver.cumulative_cost().dense(fill=np.inf)
        rows = [np.arange(band.lo[i], band.hi[i] + 1) for i in range(self.n)]
        self.order = [(i, int(j)) for i, cols in enumerate(rows) for j in cols]
        self.step = min(self.step, len(self.order))
        self.revision += 1

    def next_row_step(self) -> int:
        """The step that completes the current row i of the matrix (one body frame, drawn as
        a column of the grid): the rest of it when it is part done, else the whole next one."""
        order = self.order
        if not order:
            return 0
        k = self.step  # cells done; the next one is order[k]
        if k >= len(order):
            return len(order)
        row = order[k][0]  # the row the next cell belongs to: finish it
        while k < len(order) and order[k][0] == row:
            k += 1
        return k

    @property
    def finished(self) -> bool:
        return self.step >= len(self.order)

    def current(self) -> tuple[int, int] | None:
        return None if self.step == 0 else self.order[self.step - 1]

    def explain(self) -> str:
        """The recurrence at the current cell with its numbers (HTML)."""
        cell = self.current()
        if cell is None:
            return (
                "Press <b>Step</b> to compute the first cell. The solver fills the band "
                "body frame by body frame (i), and within one, hand frame by hand frame "
                "(j). Small grey numbers are the local costs D(i, j); hatched cells lie "
                "outside the band and are never computed."
            )
        i, j = cell
        g = self.gamma

        def val(a, b):
            if a < 0 or b < 0 or not np.isfinite(g[a, b]):
                return "∞"
            return f"{g[a, b]:.4g}"

        d = self.cost[i, j]
        if i == 0 and j == 0:
            return f"<b>γ(0, 0) = D(0, 0) = {d:.4g}</b> — every path starts here (eq. 1)."
        preds = [val(i - 1, j - 1), val(i - 1, j), val(i, j - 1)]
        best = (
            "∞"
            if all(p == "∞" for p in preds)
            else f"{min(float(p) for p in preds if p != '∞'):.4g}"
        )
        return (
            f"<b>γ({i}, {j}) = D({i}, {j}) + min(γ({i - 1}, {j - 1}), γ({i - 1}, {j}), "
            f"γ({i}, {j - 1}))</b><br>= {d:.4g} + min({', '.join(preds)}) = {d:.4g} + "
            f"{best} = <b>{val(i, j)}</b><br><span style='color:#666'>(eq. 2; ∞ = outside "
            f"the band or the matrix)</span>"
        )

    def band_text(self) -> str:
        n, m, w = self.n, self.m, self.width
        lam = w * n * math.sqrt(n * n + m * m) / (2 * n)
        text = (
            f"Band (eq. 3): W = {w:.2f} × n = {w * n:.1f} frames wide around the diagonal; "
            f"vertical half-width Λ = W·√(n²+m²)/(2n) = {lam:.2f} frames. "
            f"{self.band.area} of {n * m} cells are searched."
        )
        if self.use_point:
            x, y, t = self.points()[0]
            text += (
                f" Matching point ({x}, {y}) with tolerance T = {t} (eqs. 4-5): the band "
                f"is split into two diagonal bands meeting there, and the path must cross "
                f"body frame {x} at a hand frame within {y - t}..{y + t}."
            )
        return text


class TeachingView:
    TEXT = (
        "A 12-frame body take against a 10-frame hand take (wrist heights; the hand "
        "performer moved less, lower and slower). Step through the recurrence, narrow the "
        "band, pin a matching point, and switch between the value-based and the "
        "sign-based local cost."
    )

    def __init__(self, model: TeachingModel | None = None):
        self.model = model or TeachingModel()
        mdl = self.model
        n, m = mdl.n, mdl.m
        self.cells = ColumnDataSource(self._cells(), name="hs-teach-cells")
        fig = figure(
            width=520,
            height=450,
            x_range=Range1d(-0.5, n - 0.5),
            y_range=Range1d(-0.5, m - 0.5),
            tools="",
            toolbar_location=None,
            x_axis_label="body frame i",
            y_axis_label="hand frame j",
            name="hs-teach-grid",
        )
        fig.css_classes = ["hs-teach-grid"]
        fig.rect(
            x="i",
            y="j",
            width=0.96,
            height=0.96,
            source=self.cells,
            fill_color="fill",
            line_color="line",
            line_width="lw",
            line_dash="dash",
            hatch_pattern="hatch",
            hatch_color="#cccccc",
            hatch_scale=8,
        )
        fig.text(
            x="i",
            y="j",
            text="gamma",
            source=self.cells,
            text_align="center",
            text_baseline="middle",
            text_font_size="9pt",
            text_font_style="bold",
            name="hs-teach-gamma",
        )
        fig.text(
            x="dx",
            y="dy",
            text="d",
            source=self.cells,
            text_align="left",
            text_baseline="top",
            text_font_size="7pt",
            text_color="#555555",
        )
        self.path = ColumnDataSource({"x": [], "y": []})
        fig.line(x="x", y="y", source=self.path, color="#e31a1c", line_width=3, line_alpha=0.7)
        self.point = ColumnDataSource({"x": [], "y0": [], "y1": []})
        fig.segment(
            x0="x",
            y0="y0",
            x1="x",
            y1="y1",
            source=self.point,
            color="#f2a900",
            line_width=6,
            line_alpha=0.6,
        )
        fig.xaxis.ticker = list(range(n))
        fig.yaxis.ticker = list(range(m))
        fig.grid.visible = False
        self.grid = fig

        self.equation = pn.pane.HTML(
            "",
            css_classes=["hs-teach-equation"],
            styles={"font-size": "14px", "min-height": "70px"},
        )
        self.band_note = pn.pane.HTML("", styles={"font-size": "13px", "color": "#333"})
        self.alert = pn.pane.Alert("", alert_type="warning", visible=False)
        self.buttons = {
            "reset": pn.widgets.Button(label="Reset", width=80),
            "back": pn.widgets.Button(label="Back", width=80),
            "step": pn.widgets.Button(
                label="Step", color="primary", width=80, css_classes=["hs-teach-step"]
            ),
            "row": pn.widgets.Button(
                label="Next body frame i",
                width=140,
                css_classes=["hs-teach-row"],
                description="compute the rest of this body frame's cells: the paper's row i "
                "of the matrix, drawn upright here (one column, one x)",
            ),
            "end": pn.widgets.Button(label="Finish", width=80),
        }
        self.buttons["reset"].on_click(lambda e: setattr(mdl, "step", 0))
        self.buttons["back"].on_click(lambda e: setattr(mdl, "step", max(mdl.step - 1, 0)))
        self.buttons["step"].on_click(
            lambda e: setattr(mdl, "step", min(mdl.step + 1, len(mdl.order)))
        )
        self.buttons["row"].on_click(self._next_row)
        self.buttons["end"].on_click(lambda e: setattr(mdl, "step", len(mdl.order)))
        self.compare = self._comparison()
        mdl.param.watch(self._refresh, ["step", "revision", "error"])
        self._refresh()

    def _next_row(self, _):
        self.model.step = self.model.next_row_step()

    def _cells(self) -> dict:
        mdl = self.model
        n, m = mdl.n, mdl.m
        ii, jj = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
        ii, jj = ii.ravel(), jj.ravel()
        inside = mdl.band.contains(ii, jj)
        revealed = np.zeros(n * m, bool)
        for i, j in mdl.order[: mdl.step]:
            revealed[i * m + j] = True
        cost = mdl.cost.ravel()
        top = max(float(cost.max()), 1e-9)
        fill = []
        for k in range(n * m):
            if not inside[k]:
                fill.append("#f7f7f7")
            else:
                shade = int(255 - 90 * cost[k] / top)  # darker = more expensive
                fill.append(
                    f"#{shade:02x}{shade:02x}ff"
                    if revealed[k]
                    else f"#{shade:02x}{shade:02x}{shade:02x}"
                )
        line = ["#bbbbbb"] * (n * m)
        lw = [0.5] * (n * m)
        dash = ["solid"] * (n * m)
        cur = mdl.current()
        if cur is not None:
            i, j = cur
            for a, b in ((i - 1, j - 1), (i - 1, j), (i, j - 1)):
                if a >= 0 and b >= 0:
                    line[a * m + b], lw[a * m + b], dash[a * m + b] = "#1f78b4", 3, "dashed"
            line[i * m + j], lw[i * m + j] = "#ff7f00", 4
        gamma = mdl.gamma.ravel()
        return {
            "i": ii,
            "j": jj,
            "fill": fill,
            "line": line,
            "lw": lw,
            "dash": dash,
            "gamma": [
                short_number(gamma[k]) if revealed[k] and np.isfinite(gamma[k]) else ""
                for k in range(n * m)
            ],
            "d": [short_number(cost[k], 3) if inside[k] else "" for k in range(n * m)],
            "hatch": [" " if inside[k] else "/" for k in range(n * m)],
            "dx": ii - 0.44,
            "dy": jj + 0.46,
        }

    @with_document_lock
    def _refresh(self, *_):
        mdl = self.model
        self.alert.object = mdl.error
        self.alert.visible = bool(mdl.error)
        self.cells.data = self._cells()
        if mdl.finished:
            p = mdl.alignment.path
            self.path.data = {"x": p[:, 0], "y": p[:, 1]}
        else:
            self.path.data = {"x": [], "y": []}
        if mdl.use_point:
            x, y, t = mdl.points()[0]
            self.point.data = {"x": [x], "y0": [y - t - 0.45], "y1": [y + t + 0.45]}
        else:
            self.point.data = {"x": [], "y0": [], "y1": []}
        done = (
            f"<br><b>Done:</b> the optimal path (red) costs γ({mdl.n - 1}, {mdl.m - 1}) = "
            f"{mdl.alignment.cost:.4g}; it is traced back from the last cell along the "
            f"cheapest predecessors."
            if mdl.finished
            else ""
        )
        self.equation.object = (
            f"<div>Step {mdl.step} of {len(mdl.order)}</div>" + mdl.explain() + done
        )
        self.band_note.object = mdl.band_text()

    def _comparison(self) -> pn.viewable.Viewable:
        """Figure 3 of the paper: value-based versus sign-based matching on longer takes."""
        body, hand = example_signals(60, 45)
        figs = []
        for metric, title in (
            ("value", "Value-based cost (height difference)"),
            ("sign", "Sign-based cost (eq. 6)"),
        ):
            cost = local_costs(body, hand, metric)
            path = Aligner.from_cost(cost).solve(Band.full(len(body), len(hand))).path
            f = figure(
                width=420,
                height=220,
                title=title,
                tools="",
                toolbar_location=None,
                name=f"hs-teach-compare-{metric}",
            )
            lift = 1.2
            xs = [[int(i), int(j) * (len(body) - 1) / (len(hand) - 1)] for i, j in path[::2]]
            ys = [[body[i] + lift, hand[j]] for i, j in path[::2]]
            f.multi_line(xs=xs, ys=ys, color="#999999", line_width=0.8)
            f.line(
                np.arange(len(body)),
                body + lift,
                color="#1f78b4",
                line_width=2,
                legend_label="body",
            )
            f.line(
                np.linspace(0, len(body) - 1, len(hand)),
                hand,
                color="#e31a1c",
                line_width=2,
                legend_label="hand",
            )
            f.legend.location = "top_right"
            f.legend.label_text_font_size = "8pt"
            f.yaxis.visible = False
            f.xaxis.visible = False
            f.grid.visible = False
            figs.append(pn.pane.Bokeh(f, sizing_mode="fixed"))
        note = pn.pane.Markdown(
            "Grey lines join matched frames. With values, the small, lower hand take is matched "
            "by height, so peaks meet slopes; with signs of velocity and acceleration, the "
            "rises, peaks and falls of both takes meet — the reason pass 1 uses signs.",
            styles={"color": "#444"},
        )
        return pn.Column(pn.Row(*figs), note)

    def panel(self) -> pn.viewable.Viewable:
        mdl = self.model
        controls = pn.Column(
            pn.widgets.RadioButtonGroup.from_param(mdl.param.metric, label="Local cost"),
            pn.widgets.FloatSlider.from_param(
                mdl.param.width, label="Band width W (fraction of n)", tooltips=False
            ),
            Checkbox.from_param(
                mdl.param.use_point, label="Matching point", css_classes=["hs-teach-point"]
            ),
            pn.Row(
                pn.widgets.IntSlider.from_param(
                    mdl.param.point_body, label="body frame x", width=130, tooltips=False
                ),
                pn.widgets.IntSlider.from_param(
                    mdl.param.point_hand, label="hand frame y", width=130, tooltips=False
                ),
                pn.widgets.IntSlider.from_param(
                    mdl.param.point_tol, label="tolerance T", width=110, tooltips=False
                ),
            ),
            pn.Row(*self.buttons.values()),
            self.equation,
            self.band_note,
            self.alert,
            width=480,
            sizing_mode=None,
        )
        return pn.Column(
            pn.Row(pn.pane.Bokeh(self.grid, sizing_mode="fixed"), controls),
            pn.pane.Markdown("#### Why signs? (the paper's Figure 3)"),
            self.compare,
            css_classes=["hs-teaching"],
        )
