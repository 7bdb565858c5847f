"""Banded dynamic time warping with user matching points (Majkowska et al. 2006).

Rows are body frames (``n``), columns hand frames (``m``), indices 0-based.

Quick reference::

    from engine.dtw import Aligner, Band, align, align_features

    band = Band.sakoe_chiba(n, m, 0.30)                         # W = 30 % of n
    band = Band.from_constraints(n, m, 0.30, [(120, 98, 2)])    # (x, y, tol)
    band2 = Band.around_path(first.path, n, m, radius=20, points=[(120, 98, 2)])
    result = align(cost, band)                  # cost: (n, m) local costs
    result = align_features(a, b, band)         # a: (n, d), b: (m, d), metric="sqeuclidean"
    result.path, result.cost, result.band
    result = align_features(a, b, band, ends=Ends(body=60, hand=60, skip=0.5))  # open ends

    solver = Aligner(a, b, metric="sqeuclidean")   # incremental: keeps rows
    solver.solve(band); solver.solve(edited_band)  # recomputes only rows that can change

Modules: ``band`` (Band), ``align`` (Alignment, align, align_features),
``incremental`` (Aligner), ``views`` (cost images), ``kernels`` (numba
kernels and the metric registry: ``register_metric``).
"""

from .align import FIXED, Alignment, Ends, align, align_features, ends_through_points
from .band import Band, check_path
from .incremental import Aligner, SolveStats
from .kernels import metric_names, register_metric
from .views import BandValues, CostImage, cost_image, local_cost_image

__all__ = [
    "FIXED",
    "Aligner",
    "Alignment",
    "Ends",
    "ends_through_points",
    "Band",
    "BandValues",
    "CostImage",
    "SolveStats",
    "align",
    "align_features",
    "check_path",
    "cost_image",
    "local_cost_image",
    "metric_names",
    "register_metric",
]
