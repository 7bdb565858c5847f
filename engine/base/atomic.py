"""Atomic output: write to a temporary file beside the target, then rename.

* ``atomic_path(path)``: one file. ``atomic_group(paths)``: files that belong together
  (a spliced BVH and its report): all are written to temporary files first and renamed
  one after the other only when every one is complete, with SIGINT/SIGTERM held back
  during the renames, so a failure or an interrupt leaves all the old files (or none)
  and never a new BVH beside an old report.
* Temporary files are named ``.STEM.hstmp-HOST-PID-RAND.SUFFIX`` (the suffix kept for
  writers that look at extensions, such as imageio). They are removed when the writing
  fails, on SIGINT and SIGTERM (``handle_termination`` turns SIGTERM into an exception
  so the ``finally`` blocks run) and at interpreter exit. A run killed outright
  (SIGKILL, power loss) leaves its temporary files; the next write to the same target,
  or ``clean_stale(folder)``, removes those whose process is gone (same host) or that
  are older than ``STALE_AFTER_S`` (another host sharing the folder).
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import os
import re
import signal
import socket
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

_UMASK = os.umask(0o022)  # read once at import (setting it is process-wide)
os.umask(_UMASK)
_FILE_MODE = 0o666 & ~_UMASK

#: a temporary file of another host is stale after this many seconds (a day)
STALE_AFTER_S = 24 * 3600.0
_TAG = "hstmp"
_HOST = hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:8]
_TEMP_RE = re.compile(
    rf"\.(?P<stem>.*)\.{_TAG}-(?P<host>[0-9a-f]{{8}})-(?P<pid>[0-9]+)-[^.]+"
    r"(?P<suffix>(\.[^.]*)?)"
)
_LIVE: set[Path] = set()  # temporary files of this process not yet renamed or removed
_LIVE_LOCK = threading.Lock()


class Terminated(KeyboardInterrupt):
    """Raised in the main thread on SIGTERM (see ``handle_termination``)."""


def _temp_prefix(path: Path) -> str:
    return f".{path.stem}.{_TAG}-{_HOST}-{os.getpid()}-"


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    except OSError:
        return False
    return True


def is_stale(tmp: Path, now: float | None = None) -> bool:
    """True when ``tmp`` is a temporary file of ``atomic_path`` whose writer is gone."""
    m = _TEMP_RE.fullmatch(tmp.name)
    if m is None:
        return False
    pid = int(m["pid"][:10])
    if m["host"] == _HOST:
        if pid == os.getpid():
            with _LIVE_LOCK:
                return tmp not in _LIVE
        return not _pid_alive(pid)
    try:
        age = (time.time() if now is None else now) - tmp.stat().st_mtime
    except OSError:
        return False
    return age > STALE_AFTER_S


def clean_stale(folder: str | Path, stem: str | None = None) -> list[Path]:
    """Remove stale temporary files in ``folder`` (only those of ``stem`` if given).

    Returns the paths removed. Files that are not ``atomic_path`` temporaries, and those
    of live writers, are left alone.
    """
    folder = Path(folder)
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        name = entry.name
        if not name.startswith(".") or f".{_TAG}-" not in name:
            continue
        m = _TEMP_RE.fullmatch(name)
        if m is None or (stem is not None and m["stem"] != stem):
            continue
        p = folder / name
        if entry.is_file(follow_symlinks=False) and is_stale(p):
            with contextlib.suppress(OSError):
                p.unlink()
                removed.append(p)
    return removed


def _new_temp(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_stale(path.parent, path.stem)
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    with _LIVE_LOCK:
        _LIVE.add(tmp_path)
    os.chmod(tmp, _FILE_MODE)  # mkstemp makes 0600; outputs get the usual 0666 & ~umask
    return tmp_path


def _discard(tmp: Path) -> None:
    with contextlib.suppress(OSError):
        tmp.unlink()
    with _LIVE_LOCK:
        _LIVE.discard(tmp)


@contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait until the block ends (main thread; elsewhere a no-op)."""
    held = {signal.SIGINT, signal.SIGTERM}
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    except (AttributeError, OSError, ValueError):
        old = None
    try:
        yield
    finally:
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextmanager
def atomic_group(paths: Sequence[str | Path]) -> Iterator[list[Path]]:
    """Yield one temporary path per target; on success all replace their targets together.

    On an exception (or SIGINT/SIGTERM, see ``handle_termination``) every temporary file
    is removed and no target is touched. The renames run with SIGINT/SIGTERM held back.
    """
    targets = [Path(p) for p in paths]
    if len({t.resolve() for t in targets}) != len(targets):
        raise ValueError(f"atomic_group: the same output named twice: {[str(t) for t in targets]}")
    temps: list[Path] = []
    try:
        for t in targets:
            temps.append(_new_temp(t))
        yield list(temps)
        with _signals_held():
            for tmp, target in zip(temps, targets, strict=True):
                os.replace(tmp, target)
                with _LIVE_LOCK:
                    _LIVE.discard(tmp)
    finally:
        for tmp in temps:
            if tmp in _LIVE:
                _discard(tmp)


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path in ``path``'s folder; on success it replaces ``path``.

    On an exception the temporary file is removed and ``path`` is untouched.
    The suffix is kept so writers that look at extensions (imageio) still work.
    """
    with atomic_group([path]) as (tmp,):
        yield tmp


def _write_pieces(tmp: Path, text) -> None:
    """``text`` (a str, or an iterable of str pieces written one after another, so a long
    text is never held whole) into ``tmp`` as UTF-8."""
    if isinstance(text, str):
        tmp.write_text(text, encoding="utf-8")
        return
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        for piece in text:
            fh.write(piece)


def write_text(path: str | Path, text) -> None:
    """Write ``text`` to ``path`` atomically (UTF-8); ``text`` may be an iterable of str
    pieces (e.g. ``engine.io.bvh.iter_bvh``)."""
    with atomic_path(path) as tmp:
        _write_pieces(tmp, text)


def write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_texts(items: Sequence[tuple[str | Path, object]]) -> None:
    """Write several ``(path, text)`` files that belong together (see ``atomic_group``);
    a text may be an iterable of str pieces, as in :func:`write_text`."""
    with atomic_group([p for p, _ in items]) as temps:
        for tmp, (_, text) in zip(temps, items, strict=True):
            _write_pieces(tmp, text)


def _on_sigterm(signum, frame) -> None:
    raise Terminated(f"terminated (signal {signum})")


def handle_termination() -> None:
    """Make SIGTERM raise ``Terminated`` in the main thread, so temporary files are removed.

    Call once from a command-line entry point (the main thread). SIGINT already raises
    ``KeyboardInterrupt``.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _on_sigterm)


@atexit.register
def _remove_live() -> None:
    with _LIVE_LOCK:
        live = list(_LIVE)
    for tmp in live:
        _discard(tmp)
