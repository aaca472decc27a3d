"""The renderer draws a two-ring layout's inner beacons, each in its colour (the inner bow red)."""

from __future__ import annotations

import numpy as np
from deckpose.render.beacons import beacon_splats
from deckpose.render.config import SensorSpec

from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from tests.two_ring_frames import LAYOUT, camera


def test_inner_ring_beacons_are_drawn_in_their_colours() -> None:
    cam, pose = camera(), CameraPose.nadir(3.0)
    splats = beacon_splats(LAYOUT, (ShipPose(),), pose, cam, SensorSpec())
    drawn = {sp.beacon_id: sp for sp in splats}
    assert set(drawn) == {12, *range(13, 19)}  # from 3 m: the centre and the inner ring
    np.testing.assert_allclose(drawn[13].rgb, LAYOUT.bow_rgb, rtol=1e-6)  # the inner ring's bow
    for i in (12, 14, 15, 16, 17, 18):
        np.testing.assert_allclose(drawn[i].rgb, LAYOUT.beacon_rgb, rtol=1e-6)
    # the truth the render stage records covers every id, inner ring included
    truth = project_layout(LAYOUT, ShipPose(), pose, cam)
    assert truth.points_px.shape == (19, 2)
    np.testing.assert_array_equal(np.flatnonzero(truth.visible), sorted(drawn))
