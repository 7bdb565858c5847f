"""The upload folder: quota, no symlinks followed, no file contents echoed, the check's
budget, chunked receiving, and ``handsplice serve BODY HAND``'s pair."""

from __future__ import annotations

import asyncio
import dataclasses
import multiprocessing
import os
import re
import time
from pathlib import Path

import pytest

from engine.io.bvh import read_bvh, write_bvh
from webapp import config, uploads
from webapp.state import Session

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
HAND = MOCAP / "gestification" / "hello-world.bvh"
BODY = MOCAP / "bandai-namco" / "dataset-1_bye_normal_001.bvh"


@pytest.fixture(scope="module")
def takes(tmp_path_factory) -> list[bytes]:
    """Five different small valid BVH files (real hand take, different lengths)."""
    folder = tmp_path_factory.mktemp("takes")
    hand = read_bvh(HAND)
    out = []
    for k in range(5):
        path = folder / f"hand{k}.bvh"
        write_bvh(hand.frames(0, 20 + k), path)
        out.append(path.read_bytes())
    return out


@pytest.fixture()
def cfg(tmp_path, sample_dir) -> config.AppConfig:
    return config.AppConfig(
        sample_dir=sample_dir.resolve(),
        upload_dir=(tmp_path / "uploads").resolve(),
        max_upload_bytes=4 * 2**20,
        max_upload_files=3,
        max_upload_total_bytes=10 * 2**20,
    )


def _kept(cfg) -> list[str]:
    return sorted(p.name for p in cfg.upload_dir.iterdir())


def _age(cfg, digest: str, seconds_ago: float) -> None:
    path = cfg.upload_dir / f"{digest}.bvh"
    if path.exists():  # not removed by the quota yet
        t = time.time() - seconds_ago
        os.utime(path, (t, t))


def test_quota_keeps_at_most_n_files_oldest_removed_first(cfg, takes):
    digests = []
    for k, data in enumerate(takes):
        digest, _ = uploads.store(cfg, f"take{k}.bvh", data)
        digests.append(digest)
        for age, d in enumerate(reversed(digests)):  # older uploads look older
            _age(cfg, d, 100.0 * age)
    assert _kept(cfg) == sorted(f"{d}.bvh" for d in digests[-3:])


def test_quota_counts_bytes(cfg, takes):
    size = max(len(d) for d in takes)
    small = dataclasses.replace(cfg, max_upload_files=100, max_upload_total_bytes=int(2.5 * size))
    digests = []
    for k, data in enumerate(takes[:4]):
        digest, _ = uploads.store(small, f"take{k}.bvh", data)
        digests.append(digest)
        for age, d in enumerate(reversed(digests)):
            _age(small, d, 100.0 * age)
    kept = _kept(small)
    assert kept == sorted(f"{d}.bvh" for d in digests[-2:])
    assert sum((small.upload_dir / k).stat().st_size for k in kept) <= 2.5 * size


def test_an_upload_in_use_is_removed_last(cfg, takes):
    digests = []
    for k, data in enumerate(takes[:3]):
        digests.append(uploads.store(cfg, f"take{k}.bvh", data)[0])
        for age, d in enumerate(reversed(digests)):
            _age(cfg, d, 100.0 * age)
    uploads.path_for(cfg, digests[0])  # opened again (a session or a link): now recent
    uploads.store(cfg, "new.bvh", takes[3])
    kept = _kept(cfg)
    assert f"{digests[0]}.bvh" in kept and f"{digests[1]}.bvh" not in kept


def test_symlinks_in_the_upload_folder_are_not_followed(cfg, takes, tmp_path):
    secret = tmp_path / "secret.bvh"
    secret.write_text("root:x:0:0:TOP-SECRET-LINE:/root:/bin/bash\n")
    cfg.upload_dir.mkdir(parents=True)
    fake = "ab" * 32
    (cfg.upload_dir / f"{fake}.bvh").symlink_to(secret)
    with pytest.raises(uploads.UploadError) as info:
        uploads.path_for(cfg, fake)
    message = str(info.value)
    assert "not a regular file" in message and "TOP-SECRET" not in message
    assert str(secret) not in message

    # a session (a link naming that hash) is refused with one line, nothing read
    s = Session(cfg)
    with pytest.raises(uploads.UploadError):
        s.apply_spec(_spec(fake, fake))
    assert "TOP-SECRET" not in s.error

    # the quota neither follows nor removes the link, and the target is untouched
    for k, data in enumerate(takes):
        uploads.store(cfg, f"take{k}.bvh", data)
    assert (cfg.upload_dir / f"{fake}.bvh").is_symlink()
    assert "TOP-SECRET" in secret.read_text()


