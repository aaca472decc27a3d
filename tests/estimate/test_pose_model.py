import numpy as np
import pytest
from deckpose.estimate.pose_model import (
    params_from_relative,
    project_normalised,
    relative_from_params,
)

from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck
from deckpose.rotation import rot_x, rot_y
from tests.tolerances import ROUNDOFF


@pytest.mark.parametrize("tilt", [(0.0, 0.0), (0.2, -0.1)])
def test_params_round_trip_and_projection_match_truth(tilt):
    ship = ShipPose(0.05, -0.08, 1.2, 0.3, 1.5, -0.7)
    cam = CameraPose.nadir(35.0, x_m=0.4, y_m=-0.2, R_nadir_from_cam=rot_x(tilt[0]) @ rot_y(tilt[1]))
    T = T_cam_from_deck(ship, cam)
    p = params_from_relative(T[:3, :3], T[:3, 3], cam.R_world_from_cam)
    # Truth: angles as given, surge/sway relative to the camera, height camera above deck centre.
    np.testing.assert_allclose(p, [0.05, -0.08, 1.2, 1.5 - 0.4, -0.7 + 0.2, 35.0 - 0.3], atol=1e-12)
    R, t = relative_from_params(p, cam.R_world_from_cam)
    np.testing.assert_allclose(R, T[:3, :3], atol=ROUNDOFF)
    np.testing.assert_allclose(t, T[:3, 3], atol=1e-10)
    P = DeckLayout().positions_deck_m()
    xy, _, Z = project_normalised(p, P, cam.R_world_from_cam)
    Pc = P @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(xy, Pc[:, :2] / Pc[:, 2:], atol=1e-12)
    np.testing.assert_allclose(Z, Pc[:, 2], atol=1e-10)


def test_jacobian_matches_central_differences():
    rng = np.random.default_rng(3)
    P = DeckLayout().positions_deck_m()
    R_wc = CameraPose.nadir(20.0, R_nadir_from_cam=rot_x(0.1)).R_world_from_cam
    for _ in range(5):
        p = np.concatenate([rng.uniform(-0.3, 0.3, 3), rng.uniform(-2, 2, 2), [rng.uniform(15, 60)]])
        _, J, _ = project_normalised(p, P, R_wc)
        h = 1e-6
        Jn = np.stack([(project_normalised(p + h * e, P, R_wc)[0] - project_normalised(p - h * e, P, R_wc)[0])
                       / (2 * h) for e in np.eye(6)], axis=-1)
        np.testing.assert_allclose(J, Jn, atol=1e-8)
