"""Fuzz bench: mutated captures, annotations, sessions and role maps against every reader,
the loaders, the upload validation and the command line (issue 15).

Run (nice, two lanes on a small machine; ~15 minutes for the default 2,400 cases)::

    nice python -m benchmarks.bench_fuzz [--cases 2400] [--jobs 2] [--seed 0]
        [--subprocess 40] [--record]

Seeds are real files: BVH takes from ``../shared/data/mocap`` (Leap hand, Bandai body,
BEAT body with fingers), the pyomeca C3D and TRC, an ELAN file ``write_eaf`` makes from
a real take, session files and role maps. Each case applies 1-4 of this bench's own
mutators (below) to a seed and hands the result to one target:

=========  ==============================================================================
target     call and the outcomes that pass
=========  ==============================================================================
bvh        ``read_bvh``: a Motion, or ``MotionFormatError``
c3d, trc   ``read_c3d`` / ``read_trc``: a MarkerSet, or ``MotionFormatError``
eaf        ``read_eaf``: annotations, or ``MotionFormatError`` / ``ParameterError``
session    ``read_session``: a SessionSpec, or ``SessionError``
roles      ``load_role_overrides``: a map, or ``ParameterError``
upload     ``webapp.uploads.store`` (called as is): a take kept, or ``UploadError``
cli        ``handsplice info|analyze|splice|render`` (``engine.cli.main``) on the mutated
           file: exit 0 with its outputs, or exit 2 with one ``handsplice: error:`` line
=========  ==============================================================================

Failures, by kind:

* crash: the process running the case died (a signal: segfault, abort);
* traceback: any other exception, or a CLI run with exit 1 / "internal error" / a
  traceback / more than one line;
* hang: the case ran past its time limit (60 s for a reader, 240 s for a command, on a loaded 2-core machine);
* over 1 GB: the process running the case went over 1 GB resident on an input under
  1 MB (the case is stopped there: RLIMIT_DATA and resident-size polling), or the CLI
  answered "needs more memory";
* stray file: anything left in the case's folder besides its inputs and, on success,
  its declared outputs (temporary files, ``.bak``, an output written by a refused run),
  or an input modified.

Cases run in forked runner processes (``engine.jobs.sandbox``: one per lane, kept between
cases so numba compiles once, replaced after a limit). The resident size counts the
interpreter, numpy, numba and everything compiled so far, as a CLI process would. The
peak of every case is taken from ``VmHWM`` (reset per case through
``/proc/self/clear_refs``). ``--subprocess K`` adds K runs of the real command line in
child processes (the issue's memory cases first, then mutated files), measuring each
child process, reading each one's peak RSS (``RUSAGE_CHILDREN`` of a small intermediate).
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import io
import json
import os
import random
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "data" / "mocap"
if not MOCAP.is_dir():
    MOCAP = Path("/work/shared/data/mocap")
ONE_GB_MB = 1024.0
MAX_CASE_BYTES = 2**20  # mutated text files stay under 1 MB (the C3D seed is 2.2 MB)
READER_SECONDS = 60.0
CLI_SECONDS = 240.0
KINDS = ("crash", "traceback", "hang", "over 1 GB", "stray file")

BVH_SEEDS = {
    "hand": MOCAP / "gestification/gesture-pointing.bvh",
    "hand2": MOCAP / "gestification/fingers-ok.bvh",
    "body": MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh",
    "beat": MOCAP / "beat/1_wayne_0_1_1.bvh",
}
#: how often each seed is drawn (BEAT, 0.8 MB, is the slow one)
BVH_WEIGHTS = {"hand": 4, "hand2": 3, "body": 4, "beat": 1}


def pick_bvh(rng: random.Random) -> str:
    return rng.choices(list(BVH_WEIGHTS), weights=list(BVH_WEIGHTS.values()))[0]


C3D_SEED = MOCAP / "pyomeca/markers_analogs.c3d"
TRC_SEED = MOCAP / "pyomeca/markers.trc"

GARBAGE = [
    "nan",
    "NaN",
    "-inf",
    "Infinity",
    "1e309",
    "1e308",
    "-1e308",
    "1e300",
    "1e-300",
    "5e-324",
    "0",
    "-0",
    "",
    "abc",
    "1.5.2",
    "0x1F",
    "1_000",
    "\u0663",
    "\u0661\u0662",
    "\uff11\uff12",
    "+-1",
    "9" * 400,
    "1e99999",
    "2147483648",
    "18446744073709551616",
    "1e15",
    "-1",
    "3",
    "6",
    "7",
    "{",
    "}",
    "ROOT",
    "JOINT",
    "End Site",
    "MOTION",
    "HIERARCHY",
    "CHANNELS",
    "OFFSET",
    "Frames:",
    "\ufeff",
    "\u00e9",
    "<script>alert(1)</script>",
    "\t",
    "1e-5",
    "0.0001",
    "100",
    "300",
    "1e6",
    "2000000",
    "99999999",
    "-999999999",
]
NAMES = [
    "Chest{x}",
    "a}b",
    "<img src=x onerror=alert(1)>",
    "x" * 5000,
    "Hips",
    "rHand",
    "right_wrist",
    "\u202e",
    "a b  c",
    "\u00e9\u00e8",
    "LeftHand",
    "{",
    "}",
]


# ---------------------------------------------------------------- mutators (this bench's own)


def _lines(text: str) -> list[str]:
    return text.split("\n")


def m_flip_byte(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return data
    b = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        i = rng.randrange(len(b))
        b[i] = rng.randrange(256)
    return bytes(b)


def m_truncate(data: bytes, rng: random.Random) -> bytes:
    return data[: rng.randrange(len(data) + 1)]


def m_append_junk(data: bytes, rng: random.Random) -> bytes:
    return data + bytes(rng.randrange(256) for _ in range(rng.randint(1, 2000)))


def t_replace_number(text: str, rng: random.Random) -> str:
    nums = list(re.finditer(r"-?\d+(\.\d+)?(e-?\d+)?", text))
    if not nums:
        return text
    for _ in range(rng.randint(1, 3)):
        m = rng.choice(nums)
        text = text[: m.start()] + rng.choice(GARBAGE) + text[m.end() :]
        nums = list(re.finditer(r"-?\d+(\.\d+)?(e-?\d+)?", text))
        if not nums:
            break
    return text


def t_delete_line(text: str, rng: random.Random) -> str:
    ls = _lines(text)
    del ls[rng.randrange(len(ls))]
    return "\n".join(ls)


def t_duplicate_line(text: str, rng: random.Random) -> str:
    ls = _lines(text)
    i = rng.randrange(len(ls))
    ls[i:i] = [ls[i]] * rng.choice([1, 2, 50])
    return "\n".join(ls)


def t_swap_lines(text: str, rng: random.Random) -> str:
    ls = _lines(text)
    i, j = rng.randrange(len(ls)), rng.randrange(len(ls))
    ls[i], ls[j] = ls[j], ls[i]
    return "\n".join(ls)


def t_insert_token(text: str, rng: random.Random) -> str:
    ls = _lines(text)
    i = rng.randrange(len(ls))
    words = ls[i].split()
    words.insert(rng.randint(0, len(words)), rng.choice(GARBAGE))
    ls[i] = " ".join(words)
    return "\n".join(ls)


def t_line_endings(text: str, rng: random.Random) -> str:
    return rng.choice(
        [
            lambda t: t.replace("\n", "\r\n"),
            lambda t: "\ufeff" + t,
            lambda t: t.replace("\n", "\r"),
            lambda t: t.replace(" ", "\t"),
        ]
    )(text)


def b_header(text: str, rng: random.Random) -> str:
    """BVH header fields: Frames, Frame Time, CHANNELS counts, OFFSET values."""
    field = rng.choice(["frames", "time", "channels", "offset"])
    if field == "frames":
        return re.sub(
            r"Frames:\s*\S+", f"Frames: {rng.choice(GARBAGE + ['2000000'] * 3)}", text, count=1
        )
    if field == "time":
        value = rng.choice(
            [
                "300",
                "100",
                "1e6",
                "1e-300",
                "1e300",
                "0.9",
                "1",
                "0.0001",
                "0.00001",
                "1_0",
                "\u0660.\u0660\u0663",
                "-0.03",
            ]
            + GARBAGE
        )
        return re.sub(r"Frame Time:\s*\S+", f"Frame Time: {value}", text, count=1)
    if field == "channels":
        ms = list(re.finditer(r"CHANNELS \d[^\n]*", text))
        m = rng.choice(ms)
        new = rng.choice(
            [
                "CHANNELS 0",
                "CHANNELS 7 Xrotation",
                "CHANNELS 3 Xrotation Xrotation Yrotation",
                "CHANNELS \u0663 Xrotation Yrotation Zrotation",
                "CHANNELS 1_0",
                "CHANNELS 2 Zrotation Qrotation",
            ]
        )
        return text[: m.start()] + new + text[m.end() :]
    ms = list(re.finditer(r"OFFSET[^\n]*", text))
    m = rng.choice(ms)
    vals = " ".join(rng.choice(GARBAGE + ["0", "1", "-2.5"]) for _ in range(3))
    return text[: m.start()] + f"OFFSET {vals}" + text[m.end() :]


def b_zero_channels(text: str, rng: random.Random) -> str:
    """Every joint ``CHANNELS 0`` (data rows now extra), optionally a huge frame count."""
    text = re.sub(r"CHANNELS \d[^\n]*", "CHANNELS 0", text)
    head = text.split("MOTION")[0]
    frames = rng.choice([0, 1, 10, 100_000, 2_000_000, 1_999_999])
    rows = "" if rng.random() < 0.7 else "1 2 3\n"
    return head + f"MOTION\nFrames: {frames}\nFrame Time: 0.0333333\n" + rows


def b_deepen(text: str, rng: random.Random) -> str:
    """Nest a chain of unnamed joints (0 or 3 channels) under the first joint's OFFSET."""
    depth = rng.choice([10, 99, 100, 101, 1000])
    chans = rng.choice(["CHANNELS 0", "CHANNELS 3 Zrotation Xrotation Yrotation"])
    chain = "".join(f"JOINT deep{k}\n{{\nOFFSET 0 1 0\n{chans}\n" for k in range(depth))
    chain += "}\n" * depth
    i = text.find("OFFSET")
    j = text.find("\n", text.find("CHANNELS", i))
    return text[: j + 1] + chain + text[j + 1 :]


