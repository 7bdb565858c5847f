"""``handsplice serve BODY HAND``'s console while it warms up: each stage (reading the
takes, features, pass 1 and 2, the matrix image, the preview) as it starts and ends, and
a stage that runs long says so again, so a user sees the server is alive before it
listens. Downloads of that pair are named ``<body>-spliced`` as an uploaded pair's."""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

from conftest import MOCAP

from webapp.launch import free_port, stop_process

ROOT = Path(__file__).resolve().parents[1]
BODY = MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh"
HAND = MOCAP / "gestification" / "fingers-ok.bvh"
#: a shared two-core machine can take minutes to compile and warm up
WARM_UP_S = 600.0


def _get(port: int) -> tuple[int, str, str]:
    """``(status, X-HandSplice header, text)`` of the server's page; status 0: no answer."""
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=60) as reply:
            return reply.status, reply.headers.get("X-HandSplice", ""), reply.read().decode()
    except urllib.error.HTTPError as err:
        return err.code, err.headers.get("X-HandSplice", ""), err.read().decode()
    except OSError:
        return 0, "", ""


def test_serve_body_hand_prints_its_warm_up_stages_on_stderr():
    """The stages on the console; and from the start a light page on the app's port that
    says them (stranger 11 F3: "This site can't be reached" for the whole warm-up), then
    the app on the same port."""
    exe = Path(sys.executable).with_name("handsplice")
    port = free_port()
    proc = subprocess.Popen(
        [str(exe), "serve", str(BODY), str(HAND), "--port", str(port)],
        cwd=ROOT,
        env=os.environ.copy(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: list[str] = []

    def read():  # stderr read aside: a silent server never blocks the test
        for line in proc.stderr:
            lines.append(line.rstrip("\n"))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    warming = app = (0, "", "")
    try:
        deadline = time.monotonic() + WARM_UP_S
        while not any("warm-up done in" in line for line in lines):
            if proc.poll() is not None or time.monotonic() > deadline:
                break
            if not warming[0] and any("reading the takes" in line for line in lines):
                warming = _get(port)
            time.sleep(0.2)
        while app[0] != 200 and proc.poll() is None and time.monotonic() < deadline:
            app = _get(port)
            time.sleep(0.2)
    finally:
        stop_process(proc, timeout=20)
        reader.join(timeout=10)
    text = "\n".join(lines)
    stages = [
        "reading the takes",
        "computing the takes' features",
        "aligning: pass 1 of 2",
        "aligning: pass 2 of 2",
        "the cost matrix image",
    ]
    at = []
    for stage in stages:  # each one starts, then ends with its time, in this order
        start = text.find(f"HandSplice: {stage}")
        assert start >= 0, f"no {stage!r} line in:\n{text}"
        assert re.search(rf"HandSplice: {re.escape(stage)}.* done \(\d+\.\d s\)", text), text
        at.append(start)
    assert at == sorted(at), text
    assert re.search(r"warm-up done in \d+\.\d s", text), text
    status, header, page = warming
    assert (status, header) == (503, "warming-up"), warming
    assert "HandSplice is warming up" in page and "reading the takes" in page, page
    assert app[0] == 200 and app[1] == "" and "warming up" not in app[2], app[:2]


def test_a_long_stage_says_again_that_it_is_running():
    from webapp.app import ConsoleStages

    out = io.StringIO()
    stages = ConsoleStages(out=out, heartbeat_s=0.3)
    stages("pass 1", 0.0)
    time.sleep(1.2)
    stages("pass 1", 0.5)
    stages("pass 1", 1.0)
    stages.close()
    text = out.getvalue()
    assert "HandSplice: aligning: pass 1 of 2 ..." in text
    assert re.search(r"\.\.\. still aligning: pass 1 of 2 \(\d+ s\)", text), text
    assert "aligning: pass 1 of 2 50%" in text
    assert re.search(r"aligning: pass 1 of 2 done \(1\.\d s\)", text), text


def test_downloads_of_a_pair_opened_from_disk_are_named_after_the_body(tmp_path):
    from webapp import config
    from webapp.state import Session

    pair = config.local_pair(BODY, HAND, "right")
    cfg = config.AppConfig(
        sample_dir=(ROOT / "sample_data").resolve(),
        upload_dir=tmp_path,
        default_sample=pair.name,
        local=pair,
    )
    s = Session(cfg)
    s.sample = pair.name  # no need to open the takes for the name
    assert s.output_stem() == f"{BODY.stem}-spliced"  # was "<body>.bvh_<hand>.bvh-spliced"
    s.sample = "wave-ok"
    assert s.output_stem() == "wave-ok-spliced"


def test_show_url_labels_the_users_own_pair_as_theirs():
    """``serve BODY HAND --show-url``: the link that opens the user's pair is labelled as
    theirs (it said "demo pair:", a stranger's R3-3); no demo pair is named."""
    from webapp.config import local_pair
    from webapp.serve_cli import sample_url

    exe = Path(sys.executable).with_name("handsplice")
    port = free_port()
    proc = subprocess.Popen(
        [str(exe), "serve", str(BODY), str(HAND), "--port", str(port), "--show-url", "--no-warm"],
        cwd=ROOT,
        env=os.environ.copy(),
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    lines: list[str] = []

    def read():
        for line in proc.stdout:
            lines.append(line.rstrip("\n"))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + WARM_UP_S
        while not any("press Ctrl+C" in line for line in lines):
            assert proc.poll() is None and time.monotonic() < deadline, lines
            time.sleep(0.2)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        reader.join(timeout=10)
    url = f"http://127.0.0.1:{port}/"
    link = sample_url(url, local_pair(BODY, HAND, "right").name)
    assert f"your pair's link: {link}" in lines, lines
    assert not any(line.startswith("demo pair") for line in lines), lines


def test_the_warm_up_page_shows_file_names_as_text():
    """A stage line names the user's files: the warm-up page escapes them."""
    from webapp.warm_page import WarmPage

    page = WarmPage("127.0.0.1", 0)
    try:
        page.note("reading <img src=x onerror=alert(1)>.bvh ...")
        port = page._server.server_address[1]
        status, header, text = _get(port)
    finally:
        page.close()
    assert (status, header) == (503, "warming-up")
    assert "reading &lt;img src=x onerror=alert(1)&gt;.bvh ..." in text
    assert "<img" not in text


def test_a_hand_served_from_disk_with_no_side_in_its_name_is_said(tmp_path, capsys, sample_dir):
    """``serve BODY HAND`` with a hand file whose name and joints carry no side (ManipNet's
    left mug hand copied as ``mug_take.bvh``): the console warns at once with the flag to
    pass, and the page's takes section says it beside the pair, until another Side is
    chosen (stranger 13: spliced on the right arm, unsaid; ``splice`` and uploads warned)."""
    import shutil

    from conftest import MOCAP

    from engine.io import load_take
    from webapp import config
    from webapp.serve_cli import unnamed_side
    from webapp.state import Session
    from webapp.views.inputs import InputsView

    hand = tmp_path / "mug_take.bvh"
    shutil.copyfile(MOCAP / "manipnet" / "mug1_leftHand.bvh", hand)
    body = config.load_samples(sample_dir)[0].body
    pair = unnamed_side(config.local_pair(body, hand, "right"), None, load_take(hand))
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "mug_take.bvh" in err and "--side left" in err, err
    assert "choose Side left" in pair.extra["unnamed_side"]
    # named, or --side given: nothing said
    left = MOCAP / "manipnet" / "mug1_leftHand.bvh"
    named = unnamed_side(config.local_pair(body, left), None, load_take(left))
    assert "unnamed_side" not in named.extra
    given = unnamed_side(config.local_pair(body, hand), "right", load_take(hand))
    assert "unnamed_side" not in given.extra
    assert capsys.readouterr().err == ""

    cfg = config.AppConfig(
        sample_dir=sample_dir.resolve(),
        upload_dir=tmp_path / "up",
        default_sample=pair.name,
        local=pair,
    )
    s = Session(cfg)
    s.sample = pair.name  # the section reads the pair's name and side, not the takes
    view = InputsView(s)
    assert view.local_side.visible and "choose Side left" in view.local_side.object
    s.side = "left"
    view._show_local_side()
    assert not view.local_side.visible
