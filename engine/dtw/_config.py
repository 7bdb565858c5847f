"""Numba options of the DTW kernels: :mod:`engine.base.jit` (the one place for every kernel)."""

from __future__ import annotations

from engine.base.jit import FASTMATH, JIT, JIT_CACHED, njit, njit_cached

__all__ = ["FASTMATH", "JIT", "JIT_CACHED", "njit", "njit_cached"]
