"""Shared fixtures: paths to the real captures and to sample_data."""

from __future__ import annotations

import contextlib
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_DATA = ROOT / "sample_data"
# ../shared/data/mocap beside the checkout; HANDSPLICE_MOCAP overrides
MOCAP = Path(os.environ.get("HANDSPLICE_MOCAP", ROOT.parent / "shared" / "data" / "mocap"))

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def mocap_files(pattern: str = "**/*.bvh") -> list[Path]:
    """Real capture files under ../shared/data/mocap matching ``pattern`` (sorted)."""
    return sorted(MOCAP.glob(pattern))


@pytest.fixture(scope="session")
def mocap_dir() -> Path:
    if not MOCAP.is_dir():
        pytest.fail(f"real capture folder {MOCAP} is missing (set HANDSPLICE_MOCAP)")
    return MOCAP


@pytest.fixture(scope="session")
def sample_dir() -> Path:
    return SAMPLE_DATA


@pytest.fixture(scope="module")
def bandai():
    """``bandai("2_wave-right-hand")`` -> the Bandai-Namco take ``dataset-2_wave-right-hand_
    normal_001.bvh`` from ../shared/data/mocap, read once per test module."""
    from engine.io.bvh import read_bvh

    cache = {}

    def load(name):
        if name not in cache:
            cache[name] = read_bvh(MOCAP / "bandai-namco" / f"dataset-{name}_normal_001.bvh")
        return cache[name]

    return load


#: the sample pair the app opens first
DEMO_SAMPLE = "wave-ok"


def open_demo_session(upload_dir: Path, sample: str = DEMO_SAMPLE):
    """A ``webapp.state.Session`` on ``sample`` from sample_data, opened and aligned (its
    uploads would go to ``upload_dir``)."""
    from webapp import config
    from webapp.state import Session

    cfg = config.AppConfig(
        sample_dir=SAMPLE_DATA.resolve(), upload_dir=upload_dir, default_sample=sample
    )
    session = Session(cfg)
    session.load_sample(sample)
    assert session.error == "", session.error
    return session


# --- browser tests (tests/test_browser*.py): one copy of each page helper -----------------

#: the demo-sized pair the browser tests upload through the page's file fields
BODY_BVH = MOCAP / "bandai-namco" / "dataset-1_bye_normal_001.bvh"
HAND_BVH = MOCAP / "gestification" / "hello-world.bvh"
#: sets a flag (``window.__hs_xss``) when a page turns it into an element
XSS_PAYLOAD = "<img src=x onerror=window.__hs_xss=1>"
#: a page condition: the matrix shows a path (the pair is open and aligned)
HAS_PATH = (
    "() => window.Bokeh && Bokeh.documents.length && "
    "Bokeh.documents[0].get_model_by_name('hs-path-source')?.data.x?.length > 0"
)


@contextlib.contextmanager
def served_app(tmp_path_factory, *serve_args: str, timeout: float = 120.0):
    """``(url, upload folder, log path)``: ``handsplice serve`` with its own upload folder
    and ``serve_args``, its output in a log file; stopped on exit."""
    from webapp.launch import running_server

    uploads = tmp_path_factory.mktemp("uploads")
    log_path = tmp_path_factory.mktemp("log") / "serve.log"
    with (
        log_path.open("w+") as log,
        running_server("--upload-dir", str(uploads), *serve_args, log=log, timeout=timeout) as (
            url,
            _,
        ),
    ):
        yield url, uploads, log_path


def assert_no_traceback(log_path: Path) -> None:
    """The server's log holds no traceback (the first one is shown when it does)."""
    text = log_path.read_text(errors="replace")
    assert "Traceback" not in text, text[text.find("Traceback") :][:3000]


@pytest.fixture(scope="module")
def browser():
    """A Chromium (Playwright) for the test module."""
    sync_api = pytest.importorskip("playwright.sync_api")
    from webapp.launch import launch_chromium

    with sync_api.sync_playwright() as p:
        b = launch_chromium(p)
        yield b
        b.close()


