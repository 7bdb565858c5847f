"""Gesture analysis and hand synthesis (Heloir et al. 2010; Jin & Hahn 2005; docs/method.md §7-8).

- ``phases``: ``Phase`` codes (REST=0, PREPARATION=1, STROKE=2, HOLD=3,
  RETRACTION=4), ``PHASE_COLORS``, ``segment_phases(motion)`` -> per-frame labels,
  segments and phrases ``P? (S|H)+ R?`` per hand.
- ``handedness``: ``detect_handedness(phases)`` -> RH / LH / 2H per phrase.
- ``keyposes``: ``key_poses(motion, side)`` -> key frames and the pose-space
  distance map.
- ``synthesis``: pose library, easings, ``synthesize_from_poses``,
  ``synthesize_from_clip`` (speed matching, flexion warping).
- ``analysis``: ``analyze_take(motion)`` runs phases, handedness and key poses.
- ``body``: arm joints in the body frame, metres; ``constructed``: synthetic
  gesture paths with known phases.

Submodules are imported on use (``from engine.gesture.phases import Phase``).
"""