def b_many_joints(text: str, rng: random.Random) -> str:
    """Add hundreds of zero-channel sibling joints (poses without data)."""
    n = rng.choice([100, 999, 1001, 5000])
    fan = "".join(f"JOINT extra{k}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n}}\n" for k in range(n))
    i = text.find("OFFSET")
    j = text.find("\n", text.find("CHANNELS", i))
    return text[: j + 1] + fan + text[j + 1 :]


def b_rename(text: str, rng: random.Random) -> str:
    ms = list(re.finditer(r"(JOINT|ROOT)[ \t]+(\S+)", text))
    m = rng.choice(ms)
    name = rng.choice(NAMES)
    if rng.random() < 0.3:  # a duplicate of another joint
        name = rng.choice(ms).group(2)
    return text[: m.start(2)] + name + text[m.end(2) :]


def b_more_rows(text: str, rng: random.Random) -> str:
    head, _, data = text.partition("Frame Time:")
    first, _, rows = data.partition("\n")
    rows_l = [r for r in rows.split("\n") if r.strip()]
    if not rows_l:
        return text
    k = rng.choice([2, 10, 50])
    return head + "Frame Time:" + first + "\n" + "\n".join(rows_l * k) + "\n"


BVH_MUTATORS = [
    t_replace_number,
    t_delete_line,
    t_duplicate_line,
    t_swap_lines,
    t_insert_token,
    t_line_endings,
    b_header,
    b_header,
    b_zero_channels,
    b_deepen,
    b_many_joints,
    b_rename,
    b_more_rows,
]


