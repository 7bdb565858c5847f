"""Fixed-point costs: local costs that are whole multiples of :data:`QUANTUM`.

When every local cost and every open-end skip is a whole multiple of ``QUANTUM`` and
every γ stays below :data:`LIMIT`, float64 sums of them are exact (they are integers in
units of ``QUANTUM``, below 2**52 of them): ``γ + C`` then orders cells exactly as ``γ``
does. :class:`engine.dtw.Aligner` relies on it to stop an edit's forward re-solve at the
first row whose γ differs from the old row's by one constant over the same band (every
later row then differs by the same constant and keeps its backpointers), and
checks the costs' claim before relying on it (:meth:`engine.dtw.align.Problem.exact_costs`).

The pass-1 sign costs are whole numbers already. Costs that are not are rounded to the
nearest multiple (:func:`on_grid`) where they are made: a change of at most
``QUANTUM / 2`` = 3e-8 per cell (it changes output bits, and could flip an exact tie of
sums that today differ by less than that).
"""

from __future__ import annotations

import numpy as np

#: the unit of fixed-point costs (2**-24 ≈ 6e-8)
QUANTUM = 2.0**-24
#: the largest |γ| whose sums stay exact: 2**52 quanta (2**28 ≈ 2.7e8 cost units)
LIMIT = 2.0**52 * QUANTUM


def on_grid(value):
    """``value`` (float or array) rounded to the nearest multiple of :data:`QUANTUM`
    (±inf and NaN as they are)."""
    return np.rint(np.asarray(value, dtype=np.float64) / QUANTUM) * QUANTUM


def is_on_grid(values) -> bool:
    """True when every finite value is a whole multiple of :data:`QUANTUM` below
    :data:`LIMIT` (infinite values pass: they stay infinite)."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return bool(np.all(np.abs(v) < LIMIT) and np.array_equal(on_grid(v), v))
