"""Work on a second thread beside the caller's: started at once, its result (or its error,
re-raised) taken when the caller needs it.

The DTW kernels release the GIL, so two solves on two threads use two cores: the
backward rows of an edit beside its forward rows (``engine.dtw.incremental``), pass 2's
final solve beside its probe (``engine.splice.pipeline``).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any


class Beside:
    """``work()`` running on its own (daemon) thread named ``name``.

    :meth:`result` waits for it and returns its value, or raises what it raised. Call it
    (or :meth:`wait`) before touching anything ``work`` changes."""

    def __init__(self, work: Callable[[], Any], name: str):
        self._out: dict[str, Any] = {}

        def run() -> None:
            try:
                self._out["value"] = work()
            except BaseException as exc:  # re-raised on the calling thread
                self._out["error"] = exc

        self._thread = threading.Thread(target=run, name=name, daemon=True)
        self._thread.start()

    def wait(self) -> None:
        """Wait until ``work`` has returned or raised (its error is not raised here)."""
        self._thread.join()

    def result(self) -> Any:
        """``work()``'s value, after waiting for it; its exception re-raised."""
        self._thread.join()
        if "error" in self._out:
            raise self._out["error"]
        return self._out["value"]
