"""The app in a real browser: Debian's Chromium driven by Playwright.

A server (``handsplice serve``) is started on a free port for the module and
killed at the end. Waits poll the page (Bokeh's document model or the DOM), no
fixed sleeps. Playwright's CSS selectors pierce the open shadow roots Panel and
Bokeh render into, so the stable hooks ``.hs-cost-matrix``, ``.hs-status`` and
``.hs-points`` are found wherever they sit.
"""

from __future__ import annotations

import json
import os
import re
import time

import pytest

from webapp.launch import PAGE_HELPERS, launch_chromium, running_server

pytestmark = pytest.mark.browser

SERVER_LOG: dict = {}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """URL of a running ``handsplice serve`` (or HANDSPLICE_TEST_URL when set)."""
    if os.environ.get("HANDSPLICE_TEST_URL"):
        yield os.environ["HANDSPLICE_TEST_URL"].rstrip("/") + "/"
        return
    uploads = tmp_path_factory.mktemp("uploads")
    log_path = tmp_path_factory.mktemp("log") / "serve.log"
    with log_path.open("w+") as log, running_server("--upload-dir", str(uploads),
                                                    log=log) as (url, _):
        SERVER_LOG["path"] = log_path
        yield url


@pytest.fixture(scope="module")
def browser():
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as p:
        b = launch_chromium(p)
        yield b
        b.close()


def _open(browser, url: str):
    context = browser.new_context(viewport={"width": 1300, "height": 1000}, accept_downloads=True)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(f"pageerror: {e}"))
    page.on("console", lambda m: errors.append(f"console: {m.text}") if m.type == "error" else None)
    page.goto(url)
    page.locator(".hs-cost-matrix").first.wait_for(timeout=60_000)
    page.wait_for_function(
        "() => window.Bokeh && Bokeh.documents.length && "
        "Bokeh.documents[0].get_model_by_name('hs-path-source')?.data.x?.length > 0",
        timeout=60_000)
    page.evaluate(PAGE_HELPERS)
    page.errors = errors
    return page


def _text(locator) -> str:
    """Text of an element including its (open) shadow root, where Panel renders panes."""
    return locator.evaluate(
        "e => [...(e.shadowRoot ? e.shadowRoot.children : []), ...e.children]"
        ".filter(c => c.tagName !== 'STYLE' && c.tagName !== 'LINK')"
        ".map(c => c.innerText).join(' ')")


def _status(page) -> str:
    return page.locator(".hs-status span").inner_text()


def _revision(page) -> int:
    return int(page.locator(".hs-status span").get_attribute("data-revision"))


def _wait_revision(page, after: int, timeout: float = 30.0) -> int:
    """Poll the status line until the session has recomputed (revision > ``after``)."""
    deadline = time.monotonic() + timeout
    while True:
        rev = _revision(page)
        if rev > after:
            return rev
        if time.monotonic() > deadline:
            raise AssertionError(f"no recompute within {timeout} s (revision {rev})")
        page.wait_for_timeout(40)


def _wait_tolerances(page, expected: list) -> None:
    """Poll the matching points' tolerance column in the page until it equals ``expected``."""
    page.wait_for_function(
        "(want) => JSON.stringify(hs.cols('hs-points-source', ['tol']).tol) === want",
        arg=json.dumps(expected), timeout=30_000)


def _wait_changed(page, source: str, keys: list[str], old: dict) -> None:
    """Poll a Bokeh data source in the page until its columns differ from ``old``."""
    page.wait_for_function(
        "([name, keys, old]) => JSON.stringify(hs.cols(name, keys)) !== old",
        arg=[source, keys, json.dumps(old, separators=(",", ":"))], timeout=30_000)


