"""Leaves every layer may use: errors, input limits, numeric tolerances, numba options, atomic writes."""
