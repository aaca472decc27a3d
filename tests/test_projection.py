import math

import numpy as np
import pytest

from deckpose.camera import CameraModel, preset
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout, layout_from_dict, thesis_layout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout, project_thesis_centred
from deckpose.rotation import R_from_thesis, R_from_zyx
from tests.tolerances import PROJECTION_PX


def test_layout_ids_and_positions():
    lay = DeckLayout(n_ring=12, radius_m=10.0, has_centre=True)
    P = lay.positions_deck_m()
    assert P.shape == (13, 3) and lay.centre_id == 12
    np.testing.assert_allclose(P[0], [10, 0, 0], atol=1e-12)      # bow
    np.testing.assert_allclose(P[3], [0, 10, 0], atol=1e-12)      # port, counter-clockwise
    np.testing.assert_allclose(P[12], [0, 0, 0])
    assert thesis_layout().n_beacons == 12


@pytest.mark.parametrize("doc,match", [({"n_ring": 0}, "at least 3"), ({"radius_m": -1}, "positive"),
                                       ({"colour": 1}, r"layout: unknown key\(s\) \[.colour.\]"), ({"bow_id": 3}, "bow_id must be 0")])
def test_layout_validation(doc, match):
    with pytest.raises(ConfigError, match=match):
        layout_from_dict(doc)


def test_nadir_camera_sees_bow_up_and_port_left():
    cam = CameraModel(1000, 1000, np.array([[500.0, 0, 500], [0, 500, 500], [0, 0, 1]]))
    proj = project_layout(DeckLayout(), ShipPose(), CameraPose.nadir(20.0), cam)
    bow, port, centre = proj.points_px[0], proj.points_px[3], proj.points_px[12]
    np.testing.assert_allclose(centre, [500, 500])
    np.testing.assert_allclose(bow, [500, 500 - 500 * 10 / 20])   # image top
    np.testing.assert_allclose(port, [500 - 500 * 10 / 20, 500])  # image left
    assert proj.visible.all()
    np.testing.assert_allclose(proj.apparent_radius_px, 0.15 * 500 / 20)


@pytest.mark.parametrize("name", ["4mp", "8mp", "16mp", "64mp", "8mp-square"])
def test_general_projection_equals_thesis_algorithm_1(name):
    cam = preset(name)
    rng = np.random.default_rng(0)
    lay = thesis_layout()
    for _ in range(20):
        r, p, y = rng.uniform(-0.35, 0.35), rng.uniform(-0.17, 0.17), rng.uniform(-np.pi, np.pi)
        D = rng.uniform(20, 80)
        R = R_from_thesis(r, p, y)
        ship = ShipPose.from_R(R)
        proj = project_layout(lay, ship, CameraPose.nadir(D), cam)
        Xc = project_thesis_centred(lay.positions_deck_m(), R[None], np.array([D]), cam.fx, cam.fy)[0]
        uv = np.column_stack([Xc[:, 0] + cam.cx, cam.cy - Xc[:, 1]])
        np.testing.assert_allclose(proj.points_px, uv, atol=PROJECTION_PX * D)


def test_translation_and_heave_move_the_image_as_expected():
    cam = preset("8mp")
    lay = DeckLayout()
    base = project_layout(lay, ShipPose(), CameraPose.nadir(30.0), cam)
    up = project_layout(lay, ShipPose(heave_m=10.0), CameraPose.nadir(30.0), cam)
    # heave up by 10 m: the ring looks as if seen from 20 m
    r_base = np.linalg.norm(base.points_px[0] - base.points_px[12])
    r_up = np.linalg.norm(up.points_px[0] - up.points_px[12])
    assert r_up / r_base == pytest.approx(30 / 20)
    surge = project_layout(lay, ShipPose(surge_m=3.0), CameraPose.nadir(30.0), cam)
    assert surge.points_px[12, 1] == pytest.approx(cam.cy - cam.fy * 3 / 30)


def test_visibility_drops_out_of_frame_and_back_side():
    cam = preset("8mp")
    lay = DeckLayout()
    low = project_layout(lay, ShipPose(), CameraPose.nadir(5.0), cam)
    assert low.visible[12] and not low.visible[0]       # ring outside the frame at 5 m
    flipped = project_layout(lay, ShipPose(roll_rad=math.pi), CameraPose.nadir(20.0), cam)
    assert not flipped.visible.any()                      # deck upside down: no lit side


def test_tilted_camera_pose():
    R_tilt = R_from_zyx(0.0, 0.0, 0.0)
    a = project_layout(DeckLayout(), ShipPose(), CameraPose.nadir(20.0, R_nadir_from_cam=R_tilt), preset("8mp"))
    b = project_layout(DeckLayout(), ShipPose(), CameraPose.nadir(20.0), preset("8mp"))
    np.testing.assert_allclose(a.points_px, b.points_px)
    with pytest.raises(ConfigError):
        CameraPose.nadir(-1.0)
