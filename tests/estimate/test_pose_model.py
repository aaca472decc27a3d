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
    xy, _, Z = project_normalised(p[None], P, cam.R_world_from_cam[None])  # a batch of one
    Pc = P @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(xy[0], Pc[:, :2] / Pc[:, 2:], atol=1e-12)
    np.testing.assert_allclose(Z[0], Pc[:, 2], atol=1e-10)


def test_jacobian_matches_central_differences():
    rng = np.random.default_rng(3)
    P = DeckLayout().positions_deck_m()
    R_wc = CameraPose.nadir(20.0, R_nadir_from_cam=rot_x(0.1)).R_world_from_cam
    for _ in range(5):
        p = np.concatenate([rng.uniform(-0.3, 0.3, 3), rng.uniform(-2, 2, 2), [rng.uniform(15, 60)]])
        _, J, _ = project_normalised(p[None], P, R_wc[None])
        h = 1e-6
        Jn = np.stack([(project_normalised((p + h * e)[None], P, R_wc[None])[0]
                        - project_normalised((p - h * e)[None], P, R_wc[None])[0]) / (2 * h) for e in np.eye(6)],
                      axis=-1)
        np.testing.assert_allclose(J, Jn, atol=1e-8)


def test_stacked_rotations_and_derivatives_match_scipy_and_differences():
    """The monomial table of the stacked kernel against scipy's ZYX rotation and central differences."""
    from deckpose.estimate.pose_model import deck_rotations, deck_rotations_and_derivatives
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(11)
    angles = rng.uniform(-np.pi, np.pi, (40, 3))
    R_scipy = Rotation.from_euler("ZYX", angles[:, ::-1]).as_matrix()  # yaw, pitch, roll intrinsic
    np.testing.assert_allclose(deck_rotations(angles), R_scipy, atol=ROUNDOFF)
    RD = deck_rotations_and_derivatives(angles)
    np.testing.assert_allclose(RD[:, 0], R_scipy, atol=ROUNDOFF)
    h = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        numeric = (deck_rotations(angles + e) - deck_rotations(angles - e)) / (2 * h)
        np.testing.assert_allclose(RD[:, 1 + k], numeric, atol=1e-8)  # central difference: O(h^2) + roundoff/h


def test_stacked_projection_and_fit_match_the_truth_and_differences():
    """Stacked projection against the pose truth; its Jacobian against central differences;
    an LM from a perturbed start returns to the noise-free pose."""
    from deckpose.estimate.least_squares import levenberg_marquardt
    from deckpose.estimate.observations import Observations

    rng = np.random.default_rng(5)
    P = DeckLayout().positions_deck_m()
    F = 6
    cams = [CameraPose.nadir(rng.uniform(15, 60), R_nadir_from_cam=rot_x(rng.uniform(-0.2, 0.2))) for _ in range(F)]
    ships = [ShipPose(*rng.uniform(-0.2, 0.2, 3), rng.uniform(-1, 1), *rng.uniform(-2, 2, 2)) for _ in range(F)]
    R_wc = np.stack([c.R_world_from_cam for c in cams])
    T = [T_cam_from_deck(s, c) for s, c in zip(ships, cams)]
    p = np.stack([params_from_relative(t[:3, :3], t[:3, 3], c.R_world_from_cam) for t, c in zip(T, cams)])
    xy, J, Z = project_normalised(p, P, R_wc)
    for f in range(F):
        Pc = P @ T[f][:3, :3].T + T[f][:3, 3]
        np.testing.assert_allclose(xy[f], Pc[:, :2] / Pc[:, 2:], atol=1e-12)
        np.testing.assert_allclose(Z[f], Pc[:, 2], atol=1e-10)
    assert J is not None
    h = 1e-6
    for k in range(6):
        e = np.zeros(6)
        e[k] = h
        numeric = (project_normalised(p + e, P, R_wc)[0] - project_normalised(p - e, P, R_wc)[0]) / (2 * h)
        np.testing.assert_allclose(J[..., k], numeric, atol=1e-9)
    M = P.shape[0]
    obs = Observations(np.arange(M), P, xy, np.broadcast_to(np.eye(2) * 1e3, (F, 1, 2, 2)),
                       np.broadcast_to(np.eye(2), (F, 1, 2, 2)), R_wc)
    start = p + np.array([0.02, -0.02, 0.03, 0.2, -0.2, 0.5])
    fit = levenberg_marquardt(start, obs)
    assert fit.converged.all()
    np.testing.assert_allclose(fit.params, p, atol=1e-7)
    assert np.all(fit.chi2 < 1e-12)
