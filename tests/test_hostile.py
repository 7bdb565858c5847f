"""Issue 15 items 1, 3, 4, 7, 8, 9: hostile but fair input, case by case.

1. small files that would exhaust memory are refused before anything is allocated
   (``engine.base.limits``), and the issue's files stay under 1 GB at the command line;
3. bad input exits with status 2 and one line, never "internal error";
4. outputs that belong together are replaced together; temporary files are removed on
   failure, SIGTERM and SIGINT, and stale ones of a killed run by the next; no ``.bak``;
7. malformed numbers, rates, rows and names are refused by the readers;
8. damaged ELAN files give one error type;
9. batch pairs run under time and memory limits; ``summary.csv`` grows as pairs finish.
"""

from __future__ import annotations

import csv
import json
import os
import re
import resource
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import MOCAP, ROOT

from engine.base import atomic, limits
from engine.base.errors import HandSpliceError, MotionFormatError
from engine.cli import main
from engine.io.bvh import parse_bvh, read_bvh
from engine.io.trc import parse_trc

BODY = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"
HAND = MOCAP / "gestification/gesture-pointing.bvh"
TRC = MOCAP / "pyomeca/markers.trc"
PY = sys.executable


def with_frame_time(src: Path, value: str) -> str:
    return re.sub(r"(?m)^Frame Time:.*$", f"Frame Time: {value}", src.read_text())


def zero_channel(src: Path, frames: int, rows: str = "") -> str:
    """``src``'s skeleton with ``CHANNELS 0`` on every joint and ``Frames: frames``."""
    head = src.read_text().split("MOTION")[0]
    head = re.sub(r"CHANNELS \d[^\n]*", "CHANNELS 0", head)
    return head + f"MOTION\nFrames: {frames}\nFrame Time: 0.0333333\n" + rows


def fan(joints: int, frames: int, channels: str = "CHANNELS 0") -> str:
    lines = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 1 Xrotation"]
    for j in range(joints - 1):
        lines += [f"JOINT j{j}", "{", "OFFSET 0 1 0", channels, "}"]
    lines += ["}", "MOTION", f"Frames: {frames}", "Frame Time: 0.0333333"]
    return "\n".join(lines) + "\n" + "0\n" * frames


def refused(call, *words: str) -> str:
    with pytest.raises(HandSpliceError) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg.strip(), msg
    for w in words:
        assert w in msg, msg
    return msg


def cli(argv: list[str], capsys) -> tuple[int, str]:
    status = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip()
    return status, err


def one_line_exit_2(status: int, err: str, *words: str) -> None:
    assert status == 2, err
    lines = [ln for ln in err.splitlines() if ln.startswith("handsplice")]
    assert len(lines) == 1 and lines[0].startswith("handsplice: error: "), err
    assert "internal error" not in err and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], err


# ------------------------------------------------------------------ 1. limits before allocating


@pytest.mark.parametrize(
    "value, words",
    [
        ("300", ["0.00333333 frames per second", "expected 1 to 10000"]),
        ("100", ["0.01 frames per second"]),
        ("1e300", ["1e-300 frames per second"]),
        ("1e-300", ["1e+300 frames per second"]),
        ("0.00001", ["100000 frames per second"]),
    ],
)
def test_frame_rate_range(value, words):
    refused(
        lambda: parse_bvh(with_frame_time(HAND, value), "hand.bvh"),
        "hand.bvh line",
        f"Frame Time: {value}",
        *words,
    )


def test_frame_rate_range_edges_are_read():
    assert parse_bvh(with_frame_time(HAND, "1"), "slow.bvh").fps == 1.0
    assert parse_bvh(with_frame_time(HAND, "0.0001"), "fast.bvh").fps == 10_000.0


def test_zero_channel_skeleton_with_two_million_frames_is_refused():
    text = zero_channel(BODY, 2_000_000)
    assert len(text) < 5_000
    refused(
        lambda: parse_bvh(text, "empty.bvh"), "empty.bvh line", "hours", "refusing an absurd take"
    )


