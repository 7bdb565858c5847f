"""The one rule from a matrix position to a whole frame (webapp.matrix_frames): the page's
tooltips and the session that stores a dragged point say the same frame."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest
from bokeh.models import HoverTool
from conftest import open_demo_session

from webapp.matrix_frames import view_frame
from webapp.views.cost_matrix import CostMatrixView

#: halves (where rounding rules part), positions outside the take, a long take's frames
POSITIONS = [-3.2, -0.5, -0.49, 0.0, 0.5, 1.5, 2.5, 2.4999, 12.5, 185.5, 186.2, 240.7, 1e9]


def _run_js(code: str, args: dict, values: list[float]) -> list[str]:
    """``code`` (a CustomJSHover's body, ``value`` and ``args`` in scope) on each value."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("no node to run the page's code")
    names = ", ".join(args)
    script = (
        f"const f = ({names}, value) => {{ {code} }};\n"
        f"const args = {json.dumps(list(args.values()))};\n"
        f"console.log(JSON.stringify({json.dumps(values)}.map(v => String(f(...args, v)))));"
    )
    out = subprocess.run([node, "-e", script], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_a_points_tooltip_says_the_frame_the_session_stores(tmp_path):
    """Stranger 11 F7: while a point was dragged its tooltip said hand frame 1783, and the
    table 1782 after the release: the tooltip rounded a half up and past the take's ends,
    the session a half to even and within the take. Both use ``view_frame`` now."""
    session = open_demo_session(tmp_path)
    view = CostMatrixView(session)
    rates = {k: list(v) for k, v in view.rates.data.items()}
    assert (rates["n"], rates["m_hand"]) == ([session.n], [session.m_hand])
    hover = view.figure.select_one({"type": HoverTool, "name": "hs-point-hover"})
    assert "@y{custom}" in hover.tooltips[0][1]
    for axis, count in (("x", session.n), ("y", session.m_hand)):
        code = hover.formatters[f"@{axis}"].code
        args = {**hover.formatters[f"@{axis}"].args, "rates": {"data": rates}}
        shown = _run_js(code, args, POSITIONS)
        assert shown == [str(view_frame(v, count)) for v in POSITIONS], axis
    # the cell's tooltip too
    cell = view.figure.select_one({"type": HoverTool, "name": "hs-cell-hover"})
    shown = _run_js(cell.formatters["$y"].code, {"rates": {"data": rates}}, POSITIONS)
    assert [s.split(" · ")[0] for s in shown] == [
        str(view_frame(v, session.m_hand)) for v in POSITIONS
    ]
    # and its band line reads the band at that body frame (the take's last, past its end)
    band = {"data": {"x": [0, session.n - 1], "lo": [0, 0], "hi": [10, 10]}}
    args = {**cell.formatters["$sx"].args, "band": band, "rates": {"data": rates}}
    for x, said in ((session.n - 1.4, "inside (searched)"), (1e9, "inside (searched)")):
        args["special_vars"] = {"x": x, "y": 3.0}
        assert _run_js(cell.formatters["$sx"].code, args, [0.0]) == [said], x
    # a point dragged to each position is stored at the frame its tooltip said
    x = 60
    for y in (12.5, 30.5, -2.0, 1e9):
        before = [(p.body, p.hand, p.tolerance) for p in session.points]
        session.apply_view_edits([(before, [*before, (x, y, None)])])
        assert session.error == "", session.error
        assert session.points[-1].hand == view_frame(y, session.m_hand)
        session.set_points([])
    assert view_frame(12.5, 100) == 13 and view_frame(-0.5, 100) == 0
