"""``opencv-blob``: OpenCV's ``SimpleBlobDetector`` in each full-resolution candidate window.

``SimpleBlobDetector`` thresholds the image at a series of levels, takes the
contour moments of each binary blob and averages centres over the levels where
the blob persists. It runs on 8-bit images, so each window is scaled from its
background (0) to its peak (255); the lowest level is the frame's adaptive
threshold. The coarse-to-fine search keeps it off the full frame.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from deckpose.detect.candidate import Candidate
from deckpose.detect.candidates import measure_candidates
from deckpose.detect.registry import BlobRow, Blobs, DetectorOptions, register

from deckpose.records import Frame


def _params(min_threshold: float, min_area: int) -> cv2.SimpleBlobDetector.Params:
    # OpenCV's stubs name the class SimpleBlobDetector.Params only; the flat name, the same
    # class, is the one OpenCV 4.x has too (and so is SimpleBlobDetector_create below)
    p = cv2.SimpleBlobDetector_Params()  # pyright: ignore[reportAttributeAccessIssue]
    p.filterByColor = True
    p.blobColor = 255
    p.minThreshold = float(min_threshold)
    p.maxThreshold = 250.0
    p.thresholdStep = max(1.0, (250.0 - min_threshold) / 12.0)
    p.minRepeatability = 2
    p.filterByArea = True
    p.minArea = float(min_area)
    p.maxArea = 1e9
    p.filterByCircularity = False
    p.filterByConvexity = False
    p.filterByInertia = False
    p.minDistBetweenBlobs = 1.0
    return p


def opencv_blob(cand: Candidate) -> BlobRow | None:
    """Measure one candidate with ``SimpleBlobDetector``; ``None`` if it finds nothing there."""
    s = cand.signal()
    peak = float(s[cand.mask].max())
    if not peak > 0:
        return None
    img = np.clip(s / peak * 255.0, 0, 255).astype(np.uint8)
    t_min = float(np.clip((cand.threshold_dn - cand.background_dn) / peak * 255.0, 1.0, 240.0))
    det = cv2.SimpleBlobDetector_create(_params(t_min, 1))  # pyright: ignore[reportAttributeAccessIssue]
    kps = det.detect(img)
    if not kps:
        return None
    mu, mv, _ = cand.mask_moments()
    k = min(kps, key=lambda kp: math.hypot(kp.pt[0] + cand.u0 - mu, kp.pt[1] + cand.v0 - mv))
    u, v = k.pt[0] + cand.u0, k.pt[1] + cand.v0
    if math.hypot(u - mu, v - mv) > 0.5 * k.size + 2.0:
        return None
    flux = float(s[cand.mask].sum())
    return cand.blob(u, v, flux_dn=flux, size_px=k.size / 4.0)


@register("opencv-blob")
def detect_opencv_blob(frame: Frame, options: DetectorOptions) -> Blobs:
    """OpenCV ``SimpleBlobDetector`` per candidate window."""
    return measure_candidates(frame, options, opencv_blob)
