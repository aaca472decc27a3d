"""The painted ring's pose against its bound on analytic frames (issue 22: within 1.3x its bound).

Frames: the ring's exact area coverage (8 x 8 samples a pixel, :func:`paint_coverage`) on a flat
deck of 60 DN, paint 180 DN, white noise of 4 DN; a 640 x 480 camera looking down from 28-36 m
at seeded attitudes. The truth is the pose the frame was drawn at. The bound is the estimator's
(:attr:`PaintedRingPose.bound`): the pose Jacobian with each edge point at its own Cramér–Rao
bound (the model fit of its pixels, the deck's level and slope and the paint's level unknown).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from deckpose.detect.ring_edges import RingEdgeOptions, detect_ring_edges
from deckpose.estimate.painted_ring_pose import estimate_painted_ring
from deckpose.estimate.pose_model import params_from_relative
from deckpose.render.painted_ring import paint_coverage

from deckpose.camera import CameraModel
from deckpose.painted_ring import PaintedRing
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck

RING = PaintedRing()
CAMERA = CameraModel(640, 480, np.array([[600.0, 0.0, 318.0], [0.0, 600.0, 243.0], [0.0, 0.0, 1.0]]))
N_FRAMES = 12


def _frame(seed: int) -> tuple[np.ndarray, ShipPose, CameraPose]:
    rng = np.random.default_rng(1000 + seed)
    ship = ShipPose(math.radians(rng.uniform(-4, 4)), math.radians(rng.uniform(-4, 4)),
                    math.radians(rng.uniform(-40, 40)), 0.0, rng.uniform(-1, 1), rng.uniform(-1, 1))
    cam = CameraPose.nadir(float(rng.uniform(28, 36)))
    got = paint_coverage(RING, ship, cam, CAMERA, samples=8)
    assert got is not None
    r0, c0, cov = got
    img = np.full((CAMERA.height_px, CAMERA.width_px), 60.0)
    img[r0:r0 + cov.shape[0], c0:c0 + cov.shape[1]] += 120.0 * cov
    return img + rng.normal(0.0, 4.0, img.shape), ship, cam


def _err(est, ship: ShipPose, cam: CameraPose) -> np.ndarray:
    T = T_cam_from_deck(ship, cam)
    truth = params_from_relative(T[:3, :3], T[:3, 3], cam.R_world_from_cam)
    x = np.array([est.roll_rad, est.pitch_rad, est.yaw_rad, est.surge_m, est.sway_m, est.height_m])
    e = x - truth
    e[:3] = (e[:3] + math.pi) % (2 * math.pi) - math.pi
    return e


def test_pose_within_its_bound_on_analytic_frames():
    errs, bounds, sigmas, known, disc_ratio, corr = [], [], [], [], [], []
    for seed in range(N_FRAMES):
        img, ship, cam = _frame(seed)
        det = detect_ring_edges(img, CAMERA, RING, RingEdgeOptions(centre_disc=True))
        assert det.ok, det.reason
        with_disc = estimate_painted_ring(det, CAMERA, RING, cam.R_world_from_cam)
        det = replace(det, disc_px=np.zeros((0, 2)), disc_crb_px=np.zeros(0))  # the default: no disc
        res = estimate_painted_ring(det, CAMERA, RING, cam.R_world_from_cam)
        assert res.estimate.ok and with_disc.estimate.ok, (res.estimate.reason, with_disc.estimate.reason)
        assert with_disc.used_disc and not res.used_disc
        assert res.bound is not None and res.bound_known_levels is not None and with_disc.bound is not None
        assert res.estimate.covariance is not None
        errs.append(_err(res.estimate, ship, cam))
        bounds.append(np.sqrt(np.diag(res.bound)))
        sigmas.append(np.sqrt(np.diag(res.estimate.covariance)))
        known.append(np.sqrt(np.diag(res.bound_known_levels)))
        assert res.bound_correlated is not None
        corr.append(np.sqrt(np.diag(res.bound_correlated)))
        disc_ratio.append(np.sqrt(np.diag(res.bound)) / np.sqrt(np.diag(with_disc.bound)))
    e, b, s, k = np.array(errs), np.array(bounds), np.array(sigmas), np.array(known)
    z = e / b
    # pooled over 12 frames x 6 parameters (72 values, roll and pitch 24): were the errors at
    # the bound, the RMS of z would be 1 +- 0.08 (1 / sqrt(2 * 72)). Within 1.3x the bound is
    # then nearly 4 standard errors of margin, and a bound more than 1.4x too loose (RMS below
    # 0.7) would fail too: the bound must be reached, not just respected.
    rms = float(np.sqrt(np.mean(z ** 2)))
    assert 0.7 < rms < 1.3, rms
    tilt = float(np.sqrt(np.mean(z[:, :2] ** 2)))  # the issue's own figure: roll and pitch
    assert tilt < 1.3 * (1 + 2.5 / math.sqrt(2 * 2 * N_FRAMES)), tilt  # 1.3 plus 2.5 standard errors
    # each parameter: 12 values, RMS to +-20 %; 1.3x plus 2.5 of those
    assert np.all(np.sqrt(np.mean(z ** 2, axis=0)) < 1.3 * (1 + 2.5 / math.sqrt(2 * N_FRAMES)))
    # the estimate's own sigma (measured point scatter) is the bound to within the scatter's
    # excess over it: 1.0-1.1 measured
    assert np.all((s / b > 0.9) & (s / b < 1.3)), s / b
    # white noise: the correlated-noise bound is the white-noise bound but for the residuals'
    # sample correlation at the few lags Andrews' bandwidth keeps (each ~1/sqrt(800) = 0.035;
    # a fit's residuals lean slightly negative): measured 0.96-1.0 of it
    c = np.array(corr)
    assert np.all((c / b > 0.85) & (c / b < 1.1)), c / b
    # the known-levels (white-noise, position only) bound is below the model's: the levels cost
    assert np.all(k < b)
    # the centre disc adds tilt information: the bound of roll and pitch falls ~1.8x with it
    assert np.all(np.median(np.array(disc_ratio), axis=0)[:2] > 1.4)
