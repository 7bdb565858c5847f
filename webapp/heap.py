"""The server's heap gives large freed blocks back to the system (glibc's malloc).

A long pair's edits make and drop arrays of tens of MB (a solve's rows, a spliced take,
the trust's band rows) on several threads. glibc maps a block of at least its *mmap
threshold* on its own and unmaps it when freed, but it raises that threshold to the size of
each mapped block that is freed (up to 32 MB on 64-bit), so after the first edit the
next edits' arrays come from the threads' heaps, where a freed block stays resident until
everything above it is freed too: the server's resident memory grew by hundreds of MB
during drags on the 10-minute pair while the live arrays did not (RESULTS.md, tenmin2).
:func:`give_back_large_blocks` fixes the threshold (no raising) and trims the heaps at a
lower mark. Other C libraries: nothing is changed.
"""

from __future__ import annotations

import ctypes
import sys

#: ``mallopt`` parameters (``malloc.h``)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: blocks of this many bytes or more are mapped on their own and unmapped when freed
MMAP_BYTES = 1 << 20
#: free memory at a heap's top beyond this many bytes is given back
TRIM_BYTES = 8 << 20


def give_back_large_blocks() -> bool:
    """Fix glibc's mmap threshold at :data:`MMAP_BYTES` and its trim threshold at
    :data:`TRIM_BYTES` for this process; True when both were set (False elsewhere than
    glibc on Linux: nothing changed)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return mallopt(M_MMAP_THRESHOLD, MMAP_BYTES) == 1 and mallopt(M_TRIM_THRESHOLD, TRIM_BYTES) == 1