def c3d_word(data: bytes, rng: random.Random) -> bytes:
    """Overwrite a 16-bit word or a float of the header or the parameter section."""
    b = bytearray(data)
    where = rng.choice([rng.randrange(0, 512, 2), rng.randrange(512, min(len(b), 512 * 8), 2)])
    if rng.random() < 0.5:
        struct.pack_into("<h", b, where, rng.choice([0, 1, -1, 32767, -32768, 255, 2]))
    else:
        struct.pack_into(
            "<f",
            b,
            min(where, len(b) - 4),
            rng.choice([0.0, -1.0, 1e30, float("nan"), float("inf"), 1e-30, 1e6]),
        )
    return bytes(b)


C3D_MUTATORS = [m_flip_byte, m_truncate, m_append_junk, c3d_word, c3d_word, c3d_word]


def trc_field(text: str, rng: random.Random) -> str:
    ls = _lines(text)
    i = rng.choice([1, 2, 2, 3, 4] + [rng.randrange(5, len(ls))] * 3)
    sep = "," if "," in ls[i] else "\t"
    fields = ls[i].split(sep)
    k = rng.randrange(len(fields))
    fields[k] = rng.choice(GARBAGE + ["0.001", "1e6", "100000", "abc"])
    ls[i] = sep.join(fields)
    return "\n".join(ls)


TRC_MUTATORS = [
    trc_field,
    trc_field,
    t_delete_line,
    t_duplicate_line,
    t_replace_number,
    t_line_endings,
]


def eaf_xml(text: str, rng: random.Random) -> str:
    """ELAN: property values, time slot values and references, annotation ids, nesting."""
    op = rng.randrange(6)
    if op == 0:
        return re.sub(
            r'(<PROPERTY NAME="(fps|frames)">)[^<]*',
            lambda m: m.group(1) + rng.choice(GARBAGE),
            text,
            count=1,
        )
    if op == 1:
        ms = list(re.finditer(r'TIME_VALUE="[^"]*"', text)) or [None]
        m = rng.choice(ms)
        if m is None:
            return text
        return text[: m.start()] + f'TIME_VALUE="{rng.choice(GARBAGE)}"' + text[m.end() :]
    if op == 2:
        return re.sub(r'TIME_SLOT_REF[12]="\w+"', 'TIME_SLOT_REF1="ts999"', text, count=1)
    if op == 3:
        return re.sub(r"<TIME_SLOT [^>]*/>", "", text, count=rng.randint(1, 3))
    if op == 4:
        n = rng.choice([10, 1000, 100_000])
        return text.replace("<TIER", "<X>" * n + "</X>" * n + "<TIER", 1)
    return re.sub(
        r"<ANNOTATION_VALUE>[^<]*",
        "<ANNOTATION_VALUE>" + rng.choice(["wiggle", "", "S", "rest", "<", "2H", "\x0b"]),
        text,
        count=1,
    )


