"""The ``cog`` detector: intensity-weighted centre of gravity of each candidate (:func:`~deckpose.detect.centroid.cog_centroid`)."""

from __future__ import annotations

from deckpose.detect.candidates import measure_candidates
from deckpose.detect.centroid import cog_centroid
from deckpose.detect.registry import Blobs, DetectorOptions, register

from deckpose.records import Frame

__all__ = ["detect_cog"]


@register("cog")
def detect_cog(frame: Frame, options: DetectorOptions) -> Blobs:
    """Intensity-weighted centre of gravity in a re-centred window around each blob."""
    return measure_candidates(frame, options, lambda c: cog_centroid(c, options.window_sigma))
