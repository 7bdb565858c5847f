"""Trust in a splice: the uncertainty of its alignment with the body take's strokes.

Joins :mod:`engine.splice.uncertainty` (uncertainty per body frame, suggestions) and
:mod:`engine.gesture.phases` (where the strokes are) for the CLI, the batch and the
app; it sits above both so that neither imports the other.
"""

from __future__ import annotations

from engine.gesture.phases import Phase, marker_phase_labels
from engine.splice import uncertainty


def assess_splice(features, alignment, body_phases=None, cancelled=None) -> uncertainty.Assessment:
    """``uncertainty.Assessment`` of a splice alignment.

    features : pipeline.SpliceFeatures; alignment : pipeline.SpliceAlignment
    body_phases : (n,) phase codes of the body take when already known (the app has them),
        else segmented from the first spliced arm's wrist markers
    cancelled : callable or None; once it returns True the assessment stops with
        ``engine.base.errors.Cancelled`` (the app: a newer edit made it stale)
    """
    if body_phases is None:
        body_phases = marker_phase_labels(features.body_markers, features.fps)
    return uncertainty.assess(
        features, alignment, body_phases, int(Phase.STROKE), cancelled=cancelled
    )
