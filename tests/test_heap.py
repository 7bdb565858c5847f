"""The server's heap gives freed large arrays back to the system (``webapp.heap``; issue 13,
the 10-minute pair's drags grew the server's resident memory by hundreds of MB)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: an edit's pattern: a large array freed (glibc raises its mmap threshold to its size),
#: then arrays under that size made and all but the last dropped; prints the resident MB
#: still held over the start
CHILD = """
import sys
import numpy as np
from webapp import heap
if sys.argv[1] == "fixed":
    assert heap.give_back_large_blocks()
def rss_mb():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) >> 10
a = np.ones(16 << 17)
del a
start = rss_mb()
blocks = [np.ones(8 << 17) for _ in range(20)]
del blocks[:-1]
print(rss_mb() - start)
"""


def _held_mb(mode: str) -> int:
    out = subprocess.run(
        [sys.executable, "-c", CHILD, mode],
        cwd=ROOT,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=True,
    )
    return int(out.stdout.strip())


def test_freed_arrays_of_an_edit_leave_the_server():
    # glibc's default: 19 freed 8 MB arrays (152 MB) stay resident under the last one
    assert _held_mb("default") > 100
    # the server's setting (handsplice serve): only the live 8 MB array is held
    assert _held_mb("fixed") < 30
