"""``log``: scikit-image Laplacian-of-Gaussian blob candidates, measured by ``cog``.

:func:`skimage.feature.blob_log` runs on the block-averaged (coarse) frame, so
the scale-space search stays cheap on large frames; each blob it finds opens a
full-resolution window that the ``cog`` centroider measures.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.detect.background import difference_noise, noise_floor_dn, robust_stats
from deckpose.detect.candidates import coarse_factor, coarse_image, measure_candidate_batch
from deckpose.detect.centroid import cog_centroids
from deckpose.detect.registry import Blobs, DetectorOptions, register
from deckpose.detect.spots import SpotSearch, peak_block_max
from skimage.feature import blob_log

from deckpose.records import Frame

#: The LoG scale space is searched on at most this many coarse pixels.
LOG_MAX_PX = 500_000


def log_boxes(
    image: np.ndarray, options: DetectorOptions, search: SpotSearch | None = None
) -> tuple[list[tuple[int, int, int, int]], str]:
    """Full-resolution boxes around LoG blobs of the coarse frame.

    With the frame's bright-spot search (``search``), only LoG blobs that hold a
    beacon-bright core are kept.
    """
    f = coarse_factor(image.shape[:2], min(options.coarse_max_px, LOG_MAX_PX))
    small = coarse_image(image, f)
    step = max(1, int(math.sqrt(small.size / 60_000)))
    bg, _ = robust_stats(small[::step, ::step])
    noise = max(difference_noise(small), noise_floor_dn(image))
    sig = np.clip((small - bg) / noise, 0.0, None).astype(np.float32)
    bright = None
    if search is not None:
        # Bright-spot search: LoG only around the beacon-bright cores. Elsewhere (a lit,
        # textured deck at dusk) it finds thousands of blobs, and blob_log's pruning of
        # overlapping blobs is quadratic in their number (a minute per 8 MP frame).
        small_max = peak_block_max(search.image, f)[: sig.shape[0], : sig.shape[1]]
        bright = small_max > search.threshold_dn
        n, _, stats, _ = cv2.connectedComponentsWithStats(bright.astype(np.uint8), connectivity=8)
        r_max = math.sqrt(float(stats[1:, cv2.CC_STAT_AREA].max()) / math.pi) if n > 1 else 1.0
        R = math.ceil(3.0 * r_max + 3.0)  # the LoG of a disc of radius r reaches ~2 r
        disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * R + 1, 2 * R + 1))
        sig[cv2.dilate(bright.astype(np.uint8), disc) == 0] = 0.0
    # The scale-normalised LoG of unit-variance white noise has a standard deviation
    # of 0.40 at sigma = 1 (0.20 at 2, 0.10 at 4): the threshold is threshold_sigma
    # times that at the smallest scale searched.
    found = blob_log(
        sig,
        min_sigma=1,
        max_sigma=max(2.0, min(sig.shape) / 20.0),
        num_sigma=8,
        threshold=0.40 * options.threshold_sigma,
        overlap=0.5,
    )
    if bright is not None:
        # Bright-spot search: keep the LoG blobs that hold a beacon-bright core.
        hb, wb = bright.shape
        found = np.array(
            [
                b
                for b in found
                if bright[
                    max(0, int(b[0] - 2 * b[2] - 1)) : min(hb, int(b[0] + 2 * b[2] + 2)),
                    max(0, int(b[1] - 2 * b[2] - 1)) : min(wb, int(b[1] + 2 * b[2] + 2)),
                ].any()
            ]
        ).reshape(-1, 3)
    if len(found) > options.max_blobs:
        return [], f"{len(found)} LoG blobs exceed max_blobs={options.max_blobs}"
    H, W = image.shape[:2]
    boxes = []
    for y, x, s in found:
        half = math.ceil(3.0 * s * f) + f + 2
        cu, cv = int(x * f + (f - 1) / 2), int(y * f + (f - 1) / 2)
        boxes.append(
            (max(0, cu - half), max(0, cv - half), min(W, cu + half + 1), min(H, cv + half + 1))
        )
    return boxes, ""


@register("log")
def detect_log(frame: Frame, options: DetectorOptions) -> Blobs:
    """scikit-image ``blob_log`` candidates refined by ``cog``."""
    return measure_candidate_batch(
        frame, options, lambda cands: cog_centroids(cands, options.window_sigma), boxes_fn=log_boxes
    )
