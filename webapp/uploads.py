"""Uploaded takes: streamed to disk, checked within a budget, kept by content hash.

An upload arrives in chunks (the page's file droppers send a few MiB per websocket
message) and is written straight to a staging file in the upload folder
(:class:`Incoming`), so a 200 MB take never sits in the server's memory. It is then
checked by reading it with the engine's own reader (``engine.io.load_take``) in a
child process with a time and memory budget (:func:`check`): a malformed or hostile
file is refused with the reader's one-line message (``walk.bvh line 212: expected 96
values, found 93``), and one that takes too long or too much memory is stopped and
refused, while the server goes on serving every other session.

Kept files live in ``<upload_dir>/<sha256>.<ext>``. The server resolves an upload
only from a 64-hex-digit hash and only to a regular file (never a symlink), so a
request can never name a path outside that folder. The folder has a quota (files and
bytes, :class:`webapp.config.AppConfig`): when a new upload goes over it, the least
recently used uploads are removed first. Error messages never quote much of a file's
contents (:func:`_bounded`), and never the server's paths.
"""

from __future__ import annotations

import dataclasses
import hashlib
import multiprocessing
import os
import re
import stat
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from engine.base.errors import HandSpliceError, MotionFormatError
from webapp.config import AppConfig

EXTENSIONS = (".bvh", ".c3d", ".trc")
_HEX64 = re.compile(r"^[0-9a-f]{64}$")
_KEPT = re.compile(r"^[0-9a-f]{64}\.(bvh|c3d|trc)$")
#: staging files of a server that was killed mid-upload are removed after this long
STALE_STAGING_S = 3600.0
#: quoted text from a file longer than this is cut in error messages
QUOTE_CHARS = 80
_CHUNK = 1 << 20


class UploadError(HandSpliceError, ValueError):
    """An upload was refused; the message says why in one line (shown in the page)."""


@dataclass(frozen=True)
class Staged:
    """A received upload not yet checked: ``path`` in the upload folder, original ``name``."""

    path: Path
    name: str
    size: int


@dataclass(frozen=True)
class Kept:
    """A checked upload kept by content hash; ``summary`` describes the take
    (``kind`` "skeleton" or "markers", ``frames``, ``fps``, ``joints``/``markers``; a
    skeleton's ``hand_take`` and ``body_take``: ``engine.model.roles.Roles``'
    ``looks_like_hand_take`` and ``looks_like_body_take``) and
    ``take`` is what the reader read (handed over by the child: not read twice)."""

    digest: str
    path: Path
    name: str
    summary: dict
    take: object = field(default=None, compare=False, repr=False)  # Motion or MarkerSet


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


#: longest file name kept whole: a file system's own limit (255 bytes on ext4, NTFS, APFS),
#: so the page's command line names the user's file as it is; the page wraps long names
MAX_NAME_CHARS = 255


def display_name(filename: str | None) -> str:
    """The last component of a client-side file name (never a path), whole up to
    :data:`MAX_NAME_CHARS` (longer is no real file's name: shortened with "…")."""
    name = re.split(r"[\\/]", str(filename or ""))[-1].strip() or "upload"
    if len(name) <= MAX_NAME_CHARS:
        return name
    return name[: MAX_NAME_CHARS - 20] + "…" + name[-19:]


def _extension(name: str) -> str:
    ext = Path(name).suffix.lower()
    if ext not in EXTENSIONS:
        raise UploadError(f"{name}: expected a .bvh, .c3d or .trc file")
    return ext


def limit_words(max_bytes: int) -> str:
    """The upload limit as the page and its messages say it: ``200 MiB`` (binary
    megabytes, as ``--max-upload-mb`` counts them; a fraction to one decimal)."""
    return f"{round(max_bytes / 2**20, 1):g} MiB"


def check_name(filename: str | None) -> str:
    """The shown name of a file the browser means to upload, if its extension is one the
    server reads (:data:`EXTENSIONS`); UploadError (``x.png: expected a .bvh, .c3d or .trc
    file``) otherwise. The page's fields refuse such a file before sending it and ask
    the server for this message."""
    name = display_name(filename)
    _extension(name)
    return name


