"""The faithful thesis estimator: noise-free round trips, agreement of the per-frame
and batch forms, the conic fit against an independent solver, and failure flags."""

import math

import numpy as np
import pytest
from deckpose.estimate import registry
from deckpose.estimate.conic_fit import fit_conic, fit_conic_coefficients
from deckpose.estimate.thesis import estimate_thesis
from deckpose.estimate.thesis_algorithm import Failure, thesis_algorithm
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from deckpose.camera import preset, preset_names
from deckpose.layout import DeckLayout, thesis_layout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout, project_thesis_centred
from deckpose.records import Detections
from deckpose.rotation import R_from_thesis, R_from_zyx, wrap_angle_rad
from tests.tolerances import THESIS_ROUNDTRIP_DEG, THESIS_ROUNDTRIP_HEIGHT


def _random_cases(rng, n):
    roll = rng.uniform(-20, 20, n)
    pitch = rng.uniform(-10, 10, n)
    yaw = rng.uniform(-180, 180, n)
    height = rng.uniform(20, 80, n)
    return roll, pitch, yaw, height


@pytest.mark.parametrize("name", [n for n in preset_names() if n != "published"] + ["published"])
def test_batch_round_trip_noise_free(name):
    cam = preset(name)
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    roll, pitch, yaw, D = _random_cases(rng, 400)
    R = R_from_thesis(*np.radians([roll, pitch, yaw]))
    pc = project_thesis_centred(thesis_layout().positions_deck_m(), R, D, cam.fx, cam.fy)
    res = thesis_algorithm(pc, np.ones(pc.shape[:2], bool), cam.fx, cam.fy, 10.0)
    assert res.ok.all(), np.unique(res.failure)
    dyaw = np.degrees(wrap_angle_rad(np.radians(res.yaw_deg - yaw)))
    assert np.max(np.abs(res.roll_deg - roll)) < THESIS_ROUNDTRIP_DEG
    assert np.max(np.abs(res.pitch_deg - pitch)) < THESIS_ROUNDTRIP_DEG
    assert np.max(np.abs(dyaw)) < THESIS_ROUNDTRIP_DEG
    assert np.max(np.abs(res.height - D) / D) < THESIS_ROUNDTRIP_HEIGHT


def test_per_frame_estimator_through_general_projection_gives_zyx_truth():
    cam = preset("8mp")
    layout = DeckLayout()  # with a centre beacon, which the thesis method ignores
    rng = np.random.default_rng(7)
    for _ in range(30):
        truth = ShipPose(*np.radians([rng.uniform(-20, 20), rng.uniform(-10, 10), rng.uniform(-180, 180)]))
        D = rng.uniform(20, 80)
        proj = project_layout(layout, truth, CameraPose.nadir(D), cam)
        vis = np.flatnonzero(proj.visible)
        det = Detections(proj.points_px[vis], vis)
        est = registry.get("thesis")(det, cam, layout, registry.EstimateOptions())
        assert est.ok, est.reason
        R_est = R_from_zyx(est.roll_rad, est.pitch_rad, est.yaw_rad)
        assert np.max(np.abs(R_est - truth.R_world_from_deck)) < 1e-8
        t_r, t_p, _t_y = np.degrees(truth.thesis_angles_rad())
        assert est.extras["thesis_roll_deg"] == pytest.approx(t_r, abs=1e-6)
        assert est.extras["thesis_pitch_deg"] == pytest.approx(t_p, abs=1e-6)
        assert est.height_m == pytest.approx(D, rel=1e-9)
        assert math.isnan(est.surge_m) and math.isnan(est.sway_m)


def test_per_frame_and_batch_agree_bit_for_bit_on_noisy_input():
    cam = preset("4mp")
    rng = np.random.default_rng(3)
    roll, pitch, yaw, D = _random_cases(rng, 50)
    R = R_from_thesis(*np.radians([roll, pitch, yaw]))
    pc = project_thesis_centred(thesis_layout().positions_deck_m(), R, D, cam.fx, cam.fy)
    pc = pc + rng.normal(0, 1.0, pc.shape)
    batch = thesis_algorithm(pc, np.ones(pc.shape[:2], bool), cam.fx, cam.fy, 10.0)
    layout = thesis_layout()
    for i in range(50):
        uv = np.column_stack([pc[i, :, 0] + cam.cx, cam.cy - pc[i, :, 1]])
        est = estimate_thesis(Detections(uv, np.arange(12)), cam, layout)
        assert est.ok == batch.ok[i]
        if est.ok:
            # only the u,v <-> X',Y' round trip separates the two paths
            assert est.extras["thesis_roll_deg"] == pytest.approx(batch.roll_deg[i], abs=1e-9)
            assert est.extras["thesis_yaw_deg"] == pytest.approx(batch.yaw_deg[i], abs=1e-9)
            assert est.height_m == pytest.approx(batch.height[i], rel=1e-12)


def test_conic_fit_matches_an_independent_lstsq_on_raw_pixels():
    rng = np.random.default_rng(11)
    x = rng.uniform(-1500, 1500, (20, 12))
    y = rng.uniform(-1000, 1000, (20, 12))
    mask = rng.uniform(size=(20, 12)) > 0.2
    mask[:, :6] = True
    ours = fit_conic_coefficients(x, y, mask)
    for f in range(20):
        m = mask[f]
        M = np.column_stack([2 * x[f, m] * y[f, m], y[f, m] ** 2, 2 * x[f, m], 2 * y[f, m], np.ones(m.sum())])
        ref = np.linalg.lstsq(M, -x[f, m] ** 2, rcond=None)[0]
        np.testing.assert_allclose(ours[f], ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max())


