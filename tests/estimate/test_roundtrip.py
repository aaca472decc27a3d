"""Noise-free and noisy round trips of conic and pnp: pose -> project -> estimate."""

import dataclasses

import numpy as np
import pytest
from deckpose.estimate import registry
from deckpose.estimate.registry import EstimateOptions

from deckpose.camera import CameraModel, preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.records import POSE_PARAMS
from deckpose.rotation import rot_x, rot_y
from tests.estimate.synthetic import detections_for, pose_error
from tests.tolerances import ESTIMATOR_ROUNDTRIP_M, ESTIMATOR_ROUNDTRIP_RAD

METHODS = ["conic", "pnp"]

#: Non-square pixels, skew-free, off-centre principal point, barrel distortion.
ODD_CAMERA = CameraModel(
    3000, 2000, np.array([[2100.0, 0.0, 1420.0], [0.0, 1900.0, 1050.0], [0.0, 0.0, 1.0]]),
    np.array([-0.12, 0.05, 0.001, -0.0005, 0.0]), "odd")

CASES = {
    "nadir-8mp": (preset("8mp"), ShipPose(0.06, -0.04, 0.5, 0.0, 0.8, -0.6), CameraPose.nadir(30.0)),
    "level-deck": (preset("4mp"), ShipPose(0.0, 0.0, -2.0, 0.0, 0.0, 0.0), CameraPose.nadir(20.0)),
    "odd-camera": (ODD_CAMERA, ShipPose(-0.08, 0.1, 2.5, 0.5, -1.0, 2.0), CameraPose.nadir(40.0)),
    "tilted-camera": (preset("16mp"), ShipPose(0.05, 0.07, -0.3, 0.0, 3.0, 2.0),
                      CameraPose.nadir(25.0, x_m=1.0, R_nadir_from_cam=rot_x(0.15) @ rot_y(-0.1))),
}


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("polish", [0, 1])
def test_noise_free_round_trip(method, case, polish):
    camera, ship, cam_pose = CASES[case]
    det = detections_for(DeckLayout(), ship, cam_pose, camera)
    opts = EstimateOptions(R_world_from_cam=cam_pose.R_world_from_cam, conic_polish_steps=polish)
    est = registry.get(method)(det, camera, DeckLayout(), opts)
    assert est.ok, est.reason
    err = pose_error(est, ship, cam_pose)
    assert np.all(np.abs(err[:3]) < ESTIMATOR_ROUNDTRIP_RAD), err
    assert np.all(np.abs(err[3:]) < ESTIMATOR_ROUNDTRIP_M), err
    assert est.extras["reprojection_rms_px"] < 1e-5
    assert est.covariance is not None and np.all(np.linalg.eigvalsh(est.covariance) > 0)
    for name in POSE_PARAMS:
        assert est.extras["sigma_" + name] > 0


@pytest.mark.parametrize("method", METHODS)
def test_missing_ring_beacons(method):
    camera, ship, cam_pose = CASES["nadir-8mp"]
    det = detections_for(DeckLayout(), ship, cam_pose, camera, drop_ids=(1, 4, 5, 9))  # 8 ring + centre
    est = registry.get(method)(det, camera, DeckLayout(), EstimateOptions())
    assert est.ok, est.reason
    assert np.all(np.abs(pose_error(est, ship, cam_pose)) < 1e-6)
    assert set(est.inliers) == {0, 2, 3, 6, 7, 8, 10, 11, 12}


def test_conic_without_centre_beacon_uses_ring_ids():
    camera, ship, cam_pose = CASES["nadir-8mp"]
    layout = DeckLayout(has_centre=False)
    det = detections_for(layout, ship, cam_pose, camera)
    est = registry.get("conic")(det, camera, layout, EstimateOptions(conic_polish_steps=0))
    assert est.ok, est.reason
    assert est.extras["centre_beacon_used"] == 0.0
    assert np.all(np.abs(pose_error(est, ship, cam_pose)) < 1e-6)


@pytest.mark.parametrize("method,n_keep,ok", [("conic", 4, False), ("conic", 5, True),
                                              ("pnp", 3, False), ("pnp", 4, True)])
def test_minimum_beacon_counts(method, n_keep, ok):
    camera, ship, cam_pose = CASES["nadir-8mp"]
    det = detections_for(DeckLayout(has_centre=False), ship, cam_pose, camera,
                         drop_ids=tuple(range(n_keep, 12)))
    est = registry.get(method)(det, camera, DeckLayout(has_centre=False), EstimateOptions())
    assert est.ok is ok, est.reason
    if not ok:
        assert "too few" in est.reason and np.isnan(est.roll_rad)


@pytest.mark.parametrize("method", METHODS)
def test_noisy_errors_match_reported_covariance(method):
    """Over 300 seeded frames at 1 px the normalised errors have unit variance.

    The sampling sd of a variance from 300 draws is sqrt(2/300) = 0.08; +-0.3 is 3.6 sd.
    """
    rng = np.random.default_rng(11)
    camera, ship, cam_pose = CASES["odd-camera"]
    opts = EstimateOptions(sigma_px=1.0, refine=True)
    z = []
    for _ in range(300):
        det = detections_for(DeckLayout(), ship, cam_pose, camera, sigma_px=1.0, rng=rng)
        est = registry.get(method)(det, camera, DeckLayout(), opts)
        assert est.ok, est.reason
        z.append(pose_error(est, ship, cam_pose) / np.sqrt(np.diag(est.covariance)))
    var = np.var(np.array(z), axis=0) + np.mean(np.array(z), axis=0) ** 2
    assert np.all((var > 0.7) & (var < 1.3)), var


def test_known_camera_attitude_gives_world_attitude():
    """Same relative pose, two camera attitudes: world attitude follows the given R_world_from_cam."""
    camera, ship, cam_pose = CASES["tilted-camera"]
    det = detections_for(DeckLayout(), ship, cam_pose, camera)
    right = registry.get("pnp")(det, camera, DeckLayout(),
                                EstimateOptions(R_world_from_cam=cam_pose.R_world_from_cam))
    nadir = registry.get("pnp")(det, camera, DeckLayout(), EstimateOptions())
    assert right.ok and nadir.ok
    assert np.all(np.abs(pose_error(right, ship, cam_pose)) < 1e-6)
    assert abs(nadir.roll_rad - ship.roll_rad) > 0.05  # assuming nadir is wrong by the tilt
    rel = [f"rvec_cam_from_deck_{a}" for a in "xyz"] + [f"t_cam_from_deck_{a}_m" for a in "xyz"]
    np.testing.assert_allclose([right.extras[k] for k in rel], [nadir.extras[k] for k in rel], atol=1e-7)


def test_options_validate_camera_attitude():
    from deckpose.errors import ConfigError
    with pytest.raises(ConfigError, match="rotation"):
        EstimateOptions(R_world_from_cam=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ConfigError, match="3x3"):
        EstimateOptions(R_world_from_cam=np.eye(2))
    assert dataclasses.replace(EstimateOptions(), refine=True).refine
