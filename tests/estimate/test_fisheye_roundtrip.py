"""Fisheye (equidistant) and rational-polynomial cameras through the estimators: exact projections of
a known pose give that pose back, frame by frame (``run_estimator``) and batched (``estimate_batch``)."""

from __future__ import annotations

import numpy as np
import pytest
from deckpose.estimate.batch import estimate_batch, run_estimator
from deckpose.estimate.registry import EstimateOptions

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.rotation import rot_x, rot_y
from tests.estimate.synthetic import detections_for, pose_error
from tests.tolerances import ESTIMATOR_ROUNDTRIP_M, ESTIMATOR_ROUNDTRIP_RAD

LAYOUT = DeckLayout()
#: A 1280x800 fisheye (f = 455 px) that sees 84 deg off axis at its side edges and past 90 deg in its
#: corners: too wide to render through a pinhole raster, which the estimators do not need.
FISHEYE = CameraModel(1280, 800, [[455.2, 0.0, 641.9], [0.0, 454.7, 399.2], [0.0, 0.0, 1.0]],
                      [-0.0147, 0.0063, -0.0059, 0.0012], "fisheye", "equidistant")
RATIONAL = CameraModel(1920, 1080, [[1100.0, 0.0, 955.0], [0.0, 1105.0, 545.0], [0.0, 0.0, 1.0]],
                       [-0.21, 0.07, 0.0008, -0.0005, -0.01, 0.05, -0.02, 0.004], "rational")


def _poses(heights_m: tuple[float, float, float]) -> list[tuple[ShipPose, CameraPose]]:
    """(ship, camera pose): nadir, a tilted and offset camera, and a higher nadir one."""
    h0, h1, h2 = heights_m
    return [
        (ShipPose(0.06, -0.04, 0.5, 0.0, 0.8, -0.6), CameraPose.nadir(h0)),
        (ShipPose(-0.08, 0.1, 2.5, 0.5, -1.0, 2.0),
         CameraPose.nadir(h1, x_m=2.0, R_nadir_from_cam=rot_x(0.2) @ rot_y(-0.15))),
        (ShipPose(0.03, 0.05, -1.0, 0.0, 2.0, 1.0), CameraPose.nadir(h2)),
    ]


#: Heights where every beacon is in view, the fisheye's lowest with the ring ~45 deg off axis.
HEIGHTS_M = {"fisheye": (11.0, 18.0, 30.0), "rational": (34.0, 45.0, 60.0)}


def _off_axis_deg(camera: CameraModel, det) -> float:
    ray = np.linalg.solve(camera.K, np.c_[camera.undistort(det.points_px), np.ones(len(det))].T)
    return float(np.degrees(np.arctan(np.hypot(ray[0], ray[1]))).max())


@pytest.mark.parametrize("camera", [FISHEYE, RATIONAL], ids=["equidistant", "rational_polynomial"])
@pytest.mark.parametrize("method", ["pnp", "conic"])
def test_exact_projections_give_the_pose_back(camera: CameraModel, method: str) -> None:
    poses = _poses(HEIGHTS_M[camera.name])
    dets = [detections_for(LAYOUT, ship, cam_pose, camera) for ship, cam_pose in poses]
    assert all(len(d) == LAYOUT.n_beacons for d in dets)
    if camera is FISHEYE:
        assert _off_axis_deg(camera, dets[0]) > 40.0  # far into the fisheye, not its near-pinhole centre
    R = np.stack([cam_pose.R_world_from_cam for _, cam_pose in poses])
    batched = estimate_batch(method, dets, camera, LAYOUT, EstimateOptions(), R_world_from_cam=R)
    for (ship, cam_pose), det, est_b in zip(poses, dets, batched, strict=True):
        est = run_estimator(method, det, camera, LAYOUT, EstimateOptions(R_world_from_cam=cam_pose.R_world_from_cam))
        for e in (est, est_b):
            assert e.ok, e.reason
            err = pose_error(e, ship, cam_pose)
            assert np.all(np.abs(err[:3]) < ESTIMATOR_ROUNDTRIP_RAD), err
            assert np.all(np.abs(err[3:]) < ESTIMATOR_ROUNDTRIP_M), err
            assert e.extras["reprojection_rms_px"] < 1e-5


def test_noisy_fisheye_pose_errors_match_the_reported_covariance() -> None:
    """The pixel noise is mapped through the fisheye's Jacobian: the normalised errors have unit
    variance (a pinhole Jacobian would misstate them by the fisheye's compression off axis)."""
    ship, cam_pose = _poses(HEIGHTS_M["fisheye"])[0]
    rng = np.random.default_rng(11)
    z = []
    for _ in range(200):
        det = detections_for(LAYOUT, ship, cam_pose, FISHEYE, sigma_px=0.3, rng=rng)
        est = run_estimator("pnp", det, FISHEYE, LAYOUT, EstimateOptions(sigma_px=0.3))
        assert est.ok, est.reason
        err = pose_error(est, ship, cam_pose)
        z.append(err / np.sqrt(np.diag(est.covariance)))
    var = np.var(np.array(z), axis=0)
    # 200 samples: the variance's standard error is sqrt(2/200) = 0.1; 4 of them
    assert np.all(np.abs(var - 1.0) < 0.4), var


@pytest.mark.parametrize("method", ["pnp", "conic", "thesis"])
def test_a_detection_with_no_ray_in_front_is_left_out(method: str) -> None:
    """A fisheye pixel past 90 deg (this camera's corner) undistorts to NaN: the estimators drop it
    and fit the rest, frame by frame and batched, as they drop a NaN detection."""
    from deckpose.records import Detections

    ship, cam_pose = _poses(HEIGHTS_M["fisheye"])[0]
    det = detections_for(LAYOUT, ship, cam_pose, FISHEYE)
    assert np.isnan(FISHEYE.undistort(np.array([[2.0, 3.0]]))).all()
    pts = np.vstack([det.points_px[:-1], [[2.0, 3.0]]])  # the last beacon seen in the corner
    bad = Detections(pts, det.beacon_ids, det.covariance_px2)
    opts = EstimateOptions(R_world_from_cam=cam_pose.R_world_from_cam)
    single = run_estimator(method, bad, FISHEYE, LAYOUT, opts)
    batched = estimate_batch(method, [bad, det], FISHEYE, LAYOUT, opts)
    if method == "thesis":  # this deck is off the optical axis, which the thesis method refuses
        assert all("off-centre" in e.reason for e in (single, *batched))
        return
    for e in (single, batched[0]):
        assert e.ok, e.reason
        assert len(det) - 1 not in set(np.asarray(e.inliers).tolist())  # the corner point
        err = pose_error(e, ship, cam_pose)
        assert np.all(np.abs(err[:3]) < ESTIMATOR_ROUNDTRIP_RAD), err
