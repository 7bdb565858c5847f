"""The spliced take's files (BVH text, GLB) encoded in a child process.

A long take's BVH is tens of megabytes of text formatted by Python (``%.6f`` per
channel value, 14,400 lines of a few hundred values for two minutes at 120 fps): done
in the server's own process it holds the interpreter lock for seconds, and every
other tab's click waits that long for its answer (3.5 s on CI). Here the encoder runs
in a child forked from the app's forkserver (:func:`webapp.uploads.child_context`: a
small clean process with the readers imported, never a fork of the busy, threaded
server). The server's download thread only writes the motion's arrays into a pipe
(no copy: protocol 5's out-of-band buffers) and reads the file's bytes back; the
kernel copies, without the interpreter lock.

The child calls the very functions the command line calls (``engine.io.bvh.format_bvh``,
``engine.export.glb.glb_bytes``), so the bytes are the CLI's. An encoder's error comes
back as the same exception type and one-line text; a child that dies (out of memory)
or outlasts ``seconds`` raises :class:`EncodeFailed`.

:func:`write` has the child write the file itself, with the command line's writers
(``engine.io.bvh.write_bvh``: the text in pieces, atomically; ``engine.export.glb.write_glb``):
the server then holds none of its bytes (the page fetches it over HTTP,
``webapp.served_files``), and the child not the whole text either.
"""

from __future__ import annotations

import os
import pickle

from engine.base.errors import HandSpliceError

#: a child that has not answered after this many seconds is stopped
ENCODE_SECONDS = 600.0
#: exception types an encoder's error may come back as (anything else: HandSpliceError)
_KINDS = {"ValueError": ValueError, "TypeError": TypeError}


class EncodeFailed(HandSpliceError):
    """The child encoding a download died or ran out of time."""


def encode(kind: str, motion, seconds: float = ENCODE_SECONDS, credit: str = "") -> bytes:
    """``kind`` ("bvh" or "glb") bytes of ``motion``, made in a child process.

    ``credit``: the takes' sources and licences, carried inside a GLB (``asset.copyright``);
    a BVH has no place for it (no comment syntax: its bytes stay the command line's).
    Raises what the encoder raised (``ValueError`` for a motion BVH cannot hold, with
    its text), or :class:`EncodeFailed` when the child dies or outlasts ``seconds``."""
    return _in_child(kind, motion, None, seconds, credit)


def write(kind: str, motion, path, seconds: float = ENCODE_SECONDS, credit: str = "") -> int:
    """Write the ``kind`` file of ``motion`` to ``path`` (atomically: whole or not at all)
    in a child process, with the command line's writer; returns its size in bytes.
    ``credit`` and what it raises: as :func:`encode`."""
    return _in_child(kind, motion, str(path), seconds, credit)


def _in_child(kind: str, motion, path: str | None, seconds: float, credit: str = ""):
    from webapp.uploads import child_context

    if kind not in ENCODERS:
        raise ValueError(f"download kind: expected one of {', '.join(ENCODERS)}, got {kind!r}")
    ctx = child_context()
    here, there = ctx.Pipe(duplex=True)
    child = ctx.Process(
        target=_child_encode, args=(kind, there, path, credit), daemon=True, name=f"hs-{kind}"
    )
    died = EncodeFailed(f"the {kind.upper()} file could not be made (its process died)")
    try:
        child.start()
        there.close()
        try:
            _send_motion(here, motion)
            if not here.poll(seconds):
                raise EncodeFailed(f"the {kind.upper()} file took longer than {seconds:g} s")
            verdict, detail = here.recv()
            data = here.recv_bytes() if verdict == "ok" and path is None else detail
        except (EOFError, OSError):  # the child died: out of memory or worse
            raise died from None
    finally:
        here.close()
        if child.is_alive():
            child.kill()
        child.join(5)
    if verdict != "ok":
        raise _KINDS.get(verdict, HandSpliceError)(detail)
    return data


def _send_motion(conn, motion) -> None:
    """``motion`` down ``conn``: a pickle whose arrays travel apart (protocol 5's
    out-of-band buffers), written straight from their memory, so this interpreter copies
    none of a long take's tens of megabytes (the kernel does, without the lock)."""
    buffers: list[pickle.PickleBuffer] = []
    head = pickle.dumps(motion, protocol=5, buffer_callback=buffers.append)
    conn.send_bytes(head)
    conn.send(len(buffers))
    for buffer in buffers:
        conn.send_bytes(buffer.raw())


def _receive_motion(conn):
    head = conn.recv_bytes()
    buffers = [bytearray(conn.recv_bytes()) for _ in range(conn.recv())]  # writable arrays
    return pickle.loads(head, buffers=buffers)


def _bvh(motion, credit: str = "") -> bytes:  # BVH has no comments: no credit inside
    from engine.io.bvh import format_bvh

    return format_bvh(motion).encode("utf-8")


def _glb(motion, credit: str = "") -> bytes:
    from engine.export.glb import glb_bytes

    return glb_bytes(motion, copyright=credit or None)


def _write_bvh(motion, path: str, credit: str = "") -> None:
    from engine.io.bvh import write_bvh

    write_bvh(motion, path)


def _write_glb(motion, path: str, credit: str = "") -> None:
    from engine.export.glb import write_glb

    write_glb(motion, path, copyright=credit or None)


#: what each download kind runs in the child (the command line's own encoders)
ENCODERS = {"bvh": _bvh, "glb": _glb}
#: ... and writers (atomic; the BVH text in pieces)
WRITERS = {"bvh": _write_bvh, "glb": _write_glb}


def _child_encode(kind: str, conn, path: str | None = None, credit: str = "") -> None:
    # runs in the child
    try:
        motion = _receive_motion(conn)
        if path is None:
            data = ENCODERS[kind](motion, credit)
        else:
            WRITERS[kind](motion, path, credit)
            data = None
    except Exception as exc:  # noqa: BLE001 - the parent raises it with its one line
        text = str(exc).strip().splitlines()
        conn.send((type(exc).__name__, text[0] if text else type(exc).__name__))
    else:
        if data is None:
            conn.send(("ok", os.path.getsize(path)))
        else:
            conn.send(("ok", len(data)))
            conn.send_bytes(data)
    finally:
        conn.close()