def test_conic_canonical_parameters_of_a_known_ellipse():
    # Ellipse centre (30, -20), semi-axes 200 and 120, major axis at +25 deg.
    t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    a, b, th = 200.0, 120.0, np.radians(25.0)
    x = 30 + a * np.cos(t) * np.cos(th) - b * np.sin(t) * np.sin(th)
    y = -20 + a * np.cos(t) * np.sin(th) + b * np.sin(t) * np.cos(th)
    c = fit_conic(x[None], y[None], np.ones((1, 12), bool))
    assert c.ok[0]
    assert c.k[0] == pytest.approx(30) and c.h[0] == pytest.approx(-20)
    assert c.major[0] == pytest.approx(200) and c.minor[0] == pytest.approx(120)
    # the thesis's ellipse equation rotates by -Theta: the major axis lies at -Theta
    assert abs(np.degrees(c.tilt_rad[0])) == pytest.approx(25.0)


def _frame(cam, roll=0.0, pitch=0.0, yaw=0.0, D=30.0):
    R = R_from_thesis(*np.radians([[roll], [pitch], [yaw]]))
    return project_thesis_centred(thesis_layout().positions_deck_m(), R, np.array([D]), cam.fx, cam.fy)


def test_level_deck_is_flagged_not_nan():
    cam = preset("8mp-square")  # square pixels: a level deck images to a circle
    res = thesis_algorithm(_frame(cam), np.ones((1, 12), bool), cam.fx, cam.fy, 10.0)
    assert not res.ok[0] and res.failure[0] == Failure.LEVEL_DECK
    cam = preset("8mp")  # non-square: the first conic is fine, the undistorted one is a circle
    res = thesis_algorithm(_frame(cam, yaw=10.0), np.ones((1, 12), bool), cam.fx, cam.fy, 10.0)
    assert not res.ok[0] and res.failure[0] == Failure.LEVEL_DECK
    assert "level deck" in res.reason(0)


def test_too_few_beacons_and_missing_bow():
    cam = preset("8mp")
    pc = _frame(cam, 5.0, 3.0, 20.0)
    m = np.ones((1, 12), bool)
    m[0, 1:9] = False
    res = thesis_algorithm(pc, m, cam.fx, cam.fy, 10.0)
    assert res.failure[0] == Failure.TOO_FEW_BEACONS
    m = np.ones((1, 12), bool)
    m[0, 0] = False
    res = thesis_algorithm(pc, m, cam.fx, cam.fy, 10.0)
    assert res.failure[0] == Failure.NO_BOW_BEACON and math.isnan(res.roll_deg[0])
    est = estimate_thesis(Detections(np.zeros((3, 2)), [0, 1, 2]), cam, thesis_layout())
    assert not est and "fewer than 5" in est.reason


def test_missing_ring_beacons_still_solve():
    cam = preset("16mp")
    pc = _frame(cam, 12.0, -6.0, 140.0, 40.0)
    m = np.ones((1, 12), bool)
    m[0, [3, 7, 10]] = False
    res = thesis_algorithm(pc, m, cam.fx, cam.fy, 10.0)
    assert res.ok[0]
    assert res.roll_deg[0] == pytest.approx(12.0, abs=1e-6)
    assert res.yaw_deg[0] == pytest.approx(140.0, abs=1e-6)


def test_tilted_camera_is_refused_with_a_reason():
    cam = preset("8mp")
    opts = registry.EstimateOptions(R_world_from_cam=CameraPose.nadir(20, R_nadir_from_cam=R_from_zyx(0.1, 0, 0)).R_world_from_cam)
    est = estimate_thesis(Detections(np.zeros((6, 2)), np.arange(6)), cam, thesis_layout(), opts)
    assert not est and "nadir" in est.reason


@settings(max_examples=150, deadline=None)
@given(arrays(np.float64, (3, 12, 2), elements=st.floats(-5000, 5000, allow_nan=False)),
       arrays(np.bool_, (3, 12)))
def test_random_input_never_raises_and_never_reports_nan_as_ok(points, mask):
    res = thesis_algorithm(points, mask, 1500.0, 1400.0, 10.0)
    for arr in (res.roll_deg, res.pitch_deg, res.yaw_deg, res.height):
        assert np.all(np.isfinite(arr[res.ok]))
        assert np.all(np.isnan(arr[~res.ok]))
    assert np.all((res.failure == 0) == res.ok)


def test_thesis_inputs_centre_each_frame_and_keep_a_repeated_ids_last_detection():
    # the arrangement the method reads, written out: X' = u - cx, Y' = cy - v per ring id,
    # NaN and unmasked where missing; centre and unassigned detections ignored
    from deckpose.estimate.thesis import thesis_inputs

    cam, layout = preset("8mp"), DeckLayout()
    a = Detections(np.array([[100.0, 200.0], [300.0, 400.0], [500.0, 600.0], [7.0, 8.0], [9.0, 10.0]]),
                   [0, 3, 3, layout.centre_id, -1])
    b = Detections(np.array([[1000.0, 20.0]]), [11])
    empty = Detections(np.zeros((0, 2)), np.zeros(0, dtype=np.int64))
    points, mask = thesis_inputs([a, empty, b], cam, layout)
    assert points.shape == (3, layout.n_ring, 2) and mask.shape == (3, layout.n_ring)
    expected = np.full((3, layout.n_ring, 2), np.nan)
    expected[0, 0] = [100.0 - cam.cx, cam.cy - 200.0]
    expected[0, 3] = [500.0 - cam.cx, cam.cy - 600.0]  # id 3 listed twice: the last detection
    expected[2, 11] = [1000.0 - cam.cx, cam.cy - 20.0]
    np.testing.assert_array_equal(points, expected)  # exact: one subtraction each
    np.testing.assert_array_equal(mask, ~np.isnan(expected[:, :, 0]))