EAF_MUTATORS = [eaf_xml, eaf_xml, eaf_xml, t_delete_line, t_swap_lines, t_replace_number]

JSON_GARBAGE = [
    '"../../../../etc/passwd"',
    "[" * 5000,
    "{" * 5000,
    "1e999",
    "NaN",
    "Infinity",
    "true",
    "null",
    "[]",
    "{}",
    '"\\u0000"',
    '"\\ud800"',
    "-1",
    "0.01",
    "1000",
    '"<script>alert(1)</script>"',
    '{"a":' * 3000 + "1" + "}" * 3000,
]


def j_value(text: str, rng: random.Random) -> str:
    ms = list(re.finditer(r'(?<=: )("[^"]*"|[-\d.eE]+|true|false|null|\{|\[)', text))
    if not ms:
        return text
    m = rng.choice(ms)
    if m.group(0) in "{[":
        return text[: m.start()] + rng.choice(JSON_GARBAGE) + ", " + text[m.start() :]
    return text[: m.start()] + rng.choice(JSON_GARBAGE) + text[m.end() :]


def j_nest(text: str, rng: random.Random) -> str:
    n = rng.choice([50, 1000, 100_000])
    return '{"a":' * n + text + "}" * n


JSON_MUTATORS = [j_value, j_value, j_value, j_nest, t_delete_line, t_swap_lines]


def mutate(
    seed: bytes, mutators, rng: random.Random, binary: bool = False, limit: int = MAX_CASE_BYTES
) -> tuple[bytes, list]:
    """1-4 mutations of ``seed``; a step that would make the file ``limit`` bytes or more is
    skipped (the promise under test is about files under 1 MB)."""
    data, used = seed, []
    for _ in range(rng.randint(1, 4)):
        fn = rng.choice(mutators + [m_flip_byte] * (1 if rng.random() < 0.15 else 0))
        try:
            if fn.__name__.startswith("m_") or binary:
                new = fn(data, rng)
            else:
                new = fn(data.decode("utf-8", "replace"), rng).encode("utf-8")
        except (IndexError, ValueError, struct.error):  # nothing for it to act on
            continue
        if len(new) < limit or len(seed) >= limit:
            data = new
            used.append(fn.__name__)
    return data, used


# ---------------------------------------------------------------- seeds


def session_seeds() -> list[str]:
    return [
        json.dumps(
            {
                "format": "handsplice-session",
                "version": 1,
                "inputs": {"body": {"path": "body.bvh"}, "hand": {"path": "hand.bvh"}},
                "side": "right",
                "band": 0.3,
                "refine_band": 0.1,
                "tolerance": 2,
                "points": [
                    {"body": 10, "hand": 12, "tolerance": None},
                    {"body": 40, "hand": 35, "tolerance": 1.5},
                ],
                "roles": {"body": {"right.wrist": "RightHand"}},
                "view": {"matrix": "pass1", "frame": 3},
            },
            indent=2,
        ),
        json.dumps({"inputs": {"sample": "demo"}, "side": "both", "band": 1}, indent=1),
    ]


def roles_seeds() -> list[str]:
    return [
        json.dumps({"right.wrist": "rHand", "right.index1": "rIndex1"}, indent=1),
        json.dumps(
            {"body": {"right.wrist": "RightHand"}, "hand": {"right.wrist": "rHand"}}, indent=1
        ),
    ]


def eaf_seed() -> str:
    from engine.gesture.phases import segment_phases
    from engine.io.bvh import read_bvh
    from engine.io.eaf import write_eaf

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "seed.eaf"
        write_eaf(p, segment_phases(read_bvh(BVH_SEEDS["body"])), source="body.bvh")
        return p.read_text(encoding="utf-8")


# ---------------------------------------------------------------- cases (run in the runner)


def _peak_reset() -> None:
    with contextlib.suppress(OSError):
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")


