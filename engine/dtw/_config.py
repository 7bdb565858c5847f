"""Numba options of the DTW kernels: :mod:`engine.jit` (the one place for every kernel)."""

from __future__ import annotations

from engine.jit import FASTMATH, JIT, JIT_CACHED, njit, njit_cached

__all__ = ["FASTMATH", "JIT", "JIT_CACHED", "njit", "njit_cached"]
