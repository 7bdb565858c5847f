"""Run one function in a child process under a time and a memory limit.

``run_limited(fn, args, seconds=..., memory_mb=...)`` runs ``fn(*args)`` in a forked
child (POSIX) and returns its (picklable) result, or raises ``LimitExceeded`` when the
child ran past ``seconds`` of wall time or past ``memory_mb`` megabytes of resident
memory (it is then stopped: SIGTERM, so its temporary files are removed, then SIGKILL
after a grace period). An exception in ``fn`` comes back as ``ChildFailed`` carrying its
one-line text.

Memory is held by two means: ``RLIMIT_DATA`` in the child (an allocation beyond it
raises ``MemoryError`` there at once) and the parent reading the child's resident size
(``/proc/PID/status``) every ``POLL_S`` seconds. The child is forked, not spawned, so it
starts in milliseconds with whatever the parent has imported, and it is kept for the
next call, so what numba compiles in it is compiled once (a child stopped at a limit is
replaced by a fresh one). A kept child ends when its input pipe closes: when the
parent closes it (``shutdown``, a limit) or exits; an ``atexit`` hook closes every live
child's pipe first, because a child that holds an inherited descriptor (Python 3.13's
resource tracker pipe, say) would otherwise keep the exiting parent waiting on it. Each
new child closes the pipes of the others, so no child keeps a sibling alive.

Where ``os.fork`` does not exist, ``fn`` runs in this process without limits.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import pickle
import select
import signal
import threading
import time
from collections.abc import Callable
from typing import Any

from engine.base.errors import HandSpliceError

#: seconds between two looks at the child's memory and clock
POLL_S = 0.05
#: seconds a stopped child has to clean up after SIGTERM before SIGKILL
GRACE_S = 2.0


class LimitExceeded(HandSpliceError):
    """The child ran past its time or memory limit and was stopped."""


class ChildFailed(HandSpliceError):
    """``fn`` raised in the child (or the child died); ``str()`` is one line."""


def resident_mb(pid: int) -> float:
    """Resident memory of process ``pid`` in MB (``VmRSS``), 0 when unknown."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return 0.0


