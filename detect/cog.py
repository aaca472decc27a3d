"""The ``cog`` detector: intensity-weighted centre of gravity of each candidate (:func:`~deckpose.detect.centroid.cog_centroids`)."""

from __future__ import annotations

from deckpose.detect.candidate import Candidate
from deckpose.detect.candidates import measure_candidate_batch
from deckpose.detect.centroid import cog_centroids
from deckpose.detect.registry import BlobRow, Blobs, DetectorOptions, register, register_kernel

from deckpose.records import Frame

__all__ = ["detect_cog", "measure_cog"]


def measure_cog(cands: list[Candidate], options: DetectorOptions) -> list[BlobRow | None]:
    """The ``cog`` row of each candidate (``None``: a clipped core cut by the frame edge)."""
    rows = cog_centroids(cands, options.window_sigma)
    return [None if c.clipped_at_frame_edge() else r for c, r in zip(cands, rows)]


@register("cog")
def detect_cog(frame: Frame, options: DetectorOptions) -> Blobs:
    """Intensity-weighted centre of gravity in a re-centred window around each blob.

    A clipped core that the frame edge cuts is not measured
    (:meth:`~deckpose.detect.candidate.Candidate.clipped_at_frame_edge`): its centre of
    gravity is that of the part in view. (``gauss`` fits its wings instead.)
    """
    return measure_candidate_batch(frame, options, lambda cands: measure_cog(cands, options))


register_kernel("cog", measure_cog)
