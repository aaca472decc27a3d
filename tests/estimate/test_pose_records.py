"""A record's tail and verdict (estimate.pose_records.record_tails / pose_record), checked on their own.

Both record builders (``make_estimate`` for the robust search's frames, ``finish_batch`` for
the frames a batch settles) end their records here, so these are the rules every record keeps:
the relative pose in the tail means what OpenCV means by ``rvec``/``tvec`` (checked with
``cv2.projectPoints`` against the pose model's own projection), a failed record whose pose is
not finite keeps no relative pose, a fit without a covariance leaves no sigmas, and a problem makes a
failed record that keeps the pose as ``untrusted_*``.
"""

from __future__ import annotations

import cv2
import numpy as np
from deckpose.estimate.pose_model import project_normalised
from deckpose.estimate.pose_records import TAIL_EXTRAS, pose_record, record_head, record_tails

from deckpose.layout import DeckLayout
from deckpose.records import POSE_PARAMS
from deckpose.rotation import R_from_zyx


def _frames(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    params = np.column_stack([rng.normal(0, 0.1, (n, 3)), rng.normal(0, 2.0, (n, 2)), rng.uniform(10, 80, n)])
    R_wc = np.stack([R_from_zyx(*a) @ np.diag([1.0, -1.0, -1.0])
                     for a in rng.normal(0, 0.05, (n, 3))])  # looking down, tilted a little
    return params, R_wc


def test_the_tail_pose_is_opencvs_rvec_and_tvec():
    params, R_wc = _frames(5, 1)
    tails = np.array(record_tails(np.ones(5), np.ones(5), 20.0, np.full((5, 6), 0.01), params, R_wc))
    points = np.array(DeckLayout().positions_deck_m())
    xy, _, _ = project_normalised(params, points, R_wc, jacobian=False)
    for f in range(5):
        rvec, tvec = tails[f, 9::2], tails[f, 10::2]
        got, _ = cv2.projectPoints(points, rvec, tvec, np.eye(3), None)
        # both are double-precision projections of the same points at 10-80 m: agreement to 1e-12 rad
        np.testing.assert_allclose(got.reshape(-1, 2), xy[f], atol=1e-12)


def test_the_tail_keeps_its_inputs_and_order():
    params, R_wc = _frames(3, 2)
    rms, chi2, sig = np.array([0.1, 0.2, 0.3]), np.array([5.0, 6.0, 7.0]), np.arange(18.0).reshape(3, 6)
    tails = np.array(record_tails(rms, chi2, 14.0, sig, params, R_wc))
    assert tails.shape == (3, len(TAIL_EXTRAS))
    np.testing.assert_array_equal(tails[:, 0], rms)
    np.testing.assert_array_equal(tails[:, 1], chi2)
    np.testing.assert_array_equal(tails[:, 2], 14.0)
    np.testing.assert_array_equal(tails[:, 3:9], sig)
    # a batch is its frames: each row is that frame's batch of one
    for f in range(3):
        one = record_tails(rms[f:f + 1], chi2[f:f + 1], 14.0, sig[f:f + 1], params[f:f + 1], R_wc[f:f + 1])[0]
        np.testing.assert_array_equal(one, tails[f])


def test_pose_record_ok_failed_and_partial_tails():
    params, R_wc = _frames(1, 4)
    tail = record_tails(np.array([0.4]), np.array([9.0]), 20.0, np.full((1, 6), 0.02), params, R_wc)[0]
    p = params[0].tolist()
    cov = np.diag(np.full(6, 0.02 ** 2))
    head = record_head(13, 0, [], False)

    ok = pose_record("m", dict(head), tail, p, cov, 1.0, tuple(range(13)))
    assert ok.ok and list(ok.extras) == list(head) + list(TAIL_EXTRAS)
    assert ok.height_m == p[5] and ok.roll_rad == p[0] and ok.sway_m == p[4]

    widened = pose_record("m", dict(head), tail, p, cov * 4.0, 4.0, tuple(range(13)))
    assert widened.extras["covariance_scale"] == 4.0 and list(widened.extras)[-1] == "covariance_scale"

    failed = pose_record("m", dict(head), tail, p, None, 4.0, (), problem="why")
    assert not failed.ok and failed.reason == "why"
    names = list(failed.extras)
    assert not any(n.startswith("sigma_") for n in names) and "covariance_scale" not in names
    assert [failed.extras["untrusted_" + n] for n in POSE_PARAMS] == p
    assert "rvec_cam_from_deck_x" in names  # the pose is finite: its relative pose stays

    lost_p = list(p)
    lost_p[5] = float("nan")  # the height only
    with np.errstate(invalid="ignore"):
        lost_tail = record_tails(np.array([0.4]), np.array([9.0]), 20.0, np.full((1, 6), 0.02),
                                 np.array([lost_p]), R_wc)[0]
    lost = pose_record("m", dict(head), lost_tail, lost_p, cov, 1.0, (), problem="lost")
    assert not lost.ok and "sigma_roll_rad" in lost.extras
    assert not any(n.startswith(("rvec_", "t_cam")) for n in lost.extras)