def _send(fd: int, obj: Any) -> None:
    data = pickle.dumps(obj)
    view = memoryview(len(data).to_bytes(8, "little") + data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def _recv_exact(fd: int, n: int) -> bytes | None:
    buf = bytearray()
    while len(buf) < n:
        chunk = os.read(fd, n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return bytes(buf)


def _answer(fn: Callable, args: tuple) -> tuple[str, Any]:
    try:
        return ("ok", fn(*args))
    except MemoryError:
        return ("memory", None)
    except Exception as exc:
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        if not isinstance(exc, HandSpliceError):
            text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
        return ("error", text[:500])


def _serve(in_fd: int, out_fd: int, memory_mb: float | None, first=None) -> None:
    """The runner's loop: read ``(fn, args)``, answer ``(kind, value)``, until EOF.

    ``first``: a call inherited through the fork (not picklable), answered before the loop.
    """
    from engine.base.atomic import handle_termination

    handle_termination()  # SIGTERM: Terminated, temporary files removed on the way out
    signal.signal(signal.SIGINT, signal.default_int_handler)
    if memory_mb:
        import resource

        limit = int(memory_mb * 2**20)
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_DATA, (limit, limit))
    while True:
        if first is not None:
            payload, first = _answer(*first), None
        else:
            head = _recv_exact(in_fd, 8)
            if head is None:
                return
            body = _recv_exact(in_fd, int.from_bytes(head, "little"))
            if body is None:
                return
            try:
                fn, args = pickle.loads(body)
            except Exception as exc:
                payload = ("error", f"the call cannot be read: {type(exc).__name__}: {exc}")
            else:
                payload = _answer(fn, args)
        try:
            _send(out_fd, payload)
        except (pickle.PicklingError, TypeError, AttributeError) as exc:
            _send(out_fd, ("error", f"the result cannot be sent back: {type(exc).__name__}"))


class _Runner:
    """A forked child that runs calls one after the other (numba code compiled in it stays)."""

    def __init__(self, memory_mb: float | None, first=None):
        self.memory_mb = memory_mb
        to_child, self._in = os.pipe()  # parent writes self._in
        self._out, from_child = os.pipe()  # parent reads self._out
        with _LIVE_LOCK:
            pid = os.fork()
            if pid != 0:
                _LIVE.add(self)
        if pid == 0:  # the child: serves until its input closes, never returns
            code = 0
            try:
                os.close(self._in)
                os.close(self._out)
                for other in _LIVE:  # a sibling's pipes: its child must see EOF, not us
                    for fd in (other._in, other._out):
                        with contextlib.suppress(OSError):
                            os.close(fd)
                _serve(to_child, from_child, memory_mb, first)
            except BaseException:  # Terminated, KeyboardInterrupt: the parent reports it
                code = 1
            finally:
                os._exit(code)
        os.close(to_child)
        os.close(from_child)
        self.pid = pid

    def call(self, fn: Callable, args: tuple, seconds: float | None, send: bool = True) -> Any:
        if send:
            _send(self._in, (fn, args))
        start = time.monotonic()
        buf = bytearray()
        need = 8
        size = None
        while True:
            ready, _, _ = select.select([self._out], [], [], POLL_S)
            if ready:
                chunk = os.read(self._out, 1 << 20)
                if not chunk:
                    raise _Died()
                buf += chunk
                if size is None and len(buf) >= 8:
                    size = int.from_bytes(buf[:8], "little")
                    need = 8 + size
                if len(buf) >= need:
                    break
                continue
            if self.memory_mb and resident_mb(self.pid) > self.memory_mb:
                raise LimitExceeded(f"used more than the memory limit of {self.memory_mb:g} MB")
            if seconds and time.monotonic() - start > seconds:
                raise LimitExceeded(f"ran longer than the time limit of {seconds:g} s")
        return pickle.loads(bytes(buf[8:need]))

    def close(self, stop: bool = False) -> int:
        """Close the pipes (the child ends); ``stop``: SIGTERM/SIGKILL it first. Reaps it."""
        with _LIVE_LOCK:
            _LIVE.discard(self)
        for fd in (self._in, self._out):
            with contextlib.suppress(OSError):
                os.close(fd)
        if stop:
            _stop(self.pid)
        return _reap(self.pid)


class _Died(Exception):
    pass


_RUNNERS = threading.local()
#: every kept child of this process (any thread's), closed at exit
_LIVE: set[_Runner] = set()
_LIVE_LOCK = threading.Lock()


@atexit.register
def _close_all() -> None:
    """At exit: close every kept child's pipes and reap it (``GRACE_S``, then stopped)."""
    with _LIVE_LOCK:
        runners = list(_LIVE)
    for runner in runners:
        for fd in (runner._in, runner._out):
            with contextlib.suppress(OSError):
                os.close(fd)
        end = time.monotonic() + GRACE_S
        while time.monotonic() < end and _alive(runner.pid):
            time.sleep(0.02)
        if _alive(runner.pid):
            with contextlib.suppress(ProcessLookupError, ChildProcessError):
                os.kill(runner.pid, signal.SIGKILL)
                os.waitpid(runner.pid, 0)
    with _LIVE_LOCK:
        _LIVE.clear()


def run_limited(
    fn: Callable, args: tuple = (), seconds: float | None = None, memory_mb: float | None = None
) -> Any:
    """``fn(*args)`` in a forked child, stopped beyond ``seconds`` or ``memory_mb``.

    ``None`` or 0 means no limit. Raises ``LimitExceeded`` or ``ChildFailed``. The child
    is kept for the next call of this thread (with the same memory limit), so code that
    numba compiled in it is compiled once; a child that ran past a limit is stopped
    and the next call starts a fresh one. ``fn`` and ``args`` must be picklable.
    """
    if not hasattr(os, "fork"):
        return fn(*args)
    seconds = seconds or None
    memory_mb = memory_mb or None
    runner = getattr(_RUNNERS, "runner", None)
    if runner is not None and (runner.memory_mb != memory_mb or not _alive(runner.pid)):
        runner.close(stop=True)
        runner = None
    try:
        pickle.dumps((fn, args))
        inherited = None
    except Exception:  # a local function, say: a fresh child inherits it through the fork
        inherited = (fn, args)
        if runner is not None:
            runner.close(stop=True)
            runner = None
    if runner is None:
        runner = _RUNNERS.runner = _Runner(memory_mb, first=inherited)
    try:
        kind, value = runner.call(fn, args, seconds, send=inherited is None)
    except LimitExceeded:
        _RUNNERS.runner = None
        runner.close(stop=True)
        raise
    except (_Died, OSError):
        _RUNNERS.runner = None
        status = runner.close(stop=True)
        if os.WIFSIGNALED(status):
            sig = os.WTERMSIG(status)
            if sig == signal.SIGKILL and memory_mb:
                raise LimitExceeded(
                    f"was killed (signal {sig}), likely out of memory (limit {memory_mb:g} MB)"
                ) from None
            raise ChildFailed(f"process died (signal {sig}: a crash)") from None
        code = os.WEXITSTATUS(status) if os.WIFEXITED(status) else status
        raise ChildFailed(f"process died (exit status {code}) before giving a result") from None
    if kind == "memory":
        _RUNNERS.runner = None  # a MemoryError may leave the child in a poor state
        runner.close(stop=True)
        raise LimitExceeded(
            f"used more than the memory limit of {memory_mb:g} MB"
            if memory_mb
            else "ran out of memory"
        )
    if kind == "error":
        raise ChildFailed(value)
    return value


def shutdown() -> None:
    """End this thread's child, if any (it also ends when this process does)."""
    runner = getattr(_RUNNERS, "runner", None)
    _RUNNERS.runner = None
    if runner is not None:
        runner.close(stop=False)


def _alive(pid: int) -> bool:
    try:
        done, _ = os.waitpid(pid, os.WNOHANG)
    except ChildProcessError:
        return False
    if done:
        _REAPED[pid] = _
        return False
    return True


def _stop(pid: int) -> None:
    """SIGTERM, then SIGKILL after ``GRACE_S`` if the child is still there."""
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGTERM)
    end = time.monotonic() + GRACE_S
    while time.monotonic() < end:
        done, _ = os.waitpid(pid, os.WNOHANG)
        if done:
            _REAPED[pid] = _
            return
        time.sleep(0.02)
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)


_REAPED: dict[int, int] = {}


def _reap(pid: int) -> int:
    if pid in _REAPED:
        return _REAPED.pop(pid)
    _, status = os.waitpid(pid, 0)
    return status
