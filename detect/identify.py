"""Beacon identification: which detection is which beacon of the layout, from the frame alone.

The entry point :func:`identify_beacons` dispatches on the layout: a one-ring layout
to :func:`~deckpose.detect.one_ring_identify.identify_one_ring` (the ring's ellipse,
its even spacing, its red bow beacon), a two-ring layout to
:func:`~deckpose.detect.two_ring_identify.identify_two_rings`. The record and options
live in :mod:`~deckpose.detect.identification`; a frame that cannot be identified
alone can be by a prior pose (:mod:`~deckpose.detect.prior_identify`).
"""

from __future__ import annotations

import numpy as np
from deckpose.detect.identification import Identification, IdentifyOptions
from deckpose.detect.one_ring_identify import identify_one_ring
from deckpose.detect.two_ring_identify import identify_two_rings
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import UNASSIGNED

__all__ = ["UNASSIGNED", "Identification", "IdentifyOptions", "identify_beacons"]

FloatArray = NDArray[np.float64]


def identify_beacons(
    points_px: FloatArray,
    layout: DeckLayout,
    camera: CameraModel,
    *,
    rgb_flux: FloatArray | None = None,
    options: IdentifyOptions = IdentifyOptions(),
) -> Identification:
    """Assign layout beacon ids to detections.

    A layout with an inner ring (``layout.inner_n_ring > 0``) is identified by
    :func:`~deckpose.detect.two_ring_identify.identify_two_rings`: the outer ring as below when enough of it, its
    bow included, is in view; else the inner ring by the same steps; the other
    ring's visible beacons then by the identified ring's homography.

    Parameters
    ----------
    points_px : (N, 2) array of float
        Detected centres, distorted pixels.
    layout : DeckLayout
    camera : CameraModel
        For undistortion.
    rgb_flux : (N, 3) array of float, optional
        Per-channel flux of each blob (:func:`deckpose.detect.colour.blob_rgb_flux`);
        ``None`` for mono frames.
    options : IdentifyOptions

    Returns
    -------
    Identification
    """
    if layout.inner_n_ring:
        return identify_two_rings(points_px, layout, camera, rgb_flux=rgb_flux, options=options)
    return identify_one_ring(points_px, layout, camera, rgb_flux=rgb_flux, options=options)
