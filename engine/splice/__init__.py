"""Splicing: the two-pass alignment, merging and smoothing, and the finger transfer.

``pipeline`` (prepare, align_passes, transfer, splice), ``merge`` (path -> warp),
``transfer`` (rotations onto the body skeleton), ``report`` (REPORT.json).
"""