def _peak_mb() -> float:
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    return 0.0


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def run_case(case: dict) -> dict:
    """One case, in the runner process: returns {"outcome", "detail", "peak_mb"}."""
    from engine.base.errors import HandSpliceError, MotionFormatError, ParameterError

    folder = Path(case["folder"])
    inputs = _snapshot(folder)
    target, path = case["target"], folder / case["name"]
    outputs: list[str] = []
    _peak_reset()
    outcome, detail = "ok", ""
    try:
        if target == "cli":
            outcome, detail, outputs = _run_cli(case, folder)
        else:
            expected: tuple = (MotionFormatError,)
            if target == "bvh":
                from engine.io.bvh import read_bvh as call
            elif target == "c3d":
                from engine.io.c3d import read_c3d as call
            elif target == "trc":
                from engine.io.trc import read_trc as call
            elif target == "eaf":
                from engine.io.eaf import read_eaf as call

                expected = (MotionFormatError, ParameterError)
            elif target == "session":
                from engine.io.session import SessionError
                from engine.io.session import read_session as call

                expected = (SessionError,)
            elif target == "roles":
                from engine.model.roles import load_role_overrides as call

                expected = (ParameterError,)
            elif target == "upload":
                from webapp.config import AppConfig
                from webapp.uploads import UploadError, store

                cfg = AppConfig(upload_dir=folder / "uploads")

                def call(p, cfg=cfg):
                    digest, _ = store(cfg, p.name, p.read_bytes())
                    outputs.append(f"uploads/{digest}{p.suffix.lower()}")

                expected = (UploadError,)
            else:
                raise ValueError(target)
            try:
                call(path)
            except expected as exc:
                outcome, detail = "refused", str(exc)
                if "\n" in str(exc).strip():
                    outcome, detail = "traceback", f"multi-line message: {str(exc)[:200]!r}"
    except MemoryError:
        outcome, detail = "over 1 GB", "MemoryError"
    except HandSpliceError as exc:  # an error class not documented for this target
        outcome, detail = "traceback", f"{type(exc).__name__}: {str(exc)[:200]}"
    except Exception as exc:
        import traceback

        tb = traceback.extract_tb(exc.__traceback__)
        where = f"{Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
        outcome, detail = "traceback", f"{type(exc).__name__}: {str(exc)[:160]} [{where}]"
    peak = _peak_mb()
    after = _snapshot(folder)
    allowed = set(inputs) | (set(outputs) if outcome == "ok" else set())
    stray = sorted(set(after) - allowed)
    changed = [k for k in inputs if after.get(k) != inputs[k]]
    if (stray or changed) and outcome not in ("traceback", "over 1 GB"):
        outcome = "stray file"
        detail = f"left {stray[:3]} changed {changed[:3]}"
    return {"outcome": outcome, "detail": detail, "peak_mb": peak}


def _run_cli(case: dict, folder: Path) -> tuple[str, str, list[str]]:
    from engine.cli import main

    argv = [a.replace("{dir}", str(folder)) for a in case["argv"]]
    err = io.StringIO()
    out = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        status = main(argv)
    text = err.getvalue().strip()
    lines = [ln for ln in text.splitlines() if ln.startswith("handsplice")]
    if status == 0:
        return "ok", "", list(case.get("outputs", []))
    if "needs more memory" in text:
        return "over 1 GB", text[:200], []
    if (
        status == 2
        and len(lines) == 1
        and lines[0].startswith("handsplice: error: ")
        and "Traceback" not in text
    ):
        return "refused", lines[0], []
    return "traceback", f"exit {status}: {text[-300:]!r}", []


# ---------------------------------------------------------------- the bench


def build_cases(n: int, rng: random.Random, work: Path) -> list[dict]:
    """``n`` cases spread over the targets (CLI runs are the slow ones: fewer)."""
    seeds_bvh = {k: p.read_bytes() for k, p in BVH_SEEDS.items()}
    c3d = C3D_SEED.read_bytes()
    trc = TRC_SEED.read_bytes()
    eaf = eaf_seed().encode("utf-8")
    sessions = [s.encode() for s in session_seeds()]
    roles = [s.encode() for s in roles_seeds()]
    have_upload = _upload_available()
    shares = {
        "bvh": 0.34,
        "c3d": 0.10,
        "trc": 0.11,
        "eaf": 0.10,
        "session": 0.09,
        "roles": 0.07,
        "upload": 0.08 if have_upload else 0.0,
        "cli": 0.07,
    }
    total = sum(shares.values())
    cases: list[dict] = []
    counts = {t: max(1, round(n * s / total)) for t, s in shares.items() if s}
    counts["bvh"] += n - sum(counts.values())
    for target, k in counts.items():
        for i in range(k):
            folder = work / f"{target}-{i:05d}"
            folder.mkdir(parents=True)
            case = {"target": target, "folder": str(folder), "id": f"{target}-{i}"}
            if target == "bvh":
                seed = pick_bvh(rng)
                data, used = mutate(seeds_bvh[seed], BVH_MUTATORS, rng)
                case.update(name="take.bvh", seed=seed)
            elif target == "c3d":
                data, used = mutate(c3d, C3D_MUTATORS, rng, binary=True)
                case.update(name="take.c3d", seed="c3d")
            elif target == "trc":
                data, used = mutate(trc, TRC_MUTATORS, rng)
                case.update(name="take.trc", seed="trc")
            elif target == "eaf":
                data, used = mutate(eaf, EAF_MUTATORS, rng)
                case.update(name="phases.eaf", seed="eaf")
            elif target == "session":
                data, used = mutate(rng.choice(sessions), JSON_MUTATORS, rng)
                case.update(name="session.json", seed="session")
            elif target == "roles":
                data, used = mutate(rng.choice(roles), JSON_MUTATORS, rng)
                case.update(name="roles.json", seed="roles")
            elif target == "upload":
                kind = rng.choice(["bvh", "bvh", "c3d", "trc"])
                if kind == "bvh":
                    data, used = mutate(seeds_bvh[pick_bvh(rng)], BVH_MUTATORS, rng)
                elif kind == "c3d":
                    data, used = mutate(c3d, C3D_MUTATORS, rng, binary=True)
                else:
                    data, used = mutate(trc, TRC_MUTATORS, rng)
                case.update(name=f"up load.{kind}", seed=kind)
            else:
                data, used = _cli_case(case, rng, seeds_bvh, c3d, trc, sessions, roles, folder)
            case["mutators"] = used
            (folder / case["name"]).write_bytes(data)
            cases.append(case)
    rng.shuffle(cases)
    return cases


