"""Where a painted ring may be in a frame: bright, band-shaped components and their mid ellipses.

The channel-sum image, blurred (sigma 1.5 px), is thresholded at each of its three- and
four-class Otsu thresholds, midway between them, and at the Otsu threshold of each bright
class again (a far ring is a small class); every bright connected component that is not too
full for a band, and the unions of the two and three largest (a ring cut by the bow gap and an
occluder), gets an ellipse fitted to its pixels in a shrinking band (:func:`cv2.fitEllipse`),
and is a candidate when its pixels stay in a band of the ring's width-to-radius ratio about it
and cover most angles. Thin lines touching the ring (a deck line across it) are opened away
when the first look fails. :mod:`deckpose.detect.ring_edges` tries the candidates, largest
first.
"""

from __future__ import annotations

import itertools
import math

import cv2
import numpy as np
from numpy.typing import NDArray

from deckpose.painted_ring import PaintedRing

__all__ = ["ring_candidates"]


def ring_candidates(grey: NDArray[np.float32], ring: PaintedRing) -> list[tuple[float, float, float, float, float]]:
    """Mid lines ``(cu, cv, a, b, angle_rad)`` of the ring-like bright components, largest first."""
    from skimage.filters import threshold_multiotsu, threshold_otsu

    g = cv2.GaussianBlur(grey, (0, 0), 1.5)
    sub = g[::2, ::2].ravel()
    sub = np.minimum(sub, np.percentile(sub, 99.95))  # the beacons' and lights' few brightest pixels aside
    if np.ptp(sub) <= 0:
        return []
    thresholds: set[float] = set()
    for classes in (3, 4):
        try:
            t = sorted(float(x) for x in threshold_multiotsu(sub, classes=classes))
        except ValueError:
            continue
        thresholds.update(t)
        thresholds.update(0.5 * (a + b) for a, b in itertools.pairwise(t))
    for t in sorted(thresholds):  # a small ring (far away) is a small class: split each bright class again
        bright = sub[sub > t]
        if bright.size > 100 and np.ptp(bright) > 0:
            thresholds.add(float(threshold_otsu(bright)))
    expected = ring.line_width_m / ring.radius_m / math.sqrt(12.0)  # std of rho across a uniform band
    max_fill = max(0.3, 1.5 * math.pi * ring.line_width_m / ring.radius_m)
    found: list[tuple[float, float, float, float, float]] = []
    for t in sorted(thresholds, reverse=True):
        mask = (g > t).astype(np.uint8)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        pixels: dict[int, NDArray[np.float32]] = {}
        for k in range(1, n):
            x0, y0, w, h, area = (int(s) for s in stats[k])
            if area < 100 or min(w, h) < 16 or area > max_fill * w * h:
                continue  # too small, or too full for a band (an annulus fills (pi / 2) (width / radius) of its box)
            ys, xs = np.nonzero(labels[y0:y0 + h, x0:x0 + w] == k)
            stride = max(1, xs.size // 4000)  # a coarse ellipse needs no more
            pixels[k] = np.column_stack([xs[::stride] + x0, ys[::stride] + y0]).astype(np.float32)
        largest = sorted(pixels, key=lambda k: -int(stats[k, 4]))[:3]
        # each component, and the largest two and three together (a ring cut by the bow gap and an occluder)
        groups = [[k] for k in pixels] + [largest[:m] for m in (2, 3) if len(largest) >= m]
        for group in groups:
            pts = np.concatenate([pixels[k] for k in group])
            got = _ring_like(pts, expected)
            if got is None and group[0] in largest:  # lines thinner than the ring's touching it: open them away
                got = _ring_like(_without_thin_lines(pts), expected)
            if got is None:
                continue
            if not any(abs(got[0] - f[0]) < 0.05 * f[2] and abs(got[1] - f[1]) < 0.05 * f[2]
                       and abs(got[2] / f[2] - 1) < 0.05 for f in found):  # the same ring at another threshold
                found.append(got)
    return sorted(found, key=lambda f: -f[2] * f[3])


def _without_thin_lines(pts: NDArray[np.float32]) -> NDArray[np.float32]:
    """Pixels of a component after a morphological opening at 60 % of its line thickness.

    The thickness is the component's area over the circumference of its ellipse; deck lines
    narrower than that (a centre line across the ring) vanish, the ring's band stays.
    """
    if len(pts) < 20:
        return pts
    (_, _), (d1, d2), _ = cv2.fitEllipse(pts)
    thickness = len(pts) / (0.5 * math.pi * (d1 + d2))
    k = round(0.6 * thickness)
    if k < 3:
        return pts
    x0, y0 = pts.min(axis=0).astype(int) - k
    w, h = (pts.max(axis=0).astype(int) - (x0, y0)) + k + 1
    mask = np.zeros((h, w), np.uint8)
    mask[pts[:, 1].astype(int) - y0, pts[:, 0].astype(int) - x0] = 1
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    ys, xs = np.nonzero(mask)
    return np.column_stack([xs + x0, ys + y0]).astype(np.float32)


def _ring_like(pts: NDArray[np.float32], expected: float) -> tuple[float, float, float, float, float] | None:
    """The mid ellipse ``(cu, cv, a, b, angle_rad)`` of a component's pixels if they form a ring band.

    The ellipse is fitted to the pixels, then again to those within a shrinking band about
    it (a deck line touching the ring falls outside it); the component is a ring when at
    least 3/4 of its pixels stay in the band, their normalised radius spreads as a band of
    the ring's width would (``expected``: its standard deviation), and they cover 27 of 36
    angular sectors (the bow gap and occluders leave the rest).
    """
    keep = np.ones(len(pts), bool)
    band = max(4.0 * expected, 0.06)
    for width in (0.4, 0.2, 0.1, band, band):  # a shrinking band: a line across the ring drags the first fit
        if keep.sum() < 20:
            return None
        (cu, cv), (d1, d2), ang = cv2.fitEllipse(pts[keep])
        if not (d1 > 8 and d2 > 8):
            return None
        th = math.radians(ang)
        dx, dy = pts[:, 0] - cu, pts[:, 1] - cv
        xr = (dx * math.cos(th) + dy * math.sin(th)) / (0.5 * d1)
        yr = (-dx * math.sin(th) + dy * math.cos(th)) / (0.5 * d2)
        rho = np.hypot(xr, yr)
        keep = np.abs(rho - 1.0) < max(width, band)
        if keep.mean() < 0.5:  # not a band about any ellipse: stop early
            return None
    if keep.mean() < 0.75:
        return None
    occupied = np.unique(((np.arctan2(yr[keep], xr[keep]) + math.pi) / (2 * math.pi) * 36).astype(int) % 36).size
    if float(np.std(rho[keep])) < 2.5 * expected + 0.01 and occupied >= 27:
        return float(cu), float(cv), 0.5 * float(d1), 0.5 * float(d2), th
    return None
