"""Numba options for every kernel of the engine, in one place.

``FASTMATH`` leaves out ``nnan`` and ``ninf``: NaN gaps in capture data are
real and ``+inf`` marks forbidden DTW cells, so the compiler must keep IEEE
semantics for both. ``reassoc`` is left out too, so a sum over feature
dimensions is added in order, as in the plain-Python references
(``tests/naive.py``); DTW kernels and forward kinematics use it.

``FASTMATH_REASSOC`` adds ``reassoc`` for kernels whose result does not depend on
the order of additions beyond rounding that tests tolerate (the pass-1 and pass-2
local-cost metrics in :mod:`engine.align.metrics`, compared to references within 1e-9).

``JIT_CACHED`` is for kernels that are always called with one fixed set of
argument types (float64 C-contiguous arrays, int64 band bounds): their machine
code is cached on disk (``NUMBA_CACHE_DIR``, set to ``.numba_cache`` by the
Makefile). Kernels specialised on a user metric (a numba function passed as an
argument) use ``JIT`` and compile once per process and metric: numba cannot cache
a kernel that takes a dispatcher.

This module imports only numba: every layer (``engine.dtw`` included) may use it.
"""

from __future__ import annotations

import os
from pathlib import Path

import numba

FASTMATH = {"nsz", "arcp", "contract", "afn"}
FASTMATH_REASSOC = FASTMATH | {"reassoc"}

JIT = {"nogil": True, "fastmath": set(FASTMATH)}
JIT_CACHED = {**JIT, "cache": True}


def njit(**overrides):
    """``numba.njit`` with the defaults (no cache); ``overrides`` win."""
    return numba.njit(**{**JIT, **overrides})


def njit_cached(**overrides):
    """``numba.njit`` with the defaults and ``cache=True``; ``overrides`` win."""
    return numba.njit(**{**JIT_CACHED, **overrides})


def kernels_cached() -> bool:
    """Whether this machine's numba cache holds compiled kernels (``*.nbi`` index files in
    ``NUMBA_CACHE_DIR``, else in the engine's ``__pycache__`` folders): False on a first
    run, which compiles them (about a minute) before its first stage can run."""
    where = os.environ.get("NUMBA_CACHE_DIR")
    root = Path(where) if where else Path(__file__).resolve().parents[1]
    try:
        return next(root.rglob("*.nbi"), None) is not None
    except OSError:
        return False