def test_poses_are_bounded_by_frames_times_joints():
    # 1,000 joints, 1 channel in all: 5,000 frames fit in 10 kB of rows but are 5 M poses
    msg = refused(
        lambda: parse_bvh(fan(1000, 5000), "wide.bvh"),
        "wide.bvh line",
        "5,000 frames x 1,000 joints",
        "poses",
    )
    assert f"{limits.MAX_POSE_CELLS:,}" in msg
    assert parse_bvh(fan(1000, 2000), "ok.bvh").n_frames == 2000  # 2 M poses: read


def test_larger_files_may_hold_as_many_poses_as_their_bytes_pay_for():
    assert limits.pose_budget(0) == limits.MAX_POSE_CELLS
    assert limits.pose_budget(100 * 2**20) == 50 * 2**20
    with pytest.raises(MotionFormatError, match="poses"):
        limits.check_take("a.bvh", 100_000, 30.0, 100, 0, source_bytes=1_000_000)
    limits.check_take("a.bvh", 100_000, 30.0, 100, 300, source_bytes=60_000_000)


def test_frames_times_channels_and_duration_limits():
    with pytest.raises(MotionFormatError, match="values"):
        limits.check_take("a.bvh", 1_000_000, 120.0, 1, 101, source_bytes=10**10)
    with pytest.raises(MotionFormatError, match="hours"):
        limits.check_take("a.trc", 30_000, 1.0, 1, 3)


def test_trc_rate_is_checked():
    lines = TRC.read_text().splitlines()
    keys = lines[1].split(",")
    values = lines[2].split(",")
    values[keys.index("DataRate")] = "0.001"
    lines[2] = ",".join(values)
    refused(
        lambda: parse_trc("\n".join(lines) + "\n", "slow.trc"),
        "slow.trc",
        "DataRate",
        "frames per second",
    )


def test_splice_grid_is_bounded_before_resampling(tmp_path, capsys):
    """A 10 kHz body makes a 344-frame, 40 fps hand take 86,000 times longer on the grid."""
    body = tmp_path / "fast.bvh"
    body.write_text(with_frame_time(BODY, "0.0001"))
    hand = tmp_path / "slow.bvh"
    hand.write_text(with_frame_time(HAND, "1"))
    status, err = cli(["splice", body, hand, "-o", tmp_path / "out.bvh", "--quiet"], capsys)
    one_line_exit_2(status, err, "slow.bvh", "resampled", f"more than {limits.MAX_GRID_FRAMES:,}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fast.bvh", "slow.bvh"]


def test_band_cells_are_bounded(monkeypatch):
    from engine.io import load_take
    from engine.splice import pipeline

    monkeypatch.setattr(limits, "MAX_BAND_CELLS", 1000)
    features = pipeline.prepare(load_take(BODY), load_take(HAND), side="right")
    refused(lambda: pipeline.align_passes(features), "pass 1", "cells", "more than 1,000")


ISSUE_FILES = {
    # the issue's cases: (file text, CLI arguments after the file)
    "frame-time-300": (lambda: with_frame_time(HAND, "300"), ["info"]),
    "zero-channels-2M": (lambda: zero_channel(BODY, 2_000_000), ["analyze"]),
    "1000-zero-channel-joints": (
        lambda: fan(1000, 200_000, "CHANNELS 0")[:60_000].rsplit("\n", 1)[0] + "\n",
        ["info"],
    ),
    "frame-time-100": (lambda: with_frame_time(HAND, "100"), ["info"]),
}