def _is_regular(path: Path) -> bool:
    """True for a regular file; symlinks are never followed (``lstat``)."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def path_for(cfg: AppConfig, digest: str) -> Path:
    """The stored file of upload ``digest`` (UploadError when unknown, not a hash, or not a
    regular file). Marks it as used (:func:`_mark_used`), so the quota removes it last."""
    if not isinstance(digest, str) or not _HEX64.match(digest):
        raise UploadError(f"upload: expected a 64-digit hex hash, got {str(digest)[:70]!r}")
    for ext in EXTENSIONS:
        path = cfg.upload_dir / f"{digest}{ext}"
        if os.path.lexists(path):
            if not _is_regular(path):
                raise UploadError(
                    f"upload {digest[:12]}...: not a regular file on this server "
                    "(links are not followed)"
                )
            _mark_used(path)
            return path
    raise UploadError(
        f"upload {digest[:12]}...: no such file on this server "
        "(uploads are kept per server; upload the take again)"
    )


def file_for(cfg: AppConfig, digest: str) -> Path:
    """The file on this server whose bytes have the SHA-256 ``digest``: the upload kept
    under that hash (:func:`path_for`), else the file of ``handsplice serve BODY HAND``
    (``cfg.local``) with those bytes. The one rule by which a link or session file that
    names takes by content finds them (stranger 12: a link of an upload did not open on a
    server started on the very same files); only the hash is taken from the link, never a
    path, and only the files the server was given are read. UploadError as
    :func:`path_for`'s when no file has those bytes."""
    try:
        return path_for(cfg, digest)
    except UploadError:
        local = cfg.local
        for path in (local.body, local.hand) if local is not None else ():
            if _content_sha256(path) == digest:
                return path
        raise


def files_for(cfg: AppConfig, takes) -> tuple[Path, ...]:
    """:func:`file_for` of each ``(digest, name)`` in ``takes`` (``name``: the person's
    file name, or None); one UploadError naming every take that is not on this server
    (stranger 12: only the body was named when both were missing)."""
    paths, missing = [], []
    for digest, name in takes:
        try:
            paths.append(file_for(cfg, digest))
        except UploadError:
            if not isinstance(digest, str) or not _HEX64.match(digest):
                raise
            missing.append(f"upload {digest[:12]}..." + (f" ({name})" if name else ""))
    if missing:
        raise UploadError(
            f"{' and '.join(missing)}: no such file on this server (uploads are kept per "
            f"server; upload the {'takes' if len(missing) > 1 else 'take'} again)"
        )
    return tuple(paths)


def is_kept(cfg: AppConfig, path: Path) -> bool:
    """Whether ``path`` (from :func:`file_for`) is an upload kept in the upload folder
    (not a file the server was started on)."""
    return Path(path).parent == cfg.upload_dir


#: content hashes of the server's own files by (path, size, modification time)
_LOCAL_HASHES: dict[tuple, str] = {}


def _content_sha256(path: Path) -> str | None:
    """``path``'s SHA-256, read once per size and modification time; None if unreadable."""
    try:
        st = os.stat(path)
        key = (str(path), st.st_size, st.st_mtime_ns)
        if key not in _LOCAL_HASHES:
            _LOCAL_HASHES[key] = _file_sha256(path)
        return _LOCAL_HASHES[key]
    except OSError:
        return None


def _mark_used(path: Path) -> None:
    """Set ``path``'s access time to now, the time the quota orders by (:func:`_last_used`).
    Its modification time stays: the server's cache of opened pairs knows a file by it
    (``webapp.backend.prepare``), so opening a pair just uploaded (its files named again
    by hash) finds the features computed while it was checked instead of reading both
    takes again."""
    try:
        mtime = os.lstat(path).st_mtime_ns
        os.utime(path, ns=(time.time_ns(), mtime), follow_symlinks=False)
    except OSError:
        pass  # a read-only folder: the quota order is only a preference


def _last_used(st: os.stat_result) -> float:
    """When a kept upload was last stored or opened (s): its modification or, if later,
    its access time (:func:`_mark_used`)."""
    return max(st.st_mtime, st.st_atime)


# ---------------------------------------------------------------- receiving


