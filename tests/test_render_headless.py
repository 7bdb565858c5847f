"""Rendering never depends on X: pyglet is put in headless mode before pyrender is imported.

pyrender imports pyglet's window module (its interactive viewer); without pyglet's
headless mode that loads X11 libraries, which a minimal Debian or the Docker image
does not have (issue 19). The render runs in a fresh interpreter with DISPLAY unset,
and an import hook records pyglet's state at the moment pyrender and pyglet.window
are imported.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from conftest import ROOT

BVH = ROOT / "sample_data" / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh"

SPY = r"""
import importlib.abc, json, os, sys
seen = {}

class Spy(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name in ("pyrender", "pyglet.window") and name not in seen:
            pyglet = sys.modules.get("pyglet")
            seen[name] = {"env": os.environ.get("PYGLET_HEADLESS"),
                          "option": None if pyglet is None else pyglet.options["headless"]}
        return None

sys.meta_path.insert(0, Spy())
from engine.cli import main
rc = main(["render", sys.argv[1], "-o", sys.argv[2], "--frame", "10", "--size", "160x120"])
x11 = sorted(m for m in sys.modules if m.startswith("pyglet") and ("xlib" in m or "x11" in m))
print("SPY" + json.dumps({"rc": rc, "seen": seen, "x11": x11}))
"""


def test_render_without_display_uses_headless_pyglet(tmp_path):
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("DISPLAY", "WAYLAND_DISPLAY", "PYGLET_HEADLESS")
    }
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    out = tmp_path / "frame.png"
    proc = subprocess.run(
        [sys.executable, "-c", SPY, str(BVH), str(out)],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("SPY")]
    assert proc.returncode == 0 and lines, proc.stdout + proc.stderr
    report = json.loads(lines[-1][3:])
    assert report["rc"] == 0, proc.stderr
    # pyrender imported after the backend asked for headless pyglet ...
    assert report["seen"]["pyrender"]["env"] == "true"
    # ... and pyglet's window module (X11 or EGL) loaded in headless mode, no X11 module
    assert report["seen"]["pyglet.window"]["option"] is True
    assert report["x11"] == []
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000
