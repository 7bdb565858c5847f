"""Rejected input, case by case: absurd sizes, oversized uploads, path traversal.

Every refusal is a one-line message naming what was wrong. The second half checks
that the web app's loaders never read a file outside the sample and upload folders:
an audit hook records every file the process opens while hostile and ordinary
requests are served, and each must lie inside those folders (or be Python code).
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from conftest import MOCAP, ROOT

from engine.base import limits
from engine.base.errors import HandSpliceError
from engine.io import bvh as bvh_io
from engine.io import c3d as c3d_io
from engine.io import load_take
from engine.io import trc as trc_io
from engine.io.bvh import parse_bvh, read_bvh, write_bvh
from engine.io.session import MAX_POINTS, MAX_TEXT, parse_session

C3D = MOCAP / "pyomeca/markers_analogs.c3d"
TRC = MOCAP / "pyomeca/markers.trc"


def chain_bvh(
    joints: int,
    frames: int = 1,
    frame_time: str = "0.0333333",
    offset: str = "0 1 0",
    value: str = "0",
) -> str:
    """A chain of ``joints`` joints (each nested in the previous), 3 rotation channels each."""
    lines = [
        "HIERARCHY",
        "ROOT j0",
        "{",
        "OFFSET 0 0 0",
        "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
    ]
    for j in range(1, joints):
        lines += [
            f"JOINT j{j}",
            "{",
            f"OFFSET {offset}",
            "CHANNELS 3 Zrotation Xrotation Yrotation",
        ]
    lines += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * joints
    n_values = 6 + 3 * (joints - 1)
    row = " ".join([value] * n_values)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {frame_time}"] + [row] * frames
    return "\n".join(lines) + "\n"


def fan_bvh(joints: int, frames: int = 1) -> str:
    """A root with ``joints - 1`` children (one level deep), 3 rotation channels each."""
    lines = [
        "HIERARCHY",
        "ROOT j0",
        "{",
        "OFFSET 0 0 0",
        "CHANNELS 3 Zrotation Xrotation Yrotation",
    ]
    for j in range(1, joints):
        lines += [
            f"JOINT j{j}",
            "{",
            "OFFSET 0 1 0",
            "CHANNELS 3 Zrotation Xrotation Yrotation",
            "}",
        ]
    lines += ["}", "MOTION", f"Frames: {frames}", "Frame Time: 0.0333333"]
    lines += [" ".join(["0"] * (3 * joints))] * frames
    return "\n".join(lines) + "\n"


def refused(call, *words: str) -> str:
    with pytest.raises(HandSpliceError) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg.strip(), msg
    for w in words:
        assert w in msg, msg
    return msg


# ---------------------------------------------------------------- BVH


def test_limits_are_the_readers_limits():
    assert bvh_io.MAX_FRAMES == c3d_io.MAX_FRAMES == trc_io.MAX_FRAMES == limits.MAX_FRAMES
    assert bvh_io.MAX_JOINTS == limits.MAX_JOINTS
    assert MAX_TEXT == limits.MAX_SESSION_BYTES


@pytest.mark.parametrize("frames", ["2000001", "99999999999999999999999999", str(2**63)])
def test_bvh_absurd_frame_count_in_header(frames):
    text = chain_bvh(2).replace("Frames: 1", f"Frames: {frames}")
    refused(lambda: parse_bvh(text, "huge.bvh"), "huge.bvh line", "refusing an absurd take")


def test_bvh_more_rows_than_the_limit(monkeypatch):
    monkeypatch.setattr(bvh_io, "MAX_FRAMES", 5)
    assert parse_bvh(chain_bvh(2, frames=5), "ok.bvh").n_frames == 5
    text = chain_bvh(2, frames=7).replace("Frames: 7", "Frames: 3")  # rows beyond Frames:
    refused(lambda: parse_bvh(text, "rows.bvh"), "more than 5 data rows")


def test_bvh_absurd_joint_count():
    refused(lambda: parse_bvh(fan_bvh(1001), "bones.bvh"), "more than 1000 joints")
    m = parse_bvh(fan_bvh(1000), "wide.bvh")
    assert m.skeleton.n_joints == 1000 and m.skeleton.parents[-1] == 0


def test_bvh_absurd_depth():
    depth = limits.MAX_DEPTH
    m = parse_bvh(chain_bvh(depth), "deep.bvh")  # nested MAX_DEPTH levels: fine, no recursion
    assert m.skeleton.n_joints == depth and m.skeleton.parents[-1] == depth - 2
    msg = refused(
        lambda: parse_bvh(chain_bvh(depth + 1), "deeper.bvh"),
        "deeper.bvh line",
        f"nested more than {depth} deep",
    )
    assert f"'j{depth}'" in msg


@pytest.mark.parametrize(
    "frame_time, words",
    [
        ("1e-320", "frames per second"),
        ("0.00001", "frames per second"),
        ("0", "not a positive"),
        ("-0.03", "not a positive"),
        ("nan", "not a positive"),
        ("inf", "not a positive"),
    ],
)
def test_bvh_absurd_frame_time(frame_time, words):
    refused(lambda: parse_bvh(chain_bvh(2, frame_time=frame_time), "rate.bvh"), words)
    parse_bvh(chain_bvh(2, frame_time="0.0001"), "fast.bvh")  # 10 kHz is still accepted


@pytest.mark.parametrize(
    "kw",
    [dict(offset="0 1e300 0"), dict(offset="0 -2e9 0"), dict(value="1e12"), dict(value="-1e308")],
)
def test_bvh_absurd_values(kw):
    refused(lambda: parse_bvh(chain_bvh(3, **kw), "far.bvh"), "refusing an absurd value")


def test_bvh_values_at_the_limit_are_read():
    m = parse_bvh(chain_bvh(3, offset="0 1e9 0", value="-1e9"), "edge.bvh")
    assert np.isfinite(m.translations).all()


@pytest.mark.parametrize(
    "channels",
    [
        "CHANNELS 7 Zrotation Xrotation Yrotation",
        "CHANNELS -1",
        "CHANNELS 99999999999999999999",
        "CHANNELS 3 Zrotation Zrotation Yrotation",
    ],
)
def test_bvh_bad_channel_counts(channels):
    text = chain_bvh(2).replace("CHANNELS 3 Zrotation Xrotation Yrotation", channels)
    refused(lambda: parse_bvh(text, "ch.bvh"), "ch.bvh line")


# ---------------------------------------------------------------- C3D, TRC


def test_c3d_frame_and_marker_limits(monkeypatch):
    assert load_take(C3D).n_frames == 580
    monkeypatch.setattr(c3d_io, "MAX_FRAMES", 100)
    refused(lambda: load_take(C3D), "580 frames", "refusing an absurd take")
    monkeypatch.setattr(c3d_io, "MAX_FRAMES", limits.MAX_FRAMES)
    monkeypatch.setattr(c3d_io, "MAX_MARKERS", 50)
    refused(lambda: load_take(C3D), "51 markers", "refusing an absurd take")


def test_c3d_header_promising_more_frames_than_bytes(tmp_path):
    data = bytearray(C3D.read_bytes())
    data[8:10] = struct.pack("<H", 60000)  # last frame: 60,000 frames of 51 markers + analogs
    path = tmp_path / "promise.c3d"
    path.write_bytes(bytes(data))
    refused(lambda: load_take(path), "truncated C3D file")


def test_c3d_points_header_word_beyond_parameters(tmp_path):
    data = bytearray(C3D.read_bytes())
    data[2:4] = struct.pack("<H", 65535)  # 65,535 markers claimed by the header
    path = tmp_path / "points.c3d"
    path.write_bytes(bytes(data))
    refused(lambda: load_take(path), "points.c3d")


def test_trc_limits(monkeypatch, tmp_path):
    text = TRC.read_text(encoding="utf-8")
    rows = len(load_take(TRC).points)
    monkeypatch.setattr(trc_io, "MAX_FRAMES", rows - 1)
    refused(lambda: trc_io.parse_trc(text, "rows.trc"), f"more than {rows - 1:,} data rows")
    monkeypatch.setattr(trc_io, "MAX_FRAMES", limits.MAX_FRAMES)
    monkeypatch.setattr(trc_io, "MAX_MARKERS", 50)
    refused(lambda: trc_io.parse_trc(text, "wide.trc"), "51 markers is more than 50")
    monkeypatch.setattr(trc_io, "MAX_MARKERS", limits.MAX_MARKERS)
    lines = text.splitlines()
    k = next(i for i, ln in enumerate(lines) if i > 5 and ln.strip())
    fields = lines[k].split(",")
    fields[3] = "1e12"
    lines[k] = ",".join(fields)
    refused(lambda: trc_io.parse_trc("\n".join(lines), "far.trc"), "refusing an absurd value")


# ---------------------------------------------------------------- session JSON


def test_session_size_depth_and_points_limits():
    refused(lambda: parse_session(b" " * (MAX_TEXT + 1), "big.json"), "at most")
    refused(lambda: parse_session("[" * 200_000 + "]" * 200_000, "deep.json"), "nested too deeply")
    points = [{"body": i, "hand": i} for i in range(MAX_POINTS + 1)]
    refused(lambda: parse_session(json.dumps({"points": points}), "many.json"), "at most")
    refused(lambda: parse_session('{"band": 1e999}', "inf.json"), "band")
    refused(lambda: parse_session('{"band": NaN}', "nan.json"), "finite")


# ---------------------------------------------------------------- the web app: uploads


@pytest.fixture()
def app_dirs(tmp_path):
    """A sample folder with one small real pair and hostile samples.json entries, an
    upload folder, and a secret file outside both."""
    from webapp import config

    samples = tmp_path / "samples"
    (samples / "takes").mkdir(parents=True)
    uploads = tmp_path / "uploads"
    secret = tmp_path / "secret.bvh"
    body = read_bvh(MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh")
    write_bvh(body.frames(0, 40), samples / "takes" / "body.bvh")
    hand = read_bvh(MOCAP / "gestification/hello-world.bvh")
    write_bvh(hand.frames(0, 50), samples / "takes" / "hand.bvh")
    shutil.copy(samples / "takes" / "body.bvh", secret)
    (samples / "takes" / "link.bvh").symlink_to(secret)
    entries = [
        {"name": "ok", "body": "takes/body.bvh", "hand": "takes/hand.bvh", "side": "right"},
        {"name": "dotdot", "body": "../secret.bvh", "hand": "takes/hand.bvh"},
        {"name": "sneaky", "body": "takes/../../secret.bvh", "hand": "takes/hand.bvh"},
        {"name": "absolute", "body": str(secret), "hand": "takes/hand.bvh"},
        {"name": "symlink", "body": "takes/link.bvh", "hand": "takes/hand.bvh"},
        {"name": "etc", "body": "/etc/passwd", "hand": "/etc/shadow"},
        {"name": "not-a-string", "body": ["takes/body.bvh"], "hand": {"x": 1}},
    ]
    (samples / "samples.json").write_text(json.dumps({"pairs": entries}), encoding="utf-8")
    cfg = config.AppConfig(
        sample_dir=samples.resolve(),
        upload_dir=uploads.resolve(),
        default_sample="ok",
        max_upload_bytes=200_000,
    )
    return cfg, secret


def test_samples_json_cannot_point_outside_the_sample_folder(app_dirs):
    cfg, _ = app_dirs
    assert [p.name for p in cfg.samples()] == ["ok"]
    for name in ("dotdot", "sneaky", "absolute", "symlink", "etc", "../secret", "/etc/passwd"):
        with pytest.raises(KeyError):
            cfg.sample(name)


def test_upload_size_limit_and_refusals(app_dirs):
    from webapp import uploads

    cfg, _ = app_dirs
    good = (cfg.sample_dir / "takes" / "hand.bvh").read_bytes()
    refused(
        lambda: uploads.store(cfg, "big.bvh", good + b"\n" * cfg.max_upload_bytes),
        "big.bvh",
        "upload limit",
    )
    refused(lambda: uploads.store(cfg, "empty.bvh", b""), "empty")
    refused(lambda: uploads.store(cfg, "take.exe", good), "expected a .bvh, .c3d or .trc")
    refused(lambda: uploads.store(cfg, "noext", good), "expected a .bvh")
    absurd = chain_bvh(2).replace("Frames: 1", "Frames: 999999999").encode()
    msg = refused(
        lambda: uploads.store(cfg, "absurd.bvh", absurd), "absurd.bvh", "refusing an absurd take"
    )
    assert ".check-" not in msg  # the staging name is not shown to the user
    refused(lambda: uploads.store(cfg, "bones.bvh", fan_bvh(1001).encode()), "joints")
    assert sorted(p.name for p in cfg.upload_dir.iterdir()) == []  # nothing kept


def test_upload_names_cannot_escape_the_upload_folder(app_dirs, tmp_path):
    from webapp import uploads

    cfg, secret = app_dirs
    good = (cfg.sample_dir / "takes" / "hand.bvh").read_bytes()
    for name in (
        "../../evil.bvh",
        "/etc/cron.d/evil.bvh",
        "..\\..\\evil.bvh",
        "a/../../../evil.bvh",
    ):
        digest, take = uploads.store(cfg, name, good)
        assert take.n_frames == 50
    kept = list(cfg.upload_dir.iterdir())
    assert [p.name for p in kept] == [f"{digest}.bvh"]
    assert not list(tmp_path.rglob("evil*"))
    assert uploads.path_for(cfg, digest) == cfg.upload_dir / f"{digest}.bvh"
    for bad in (
        "../../secret",
        str(secret),
        "../" * 10 + "etc/passwd",
        digest.upper(),
        digest[:-1],
        digest + "0",
        digest[:60] + "/../",
        "",
        None,
        12,
    ):
        refused(lambda b=bad: uploads.path_for(cfg, b), "upload")


# ---------------------------------------------------------------- the web app: no reads outside


_RECORDING: list[str] | None = None


def _audit(event: str, args) -> None:
    if _RECORDING is not None and event == "open" and args and isinstance(args[0], str | bytes):
        _RECORDING.append(args[0].decode() if isinstance(args[0], bytes) else args[0])


_HOOKED = False


@contextmanager
def recorded_opens():
    """Every path the process opens inside the block (``sys.addaudithook``)."""
    global _RECORDING, _HOOKED
    if not _HOOKED:
        sys.addaudithook(_audit)  # hooks cannot be removed: one for the whole session
        _HOOKED = True
    _RECORDING = []
    try:
        yield _RECORDING
    finally:
        _RECORDING = None


def _outside(paths: list[str], allowed: list[Path]) -> list[str]:
    code = [
        Path(sys.prefix).resolve(),
        Path(sys.base_prefix).resolve(),
        ROOT / "engine",
        ROOT / "webapp",
    ]
    if os.environ.get("NUMBA_CACHE_DIR"):  # numba's compiled-kernel cache (cold on a fresh clone)
        code.append(Path(os.environ["NUMBA_CACHE_DIR"]).resolve())
    out = []
    for p in paths:
        if p.startswith(("/proc/", "/sys/", "/dev/")) or p.endswith(".__path_hook__"):
            continue  # kernel files; the editable install's import hook (not a file)
        rp = Path(p).resolve()
        if any(rp.is_relative_to(a) for a in allowed + code):
            continue
        out.append(p)
    return out


def refused_or_reported(session, request) -> None:
    """A hostile request is refused: it raises a documented error, or the session reports
    it in ``error`` (the app's two styles). What matters here is what gets read."""
    session.error = ""
    try:
        request()
    except (HandSpliceError, KeyError, ValueError) as err:
        assert str(err)
        return
    assert session.error, "a hostile request was accepted"


@pytest.mark.timeout(300, method="thread")
def test_webapp_reads_only_its_sample_and_upload_folders(app_dirs):
    from webapp import uploads
    from webapp.state import Session

    cfg, secret = app_dirs
    Session(cfg)  # imports done before recording
    hand_bytes = (cfg.sample_dir / "takes" / "hand.bvh").read_bytes()
    body_bytes = (cfg.sample_dir / "takes" / "body.bvh").read_bytes()
    hostile_json = [
        {"inputs": {"body": {"path": str(secret)}, "hand": {"path": "/etc/passwd"}}},
        {"inputs": {"body": {"path": "../secret.bvh"}, "hand": {"path": "takes/hand.bvh"}}},
        {"inputs": {"sample": "../secret"}},
        {"inputs": {"sample": "/etc/passwd"}},
        {"inputs": {"sample": "symlink"}},
        {"inputs": {"body": {"sha256": "0" * 64}, "hand": {"sha256": "1" * 64}}},
    ]
    hostile_queries = [
        {"sample": "../../secret"},
        {"sample": "dotdot"},
        {"body": "../../etc/passwd", "hand": "x"},
        {"body": "ab" * 32, "hand": "cd" * 32},
    ]
    with recorded_opens() as opened:
        s = Session(cfg)
        s.load_sample("ok")  # an ordinary request: reads both sample takes
        assert s.prepared is not None and s.n == 40 and not s.error
        for request in (
            [lambda d=d: s.from_json(json.dumps(d), "hostile.json") for d in hostile_json]
            + [lambda q=q: s.from_query(q) for q in hostile_queries]
            + [
                lambda n=n: s.load_sample(n)
                for n in ("dotdot", "sneaky", "absolute", "symlink", "etc")
            ]
            + [lambda: s.load_uploads("../../secret", "../../secret")]
        ):
            refused_or_reported(s, request)
        b, _ = uploads.store(cfg, "../../body.bvh", body_bytes)
        h, _ = uploads.store(cfg, "/etc/hand.bvh", hand_bytes)
        s2 = Session(cfg)
        s2.load_uploads(b, h, "body.bvh", "hand.bvh")  # an ordinary upload session
        assert s2.prepared is not None and not s2.error
    reads = [p for p in opened if p]
    assert any(Path(p).resolve().is_relative_to(cfg.sample_dir) for p in reads)
    assert any(Path(p).resolve().is_relative_to(cfg.upload_dir) for p in reads)
    assert _outside(reads, [cfg.sample_dir, cfg.upload_dir]) == []
    assert not any(Path(p).resolve() == secret.resolve() for p in reads)
    assert not any(p.startswith("/etc") for p in reads)