@contextlib.contextmanager
def served_chromium(tmp_path_factory, *serve_args: str, timeout: float = 400.0):
    """``(browser, url)``: ``handsplice serve`` (its own upload folder, ``serve_args``) and a
    Chromium; on exit, the server's log must hold no traceback."""
    sync_api = pytest.importorskip("playwright.sync_api")
    from webapp.launch import launch_chromium

    with (
        served_app(tmp_path_factory, *serve_args, timeout=timeout) as (url, _, log_path),
        sync_api.sync_playwright() as p,
    ):
        browser = launch_chromium(p)
        try:
            yield browser, url
        finally:
            browser.close()
    assert_no_traceback(log_path)


def open_tab(
    context,
    url: str,
    *,
    timeout_s: float = 60.0,
    ready: str = HAS_PATH,
    matrix_timeout_s: float | None = None,
    console: bool = False,
):
    """A new tab of the Playwright ``context`` at ``url``, once the page condition
    ``ready`` holds (default: the matrix shows a path), with the page's ``hs`` helpers.

    ``page.errors`` collects the tab's JavaScript errors (``console``: console errors
    too). ``timeout_s`` bounds the load and the wait for ``ready``; ``matrix_timeout_s``
    set: wait first for the cost matrix's element that long."""
    from webapp.launch import PAGE_HELPERS

    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(f"pageerror: {e}"))
    if console:
        page.on(
            "console", lambda m: errors.append(f"console: {m.text}") if m.type == "error" else None
        )
    page.goto(url, timeout=timeout_s * 1000)
    if matrix_timeout_s is not None:
        page.locator(".hs-cost-matrix").first.wait_for(timeout=matrix_timeout_s * 1000)
    page.wait_for_function(ready, timeout=timeout_s * 1000)
    page.evaluate(PAGE_HELPERS)
    page.errors = errors
    return page


def open_page(browser, url: str, *, width: int = 1300, height: int = 1000, **wait):
    """A tab in a fresh context (a ``width`` x ``height`` screen, downloads accepted) of
    ``browser`` at ``url``: :func:`open_tab` with ``wait``'s options. Close it with
    ``page.context.close()``."""
    context = browser.new_context(
        viewport={"width": width, "height": height}, accept_downloads=True
    )
    return open_tab(context, url, **wait)


def pane_text(locator) -> str:
    """Text of an element including its (open) shadow root, where Panel renders panes."""
    return locator.evaluate(
        "e => [...(e.shadowRoot ? e.shadowRoot.children : []), ...e.children]"
        ".filter(c => c.tagName !== 'STYLE' && c.tagName !== 'LINK')"
        ".map(c => c.innerText).join(' ')"
    )


def revision(page) -> int:
    """The session's revision the status line carries (it grows with every recompute)."""
    return int(page.locator(".hs-status span").get_attribute("data-revision"))


def status_line(page) -> str:
    """The status line's text ("pass 1 cost … · band N cells · …")."""
    return page.locator(".hs-status span").inner_text()


def band_cells(status: str) -> int:
    """The band's cell count a status line names."""
    match = re.search(r"band ([\d,]+) cells", status)
    assert match, status
    return int(match.group(1).replace(",", ""))


def busy_line(page) -> str:
    """The "aligning…"/"opening…" line's text ('' when nothing runs, or it went away meanwhile)."""
    line = page.locator(".hs-busy")
    try:
        return line.first.inner_text(timeout=1_000) if line.count() else ""
    except Exception:  # noqa: BLE001 - the line went away meanwhile
        return ""


#: texts of the hover tooltips shown now (Bokeh draws them in shadow roots)
_JS_TOOLTIPS = """() => {
  const out = [];
  const walk = (root) => {
    for (const el of root.querySelectorAll('*')) {
      if (el.classList && el.classList.contains('bk-tooltip-content') && el.offsetParent !== null)
        out.push(el.innerText);
      if (el.shadowRoot) walk(el.shadowRoot);
    }
  };
  walk(document);
  return out;
}"""


def visible_tooltips(page) -> list[str]:
    """Texts of the hover tooltips the page shows now."""
    return page.evaluate(_JS_TOOLTIPS)


def xss_ran(page) -> bool:
    """Whether :data:`XSS_PAYLOAD`'s script ran in ``page``."""
    page.wait_for_timeout(500)  # an <img onerror> fires within a few ms of insertion
    return bool(page.evaluate("window.__hs_xss === 1"))
