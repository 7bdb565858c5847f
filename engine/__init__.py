"""HandSplice engine: everything computational (no web imports).

Layers, top to bottom: ``io`` (files) -> ``motion`` (data model) ->
``kinematics``/``roles`` -> ``features``/``metrics`` -> ``dtw`` -> ``splice``;
``gesture``, ``mesh`` and ``render`` read ``Motion`` too.
"""

__version__ = "0.1.0"