def _edit_cell(page, field: str, row: int = 0):
    """Open the editor of a points-table cell; returns the editor's input."""
    cell = page.locator(".hs-points .tabulator-row").nth(row).locator(f"[tabulator-field='{field}']")
    editors = page.locator(".hs-points .tabulator-row input")
    for _ in range(5):  # the table may be re-rendered by a recompute: retry on a fresh cell
        try:
            cell.scroll_into_view_if_needed(timeout=5_000)
            page.wait_for_timeout(300)  # the layout settles after scrolling, else the editor blurs
            cell.click(timeout=5_000)
            editors.first.wait_for(timeout=3_000)
            if editors.count() == 1:
                return editors.first
        except Exception:  # noqa: BLE001 - Playwright errors: detached element, timeout
            pass
        if editors.count():
            editors.first.press("Escape")  # never leave an editor open: it commits on blur
    raise AssertionError(f"could not edit the {field} cell")


def _close_editors(page) -> None:
    """Wait until no table editor is open (an open one would commit when focus moves)."""
    page.locator(".hs-points .tabulator-row input").first.wait_for(state="detached",
                                                                   timeout=10_000)


def _drag(page, x0, y0, x1, y1) -> None:
    a = page.evaluate(f"hs.xy({x0}, {y0})")
    b = page.evaluate(f"hs.xy({x1}, {y1})")
    page.mouse.move(*a)
    page.mouse.down()
    page.mouse.move(*b, steps=6)
    page.mouse.up()


@pytest.fixture(scope="module")
def page(browser, server):
    p = _open(browser, server)
    yield p
    p.context.close()


@pytest.fixture(autouse=True)
def no_page_errors(request):
    """Every test leaves the shared page without JavaScript errors."""
    yield
    if "page" in request.fixturenames:
        page = request.getfixturevalue("page")
        errors, page.errors[:] = list(page.errors), []
        assert not errors, errors


def test_app_loads_with_matrix_path_band_status(page):
    status = _status(page)
    assert "pass 1 cost" in status and "ms" in status
    band = page.evaluate("hs.cols('hs-band-source', ['lo', 'hi'])")
    assert len(band["lo"]) > 10 and all(lo <= hi for lo, hi in zip(band["lo"], band["hi"]))
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    assert path["x"][0] == 0 and path["y"][0] == 0
    assert all(b >= a for a, b in zip(path["x"], path["x"][1:]))
    assert page.locator(".hs-points").count() >= 1
    assert not page.errors


