"""The ``binary`` detector: threshold + connected components, centre of the binary blob (the baseline)."""

from __future__ import annotations

from deckpose.detect.candidates import measure_candidates
from deckpose.detect.centroid import binary_centroid
from deckpose.detect.registry import Blobs, DetectorOptions, register

from deckpose.records import Frame

__all__ = ["detect_binary"]


@register("binary")
def detect_binary(frame: Frame, options: DetectorOptions) -> Blobs:
    """Baseline: adaptive threshold + connected components, binary-blob centre."""
    return measure_candidates(frame, options, binary_centroid)