def test_a_planted_link_at_the_kept_name_is_replaced_not_written_through(cfg, takes, tmp_path):
    target = tmp_path / "victim.txt"
    target.write_text("keep me")
    digest = uploads.sha256(takes[0])
    cfg.upload_dir.mkdir(parents=True)
    (cfg.upload_dir / f"{digest}.bvh").symlink_to(target)
    assert uploads.store(cfg, "take.bvh", takes[0])[0] == digest
    kept = cfg.upload_dir / f"{digest}.bvh"
    assert not kept.is_symlink() and kept.read_bytes() == takes[0]
    assert target.read_text() == "keep me"


def _spec(body: str, hand: str):
    from engine.io.session import SessionSpec, TakeRef

    return SessionSpec(
        body=TakeRef(sha256=body, name="b.bvh"), hand=TakeRef(sha256=hand, name="h.bvh")
    )


def test_errors_never_echo_file_contents_at_length(cfg):
    line = "SECRET-" + "x" * 300
    bad = (
        f"HIERARCHY\nROOT Hips\n{{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation "
        f"Zrotation\n {line}\n}}\n"
    ).encode()
    with pytest.raises(uploads.UploadError) as info:
        uploads.store(cfg, "leak.bvh", bad)
    message = str(info.value)
    assert message.startswith("leak.bvh") and "\n" not in message
    assert line not in message
    quoted = re.findall(r"'[^']*'", message)
    assert all(len(q) <= uploads.QUOTE_CHARS for q in quoted), message


def test_the_check_runs_within_a_time_budget_off_the_event_loop(cfg):
    """A file whose reading never ends (a FIFO nobody writes to) is refused when the budget
    runs out and its reader is stopped, while an event loop (the server's) keeps ticking."""
    budget = 1.5
    slow = dataclasses.replace(cfg, upload_check_seconds=budget)
    cfg.upload_dir.mkdir(parents=True)
    fifo = cfg.upload_dir / ".part-fifo.bvh"
    os.mkfifo(fifo)
    staged = uploads.Staged(fifo, "endless.bvh", 1)

    async def run():
        gaps, done = [], asyncio.Event()

        async def tick():
            last = time.perf_counter()
            while not done.is_set():
                await asyncio.sleep(0.005)
                now = time.perf_counter()
                gaps.append(now - last)
                last = now

        ticker = asyncio.create_task(tick())
        loop = asyncio.get_running_loop()
        t0 = time.perf_counter()
        try:
            with pytest.raises(uploads.UploadError, match="budget") as info:
                await loop.run_in_executor(None, uploads.check, slow, staged)
        finally:
            done.set()
            await ticker
        return gaps, time.perf_counter() - t0, str(info.value)

    gaps, seconds, message = asyncio.run(run())
    assert message == (
        "endless.bvh: reading it took longer than the server's 1.5 s budget for one file"
    )
    assert seconds >= budget and len(gaps) > 50 and max(gaps) < budget / 2, max(gaps)
    assert not [p for p in multiprocessing.active_children() if p.name == "hs-upload-check"]
    assert not fifo.exists()  # the staging entry is gone
    assert not list(cfg.upload_dir.glob("*.bvh"))  # nothing kept


def test_the_check_runs_within_a_memory_budget(cfg):
    """A take whose arrays do not fit the budget (a 2.7 MB, 3,945-frame real take in 64 MiB
    of address space, less than the reader's own process holds) is refused, not kept."""
    tight = dataclasses.replace(cfg, upload_check_bytes=64 * 2**20)
    with pytest.raises(uploads.UploadError, match="memory budget"):
        uploads.store(tight, "long.bvh", (MOCAP / "lafan1" / "dance1_subject1.bvh").read_bytes())
    assert not list(cfg.upload_dir.glob("*.bvh"))


def test_chunks_go_to_disk_and_the_limit_stops_them(cfg):
    data = BODY.read_bytes()
    incoming = uploads.Incoming(cfg, "C:\\Users\\me\\body.bvh")
    assert incoming.name == "body.bvh"
    for k in range(0, len(data), 40_000):
        incoming.write(data[k : k + 40_000])
    kept = uploads.check(cfg, incoming.finish())
    assert kept.path.read_bytes() == data and kept.summary["kind"] == "skeleton"
    assert kept.summary["frames"] == read_bvh(BODY).n_frames

    over = uploads.Incoming(cfg, "big.bvh")
    with pytest.raises(uploads.UploadError, match="upload limit"):
        for _ in range(5):
            over.write(b" " * 2**20)
    assert not list(cfg.upload_dir.glob(".part-*"))
    with pytest.raises(uploads.UploadError, match=r"expected a \.bvh, \.c3d or \.trc"):
        uploads.Incoming(cfg, "notes.txt")