def test_add_and_drag_matching_point_changes_band_path_status(page):
    n = len(page.evaluate("hs.cols('hs-band-source', ['x'])")["x"])
    path0 = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    # a point off the current path: the path must move to pass through it
    x = n // 2
    k = path0["x"].index(x)
    y_on_path = path0["y"][k]
    rev = _revision(page)
    xy = page.evaluate(f"hs.xy({x}, {y_on_path})")
    page.mouse.click(*xy)
    _wait_revision(page, rev)
    _wait_tolerances(page, [None])  # one point, using the global tolerance
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    assert len(pts["x"]) == 1 and abs(pts["x"][0] - x) <= 1
    assert "1 matching point" in _status(page)

    band0 = page.evaluate("hs.cols('hs-band-source', ['lo', 'hi'])")
    status0 = _status(page)
    path1 = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    target = y_on_path + max(8, n // 12)
    rev = _revision(page)
    _drag(page, pts["x"][0], pts["y"][0], pts["x"][0], target)
    _wait_revision(page, rev)
    _wait_changed(page, "hs-path-source", ["x", "y"], path1)
    _wait_changed(page, "hs-band-source", ["lo", "hi"], band0)
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    assert abs(pts["y"][0] - target) <= 2, pts
    band1 = page.evaluate("hs.cols('hs-band-source', ['lo', 'hi'])")
    path2 = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    assert band1 != band0
    assert path2 != path1
    # tolerance 0: the path passes exactly through the dragged point
    cells = set(zip(path2["x"], path2["y"]))
    assert (round(pts["x"][0]), round(pts["y"][0])) in cells
    assert _status(page) != status0


def test_tolerance_edit_in_table_widens_the_band_at_the_point(page):
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    assert len(pts["x"]) == 1
    x = round(pts["x"][0])
    band0 = page.evaluate("hs.cols('hs-band-source', ['lo', 'hi'])")
    rev = _revision(page)
    editor = _edit_cell(page, "tolerance")
    editor.fill("6")
    editor.press("Enter")
    _close_editors(page)
    _wait_tolerances(page, [6])
    _wait_revision(page, rev)
    _wait_changed(page, "hs-band-source", ["lo", "hi"], band0)
    band1 = page.evaluate("hs.cols('hs-band-source', ['lo', 'hi'])")
    width0 = band0["hi"][x] - band0["lo"][x]
    width1 = band1["hi"][x] - band1["lo"][x]
    assert width1 > width0
    tol = page.evaluate("hs.cols('hs-points-source', ['tol'])")["tol"]
    assert tol == [6]


def test_undo_and_redo_the_tolerance_edit(page):
    page.locator(".hs-undo button").click()
    _wait_tolerances(page, [None])
    page.locator(".hs-redo button:enabled").click()
    _wait_tolerances(page, [6])


def test_render_preview(page):
    page.locator(".hs-render button").click()
    img = page.locator(".hs-preview-image img")
    img.wait_for(timeout=60_000)
    src = img.get_attribute("src")
    assert src and src.startswith("data:image/png")
    assert len(src) > 5000
    assert "hand frame" in page.locator(".hs-preview-info span").inner_text()


def test_click_on_the_path_in_pick_mode_shows_that_frame_pair(page):
    page.locator(".hs-click-mode button", has_text="Pick frames").click()
    page.wait_for_function("() => hs.model('hs-point-tool').add === false")
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    k = len(path["x"]) * 2 // 3
    x, y = path["x"][k], path["y"][k]
    npts = len(page.evaluate("hs.cols('hs-points-source', ['x'])")["x"])
    page.mouse.click(*page.evaluate(f"hs.xy({x}, {y})"))
    page.locator(f".hs-preview-info span[data-frame='{x}']").wait_for(timeout=60_000)
    assert f"body frame {x}" in page.locator(".hs-preview-info span").inner_text()
    frame = page.evaluate("hs.cols('hs-frame-source', ['x', 'y'])")
    # the marker sits on the merged pass-2 path, which stays within W2 (0.1 n) of pass 1's
    n = len(page.evaluate("hs.cols('hs-band-source', ['x'])")["x"])
    assert frame["x"] == [x] and abs(frame["y"][0] - y) <= max(3, round(0.1 * n))
    assert len(page.evaluate("hs.cols('hs-points-source', ['x'])")["x"]) == npts  # no new point
    page.locator(".hs-click-mode button", has_text="Edit points").click()
    page.wait_for_function("() => hs.model('hs-point-tool').add === true")


def test_download_bvh_and_session(page, tmp_path):
    with page.expect_download(timeout=60_000) as info:
        page.locator(".hs-download-bvh button").click()
    path = tmp_path / "out.bvh"
    info.value.save_as(path)
    text = path.read_text()
    assert text.startswith("HIERARCHY") and "MOTION" in text
    from engine.io.bvh import read_bvh

    assert read_bvh(path).rotations.shape[0] > 10

    with page.expect_download(timeout=30_000) as info:
        page.locator(".hs-download-session button").click()
    spath = tmp_path / "s.json"
    info.value.save_as(spath)
    data = json.loads(spath.read_text())
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    assert [(p["body"], p["hand"]) for p in data["points"]] == \
        [(round(x), round(y)) for x, y in zip(pts["x"], pts["y"])]
    from engine.io.session import read_session

    assert read_session(spath).sample == data["inputs"]["sample"]


def test_download_glb_is_the_spliced_take_in_3d(page, tmp_path):
    """The GLB button downloads the spliced take: its joints move as the BVH download's."""
    import numpy as np
    import pygltflib
    from test_glb import accessor, animated_world

    from engine.io.bvh import read_bvh
    from engine.kinematics import forward_kinematics

    saved = {}
    for name in ("glb", "bvh"):
        with page.expect_download(timeout=60_000) as info:
            page.locator(f".hs-download-{name} button").click()
        saved[name] = tmp_path / f"spliced.{name}"
        info.value.save_as(saved[name])
    assert info.value.suggested_filename.endswith(".bvh")
    motion = read_bvh(saved["bvh"])
    doc = pygltflib.GLTF2().load_binary(str(saved["glb"]))
    blob = doc.binary_blob()
    world, names = animated_world(doc, blob, motion.n_frames)
    by_name = {names[j]: j for j in doc.skins[0].joints}  # the BVH file lists joints depth-first
    assert sorted(by_name) == sorted(motion.skeleton.names)
    joints = [by_name[n] for n in motion.skeleton.names]
    scale = motion.meters_per_unit  # the demo body is in centimetres, Y up
    assert motion.meta.units == "cm" and motion.meta.up_axis == "y"
    want = forward_kinematics(motion)[0] * scale
    assert np.abs(world[:, joints][..., :3, 3] - want).max() < 1e-4
    assert accessor(doc, blob, doc.meshes[0].primitives[0].attributes.POSITION).shape[0] > 1000


def test_download_preview_gif(page, browser, server, tmp_path):
    """The export shows its progress, and another session stays responsive meanwhile."""
    other = _open(browser, server)
    try:
        with page.expect_download(timeout=120_000) as info:
            page.locator(".hs-download-gif button").click()
            page.locator("progress.hs-export-progress").wait_for(state="visible", timeout=30_000)
            rev = _revision(other)
            t0 = time.monotonic()
            other.mouse.click(*other.evaluate("hs.xy(40, 30)"))  # an edit in the other tab
            _wait_revision(other, rev)
            elapsed = time.monotonic() - t0
            busy = "rendering" in _text(page.locator(".hs-export-status"))
        assert busy, "the export ended before the other session's edit: nothing was measured"
        assert elapsed < 2.0, f"another session waited {elapsed:.1f} s during the export"
        assert not other.errors, other.errors
    finally:
        other.context.close()
    path = tmp_path / "preview.gif"
    info.value.save_as(path)
    import imageio.v3 as iio

    frames = iio.imread(path, index=None)
    assert frames.ndim == 4 and frames.shape[0] > 10 and frames.shape[3] in (3, 4)


def test_shared_url_restores_the_session(page, browser):
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y', 'tol'])")
    want = "pts=" + ",".join(f"{x:g}:{y:g}" + ("" if t is None else f":{t:g}")
                             for x, y, t in zip(pts["x"], pts["y"], pts["tol"]))
    link = page.locator(".hs-share-url input")
    deadline = time.monotonic() + 30
    while want not in (url := link.input_value()):  # the link follows every edit
        assert time.monotonic() < deadline, f"{want} not in {url}"
        page.wait_for_timeout(50)
    status = _status(page)
    other = _open(browser, url)
    try:
        assert other.evaluate("hs.cols('hs-points-source', ['x', 'y', 'tol'])") == pts
        cost = status.split("·")[0].strip()
        assert _status(other).split("·")[0].strip() == cost
    finally:
        other.context.close()


def test_a_bad_link_opens_the_demo_and_says_why(browser, server):
    other = _open(browser, server + "?sample=nope&band=0.5&pts=3:4")
    try:
        alert = other.locator(".hs-error")
        alert.wait_for(state="visible", timeout=30_000)
        text = _text(alert)
        assert "shared link" in text and "nope" in text
        assert "pass 1 cost" in _status(other)  # the demo pair is open and solved
        other.wait_for_function("() => !location.search.includes('nope')", timeout=30_000)
        assert "sample=nope" not in other.url and "band=0.5" not in other.url
        assert other.locator(".hs-share-url input").input_value().find("nope") < 0
        assert not other.errors, other.errors
    finally:
        other.context.close()


def _band_cells(status: str) -> int:
    match = re.search(r"band ([\d,]+) cells", status)
    assert match, status
    return int(match.group(1).replace(",", ""))


def _nudge_slider(page, index: int, key: str, times: int) -> None:
    """Move the ``index``-th parameter slider (0 band W1, 1 band W2, 2 global tolerance)
    by ``times`` steps with the keyboard, as a user can (each step is one release)."""
    handle = page.locator(".hs-params .noUi-handle").nth(index)
    handle.scroll_into_view_if_needed()
    handle.focus()
    for _ in range(times):
        handle.press(key)


def _settle(page, quiet: float = 1.0, timeout: float = 30.0) -> str:
    """Poll until the session's revision has not moved for ``quiet`` seconds (every step of a
    keyboard-driven slider recomputed), then return the status line."""
    deadline = time.monotonic() + timeout
    rev, since = _revision(page), time.monotonic()
    while time.monotonic() - since < quiet:
        assert time.monotonic() < deadline, f"no quiet {quiet} s within {timeout} s"
        page.wait_for_timeout(100)
        now = _revision(page)
        if now != rev:
            rev, since = now, time.monotonic()
    return _status(page)


def test_band_and_global_tolerance_sliders_change_the_band(browser, server):
    other = _open(browser, server)
    try:
        cells0 = _band_cells(_settle(other))
        rev = _revision(other)
        _nudge_slider(other, 0, "ArrowLeft", 5)  # W1 0.30 -> 0.25
        _wait_revision(other, rev)
        cells1 = _band_cells(_settle(other))
        assert cells1 < cells0
        # a matching point without its own tolerance follows the global one
        path = other.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
        k = len(path["x"]) // 2
        rev = _revision(other)
        other.mouse.click(*other.evaluate(f"hs.xy({path['x'][k]}, {path['y'][k]})"))
        _wait_revision(other, rev)
        _wait_tolerances(other, [None])
        cells2 = _band_cells(_settle(other))
        assert cells2 < cells1  # a point with T = 0 pins the band
        rev = _revision(other)
        _nudge_slider(other, 2, "ArrowRight", 6)  # T 0 -> 6 frames
        _wait_revision(other, rev)
        status = _settle(other)
        assert _band_cells(status) > cells2, (
            status, other.evaluate("hs.cols('hs-tol-source', ['x', 'y0', 'y1'])"))
        assert not other.errors, other.errors
    finally:
        other.context.close()


def test_sessions_are_independent(page, browser):
    other = _open(browser, page.url.split("?")[0])
    try:
        # a fresh session on the bare URL has no points, whatever this one has
        assert other.evaluate("hs.cols('hs-points-source', ['x'])")["x"] == []
        assert page.evaluate("hs.cols('hs-points-source', ['x'])")["x"] != []
    finally:
        other.context.close()


def test_malformed_upload_is_rejected_with_a_message(page, tmp_path):
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0\n")
    page.locator(".hs-upload-body input[type=file]").set_input_files(str(bad))
    alert = page.locator(".hs-upload-error")
    alert.wait_for(state="visible", timeout=30_000)
    text = _text(alert)
    assert "broken.bvh" in text and "line" in text
    assert "Traceback" not in page.content()


def test_server_log_has_no_tracebacks(page):
    """Whatever the page did, the server raised nothing (run last: it reads the whole log)."""
    path = SERVER_LOG.get("path")
    if path is None:
        pytest.skip("server not started by this test module")
    text = path.read_text(errors="replace")
    assert "Traceback" not in text, text[text.find("Traceback"):][:3000]
