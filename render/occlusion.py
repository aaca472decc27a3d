"""Beacons hidden by crew, equipment or spray: a straight occluder edge across the spot.

An occluded beacon's light is cut by a half-plane ``n . (x - c) > s`` in the image
(``c`` the spot's centre, ``n`` a unit normal at a random angle), placed so that it
hides a fraction ``f`` of the core's light: for a Gaussian core of second-moment
matrix ``S``, ``s = sigma_n Phi^-1(1 - f)`` with ``sigma_n^2 = n^T S n``. The edge is
antialiased over one pixel (the mask ramps from 1 to 0 across it), and the mask cuts
core and halo alike (the occluder stands in front of the light). ``f = 1`` removes
the beacon from the image.

The record is what was drawn: the fraction of the spot's light the mask removed and
the centroid of the light left, both summed over the masked patch, so a benchmark can
score an occluded beacon against the light that is there (its projected centre, the
pose truth, does not move).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from deckpose.render.beacons import Splat
from deckpose.render.occlusion_config import OcclusionSpec
from numpy.typing import NDArray
from scipy.special import ndtri

#: Stream index of the occluders in ``SeedSequence([frame seed, stream])``.
OCCLUSION_STREAM = 1


@dataclass(frozen=True)
class OcclusionRecord:
    """Per-beacon occlusion of one frame; arrays are (N,) over the layout's beacons.

    Attributes
    ----------
    hidden_fraction : (N,) array of float
        Fraction of the spot's light the occluder removed (0: not occluded; 1: hidden).
    light_u_px, light_v_px : (N,) arrays of float
        Centroid of the beacon's light left in the image, pixels (the spot's centre when
        not occluded; NaN when hidden or without a spot).
    """

    hidden_fraction: NDArray[np.float64]
    light_u_px: NDArray[np.float64]
    light_v_px: NDArray[np.float64]


def _centroid(patch: NDArray[np.float32], row0: int, col0: int) -> tuple[float, float, float]:
    total = float(patch.sum(dtype=np.float64))
    if total <= 0:
        return math.nan, math.nan, 0.0
    rows = np.arange(row0, row0 + patch.shape[0], dtype=np.float64)
    cols = np.arange(col0, col0 + patch.shape[1], dtype=np.float64)
    u = float(patch.sum(axis=0, dtype=np.float64) @ cols) / total
    v = float(patch.sum(axis=1, dtype=np.float64) @ rows) / total
    return u, v, total


def occlude(splats: list[Splat], spec: OcclusionSpec, n_beacons: int,
            rng: np.random.Generator) -> tuple[list[Splat], OcclusionRecord]:
    """Cut the occluded beacons' splats and record what was hidden.

    Parameters
    ----------
    splats : list of Splat
        The frame's beacon splats (:func:`deckpose.render.beacons.beacon_splats`).
    spec : OcclusionSpec
    n_beacons : int
        Beacons in the layout (length of the record's arrays).
    rng : numpy.random.Generator
        The frame's occlusion stream; three values are drawn per splat whether or not
        it is occluded, so one beacon's occluder does not depend on the others'.

    Returns
    -------
    list of Splat
        The splats, occluded ones masked (their ``core_flux`` scaled by the light left)
        and wholly hidden ones dropped.
    OcclusionRecord
    """
    hidden = np.zeros(n_beacons)
    lu = np.full(n_beacons, np.nan)
    lv = np.full(n_beacons, np.nan)
    out: list[Splat] = []
    for sp in splats:
        i = sp.beacon_id
        draw = rng.random(3)  # occluded?, hidden fraction, edge angle
        lu[i], lv[i] = sp.centre_px
        if spec.probability == 0 or draw[0] >= spec.probability:
            out.append(sp)
            continue
        f = spec.min_fraction + (spec.max_fraction - spec.min_fraction) * draw[1]
        if f >= 1.0:
            hidden[i], lu[i], lv[i] = 1.0, math.nan, math.nan
            continue
        angle = 2.0 * math.pi * draw[2]
        n = np.array([math.cos(angle), math.sin(angle)])
        sigma_n = math.sqrt(float(n @ sp.cov_px2 @ n))
        s = sigma_n * float(ndtri(1.0 - f))
        h, w = sp.patch.shape
        du = np.arange(sp.col0, sp.col0 + w, dtype=np.float64)[None, :] - sp.centre_px[0]
        dv = np.arange(sp.row0, sp.row0 + h, dtype=np.float64)[:, None] - sp.centre_px[1]
        mask = np.clip(0.5 - (n[0] * du + n[1] * dv - s), 0.0, 1.0).astype(np.float32)
        patch = sp.patch * mask
        _, _, before = _centroid(sp.patch, sp.row0, sp.col0)
        u, v, after = _centroid(patch, sp.row0, sp.col0)
        kept = after / before if before > 0 else 0.0
        hidden[i], lu[i], lv[i] = 1.0 - kept, u, v
        out.append(dataclasses.replace(sp, patch=patch, core_flux=sp.core_flux * kept))
    return out, OcclusionRecord(hidden, lu, lv)
