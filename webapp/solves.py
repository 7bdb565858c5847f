"""Long work of one browser session off the server's event loop: opening takes, solving.

A Bokeh server runs every session's callbacks on one event loop, so a solve that takes
seconds there (the first alignment of a 10-minute pair: about 15 s) freezes every tab
the server has. :class:`SolveRunner` runs such work on a worker thread instead and
applies its result on the event loop, under the session's document lock (a next-tick
callback), like the preview renders (``webapp.views.preview``).

One runner per session; its jobs run one at a time, in order, so each solve can reuse
the previous one's DTW rows (the engine's incremental solvers are not shared between
threads). Two kinds of job:

* ``"inputs"``: open takes (read, features) or a whole staged session (a link or a
  session file). A newer ``inputs`` job supersedes an older one; a ``"solve"`` job asked
  for while one is pending is dropped (the opening solves the state it finds).
* ``"solve"``: band and path for the current parameters and matching points. A newer
  solve supersedes an older one: a queued one is replaced (never computed), a running
  one's result is not shown (only the newest edit's path is drawn).

Without a server (tests, scripts) there is no runner: the session computes at once.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

from webapp.views._dispatch import next_tick

#: worker threads shared by every session (each session runs one job at a time); the
#: engine's kernels release the GIL, so a solve leaves the event loop free
_POOL = ThreadPoolExecutor(max_workers=4, thread_name_prefix="hs-solve")

KINDS = ("inputs", "solve")


@dataclass
class Job:
    """One piece of work: ``work(progress)`` on the worker; ``done(result)`` or
    ``failed(exc)`` on the event loop when it is still the newest of its kind;
    ``dropped()`` when it was superseded (queued or running)."""

    kind: str
    label: str
    work: Callable
    done: Callable
    failed: Callable
    dropped: Callable | None = None
    gens: dict = field(default_factory=dict)


class SolveRunner:
    """Runs a session's jobs on a worker thread, newest wins (see the module docstring).

    ``doc``: the session's Bokeh document (results are applied in its next-tick
    callbacks); ``on_busy(label)``: called on the event loop with the running job's
    label, or ``""`` when nothing is left to do.
    """

    def __init__(self, doc, on_busy: Callable[[str], None] | None = None, pool=_POOL):
        self._doc = doc
        self._pool = pool
        self._on_busy = on_busy
        self._running: Job | None = None
        self._queued: Job | None = None
        self._gen = dict.fromkeys(KINDS, 0)
        #: what the running job is doing (the engine's stage) and since when (monotonic s);
        #: read by the page's progress line
        self.stage = ""
        self.started = 0.0

    # ------------------------------------------------------------ on the event loop

    @property
    def busy(self) -> bool:
        return self._running is not None or self._queued is not None

    def _current(self, job: Job | None) -> bool:
        """True while ``job`` is the newest of its kind (a solve: and no opening since)."""
        if job is None:
            return False
        if job.kind == "inputs":
            return job.gens["inputs"] == self._gen["inputs"]
        return job.gens == self._gen

    def solving(self) -> bool:
        """True while a solve job runs or waits (its path is not in the page yet)."""
        return any(
            j is not None and j.kind == "solve" and self._current(j)
            for j in (self._running, self._queued)
        )

    def inputs_pending(self) -> bool:
        return any(
            j is not None and j.kind == "inputs" and self._current(j)
            for j in (self._running, self._queued)
        )

    def submit(self, job: Job) -> bool:
        """Queue ``job`` (it supersedes older work, see the module docstring); False when a
        solve is dropped because takes are being opened."""
        if job.kind == "solve" and self.inputs_pending():
            if job.dropped is not None:
                job.dropped()
            return False
        self._gen[job.kind] += 1
        if job.kind == "inputs":  # a new pair: any solve of the old one is stale
            self._gen["solve"] += 1
        job.gens = dict(self._gen)
        old, self._queued = self._queued, job
        if old is not None and old.dropped is not None:
            old.dropped()
        if self._running is None:
            self._start()
        return True

    def _start(self) -> None:
        job, self._queued = self._queued, None
        if job is None:
            self._report("")
            return
        self._running = job
        self.stage, self.started = job.label, time.monotonic()
        self._report(job.label)
        future = self._pool.submit(self._run, job)
        doc = self._doc

        def finished(f):
            try:
                next_tick(doc, lambda: self._finish(job, f))
            except Exception:  # the tab was closed meanwhile: nothing to show
                pass

        future.add_done_callback(finished)

    def _finish(self, job: Job, future) -> None:
        self._running = None
        try:
            if not self._current(job):
                if job.dropped is not None:
                    job.dropped()
                return
            try:
                result = future.result()
            except Exception as exc:  # the job's own refusal: the session says why
                job.failed(exc)
                return
            job.done(result)
        finally:
            if self._running is None:  # done/failed may have started the next job already
                self._start()

    def _report(self, label: str) -> None:
        if self._on_busy is not None:
            self._on_busy(label)

    # ------------------------------------------------------------ on the worker

    def _run(self, job: Job):
        def progress(stage: str, fraction: float) -> None:
            self.stage = f"{job.label}: {stage}"

        return job.work(progress)