class Incoming:
    """One upload being received: chunks are appended to a staging file.

    ``write`` refuses (UploadError, staging file removed) as soon as the bytes pass
    the upload limit; ``finish`` returns the :class:`Staged` file. The staging file is
    created exclusively and never through a symlink.
    """

    def __init__(self, cfg: AppConfig, filename: str | None):
        self.cfg = cfg
        self.name = display_name(filename)
        self.ext = _extension(self.name)
        self.size = 0
        self.path = cfg.upload_dir / f".part-{uuid.uuid4().hex}{self.ext}"
        self._fd = None
        try:
            cfg.upload_dir.mkdir(parents=True, exist_ok=True)
            self._fd = _open_staging(self.path)
        except OSError as exc:
            raise UploadError(
                f"{self.name}: the server cannot store uploads ({_os_reason(exc)})"
            ) from None

    def write(self, data) -> None:
        if self._fd is None:
            raise UploadError(f"{self.name}: the upload was already closed")
        self.size += len(data)
        if self.size > self.cfg.max_upload_bytes:
            self.discard()
            raise UploadError(
                f"{self.name}: over the {limit_words(self.cfg.max_upload_bytes)} upload limit"
            )
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(self._fd, view) :]
        except OSError as exc:
            self.discard()
            raise UploadError(
                f"{self.name}: the server cannot store uploads ({_os_reason(exc)})"
            ) from None

    def finish(self) -> Staged:
        self._close()
        if self.size == 0:
            self.discard()
            raise UploadError(str(MotionFormatError.empty(self.name)))
        return Staged(self.path, self.name, self.size)

    def discard(self) -> None:
        self._close()
        _discard(self.path)

    def _close(self) -> None:
        fd, self._fd = getattr(self, "_fd", None), None
        if fd is not None:
            os.close(fd)


def _open_staging(path: Path) -> int:
    """A new file for writing, created exclusively and never through a symlink."""
    return os.open(
        path,
        os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0),
        0o600,
    )


def stage_bytes(cfg: AppConfig, filename: str | None, data: bytes | None) -> Staged:
    """An upload held in memory (a test, a small file) written to a staging file."""
    name = display_name(filename)
    _extension(name)
    if not data:
        raise UploadError(str(MotionFormatError.empty(name)))
    if len(data) > cfg.max_upload_bytes:
        raise UploadError(
            f"{name}: {len(data) / 2**20:.1f} MiB is over the "
            f"{cfg.max_upload_bytes / 2**20:.0f} MiB upload limit"
        )
    incoming = Incoming(cfg, name)
    incoming.write(data)
    return incoming.finish()


# ---------------------------------------------------------------- checking


def check(cfg: AppConfig, staged: Staged) -> Kept:
    """Read a staged upload in a child process within the budget, then keep it by hash.

    Blocks for as long as the check takes (call it off the event loop, e.g. in an
    executor). Raises UploadError with a one-line reason; the staging file is removed
    either way.
    """
    try:
        summary, take = _read_in_child(staged, cfg.upload_check_seconds, cfg.upload_check_bytes)
        digest = _file_sha256(staged.path)
        target = cfg.upload_dir / f"{digest}{staged.path.suffix}"
        try:
            os.replace(staged.path, target)  # a symlink planted there is replaced, not followed
            os.utime(target, follow_symlinks=False)
        except OSError as exc:
            raise UploadError(
                f"{staged.name}: the server cannot store uploads ({_os_reason(exc)})"
            ) from None
    finally:
        _discard(staged.path)
    enforce_quota(cfg, keep={target.name})
    if take is not None and hasattr(take, "meta"):  # the kept file's name, as a read gives
        # the reader's notes name the user's file, as its errors do (shown in the page)
        notes = tuple(_bounded(_rename(n, staged.path, staged.name)) for n in take.meta.notes)
        summary = {**summary, "notes": list(notes)}
        take = dataclasses.replace(
            take, meta=dataclasses.replace(take.meta, source=str(target), notes=notes)
        )
    return Kept(digest, target, staged.name, summary, take)


def store(cfg: AppConfig, filename: str, data: bytes | None) -> tuple[str, object]:
    """Check an upload held in memory and keep it; returns ``(sha256, take)``.

    ``take`` is the Motion or MarkerSet read from the kept file.
    """
    kept = check(cfg, stage_bytes(cfg, filename, data))
    return kept.digest, kept.take


def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


_CONTEXT = None


def child_context():
    """A forkserver context: children fork from a small clean process that has the
    readers imported (fast, and never a copy of the busy, threaded server; which is why
    this is not ``engine.jobs.sandbox.run_limited``, whose child is a fork of its caller).
    The downloads' encoders (``webapp.downloads``) start their children from it too."""
    global _CONTEXT
    if _CONTEXT is None:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(
            ["engine.io", "engine.io.bvh", "engine.io.c3d", "engine.io.trc", "engine.model.roles"]
        )
        _CONTEXT = ctx
    return _CONTEXT


