"""The ``cog`` detector: intensity-weighted centre of gravity of each candidate (:func:`~deckpose.detect.centroid.cog_centroid`)."""

from __future__ import annotations

from deckpose.detect.candidate import Candidate
from deckpose.detect.candidates import measure_candidates
from deckpose.detect.centroid import Row, cog_centroid
from deckpose.detect.registry import Blobs, DetectorOptions, register

from deckpose.records import Frame

__all__ = ["detect_cog"]


@register("cog")
def detect_cog(frame: Frame, options: DetectorOptions) -> Blobs:
    """Intensity-weighted centre of gravity in a re-centred window around each blob.

    A clipped core that the frame edge cuts is not measured
    (:meth:`~deckpose.detect.candidate.Candidate.clipped_at_frame_edge`): its centre of
    gravity is that of the part in view. (``gauss`` fits its wings instead.)
    """

    def measure(c: Candidate) -> Row | None:
        return None if c.clipped_at_frame_edge() else cog_centroid(c, options.window_sigma)

    return measure_candidates(frame, options, measure)
