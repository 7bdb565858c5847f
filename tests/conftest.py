"""Shared fixtures: paths to the real captures and to sample_data."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: where the browser tests put the README gallery's screenshots: ``benchmarks/figures``
#: under ``HANDSPLICE_GALLERY=1`` (``make gallery``), else a folder of their own for the
#: run, so running the tests leaves the checkout as it was
GALLERY_ENV = "HANDSPLICE_GALLERY"


def gallery_dir() -> Path:
    """The folder for gallery screenshots (see :data:`GALLERY_ENV`), made if missing."""
    if os.environ.get(GALLERY_ENV) == "1":
        folder = ROOT / "benchmarks" / "figures"
    else:
        import tempfile

        folder = Path(tempfile.gettempdir()) / f"handsplice-gallery-{os.getpid()}"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


SAMPLE_DATA = ROOT / "sample_data"
# ../shared/data/mocap beside the checkout; HANDSPLICE_MOCAP overrides
MOCAP = Path(os.environ.get("HANDSPLICE_MOCAP", ROOT.parent / "shared" / "data" / "mocap"))

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

# property tests (hypothesis) draw the same examples on every run unless
# HANDSPLICE_FUZZ_RANDOM=1 or HANDSPLICE_FUZZ_SCALE>1 ask for an exploratory run (see
# test_fuzz.py): the gate answers the same on every clone
if os.environ.get("HANDSPLICE_FUZZ_RANDOM") != "1" and os.environ.get(
    "HANDSPLICE_FUZZ_SCALE", "1"
) in ("", "1"):
    from hypothesis import settings as _hypothesis_settings

    _hypothesis_settings.register_profile("gate", derandomize=True)
    _hypothesis_settings.load_profile("gate")


def mocap_files(pattern: str = "**/*.bvh") -> list[Path]:
    """Real capture files under ../shared/data/mocap matching ``pattern`` (sorted)."""
    return sorted(MOCAP.glob(pattern))


def cropped_bvh(src: Path, dest: Path, frames: int) -> Path:
    """``src`` (a BVH) cut to its first ``frames`` frames, written to ``dest`` (a short real
    take under a name of the test's choosing: ``mug_leftHand.bvh``)."""
    head, _, motion = src.read_text().partition("MOTION\n")
    lines = motion.splitlines()
    dest.write_text(
        head + f"MOTION\nFrames: {frames}\n{lines[1]}\n" + "\n".join(lines[2 : 2 + frames]) + "\n"
    )
    return dest


LONG_BODY = MOCAP / "lafan1" / "multipleActions1_subject1.bvh"
MUG_HAND = MOCAP / "manipnet" / "mug1_rightHand.bvh"


@pytest.fixture(scope="session")
def long_pair(tmp_path_factory):
    """``long_pair(seconds, fps=120.0) -> (body, hand)``: a long real pair on disk, made once
    per session for each length: LAFAN1 ``multipleActions1`` resampled to ``fps`` and cut to
    its first ``seconds`` (``seconds * fps`` frames), with ManipNet's mug hand take (33 s at
    120 fps)."""
    made: dict[tuple[float, float], tuple[Path, Path]] = {}

    def make(seconds: float, fps: float = 120.0) -> tuple[Path, Path]:
        key = (float(seconds), float(fps))
        if key not in made:
            from engine.io import load_take
            from engine.io.bvh import write_bvh
            from engine.model.kinematics import resample

            body = resample(load_take(LONG_BODY), fps)
            folder = tmp_path_factory.mktemp(f"long{int(seconds)}s")
            path = folder / f"multipleActions1_{int(seconds)}s_{int(fps)}fps.bvh"
            write_bvh(body.frames(0, int(seconds * fps)), path)
            made[key] = (path, MUG_HAND)
        return made[key]

    return make


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


def demo_config(sample_dir: Path, tmp_path_factory, max_upload_bytes: int = 2 * 1024 * 1024):
    """The app's configuration for session tests: the bundled samples, the demo pair by
    default, a fresh upload folder (``max_upload_bytes`` per file)."""
    from webapp import config

    return config.AppConfig(
        sample_dir=sample_dir.resolve(),
        upload_dir=tmp_path_factory.mktemp("uploads"),
        default_sample=DEMO_SAMPLE,
        max_upload_bytes=max_upload_bytes,
    )


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


def demo_pair_uploaded(cfg, session=None):
    """``(session, body_hash, hand_hash)``: the demo pair's two takes stored as uploads in
    ``cfg``'s upload folder (as ``body.bvh`` and ``hand.bvh``) and opened in ``session`` (a
    new ``webapp.state.Session`` if None), aligned."""
    from webapp import uploads
    from webapp.state import Session

    pair = cfg.sample(DEMO_SAMPLE)
    body, _ = uploads.store(cfg, "body.bvh", pair.body.read_bytes())
    hand, _ = uploads.store(cfg, "hand.bvh", pair.hand.read_bytes())
    session = session if session is not None else Session(cfg)
    session.load_uploads(body, hand, "body.bvh", "hand.bvh")
    assert session.error == "" and session.solution is not None, session.error
    return session, body, hand


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


def assert_no_traceback(log_path: Path, since: int = 0) -> None:
    """The server's log holds no traceback (the first one is shown when it does); ``since``:
    in what it wrote after that byte offset."""
    with log_path.open("rb") as log:
        log.seek(since)
        text = log.read().decode(errors="replace")
    assert "Traceback" not in text, text[text.find("Traceback") :][:3000]


# One Playwright and one Chromium serve the browser tests of the run (each test opens its
# tabs in a context of its own). While Playwright's sync API runs, ``asyncio.run`` fails in
# this thread ("cannot be called from a running event loop"): a test that drives no browser
# stops it first (it starts again, in a second or two, for the next browser test).
_CHROMIUM: dict = {}


def shared_browser():
    """The run's Chromium (Playwright driving Debian's Chromium), started on first use (again
    if it was stopped or went away)."""
    browser = _CHROMIUM.get("browser")
    if browser is not None and browser.is_connected():
        return browser
    sync_api = pytest.importorskip("playwright.sync_api")
    from webapp.launch import launch_chromium

    if "playwright" not in _CHROMIUM:
        _CHROMIUM["playwright"] = sync_api.sync_playwright().start()
    _CHROMIUM["browser"] = launch_chromium(_CHROMIUM["playwright"])
    return _CHROMIUM["browser"]


def stop_shared_browser() -> None:
    """Close the run's Chromium and stop Playwright, if they run."""
    browser = _CHROMIUM.pop("browser", None)
    if browser is not None and browser.is_connected():
        browser.close()
    playwright = _CHROMIUM.pop("playwright", None)
    if playwright is not None:
        playwright.stop()


def pytest_sessionfinish(session, exitstatus):
    stop_shared_browser()


#: the lane of the browser modules (``make test`` runs two pytest-xdist workers)
BROWSER_LANE = "browser"


def test_lane(nodeid: str) -> str:
    """The lane a test runs in under ``make test``: every ``tests/test_browser*.py`` module
    in one (one after another on one worker: they share the run's Chromium and demo server,
    and each loads the machine as a user's page does), every other module whole in a lane
    of its own (its module fixtures computed once), on whichever worker is free."""
    module = nodeid.split("::", 1)[0]
    return BROWSER_LANE if Path(module).name.startswith("test_browser") else module


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadscope`` schedules by :func:`test_lane` (xdist's ``loadgroup`` cannot
    mark groups under pytest 9.2, whose node ids are read-only)."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class Lanes(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return test_lane(nodeid)

    return Lanes(config, log)


def pytest_collection_modifyitems(config, items):
    """The browser lane first (stable: the modules' order is kept otherwise), so that the
    longest lane starts at once (``--no-loadscope-reorder``)."""
    items.sort(key=lambda item: test_lane(item.nodeid) != BROWSER_LANE)


def _is_browser_test(item) -> bool:
    return item.get_closest_marker("browser") is not None or "browser" in getattr(
        item, "fixturenames", ()
    )


@pytest.fixture(autouse=True)
def _no_playwright_outside_browser_tests(request):
    """A test that drives no browser (no ``browser`` mark, no ``browser`` fixture) runs with
    Playwright stopped, so that its ``asyncio.run`` works."""
    if not _is_browser_test(request.node):
        stop_shared_browser()


@pytest.fixture(scope="module")
def browser():
    """The run's Chromium (Playwright), shared by every browser test: a test opens its tabs
    in a fresh context (:func:`open_page`) and closes it."""
    return shared_browser()


@contextlib.contextmanager
def served_chromium(tmp_path_factory, *serve_args: str, timeout: float = 400.0):
    """``(browser, url)``: ``handsplice serve`` of its own (its own upload folder,
    ``serve_args``) and the run's Chromium; on exit, the server's log must hold no
    traceback. Without ``serve_args`` a module needing no fresh server uses
    :func:`demo_url` instead."""
    with served_app(tmp_path_factory, *serve_args, timeout=timeout) as (url, _, log_path):
        yield shared_browser(), url
    assert_no_traceback(log_path)


#: a shared two-core machine can take minutes to warm the demo pair
DEMO_SERVER_START_S = 600.0


@pytest.fixture(scope="session")
def demo_server(tmp_path_factory):
    """``(url, log path)`` of the run's one ``handsplice serve`` with the default options
    (the demo pair, warmed up), shared by the browser modules that need no fresh server;
    HANDSPLICE_TEST_URL: that server instead (log path None). At the end of the run its
    whole log must hold no traceback."""
    if os.environ.get("HANDSPLICE_TEST_URL"):
        yield os.environ["HANDSPLICE_TEST_URL"].rstrip("/") + "/", None
        return
    with served_app(tmp_path_factory, timeout=DEMO_SERVER_START_S) as (url, _, log_path):
        yield url, log_path
    assert_no_traceback(log_path)


@dataclasses.dataclass(frozen=True)
class ServerLog:
    """What a server logged from byte ``since`` of its log ``path`` on (None: not ours)."""

    path: Path | None
    since: int = 0

    def assert_no_traceback(self) -> None:
        if self.path is not None:
            assert_no_traceback(self.path, self.since)


@pytest.fixture(scope="module")
def demo_log(demo_server) -> ServerLog:
    """The shared demo server's log from the module's start on; at the end of the module it
    must hold no traceback."""
    path = demo_server[1]
    log = ServerLog(path, path.stat().st_size if path is not None else 0)
    yield log
    log.assert_no_traceback()


@pytest.fixture(scope="module")
def demo_url(demo_server, demo_log) -> str:
    """URL of the run's shared demo server (:func:`demo_server`). Each tab is a session of
    its own; what a server keeps across sessions (uploads, the opened pairs it caches, the
    warm-up's spare solution, taken by the first tab) is shared with the modules before."""
    return demo_server[0]


@pytest.fixture()
def demo_page(browser, demo_url):
    """A fresh tab (1300 x 1000) on the shared demo server once its matrix shows a path; at
    the end, the tab must have had no JavaScript error."""
    page = open_page(browser, demo_url, timeout_s=DEMO_SERVER_START_S)
    yield page
    page.context.close()
    assert not page.errors, page.errors


@pytest.fixture()
def stranger_page(browser, demo_url):
    """:func:`demo_page` at the strangers' screen size, 1440 x 900."""
    page = open_page(browser, demo_url, width=1440, height=900, timeout_s=DEMO_SERVER_START_S)
    page.wait_for_timeout(500)  # as the strangers did: a look at the page before acting
    yield page
    page.context.close()
    assert not page.errors, page.errors


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
    ``ready`` holds (default: the matrix shows a path, and the page's later sections,
    built after it, are in the page), with the page's ``hs`` helpers.

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
    if ready is HAS_PATH:  # the page's later sections (share, lesson) follow the first path
        page.locator(".hs-share-url").first.wait_for(state="attached", timeout=timeout_s * 1000)
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


def wait_pane_text(locator, *words: str, timeout_s: float = 30.0) -> str:
    """:func:`pane_text` of ``locator`` once it holds every one of ``words`` (polled)."""
    deadline = time.monotonic() + timeout_s
    while not all(w in (text := pane_text(locator)) for w in words):
        assert time.monotonic() < deadline, f"{words} not all in {text!r}"
        locator.page.wait_for_timeout(50)
    return text


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


def click_path_mid_take(page, timeout_s: float = 60.0) -> int:
    """Click the path's cell at the middle body frame and wait for the point it places (the
    page had none); the open pair's body frame count."""
    n = page.evaluate("hs.frames()")
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    k = path["x"].index(n // 2)
    page.mouse.click(*page.evaluate(f"hs.xy({path['x'][k]}, {path['y'][k]})"))
    page.wait_for_function(
        "() => hs.cols('hs-points-source', ['x']).x.length === 1", timeout=timeout_s * 1000
    )
    return n


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
