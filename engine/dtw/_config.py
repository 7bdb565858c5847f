"""Numba options for every DTW kernel, in one place.

``FASTMATH`` leaves out ``nnan`` and ``ninf``: NaN gaps in capture data are
real and ``+inf`` marks forbidden cells, so the compiler must keep IEEE
semantics for both. ``reassoc`` is left out too, so a sum over feature
dimensions is added in order, as in the plain-Python reference.

``JIT_CACHED`` is for kernels that are always called with one fixed set of
argument types (float64 C-contiguous arrays, int64 band bounds): their machine
code is cached on disk (``NUMBA_CACHE_DIR``, set to ``.numba_cache`` by the
Makefile). Kernels specialised on a user metric (a numba function passed as an
argument) use ``JIT`` and compile once per process and metric.
"""

from __future__ import annotations

import numba

FASTMATH = {"nsz", "arcp", "contract", "afn"}

JIT = {"nogil": True, "fastmath": set(FASTMATH)}
JIT_CACHED = {**JIT, "cache": True}


def njit(**overrides):
    """``numba.njit`` with the DTW defaults (no cache); ``overrides`` win."""
    return numba.njit(**{**JIT, **overrides})


def njit_cached(**overrides):
    """``numba.njit`` with the DTW defaults and ``cache=True``."""
    return numba.njit(**{**JIT_CACHED, **overrides})