def test_stale_staging_files_are_removed(cfg, takes):
    cfg.upload_dir.mkdir(parents=True)
    stale = cfg.upload_dir / ".part-0123.bvh"
    stale.write_bytes(b"half")
    old = time.time() - 2 * uploads.STALE_STAGING_S
    os.utime(stale, (old, old))
    fresh = cfg.upload_dir / ".part-4567.bvh"  # another upload in progress
    fresh.write_bytes(b"half")
    uploads.store(cfg, "take.bvh", takes[0])
    assert not stale.exists() and fresh.exists()


def test_serve_body_hand_opens_the_pair_first(tmp_path, sample_dir):
    pair = config.local_pair(BODY, HAND, "right")
    cfg = config.configure(sample_dir=sample_dir, upload_dir=tmp_path / "up", local=pair)
    try:
        assert cfg.default_sample == pair.name == f"{BODY.name} + {HAND.name}"
        assert cfg.samples()[0] == pair
        s = Session(cfg)
        s.load_sample(cfg.default_sample)
        assert s.error == "" and s.n == read_bvh(BODY).n_frames
    finally:
        config.configure(sample_dir=sample_dir)


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["serve", str(BODY)], "both BODY and HAND"),
        (["serve", str(BODY), "missing.bvh"], "HAND missing.bvh: no such file"),
        (["serve", str(BODY), __file__], "expected a .bvh, .c3d or .trc"),
        (["serve", str(BODY), str(HAND), "--sample", "wave-ok"], "give one"),
    ],
)
def test_serve_body_hand_bad_arguments_exit_2(argv, needle, capsys):
    from engine.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1, err


def test_a_long_file_name_is_kept_whole_for_the_command_line():
    """The page's command line names the user's file: a name as long as a file system
    allows is kept whole (only the folder part of a client path is dropped)."""
    import shlex

    from webapp import backend

    long = "take-" + "x" * 240 + ".bvh"  # 249 characters: a real file's name
    assert uploads.display_name(long) == long
    assert uploads.display_name("C:\\takes\\" + long) == long
    cmd = backend.cli_command(long, "hand.bvh", "right", 0.3, 0.1, [])
    assert shlex.split(cmd)[2] == long
    absurd = "y" * 1000 + ".bvh"  # no file system holds such a name
    shown = uploads.display_name(absurd)
    assert len(shown) == uploads.MAX_NAME_CHARS and "…" in shown and shown.endswith(".bvh")


def test_opening_an_upload_again_finds_its_pair_still_prepared(cfg):
    """The page prepares a pair as its second take is checked, then the session opens it
    by hash (``path_for``, which marks both files used): that must find the same features,
    not read and compute both takes again (the file's modification time, which the cache
    knows it by, stays; the quota's order goes by the access time)."""
    from webapp import backend

    body = uploads.check(cfg, uploads.stage_bytes(cfg, "body.bvh", BODY.read_bytes()))
    hand = uploads.check(cfg, uploads.stage_bytes(cfg, "hand.bvh", HAND.read_bytes()))
    first = backend.prepare(body.path, hand.path, "auto", {}, takes=(body.take, hand.take))
    before = body.path.stat()
    time.sleep(0.01)  # a clock step, so that a touched modification time would differ
    paths = uploads.path_for(cfg, body.digest), uploads.path_for(cfg, hand.digest)
    after = body.path.stat()
    assert after.st_mtime_ns == before.st_mtime_ns
    assert after.st_atime_ns > before.st_atime_ns  # marked used
    assert backend.prepare(*paths, "auto", {}) is first


@pytest.mark.parametrize("ext", [".bvh", ".c3d", ".trc"])
def test_an_empty_file_is_said_in_one_wording_by_the_page_and_the_cli(cfg, ext, tmp_path, capsys):
    """Stranger 11 F11: the page said "empty.bvh: the file is empty", the CLI "empty.bvh line
    1: empty file (expected 'HIERARCHY')" (and other words for C3D and TRC): one text,
    ``MotionFormatError.empty``, from the upload fields and every command."""
    from engine.cli import main

    with pytest.raises(uploads.UploadError) as page:
        uploads.stage_bytes(cfg, f"empty{ext}", b"")
    assert str(page.value) == f"empty{ext}: the file is empty"
    path = tmp_path / f"empty{ext}"
    path.write_bytes(b"")
    assert main(["info", str(path)]) == 2
    assert capsys.readouterr().err == f"handsplice: error: {page.value}\n"
