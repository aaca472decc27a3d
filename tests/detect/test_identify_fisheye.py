"""Identification through a fisheye: a blob whose pixel has no ray in front of the camera (past
90 deg off axis, in the corner of a wide fisheye) is left unassigned, not a failed frame."""

from __future__ import annotations

import numpy as np
from deckpose.detect.identify import UNASSIGNED, identify_beacons

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout

#: 1280x800, f = 455 px: 84 deg off axis at the side edges, past 90 deg in the corners.
FISHEYE = CameraModel(1280, 800, [[455.2, 0.0, 641.9], [0.0, 454.7, 399.2], [0.0, 0.0, 1.0]],
                      [-0.0147, 0.0063, -0.0059, 0.0012], "fisheye", "equidistant")


def test_a_blob_with_no_ray_is_unassigned_and_the_ring_still_identified() -> None:
    layout = DeckLayout()
    proj = project_layout(layout, ShipPose(0.05, -0.03, 0.7), CameraPose.nadir(12.0), FISHEYE)
    assert proj.visible.all()
    corner = np.array([[2.0, 3.0]])
    assert np.isnan(FISHEYE.undistort(corner)).all()
    pts = np.vstack([corner, proj.points_px])
    rgb = np.ones((len(pts), 3))
    rgb[1 + layout.bow_id] = [3.0, 0.2, 0.2]  # the red bow
    ident = identify_beacons(pts, layout, FISHEYE, rgb_flux=rgb)
    assert ident.ok, ident.reason
    assert ident.beacon_ids[0] == UNASSIGNED
    np.testing.assert_array_equal(ident.beacon_ids[1:], np.arange(layout.n_beacons))