def _cli_case(case, rng, seeds_bvh, c3d, trc, sessions, roles, folder) -> tuple[bytes, list]:
    """A command on a mutated file; the partners of a splice are real takes (copied in)."""
    cmd = rng.choices(["info", "analyze", "splice", "render"], weights=[40, 25, 25, 10])[0]
    d = "{dir}"
    if cmd == "info":
        kind = rng.choice(["bvh", "bvh", "c3d", "trc"])
        seed = {"c3d": c3d, "trc": trc}.get(kind) or seeds_bvh[pick_bvh(rng)]
        data, used = mutate(
            seed,
            {"bvh": BVH_MUTATORS, "c3d": C3D_MUTATORS, "trc": TRC_MUTATORS}[kind],
            rng,
            binary=kind == "c3d",
        )
        case.update(name=f"take.{kind}", argv=["info", f"{d}/take.{kind}"])
        if rng.random() < 0.3:
            case["argv"].append("--json")
        return data, used
    if cmd == "analyze":
        data, used = mutate(seeds_bvh[rng.choice(["body", "beat"])], BVH_MUTATORS, rng)
        case.update(
            name="take.bvh",
            argv=[
                "analyze",
                f"{d}/take.bvh",
                "--eaf",
                f"{d}/phases.eaf",
                "--csv",
                f"{d}/phases.csv",
            ],
            outputs=["phases.eaf", "phases.csv"],
        )
        return data, used
    if cmd == "render":
        data, used = mutate(seeds_bvh[pick_bvh(rng)], BVH_MUTATORS, rng)
        case.update(
            name="take.bvh",
            argv=["render", f"{d}/take.bvh", "-o", f"{d}/out.png", "--size", "64x48", "--quiet"],
            outputs=["out.png"],
        )
        return data, used
    # splice: mutate the hand, the body, the session or the roles
    what = rng.choice(["hand", "body", "session", "roles"])
    body = seeds_bvh["body"]
    hand = seeds_bvh[rng.choice(["hand", "hand2"])]
    outputs = ["out.bvh", "out.json"]
    argv = [
        "splice",
        f"{d}/body.bvh",
        f"{d}/hand.bvh",
        "-o",
        f"{d}/out.bvh",
        "--report",
        f"{d}/out.json",
        "--quiet",
        "--side",
        "right",
    ]
    if what == "hand":
        data, used = mutate(hand, BVH_MUTATORS, rng)
        (folder / "body.bvh").write_bytes(body)
        case.update(name="hand.bvh")
    elif what == "body":
        data, used = mutate(body, BVH_MUTATORS, rng)
        (folder / "hand.bvh").write_bytes(hand)
        case.update(name="body.bvh")
    else:
        (folder / "body.bvh").write_bytes(body)
        (folder / "hand.bvh").write_bytes(hand)
        seed = rng.choice(sessions if what == "session" else roles)
        data, used = mutate(seed, JSON_MUTATORS, rng)
        case.update(name=f"{what}.json")
        argv += [f"--{what}", f"{d}/{what}.json"]
    case.update(argv=argv, outputs=outputs)
    return data, used


def _upload_available() -> bool:
    try:
        from webapp import uploads  # noqa: F401
        from webapp.config import AppConfig  # noqa: F401
    except ImportError:
        return False
    return hasattr(uploads, "store")


def run_in_lane(case: dict) -> dict:
    from engine.jobs.sandbox import ChildFailed, LimitExceeded, run_limited

    seconds = CLI_SECONDS if case["target"] == "cli" else READER_SECONDS
    t0 = time.monotonic()
    try:
        res = run_limited(run_case, (case,), seconds=seconds, memory_mb=ONE_GB_MB)
    except LimitExceeded as exc:
        kind = "hang" if "time limit" in str(exc) else "over 1 GB"
        res = {"outcome": kind, "detail": str(exc), "peak_mb": float("nan")}
    except ChildFailed as exc:
        kind = "crash" if "died" in str(exc) else "traceback"
        res = {"outcome": kind, "detail": str(exc), "peak_mb": float("nan")}
    res["seconds"] = time.monotonic() - t0
    size = (Path(case["folder"]) / case["name"]).stat().st_size
    if res["outcome"] == "over 1 GB" and size >= 2**20:
        res["outcome"] = "refused"  # the promise covers files under 1 MB
        res["detail"] = f"(file of {size} bytes) " + res["detail"]
    # a stopped case may leave its partial outputs only as stale temporaries: cleaned next
    if res["outcome"] in ("hang", "over 1 GB", "crash"):
        from engine.base.atomic import clean_stale

        clean_stale(case["folder"])
    return res


