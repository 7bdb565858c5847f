"""Shared fixtures: paths to the real captures and to sample_data."""

from __future__ import annotations

import contextlib
import os
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


@contextlib.contextmanager
def served_chromium(tmp_path_factory, *serve_args: str):
    """``(browser, url)``: ``handsplice serve`` (its own upload folder, ``serve_args``) and a
    Chromium; on exit, the server's log must hold no traceback."""
    sync_api = pytest.importorskip("playwright.sync_api")
    from webapp.launch import launch_chromium, running_server

    uploads = tmp_path_factory.mktemp("uploads")
    log_path = tmp_path_factory.mktemp("log") / "serve.log"
    with (
        log_path.open("w+") as log,
        running_server("--upload-dir", str(uploads), *serve_args, log=log, timeout=400) as (
            url,
            _,
        ),
        sync_api.sync_playwright() as p,
    ):
        browser = launch_chromium(p)
        try:
            yield browser, url
        finally:
            browser.close()
    assert "Traceback" not in log_path.read_text()