def _read_in_child(staged: Staged, seconds: float, memory: int) -> dict:
    ctx = child_context()
    receive, send = ctx.Pipe(duplex=False)
    child = ctx.Process(
        target=_child_read,
        args=(str(staged.path), memory, send),
        daemon=True,
        name="hs-upload-check",
    )
    try:
        child.start()
    except OSError as exc:
        raise UploadError(
            f"{staged.name}: the server cannot check uploads now ({_os_reason(exc)})"
        ) from None
    send.close()
    try:
        if not receive.poll(seconds):
            raise UploadError(
                f"{staged.name}: reading it took longer than the server's "
                f"{seconds:g} s budget for one file"
            )
        try:
            verdict, detail, take = receive.recv()
        except (EOFError, OSError):  # the child died: out of memory or worse
            raise UploadError(
                f"{staged.name}: cannot be read within the server's "
                f"{memory / 2**30:.1f} GiB memory budget"
            ) from None
    finally:
        receive.close()
        if child.is_alive():
            child.kill()
        child.join(5)
    if verdict != "ok":
        raise UploadError(_bounded(_rename(detail, staged.path, staged.name)))
    return detail, take


def _child_read(path: str, memory: int, conn) -> None:  # runs in the child process
    import resource

    try:
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    except (ValueError, OSError):
        pass
    try:
        from engine.io import load_take
        from engine.model.motion import MarkerSet
        from engine.model.roles import find_roles

        take = load_take(path)
        if isinstance(take, MarkerSet):
            summary = {"kind": "markers", "markers": len(take.labels)}
        else:
            roles = find_roles(take.skeleton)  # by its joint names, as a pair opens it
            summary = {
                "kind": "skeleton",
                "joints": int(take.skeleton.n_joints),
                "hand_take": roles.looks_like_hand_take,
                "body_take": roles.looks_like_body_take,
            }
        summary.update(frames=int(take.n_frames), fps=float(take.fps))
        conn.send(("ok", summary, take))
    except MemoryError:
        conn.send(
            (
                "refused",
                f"{Path(path).name}: reading it needs more than the server's "
                f"{memory / 2**30:.1f} GiB memory budget",
                None,
            )
        )
    except HandSpliceError as exc:
        conn.send(("refused", str(exc), None))
    except Exception as exc:  # noqa: BLE001 - any reader failure is a refusal, never a crash
        conn.send(("refused", f"{Path(path).name}: cannot be read ({type(exc).__name__})", None))
    finally:
        conn.close()


# ---------------------------------------------------------------- the folder


def enforce_quota(cfg: AppConfig, keep: set[str] = frozenset()) -> list[str]:
    """Remove the least recently used uploads until the folder holds at most
    ``cfg.max_upload_files`` files and ``cfg.max_upload_total_bytes`` bytes (``keep``:
    names never removed); stale staging files go too. Returns the removed names.

    Only regular files named ``<sha256>.<ext>`` count; links and other entries are
    neither followed nor removed."""
    kept: list[tuple[float, int, str]] = []
    removed = []
    now = time.time()
    try:
        entries = list(os.scandir(cfg.upload_dir))
    except OSError:
        return removed
    for entry in entries:
        try:
            st = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISREG(st.st_mode):
            continue
        if entry.name.startswith(".part-") and now - st.st_mtime > STALE_STAGING_S:
            _discard(Path(entry.path))
            removed.append(entry.name)
        elif _KEPT.match(entry.name):
            kept.append((_last_used(st), st.st_size, entry.name))
    kept.sort()
    count, total = len(kept), sum(size for _, size, _ in kept)
    for _, size, name in kept:
        if count <= cfg.max_upload_files and total <= cfg.max_upload_total_bytes:
            break
        if name in keep:
            continue
        _discard(cfg.upload_dir / name)
        removed.append(name)
        count, total = count - 1, total - size
    return removed


def _discard(path: Path) -> None:
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass  # an unwritable folder: nothing was staged there


def _os_reason(exc: OSError) -> str:
    """An OSError in one line, without the server's paths (``permission denied``)."""
    reason = exc.strerror or type(exc).__name__
    return reason[:1].lower() + reason[1:]


def _rename(message: str, staged: Path, original: str) -> str:
    """The first line of ``message`` with the staging file named as the user's file."""
    text = message.strip().splitlines()[0] if message.strip() else original
    return text.replace(str(staged), original).replace(staged.name, original)


_QUOTED = re.compile(r"('[^'\n]*'|\"[^\"\n]*\")")


def _bounded(message: str) -> str:
    """``message`` with any quoted file text over QUOTE_CHARS characters cut short, so an
    error never echoes a file's contents at length."""

    def cut(match: re.Match) -> str:
        text = match.group(0)
        return text if len(text) <= QUOTE_CHARS else text[: QUOTE_CHARS - 12] + "…" + text[0]

    return _QUOTED.sub(cut, message)[:400]
