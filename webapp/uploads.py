"""Uploaded takes: size-limited, validated, stored by content hash.

An upload is checked by reading it with the engine's own reader
(``engine.io.load_take``) before it is kept, so a malformed file is refused with
the reader's one-line message (``walk.bvh line 212: expected 96 values, found
93``). Kept files live in ``<upload_dir>/<sha256>.<ext>``; the server resolves an
upload only from a 64-hex-digit hash, so a request can never name a path outside
that folder.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from engine.atomic import write_bytes
from engine.errors import HandSpliceError
from webapp.config import AppConfig

EXTENSIONS = (".bvh", ".c3d", ".trc")
_HEX64 = re.compile(r"^[0-9a-f]{64}$")


class UploadError(HandSpliceError, ValueError):
    """An upload was refused; the message says why (shown in the page)."""


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def path_for(cfg: AppConfig, digest: str) -> Path:
    """The stored file of upload ``digest`` (UploadError when unknown or not a hash)."""
    if not isinstance(digest, str) or not _HEX64.match(digest):
        raise UploadError(f"upload: expected a 64-digit hex hash, got {str(digest)[:70]!r}")
    for ext in EXTENSIONS:
        path = cfg.upload_dir / f"{digest}{ext}"
        if path.is_file():
            return path
    raise UploadError(f"upload {digest[:12]}...: no such file on this server "
                      "(uploads are kept per server; upload the take again)")


def store(cfg: AppConfig, filename: str, data: bytes | None) -> tuple[str, object]:
    """Validate an uploaded file and keep it; returns ``(sha256, take)``.

    ``take`` is the Motion or MarkerSet read from it. Raises UploadError with a
    one-line reason: empty, too large, unknown extension, or what the reader found.
    """
    from engine.io import load_take

    name = Path(filename or "upload").name
    ext = Path(name).suffix.lower()
    if ext not in EXTENSIONS:
        raise UploadError(f"{name}: expected a .bvh, .c3d or .trc file")
    if not data:
        raise UploadError(f"{name}: the file is empty")
    if len(data) > cfg.max_upload_bytes:
        raise UploadError(f"{name}: {len(data) / 2**20:.1f} MiB is over the "
                          f"{cfg.max_upload_bytes / 2**20:.0f} MiB upload limit")
    digest = sha256(data)
    target = cfg.upload_dir / f"{digest}{ext}"
    staging = cfg.upload_dir / f".check-{digest}{ext}"
    try:
        cfg.upload_dir.mkdir(parents=True, exist_ok=True)
        write_bytes(staging, data)
    except OSError as exc:
        _discard(staging)
        raise UploadError(f"{name}: the server cannot store uploads ({_os_reason(exc)})") \
            from None
    try:
        try:
            take = load_take(staging)
        except HandSpliceError as exc:
            raise UploadError(_rename(str(exc), staging.name, name)) from None
        except (ValueError, OSError, KeyError, IndexError, RuntimeError) as exc:
            raise UploadError(f"{name}: cannot be read ({type(exc).__name__}: "
                              f"{_rename(str(exc), staging.name, name)})") from None
        if not target.exists():
            try:
                staging.replace(target)
            except OSError as exc:
                raise UploadError(f"{name}: the server cannot store uploads "
                                  f"({_os_reason(exc)})") from None
    finally:
        _discard(staging)
    return digest, take


def _discard(path: Path) -> None:
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass  # an unwritable folder: nothing was staged there


def _os_reason(exc: OSError) -> str:
    """An OSError in one line, without the server's paths (``permission denied``)."""
    reason = exc.strerror or type(exc).__name__
    return reason[:1].lower() + reason[1:]


def _rename(message: str, staged: str, original: str) -> str:
    return message.strip().splitlines()[0].replace(staged, original) if message.strip() \
        else original