@pytest.mark.parametrize("case", list(ISSUE_FILES))
def test_issue_files_exit_2_within_1_gb(case, tmp_path):
    """The real command line, in a child process: one line, exit 2, peak RSS under 1 GB."""
    make, args = ISSUE_FILES[case]
    path = tmp_path / f"{case}.bvh"
    path.write_text(make())
    assert path.stat().st_size < 2**20
    code = textwrap.dedent(f"""
        import resource, subprocess, sys
        p = subprocess.run([sys.executable, "-m", "engine.cli", {args[0]!r}, {str(path)!r}],
                           capture_output=True, text=True)
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        print(p.returncode, peak, repr(p.stderr))
    """)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([PY, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    status, peak_kb, err = out.stdout.split(" ", 2)
    err = eval(err)  # noqa: S307 -- our own repr() above
    assert int(status) == 2, err
    assert err.count("\n") == 1 and err.startswith("handsplice: error: "), err
    assert f"{case}.bvh" in err and "refusing" in err or "expected" in err, err
    assert int(peak_kb) < 2**20, f"{case}: peak RSS {int(peak_kb) / 1024:.0f} MB"


# ------------------------------------------------------------------ 3. exit 2, one line


def test_render_of_a_1000_deep_skeleton_exits_2(tmp_path, capsys):
    lines = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 3 Xrotation Yrotation Zrotation"]
    for i in range(999):
        lines += [f"JOINT j{i}", "{", "OFFSET 0 1 0", "CHANNELS 3 Xrotation Yrotation Zrotation"]
    lines += ["}"] * 1000 + ["MOTION", "Frames: 1", "Frame Time: 0.0333333", " ".join(["0"] * 3000)]
    path = tmp_path / "deep.bvh"
    path.write_text("\n".join(lines) + "\n")
    status, err = cli(["render", path, "-o", tmp_path / "d.png", "--quiet"], capsys)
    one_line_exit_2(status, err, "deep.bvh line", "nested more than 100 deep")


def test_render_of_unnamed_joints_exits_2_naming_the_file(tmp_path, capsys):
    lines = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 3 Xrotation Yrotation Zrotation"]
    for i in range(20):
        lines += [f"JOINT j{i}", "{", "OFFSET 0 1 0", "CHANNELS 3 Xrotation Yrotation Zrotation"]
    lines += ["}"] * 21 + ["MOTION", "Frames: 1", "Frame Time: 0.0333333", " ".join(["0"] * 63)]
    path = tmp_path / "chain.bvh"
    path.write_text("\n".join(lines) + "\n")
    status, err = cli(["render", path, "-o", tmp_path / "c.png", "--quiet"], capsys)
    one_line_exit_2(status, err, "chain.bvh", "nothing to draw")


def test_zero_motion_render_names_the_file(tmp_path, capsys):
    text = re.sub(r"OFFSET[^\n]*", "OFFSET 0 0 0", zero_channel(BODY, 3))
    path = tmp_path / "still.bvh"
    path.write_text(text)
    status, err = cli(["render", path, "-o", tmp_path / "s.png", "--quiet"], capsys)
    one_line_exit_2(status, err, "still.bvh", "nothing to draw")
    assert not (tmp_path / "s.png").exists()


def test_deeply_nested_roles_json_exits_2(tmp_path, capsys):
    roles = tmp_path / "roles.json"
    roles.write_text('{"a":' * 100_000 + "1" + "}" * 100_000)
    status, err = cli(
        ["splice", BODY, HAND, "-o", tmp_path / "o.bvh", "--roles", roles, "--quiet"], capsys
    )
    one_line_exit_2(status, err, "roles.json", "nested too deeply")
    roles.write_bytes(b'{"right.wrist": "\xff"}')
    status, err = cli(["render", BODY, "-o", tmp_path / "o.png", "--roles", roles], capsys)
    one_line_exit_2(status, err, "roles.json", "not UTF-8")


@pytest.mark.parametrize("exc", [MemoryError("Unable to allocate 44.7 GiB"), RecursionError()])
def test_memory_and_recursion_errors_exit_2(monkeypatch, capsys, exc):
    from engine.cli import info

    def boom(args):
        raise exc

    monkeypatch.setattr(info, "run", boom)
    status, err = cli(["info", BODY], capsys)
    one_line_exit_2(status, err, "refusing it")


# ------------------------------------------------------------------ 4. atomic pairs, debris


def test_atomic_group_replaces_all_or_nothing(tmp_path):
    a, b = tmp_path / "out.bvh", tmp_path / "out.json"
    a.write_text("old bvh")
    b.write_text("old report")
    with pytest.raises(RuntimeError):
        with atomic.atomic_group([a, b]) as (ta, tb):
            ta.write_text("new bvh")
            raise RuntimeError("report failed")
    assert (a.read_text(), b.read_text()) == ("old bvh", "old report")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh", "out.json"]
    atomic.write_texts([(a, "new bvh"), (b, "new report")])
    assert (a.read_text(), b.read_text()) == ("new bvh", "new report")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh", "out.json"]


def test_splice_replaces_bvh_and_report_together(tmp_path, capsys, monkeypatch):
    from engine.splice import report as report_module

    out, rep = tmp_path / "out.bvh", tmp_path / "out.json"
    out.write_text("old bvh")
    rep.write_text("old report")

    def broken(*args, **kwargs):
        raise ValueError("report cannot be built")

    monkeypatch.setattr(report_module, "build_report", broken)
    status, err = cli(["splice", BODY, HAND, "-o", out, "--report", rep, "--quiet"], capsys)
    one_line_exit_2(status, err, "report cannot be built")
    assert (out.read_text(), rep.read_text()) == ("old bvh", "old report")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh", "out.json"]
    monkeypatch.undo()
    status, err = cli(["splice", BODY, HAND, "-o", out, "--report", rep, "--quiet"], capsys)
    assert status == 0, err
    assert read_bvh(out).n_frames > 0 and json.loads(rep.read_text())["output"] == str(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh", "out.json"]


_WRITER = textwrap.dedent("""
    import sys, time
    from engine.base import atomic
    atomic.handle_termination()
    folder = sys.argv[1]
    try:
        with atomic.atomic_group([folder + "/out.bvh", folder + "/out.json"]) as temps:
            for t in temps:
                t.write_text("partial")
            print("writing", flush=True)
            time.sleep(60)
    except KeyboardInterrupt as exc:
        print(type(exc).__name__, flush=True)
        sys.exit(143)
""")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_temporary_files_removed_on_signals(tmp_path, sig):
    (tmp_path / "out.bvh").write_text("old")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # a run started in the background by a script inherits SIGINT ignored (the shell's
    # rule for background jobs), and Python then raises nothing on it: the writer gets
    # SIGINT's default, as a command typed at a terminal has
    p = subprocess.Popen(
        [PY, "-c", _WRITER, str(tmp_path)],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert p.stdout.readline().strip() == "writing"
    assert len(list(tmp_path.glob(".out.hstmp-*"))) == 2  # the partial files exist
    p.send_signal(sig)
    rest = p.communicate(timeout=60)[0]
    assert ("Terminated" if sig == signal.SIGTERM else "KeyboardInterrupt") in rest
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bvh"]
    assert (tmp_path / "out.bvh").read_text() == "old"


def test_stale_temporary_files_of_a_killed_run_are_cleaned_by_the_next(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen(
        [PY, "-c", _WRITER, str(tmp_path)], stdout=subprocess.PIPE, text=True, env=env
    )
    assert p.stdout.readline().strip() == "writing"
    p.kill()  # SIGKILL: nothing can clean up
    p.wait(timeout=60)
    stale = sorted(tmp_path.glob(".out.hstmp-*"))
    assert len(stale) == 2
    # a live writer's file and a file that is not ours are left alone
    live = tmp_path / f".out.hstmp-{atomic._HOST}-{os.getpid()}-abc.bvh"
    live.write_text("mine")
    with atomic._LIVE_LOCK:
        atomic._LIVE.add(live)
    other = tmp_path / ".out.notours.bvh"
    other.write_text("user file")
    try:
        atomic.write_text(tmp_path / "out.bvh", "new")
        assert not stale[0].exists() and not stale[1].exists()  # both of stem "out"
        assert live.exists() and other.exists()
    finally:
        with atomic._LIVE_LOCK:
            atomic._LIVE.discard(live)
    # another host's file: only after STALE_AFTER_S
    far = tmp_path / ".out.hstmp-0123abcd-1-xyz.bvh"
    far.write_text("x")
    atomic.clean_stale(tmp_path)
    assert far.exists()
    old = time.time() - atomic.STALE_AFTER_S - 60
    os.utime(far, (old, old))
    atomic.clean_stale(tmp_path)
    assert not far.exists()


def test_analyze_eaf_leaves_no_bak(tmp_path, capsys):
    eaf = tmp_path / "phases.eaf"
    for _ in range(2):  # the second run replaces an existing file
        status, err = cli(["analyze", BODY, "--eaf", eaf], capsys)
        assert status == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["phases.eaf"]
    from engine.io.eaf import read_eaf

    assert read_eaf(eaf).fps == 30.0


# ------------------------------------------------------------------ 7. malformed input refused


def _replace_first_value(text: str, new: str) -> str:
    head, motion = text.split("MOTION", 1)
    lines = motion.split("\n")
    first = next(i for i, ln in enumerate(lines) if i > 2 and ln.strip())
    vals = lines[first].split()
    vals[1] = new
    lines[first] = " ".join(vals)
    return head + "MOTION" + "\n".join(lines)


@pytest.mark.parametrize(
    "value",
    ["1_000", "\u0663", "\u0661\u0662.\u0665", "\uff11", "1e1_0", "nan", "Infinity", "0x10"],
)
def test_numbers_python_accepts_but_no_exporter_writes(value):
    text = _replace_first_value(HAND.read_text(), value)
    msg = refused(lambda: parse_bvh(text, "odd.bvh"), "odd.bvh line", "value 2")
    assert "expected a finite number" in msg


@pytest.mark.parametrize(
    "field, before, after",
    [
        ("OFFSET", r"OFFSET\s+(\S+)", "OFFSET 1_0"),
        ("Frames", r"Frames:\s*\d+", "Frames: 3_44"),
        ("Frame Time", r"Frame Time:\s*\S+", "Frame Time: 0.0\u0662"),
        ("CHANNELS", r"CHANNELS\s+6", "CHANNELS \u0666"),
    ],
)
def test_header_numbers_are_ascii(field, before, after):
    text = re.sub(before, after, HAND.read_text(), count=1)
    refused(lambda: parse_bvh(text, "odd.bvh"), "odd.bvh line", field)


def test_data_rows_under_channels_0_are_refused():
    text = zero_channel(BODY, 2, rows="1 2 3\n4 5 6\n")
    refused(lambda: parse_bvh(text, "rows.bvh"), "rows.bvh line", "'1 2 3'", "CHANNELS 0")
    assert parse_bvh(zero_channel(BODY, 2, rows="\n\n"), "ok.bvh").n_frames == 2


def test_joint_names_with_braces_fail_at_read_with_the_line():
    text = HAND.read_text().replace("JOINT rHand", "JOINT rHand{x}", 1)
    line = text.split("\n").index(next(ln for ln in text.split("\n") if "rHand{x}" in ln)) + 1
    msg = refused(lambda: parse_bvh(text, "brace.bvh"), f"brace.bvh line {line}", "brace")
    assert "rHand{x}" in msg
    # "JOINT Name{" (no space before the brace) still opens the block
    glued = re.sub(r"JOINT rHand\s*\n\s*\{", "JOINT rHand{", HAND.read_text(), count=1)
    assert glued != HAND.read_text()
    assert "rHand" in parse_bvh(glued, "glued.bvh").skeleton.names


def test_trc_numbers_are_ascii():
    lines = TRC.read_text().splitlines()
    fields = lines[6].split(",")
    fields[3] = "1_000"
    lines[6] = ",".join(fields)
    refused(
        lambda: parse_trc("\n".join(lines) + "\n", "odd.trc"),
        "odd.trc line 7",
        "'1_000' is not a number",
    )


# ------------------------------------------------------------------ 8. damaged ELAN files


def _eaf_text(tmp_path) -> str:
    from engine.gesture.phases import segment_phases
    from engine.io.eaf import write_eaf

    path = tmp_path / "good.eaf"
    write_eaf(path, segment_phases(read_bvh(BODY)), source=BODY.name)
    return path.read_text(encoding="utf-8")


def _eaf_damage(text: str) -> dict[str, str]:
    slot = re.search(r'TIME_VALUE="(\d+)"', text)
    ref = re.search(r'TIME_SLOT_REF1="(\w+)"', text)
    assert slot and ref
    prop = re.compile(r'(<PROPERTY NAME="fps">)[^<]*(</PROPERTY>)')
    frames = re.compile(r'(<PROPERTY NAME="frames">)[^<]*(</PROPERTY>)')
    return {
        "fps-text": prop.sub(r"\1abc\2", text),
        "fps-overflow": prop.sub(r"\g<1>1e999\2", text),
        "fps-nan": prop.sub(r"\1nan\2", text),
        "fps-negative": prop.sub(r"\1-30\2", text),
        "fps-tiny": prop.sub(r"\g<1>1e-300\2", text),
        "fps-underscore": prop.sub(r"\g<1>3_0\2", text),
        "frames-text": frames.sub(r"\1many\2", text),
        "frames-huge": frames.sub(r"\g<1>99999999999999999999999\2", text),
        "frames-float": frames.sub(r"\g<1>1e999\2", text),
        "slot-missing": text.replace(f'TIME_SLOT_REF1="{ref[1]}"', 'TIME_SLOT_REF1="ts999999"', 1),
        "slot-text": text.replace(slot[0], 'TIME_VALUE="soon"', 1),
        "slot-huge": text.replace(slot[0], 'TIME_VALUE="' + "9" * 400 + '"', 1),
        "slot-negative": text.replace(slot[0], 'TIME_VALUE="-5"', 1),
        "truncated": text[: len(text) // 2],
        "not-xml": "not xml at all",
        "empty": "",
        "nested": "<a>" * 100_000 + "</a>" * 100_000,
        "no-id": re.sub(r'ANNOTATION_ID="\w+"', "", text, count=1),
        "wrong-root": text.replace("ANNOTATION_DOCUMENT", "DOCUMENT"),
    }


def test_damaged_elan_files_raise_one_error_type(tmp_path):
    from engine.io.eaf import read_eaf

    cases = _eaf_damage(_eaf_text(tmp_path))
    kinds = {}
    for name, text in cases.items():
        path = tmp_path / f"{name}.eaf"
        path.write_text(text, encoding="utf-8")
        try:
            read_eaf(path)
            kinds[name] = "read"
        except HandSpliceError as exc:
            assert "\n" not in str(exc).strip(), (name, str(exc))
            assert f"{name}.eaf" in str(exc), (name, str(exc))
            kinds[name] = type(exc).__name__
    wrong = {n: k for n, k in kinds.items() if k not in ("MotionFormatError", "read")}
    assert not wrong, wrong
    for name in (
        "fps-text",
        "fps-overflow",
        "fps-nan",
        "frames-huge",
        "slot-missing",
        "slot-text",
        "slot-huge",
        "truncated",
        "not-xml",
        "empty",
        "nested",
    ):
        assert kinds[name] == "MotionFormatError", (name, kinds[name])


# ------------------------------------------------------------------ 9. batch limits, summary


def _pass_through(body, hand, job):
    """A splice stand-in: the body take unchanged (no numba), with what it saw."""
    return body, {"seen": job.name}


def _sleepy(body, hand, job):
    time.sleep(30)
    return body, {}


def _greedy(body, hand, job):
    hog = np.ones((64, 2**20))  # 512 MB, touched
    return body, {"sum": float(hog.sum())}


def _job(name: str):
    from engine.jobs.batch import PairJob

    return PairJob(line=2, name=name, body=str(BODY), hand=str(HAND), side="right")


def test_batch_pair_time_limit(tmp_path):
    from engine.jobs.batch import run_pair

    t0 = time.monotonic()
    rec = run_pair(_job("slow"), tmp_path, "none", _sleepy, seconds=2, memory_mb=0)
    assert time.monotonic() - t0 < 20
    assert rec["status"] == "failed" and "time limit of 2 s" in rec["error"], rec
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]  # nothing written


def test_batch_pair_memory_limit(tmp_path):
    from engine.jobs.batch import run_pair

    rec = run_pair(_job("greedy"), tmp_path, "none", _greedy, seconds=60, memory_mb=300)
    assert rec["status"] == "failed" and "memory limit of 300 MB" in rec["error"], rec
    ok = run_pair(_job("fine"), tmp_path, "none", _pass_through, seconds=60, memory_mb=0)
    assert ok["status"] == "done", ok
    assert (tmp_path / "fine.bvh").is_file() and (tmp_path / "fine.report.json").is_file()


def test_batch_summary_grows_as_pairs_finish(tmp_path, monkeypatch):
    from engine.jobs import batch

    manifest = tmp_path / "m.csv"
    manifest.write_text(
        "body,hand,side,band,refine_band,match,name\n"
        f"{BODY},{HAND},right,,,,first\n{BODY},{HAND},right,,,,second\n"
    )
    seen = []
    real = batch.write_summary_csv

    def spy(records, path):
        seen.append([r["name"] for r in records])
        return real(records, path)

    monkeypatch.setattr(batch, "write_summary_csv", spy)

    def fake_dask(
        todo,
        outdir,
        thumbnails,
        scheduler,
        workers,
        client,
        show,
        splice,
        limits=(),
        on_record=None,
    ):
        out = []
        for job in todo:
            rec = batch.run_pair(job, outdir, thumbnails, splice, *limits)
            out.append(rec)
            on_record(rec)
            time.sleep(1.1)  # the summary is rewritten at most once a second
        return out

    monkeypatch.setattr(batch, "_run_on_dask", fake_dask)
    result = batch.run_batch(
        manifest,
        tmp_path / "out",
        thumbnails="none",
        splice=_pass_through,
        pair_seconds=60,
        pair_memory_mb=0,
    )
    assert [r["status"] for r in result.records] == ["done", "done"]
    assert seen[0] == ["first"] and seen[-1] == ["first", "second"], seen
    rows = list(csv.DictReader((tmp_path / "out" / "summary.csv").open()))
    assert [r["name"] for r in rows] == ["first", "second"]


def test_batch_cli_limit_options(tmp_path, capsys):
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"body,hand,side\n{BODY},{HAND},right\n")
    status, err = cli(["batch", manifest, "-o", tmp_path / "o", "--pair-seconds", "-1"], capsys)
    one_line_exit_2(status, err, "--pair-seconds")
    with pytest.raises(SystemExit) as info:  # argparse's own one-line error
        main(["batch", str(manifest), "-o", str(tmp_path / "o"), "--pair-memory-mb", "x"])
    assert info.value.code == 2 and "--pair-memory-mb" in capsys.readouterr().err


def test_limits_module_is_the_one_place():
    from engine.io import bvh, c3d, trc

    for mod in (bvh, c3d, trc):
        src = Path(mod.__file__).read_text()
        assert "limits.check_take" in src, mod.__name__
    assert resource.RLIMIT_DATA  # the sandbox's hard memory cap exists on this platform


# ------------------------------------------------------------------ tokens of thousands of digits

DIGITS = "9" * 5000  # past Python's int-from-text limit (4,300 digits); float reads it as inf


@pytest.mark.parametrize(
    ("field", "edit", "words"),
    [
        (
            "CHANNELS",
            lambda t: re.sub(r"CHANNELS \d", "CHANNELS " + DIGITS, t, count=1),
            ("line 5", "CHANNELS count must be a whole number 0-6"),
        ),
        (
            "OFFSET",
            lambda t: re.sub(r"OFFSET \S+", "OFFSET " + DIGITS, t, count=1),
            ("line 4", "OFFSET", "is not a finite number"),
        ),
    ],
)
def test_a_bvh_token_of_thousands_of_digits_is_one_short_line(field, edit, words, tmp_path, capsys):
    path = tmp_path / f"huge-{field}.bvh"
    path.write_text(edit(BODY.read_text()))
    status, err = cli(["info", str(path)], capsys)
    one_line_exit_2(status, err, path.name, *words)
    assert len(err) < 200, err  # the token is quoted clipped, not whole


def test_a_trc_value_of_thousands_of_digits_is_one_short_line(tmp_path, capsys):
    lines = TRC.read_text().splitlines()
    cells = lines[6].split(",")
    cells[2] = DIGITS
    lines[6] = ",".join(cells)
    path = tmp_path / "huge.trc"
    path.write_text("\n".join(lines) + "\n")
    status, err = cli(["info", str(path)], capsys)
    one_line_exit_2(status, err, "huge.trc line 7", "is not finite")
    assert len(err) < 200, err


def test_any_format_error_is_clipped_to_one_short_line():
    err = MotionFormatError("x.bvh", "found " + DIGITS + "\nsecond line", line=3)
    assert str(err).startswith("x.bvh line 3: found 999") and str(err).endswith("…")
    assert "\n" not in str(err) and len(str(err)) < 330


@pytest.mark.parametrize(
    ("flag", "value"),
    [("--frame", DIGITS), ("--size", DIGITS + "x10"), ("--frames", "1:" + DIGITS)],
)
def test_a_flag_value_of_thousands_of_digits_is_one_short_line(flag, value, tmp_path, capsys):
    try:  # argparse's refusals exit from inside main
        status = main(["render", str(BODY), "-o", str(tmp_path / "r.png"), flag, value])
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err.strip()
    one_line_exit_2(status, err, flag)
    assert len(err) < 400, err
