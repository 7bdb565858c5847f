"""Lines thinned to screen resolution (``webapp.views.decimate``) draw the same pixels.

The demo pair's real path, band edges and wrist speed (a noisy line), drawn on a plot
only 12 pixels wide, so that each screen column holds several frames (as a long take's
does on the page's 560 pixels), rasterised whole and thinned: the same pixels within
one, with a handful of vertices a column.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import open_demo_session
from PIL import Image, ImageDraw

from webapp.state import Session
from webapp.views import decimate

#: a plot this many pixels wide gives the demo take (187 frames) about 8 frames a screen
#: column (with OVERSAMPLE 2), as 560 pixels give a 2-minute 120 fps take 13
WIDTH = 12


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> Session:
    s = open_demo_session(tmp_path_factory.mktemp("uploads"))
    assert s.n > 3 * WIDTH
    return s


def _lines(session) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Real polylines of the page: (x, y) each."""
    sol = session.solution
    band = sol.pass1.band
    body_speed = session.axis_signals()[0]
    return {
        "path": (sol.pass1.path[:, 0], sol.pass1.path[:, 1].astype(float)),
        "band lo": (np.arange(band.n), band.lo - 0.5),
        "band hi": (np.arange(band.n), band.hi + 0.5),
        "wrist speed": (np.arange(len(body_speed)), np.asarray(body_speed, dtype=float)),
    }


def _raster(x, y, xr, yr, size=(WIDTH, 60)) -> np.ndarray:
    """Pixels a 1-pixel line through ``(x, y)`` covers on a ``size`` plot of ranges xr, yr."""
    w, h = size
    img = Image.new("1", size, 0)
    sx = (np.asarray(x, float) - xr[0]) / (xr[1] - xr[0]) * w
    sy = h - (np.asarray(y, float) - yr[0]) / (yr[1] - yr[0]) * h
    ImageDraw.Draw(img).line(list(zip(sx.tolist(), sy.tolist())), fill=1, width=1)
    return np.asarray(img, dtype=bool)


def _near(a: np.ndarray, b: np.ndarray) -> bool:
    """Every pixel of ``a`` is within one pixel of one of ``b``."""
    grown = b.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            grown |= np.roll(np.roll(b, dy, 0), dx, 1)
    return bool(np.all(grown[a]))


@pytest.mark.parametrize("name", ["path", "band lo", "band hi", "wrist speed"])
def test_thinned_lines_cover_the_same_pixels(session, name):
    x, y = _lines(session)[name]
    n = session.n
    xr = (-0.5, n - 0.5)
    yr = (float(np.nanmin(y)) - 1, float(np.nanmax(y)) + 1)
    thin = decimate.thin(x, {"y": y}, xr, n, WIDTH)
    assert len(thin["x"]) < len(x) / 2, (len(thin["x"]), len(x))  # it thins
    assert len(thin["x"]) <= 4 * decimate.OVERSAMPLE * WIDTH + 4  # a few vertices a column
    # ends kept exactly: the path's first and last cells are where its open ends lie
    assert (thin["x"][0], thin["y"][0]) == (x[0], y[0])
    assert (thin["x"][-1], thin["y"][-1]) == (x[-1], y[-1])
    full, few = _raster(x, y, xr, yr), _raster(thin["x"], thin["y"], xr, yr)
    assert _near(full, few) and _near(few, full)
    assert (full != few).mean() < 0.01, (full != few).sum()
    if name == "path":  # monotone: two vertices a column at most
        assert len(thin["x"]) <= 2 * decimate.OVERSAMPLE * WIDTH + 2


def test_a_zoomed_view_gets_every_frame_and_the_rest_stays_coarse(session):
    x, y = _lines(session)["band lo"]
    n = session.n
    view = (60.0, 60.0 + WIDTH)  # one frame a pixel: every frame of the view is a vertex
    thin = decimate.thin(x, {"y": y}, view, n, WIDTH)
    kept = set(thin["x"].tolist())
    assert set(range(60, 60 + WIDTH)) <= kept
    outside = [k for k in kept if k < 60 or k > 60 + WIDTH]
    assert len(outside) < (n - WIDTH) / 3  # off screen: the whole take's resolution


def test_the_matrix_view_sends_thinned_lines_and_zoom_refines_them(sample_dir, session):
    from webapp.views.cost_matrix import CostMatrixView

    view = CostMatrixView(session, size=WIDTH)
    band = view.band_source.data
    full = session.solution.pass1.band
    assert len(band["x"]) < full.n / 2 and band["x"][0] == 0 and band["x"][-1] == full.n - 1
    path = view.path_source.data
    # the red line is the alignment used (pipeline.alignment_pass)
    used = session.solution.pass1 if view._used_pass() == 1 else session.solution.pass2
    assert len(path["x"]) < len(used.path) / 2
    assert list(path["x"][[0, -1]]) == list(used.path[[0, -1], 0])
    # the hand take's wrist-speed strip runs up the y axis: thinned along it
    hand = view.hand_signal_source.data
    assert len(hand["y"]) < len(session.axis_signals()[1]) / 2 and hand["y"][0] == 0
    y0, y1 = view.y_range.start, view.y_range.end
    view._rethin((60.0, 60.0 + WIDTH, y0, y1))  # what a zoom sends (after RangesUpdate)
    xs = set(view.band_source.data["x"].tolist())
    assert set(range(60, 60 + WIDTH)) <= xs
    k = int(np.searchsorted(view.band_source.data["x"], 66))  # a frame in view: its own values
    assert view.band_source.data["x"][k] == 66
    assert view.band_source.data["lo"][k] == np.float32((full.lo[66] - 0.5) * session.hand_scale)
