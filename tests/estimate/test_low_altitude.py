"""Estimates below the outer ring (two-ring layout) against exact projections, and the sequence driver.

Frames are projected by hand (``tests/two_ring_frames.py``), identified with no knowledge of
the ids, and estimated by ``pnp`` from whatever was identified: the inner ring and the centre
(7 beacons), or fewer with a prior pose. Noise-free frames must give the pose exactly; noisy
ones an ok estimate whose errors are distributed as its own sigmas say.
"""

from __future__ import annotations

import numpy as np
import pytest
from deckpose.estimate import EstimateOptions

from deckpose.records import POSE_PARAMS
from deckpose.rotation import wrap_angle_rad
from deckpose.sequence_estimate import (
    IdentifiedBy,
    SequenceFrame,
    SequenceOptions,
    estimate_sequence,
)
from tests.tolerances import ESTIMATOR_ROUNDTRIP_M, ESTIMATOR_ROUNDTRIP_RAD
from tests.two_ring_frames import LAYOUT, TrueFrame, camera, shuffled_noisy, true_frame

SIGMA_PX = 0.3
#: 0.1 s between frames, ns.
DT_NS = 100_000_000


def _frame(f: TrueFrame, k: int, sigma_px: float, rng: np.random.Generator) -> SequenceFrame:
    pts, rgb, _ = shuffled_noisy(f, sigma_px, rng)
    cov = np.broadcast_to(np.eye(2) * max(sigma_px, 0.01) ** 2, (pts.shape[0], 2, 2))
    return SequenceFrame(k, k * DT_NS, pts, cov, f.R_world_from_cam, rgb)


def _error(e: object, truth: np.ndarray) -> np.ndarray:
    p = np.array([getattr(e, n) for n in POSE_PARAMS])
    d = p - truth
    d[:3] = wrap_angle_rad(d[:3])
    return d


@pytest.mark.parametrize(("height_m", "x_m"), [(2.0, 0.2), (3.0, -0.3), (6.0, 0.0)])
def test_noise_free_low_frames_give_the_exact_pose(height_m: float, x_m: float) -> None:
    f = true_frame(height_m, x_m=x_m)
    assert f.ids.max() >= 13 and np.all(f.ids >= 12)  # below the outer ring: inner ring and centre only
    opts = EstimateOptions(sigma_px=0.01)
    (r,) = estimate_sequence([_frame(f, 0, 0.0, np.random.default_rng(0))], camera(), LAYOUT, opts)
    assert r.estimate.ok, r.estimate.reason
    assert r.identified_by is IdentifiedBy.FRAME
    err = _error(r.estimate, f.params)
    # exact points: the limits are the solver's convergence (ESTIMATOR_ROUNDTRIP_*, for 20-80 m;
    # metres scale with the height, so they hold with margin at 2-6 m)
    assert np.all(np.abs(err[:3]) < ESTIMATOR_ROUNDTRIP_RAD)
    assert np.all(np.abs(err[3:]) < ESTIMATOR_ROUNDTRIP_M)


def test_noisy_low_estimates_are_within_their_own_sigmas() -> None:
    # 40 independent frames at 3 m (7 beacons, the inner ring and the centre), 0.3 px noise.
    rng = np.random.default_rng(21)
    opts = EstimateOptions(sigma_px=SIGMA_PX)
    z = []
    for k in range(40):
        f = true_frame(3.0, x_m=rng.uniform(-0.3, 0.3), y_m=rng.uniform(-0.3, 0.3),
                       roll_rad=rng.uniform(-0.1, 0.1), pitch_rad=rng.uniform(-0.1, 0.1),
                       yaw_rad=rng.uniform(-np.pi, np.pi))
        (r,) = estimate_sequence([_frame(f, k, SIGMA_PX, rng)], camera(), LAYOUT, opts)
        assert r.estimate.ok, r.estimate.reason
        assert r.estimate.covariance is not None
        z.append(_error(r.estimate, f.params) / np.sqrt(np.diag(r.estimate.covariance)))
    zz = np.array(z)
    # None beyond 5 sigma (the target; a Gaussian exceeds it with probability 6e-7).
    assert np.abs(zz).max() < 5
    # Each parameter's RMS z over 40 frames: 1 if the covariance is right. The mean of 40
    # chi2(1) values has a standard deviation of sqrt(2/40) = 0.22, so 3 of those give
    # RMS z within [sqrt(1 - 0.67), sqrt(1 + 0.67)] = [0.58, 1.29]; an over- or understated
    # covariance by a factor 2 in variance falls outside.
    rms = np.sqrt(np.mean(zz ** 2, axis=0))
    assert np.all((rms > 0.58) & (rms < 1.29)), rms


def test_a_bow_less_frame_is_estimated_with_the_previous_frames_pose() -> None:
    rng = np.random.default_rng(7)
    f0 = true_frame(1.55, x_m=-0.2)  # inner bow in view
    f1 = true_frame(1.5, x_m=-0.3, yaw_rad=0.41)  # 0.1 s later: inner bow out of view
    assert 13 in f0.ids and 13 not in f1.ids and f1.ids.size >= 4
    opts = EstimateOptions(sigma_px=SIGMA_PX)
    res = estimate_sequence([_frame(f0, 0, SIGMA_PX, rng), _frame(f1, 1, SIGMA_PX, rng)], camera(), LAYOUT, opts)
    assert [r.identified_by for r in res] == [IdentifiedBy.FRAME, IdentifiedBy.PRIOR]
    assert res[1].prior_age_s == pytest.approx(0.1)
    e = res[1].estimate
    assert e.ok and e.covariance is not None, e.reason
    # 5 sigma: the bound for an ok estimate (a Gaussian exceeds it with probability 6e-7)
    assert np.all(np.abs(_error(e, f1.params)) < 5 * np.sqrt(np.diag(e.covariance)))


def test_a_bow_less_frame_without_a_prior_stays_not_ok_with_its_reason() -> None:
    f1 = true_frame(1.5, x_m=-0.3)
    opts = EstimateOptions(sigma_px=SIGMA_PX)
    (r,) = estimate_sequence([_frame(f1, 0, SIGMA_PX, np.random.default_rng(8))], camera(), LAYOUT, opts)
    assert not r.estimate.ok and r.identified_by is IdentifiedBy.NONE
    # why, for each ring (the inner ring's bow is out of view, 5 of its 6 beacons too few for its
    # ellipse test), and that no prior was there to help
    for words in ("identification: outer ring:", "; inner ring:", "no earlier ok estimate"):
        assert words in r.estimate.reason
    assert np.all(r.beacon_ids == -1)


def test_a_stale_prior_is_not_used() -> None:
    rng = np.random.default_rng(9)
    f0, f1 = true_frame(1.55, x_m=-0.2), true_frame(1.5, x_m=-0.3)
    frames = [_frame(f0, 0, SIGMA_PX, rng), _frame(f1, 10, SIGMA_PX, rng)]  # 1 s apart
    res = estimate_sequence(frames, camera(), LAYOUT, EstimateOptions(sigma_px=SIGMA_PX),
                            options=SequenceOptions(max_prior_age_s=0.5))
    assert res[0].estimate.ok and not res[1].estimate.ok
    assert "1.00 s old (> 0.5 s)" in res[1].estimate.reason
