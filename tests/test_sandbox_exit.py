"""A process that kept a sandbox child exits promptly, even when something at exit
waits for a helper process whose pipe the child inherited (Python 3.13's multiprocessing
resource tracker does: ``make test`` hung after "1304 passed" on Debian 13)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# What Python 3.13 does at exit, done here by hand so any Python shows it: the resource
# tracker's pipe is closed and its process waited for; the tracker ends only when every
# holder of the pipe's write end (a forked child too) has closed it.
SCRIPT = textwrap.dedent(
    """
    import atexit, os
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    tracker = resource_tracker._resource_tracker

    def wait_for_tracker():  # registered first, so it runs after the sandbox's own hook
        os.close(tracker._fd)
        os.waitpid(tracker._pid, 0)

    atexit.register(wait_for_tracker)

    import threading
    from engine.jobs.sandbox import run_limited

    assert run_limited(pow, (2, 10), seconds=30) == 1024  # a child kept for the next call
    box = []
    worker = threading.Thread(target=lambda: box.append(run_limited(pow, (3, 3))))
    worker.start(); worker.join()  # a second thread's child, forked beside the first
    assert box == [27]
    print("done", flush=True)
    """
)


def test_a_process_with_kept_children_exits_promptly():
    t0 = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    took = time.monotonic() - t0
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == "done"
    assert took < 60, f"exit took {took:.1f} s"