def subprocess_runs(k: int, rng: random.Random, work: Path) -> list[dict]:
    """The real command line in child processes, with the peak RSS of each."""
    issue = {
        "frame-time-300 splice": (
            "hand",
            lambda t: re.sub(r"Frame Time:\s*\S+", "Frame Time: 300", t),
            "splice",
        ),
        "frame-time-1e6 splice": (
            "hand",
            lambda t: re.sub(r"Frame Time:\s*\S+", "Frame Time: 1e6", t),
            "splice",
        ),
        "frame-time-100 info": (
            "hand",
            lambda t: re.sub(r"Frame Time:\s*\S+", "Frame Time: 100", t),
            "info",
        ),
        "zero-channels-2M info": (
            "body",
            lambda t: (
                re.sub(r"CHANNELS \d[^\n]*", "CHANNELS 0", t.split("MOTION")[0])
                + "MOTION\nFrames: 2000000\nFrame Time: 0.0333333\n"
            ),
            "info",
        ),
        "zero-channels-2M analyze": (
            "body",
            lambda t: (
                re.sub(r"CHANNELS \d[^\n]*", "CHANNELS 0", t.split("MOTION")[0])
                + "MOTION\nFrames: 2000000\nFrame Time: 0.0333333\n"
            ),
            "analyze",
        ),
        "1000 zero-channel joints info": ("hand", lambda t: _fan_text(1000, 1_000_000), "info"),
    }
    runs = []
    names = list(issue)
    for i in range(k):
        folder = work / f"sub-{i:03d}"
        folder.mkdir(parents=True)
        if i < len(names):
            label = names[i]
            seed, fn, cmd = issue[label]
            text = fn(BVH_SEEDS[seed].read_text())
        else:
            cmd = rng.choice(["info", "info", "analyze"])
            seed = rng.choice(list(BVH_SEEDS))
            data, used = mutate(BVH_SEEDS[seed].read_bytes(), BVH_MUTATORS, rng)
            text = data.decode("utf-8", "replace")
            label = f"{cmd} {seed} " + "+".join(used)
        take = folder / "take.bvh"
        take.write_text(text, encoding="utf-8")
        argv = [sys.executable, "-m", "engine.cli", cmd, str(take)]
        if cmd == "splice":
            (folder / "body.bvh").write_bytes(BVH_SEEDS["body"].read_bytes())
            argv = [
                sys.executable,
                "-m",
                "engine.cli",
                "splice",
                str(folder / "body.bvh"),
                str(take),
                "-o",
                str(folder / "out.bvh"),
                "--quiet",
            ]
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        t0 = time.monotonic()
        # a small intermediate interpreter starts the command and reads its peak RSS
        # (ru_maxrss of a child forked from this big process would count our pages)
        probe = subprocess.run(
            [sys.executable, "-c", _PROBE, json.dumps(argv), str(CLI_SECONDS)],
            capture_output=True,
            text=True,
            env=env,
            cwd=folder,
        )
        status, peak_kb, signalled, err = json.loads(probe.stdout)
        peak = peak_kb / 1024.0
        lines = [ln for ln in err.strip().splitlines() if ln.startswith("handsplice")]
        if signalled:
            outcome = "hang" if time.monotonic() - t0 >= CLI_SECONDS else "crash"
        elif status == 0:
            outcome = "ok"
        elif status == 2 and len(lines) == 1 and "Traceback" not in err:
            outcome = "refused"
        else:
            outcome = "traceback"
        if "needs more memory" in err or (peak > ONE_GB_MB and take.stat().st_size < 2**20):
            outcome = "over 1 GB"
        left = sorted(
            str(q.relative_to(folder))
            for q in folder.rglob("*")
            if q.is_file() and q.name not in ("take.bvh", "body.bvh", "out.bvh")
        )
        if left and outcome in ("ok", "refused"):
            outcome = "stray file"
        runs.append(
            {
                "label": label,
                "outcome": outcome,
                "peak_mb": peak,
                "size": take.stat().st_size,
                "detail": err.strip()[-200:],
                "seconds": time.monotonic() - t0,
            }
        )
    return runs


_PROBE = """
import json, resource, subprocess, sys
try:
    p = subprocess.run(json.loads(sys.argv[1]), capture_output=True, text=True,
                       timeout=float(sys.argv[2]))
    status, err = p.returncode, p.stderr
except subprocess.TimeoutExpired as exc:
    status, err = -9, str(exc)
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(json.dumps([status, peak, status < 0, err]))
"""


def _fan_text(joints: int, frames: int) -> str:
    lines = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 0"]
    for j in range(joints - 1):
        lines += [f"JOINT j{j}", "{", "OFFSET 0 1 0", "CHANNELS 0", "}"]
    lines += ["}", "MOTION", f"Frames: {frames}", "Frame Time: 0.0333333"]
    return "\n".join(lines) + "\n"


def warm_up() -> None:
    """Import and compile in this process before the lanes fork (one splice, one analyze)."""
    from engine.gesture.phases import segment_phases
    from engine.io.bvh import read_bvh
    from engine.splice import pipeline

    body, hand = read_bvh(BVH_SEEDS["body"]), read_bvh(BVH_SEEDS["hand"])
    pipeline.splice(body, hand, side="right")
    segment_phases(body)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=2400)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--subprocess", type=int, default=40)
    ap.add_argument("--keep", action="store_true", help="keep the case folders")
    ap.add_argument("--record", action="store_true", help="write the table to RESULTS.md")
    args = ap.parse_args(argv)
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="handsplice-fuzz-"))
    t0 = time.monotonic()
    try:
        print(f"bench_fuzz: building {args.cases} cases in {work}", flush=True)
        cases = build_cases(args.cases, rng, work)
        sizes = [(Path(c["folder"]) / c["name"]).stat().st_size for c in cases]
        print("bench_fuzz: warming up (imports, numba) ...", flush=True)
        warm_up()
        results: list[tuple[dict, dict]] = []
        lock = threading.Lock()
        queue = list(cases)

        def lane() -> None:
            while True:
                with lock:
                    if not queue:
                        return
                    case = queue.pop()
                res = run_in_lane(case)
                with lock:
                    results.append((case, res))
                    n = len(results)
                    if res["outcome"] not in ("ok", "refused"):
                        print(
                            f"  FAIL {case['id']} {res['outcome']}: {res['detail'][:240]} "
                            f"(mutators {case['mutators']})",
                            flush=True,
                        )
                    if n % 100 == 0:
                        print(
                            f"  {n}/{len(cases)} cases, {time.monotonic() - t0:.0f} s", flush=True
                        )

        threads = [threading.Thread(target=lane) for _ in range(max(1, args.jobs))]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        sub = subprocess_runs(args.subprocess, rng, work / "sub") if args.subprocess else []
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    seconds = time.monotonic() - t0
    table = report(results, sub, sizes, seconds, args)
    print(table)
    if args.record:
        from benchmarks._results import write_section

        write_section("fuzz", table)
    failures = sum(1 for _, r in results if r["outcome"] in KINDS) + sum(
        1 for r in sub if r["outcome"] in KINDS
    )
    return 1 if failures else 0


def report(results, sub, sizes, seconds, args) -> str:
    by_target: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    peaks: dict[str, float] = collections.defaultdict(float)
    secs: dict[str, list] = collections.defaultdict(list)
    for case, res in results:
        by_target[case["target"]][res["outcome"]] += 1
        secs[case["target"]].append(res["seconds"])
        if res["peak_mb"] == res["peak_mb"]:
            peaks[case["target"]] = max(peaks[case["target"]], res["peak_mb"])
    cols = ["ok", "refused", *KINDS]
    lines = [
        f"Fuzz bench (`benchmarks/bench_fuzz.py --cases {args.cases} --jobs {args.jobs} "
        f"--seed {args.seed} --subprocess {args.subprocess}`): {len(results)} in-process "
        f"cases + {len(sub)} command-line processes in {seconds / 60:.1f} min; inputs "
        f"{min(sizes)}-{max(sizes)} bytes (median {sorted(sizes)[len(sizes) // 2]}).",
        "",
        "| target | cases | " + " | ".join(cols) + " | peak RSS MB | mean s |",
        "|---|---:|" + "---:|" * len(cols) + "---:|---:|",
    ]
    total = collections.Counter()
    for target in sorted(by_target):
        c = by_target[target]
        total += c
        mean = sum(secs[target]) / len(secs[target])
        lines.append(
            f"| {target} | {sum(c.values())} | "
            + " | ".join(str(c[k]) for k in cols)
            + f" | {peaks[target]:.0f} | {mean:.2f} |"
        )
    sc = collections.Counter(r["outcome"] for r in sub)
    if sub:
        total += sc
        lines.append(
            f"| CLI processes | {len(sub)} | "
            + " | ".join(str(sc[k]) for k in cols)
            + f" | {max(r['peak_mb'] for r in sub):.0f} | "
            f"{sum(r['seconds'] for r in sub) / len(sub):.2f} |"
        )
    lines.append(
        f"| **all** | **{sum(total.values())}** | "
        + " | ".join(f"**{total[k]}**" for k in cols)
        + " | | |"
    )
    if sub:
        lines += [
            "",
            "The issue's cases as real command-line processes (peak RSS of the child):",
            "",
            "| case | outcome | peak RSS MB | message |",
            "|---|---|---:|---|",
        ]
        for r in sub[:6]:
            msg = r["detail"].splitlines()[-1] if r["detail"] else ""
            lines.append(
                f"| {r['label']} | {r['outcome']} | {r['peak_mb']:.0f} | "
                f"{msg[:110].replace('|', '/')} |"
            )
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
