"""Spurious points, wrong ids and random garbage: detected, removed or flagged, never an exception."""

import math

import numpy as np
import pytest
from deckpose.estimate import registry
from deckpose.estimate.batch import run_estimator
from deckpose.estimate.registry import EstimateOptions
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.records import Detections
from tests.estimate.synthetic import detections_for, pose_error

CAMERA = preset("8mp")
SHIP = ShipPose(0.05, -0.03, 0.4, 0.0, 1.0, -0.5)
CAM_POSE = CameraPose.nadir(30.0)
METHODS = ["conic", "pnp"]


def _noisy(rng: np.random.Generator) -> Detections:
    return detections_for(DeckLayout(), SHIP, CAM_POSE, CAMERA, sigma_px=0.5, rng=rng)


@pytest.mark.parametrize("method", METHODS)
def test_spurious_point_with_a_valid_id_is_removed(method):
    rng = np.random.default_rng(5)
    det = _noisy(rng)
    pts = np.vstack([det.points_px, det.points_px[2] + [60.0, -45.0]])   # a reflection near beacon 2
    ids = np.append(det.beacon_ids, 2)
    bad = Detections(pts, ids, np.broadcast_to(np.eye(2) * 0.25, (len(ids), 2, 2)))
    est = registry.get(method)(bad, CAMERA, DeckLayout(), EstimateOptions(sigma_px=0.5))
    assert est.ok, est.reason
    assert est.extras["n_outliers_removed"] == 1 and est.extras["outlier_id_0"] == 2
    assert np.all(np.abs(pose_error(est, SHIP, CAM_POSE)[:3]) < 0.01)


@pytest.mark.parametrize("method", METHODS)
def test_unassigned_and_unknown_ids_are_ignored(method):
    det = _noisy(np.random.default_rng(6))
    pts = np.vstack([det.points_px, [[100.0, 100.0], [200.0, 50.0]]])
    ids = np.append(det.beacon_ids, [-1, 99])
    est = registry.get(method)(Detections(pts, ids, np.broadcast_to(np.eye(2) * 0.25, (len(ids), 2, 2))),
                               CAMERA, DeckLayout(), EstimateOptions(sigma_px=0.5))
    assert est.ok and est.extras["n_ignored"] == 2 and est.extras["n_outliers_removed"] == 0


@pytest.mark.parametrize("method", METHODS)
def test_swapped_ids_are_detected(method):
    det = _noisy(np.random.default_rng(7))
    ids = det.beacon_ids.copy()
    ids[[3, 7]] = ids[[7, 3]]
    est = registry.get(method)(Detections(det.points_px, ids, det.covariance_px2),
                               CAMERA, DeckLayout(), EstimateOptions(sigma_px=0.5))
    if est.ok:  # removed: the pose must then be right
        assert est.extras["n_outliers_removed"] >= 1
        assert {3, 7} & {int(est.extras[f"outlier_id_{k}"]) for k in range(int(est.extras["n_outliers_removed"]))}
        assert np.all(np.abs(pose_error(est, SHIP, CAM_POSE)[:3]) < 0.01)
    else:
        assert "residual" in est.reason


@pytest.mark.parametrize("method", METHODS)
def test_covariances_understated_alike_are_widened_not_taken_for_outliers(method):
    """0.5 px noise declared as 0.05 px: every residual is ~10 sigma. No point is an outlier;
    the estimate is ok, says by how much it widened the covariance, and its sigmas then
    match the errors a 0.5 px declaration gives."""
    det = _noisy(np.random.default_rng(12))
    small = Detections(det.points_px, det.beacon_ids, np.broadcast_to(np.eye(2) * 0.05**2, (len(det), 2, 2)))
    est = registry.get(method)(small, CAMERA, DeckLayout(), EstimateOptions())
    honest = registry.get(method)(det, CAMERA, DeckLayout(), EstimateOptions(sigma_px=0.5))
    assert est.ok, est.reason
    assert est.extras["n_outliers_removed"] == 0
    assert 100 / 3 < est.extras["covariance_scale"] < 100 * 3
    assert "covariance_scale" not in honest.extras
    ratio = np.sqrt(np.diag(est.covariance) / np.diag(honest.covariance))
    assert np.all((ratio > 1 / 1.8) & (ratio < 1.8))


def test_a_wrong_point_is_not_hidden_in_the_covariance_scale():
    """Understated covariances plus one point 30 px off: the point is removed, not absorbed."""
    det = _noisy(np.random.default_rng(13))
    pts = det.points_px.copy()
    pts[5] += [30.0, -10.0]
    small = Detections(pts, det.beacon_ids, np.broadcast_to(np.eye(2) * 0.05**2, (len(det), 2, 2)))
    est = registry.get("pnp")(small, CAMERA, DeckLayout(), EstimateOptions())
    assert est.ok, est.reason
    assert est.extras["n_outliers_removed"] == 1 and est.extras["outlier_id_0"] == int(det.beacon_ids[5])
    assert np.all(np.abs(pose_error(est, SHIP, CAM_POSE)[:3]) < 0.01)


def test_too_many_outliers_are_flagged_not_hidden():
    det = _noisy(np.random.default_rng(8))
    pts = det.points_px.copy()
    pts[[1, 4, 6, 9]] += [[40, 0], [0, 50], [-45, 10], [30, 30]]
    est = registry.get("pnp")(Detections(pts, det.beacon_ids, det.covariance_px2), CAMERA, DeckLayout(),
                              EstimateOptions(sigma_px=0.5, max_outliers=2))
    assert not est.ok and "residual" in est.reason
    assert math.isnan(est.roll_rad) and "untrusted_roll_rad" in est.extras


def test_reprojection_threshold_flags():
    det = _noisy(np.random.default_rng(9))
    est = registry.get("pnp")(det, CAMERA, DeckLayout(),
                              EstimateOptions(sigma_px=0.5, max_reprojection_rms_px=0.05))
    assert not est.ok and "max_reprojection_rms_px" in est.reason


coords = st.one_of(st.floats(min_value=-1e5, max_value=1e5), st.just(math.nan), st.just(math.inf))


@st.composite
def garbage_detections(draw):
    n = draw(st.integers(min_value=0, max_value=16))
    pts = draw(st.lists(st.tuples(coords, coords), min_size=n, max_size=n))
    ids = draw(st.lists(st.integers(min_value=-2, max_value=14), min_size=n, max_size=n))
    s = draw(st.floats(min_value=1e-6, max_value=1e3))
    return Detections(np.array(pts, dtype=float).reshape(n, 2), np.array(ids, dtype=int),
                      np.broadcast_to(np.eye(2) * s, (n, 2, 2)))


@st.composite
def perturbed_truth(draw):
    """Exact beacons with a few points moved, dropped or relabelled — near-degenerate inputs."""
    det = detections_for(DeckLayout(), SHIP, CAM_POSE, CAMERA)
    pts, ids = det.points_px.copy(), det.beacon_ids.copy()
    k = draw(st.integers(min_value=0, max_value=len(ids)))
    for _ in range(draw(st.integers(min_value=0, max_value=4))):
        i = draw(st.integers(min_value=0, max_value=len(ids) - 1))
        pts[i] += draw(st.tuples(st.floats(-500, 500), st.floats(-500, 500)))
        ids[i] = draw(st.integers(min_value=-1, max_value=13))
    if draw(st.booleans()):
        pts[:] = pts[0]  # all coincident
    return Detections(pts[:k], ids[:k], np.broadcast_to(np.eye(2) * 0.25, (k, 2, 2)))


def _check(est):
    if est.ok:
        vals = [est.roll_rad, est.pitch_rad, est.yaw_rad, est.height_m, est.surge_m, est.sway_m]
        assert all(math.isfinite(v) for v in vals)
        assert est.covariance is not None and np.all(np.isfinite(est.covariance))
    else:
        assert est.reason


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(det=st.one_of(garbage_detections(), perturbed_truth()), refine=st.sampled_from([False, True, "mean"]))
def test_random_inputs_never_raise_nor_report_nan_as_ok(method, det, refine):
    opts = EstimateOptions(refine=bool(refine), posterior_mean=refine == "mean", sigma_px=0.5)
    _check(run_estimator(method, det, CAMERA, DeckLayout(), opts))


@pytest.mark.parametrize("method", ["conic", "pnp"])
def test_near_coincident_points_are_not_reported_ok(method):
    """Thirteen beacons within a hundredth of a pixel of each other: a finite but meaningless pose."""
    from deckpose.estimate import registry
    from deckpose.estimate.batch import estimate_many
    from deckpose.estimate.registry import EstimateOptions

    from deckpose.camera import preset
    from deckpose.layout import DeckLayout
    from deckpose.records import Detections

    layout, camera = DeckLayout(), preset("8mp")
    rng = np.random.default_rng(2)
    dets = []
    for _ in range(6):
        pts = np.array([1900.0, 1100.0]) + rng.normal(0, 0.01, (layout.n_beacons, 2))
        dets.append(Detections(pts, np.arange(layout.n_beacons), np.broadcast_to(np.eye(2), (layout.n_beacons, 2, 2))))
    opts = EstimateOptions()
    single = [registry.get(method)(d, camera, layout, opts) for d in dets]
    batched = estimate_many(method, dets, camera, layout, opts)
    for s, b in zip(single, batched):
        assert not s.ok and not b.ok
        assert s.reason == b.reason


def _frames_with_one_outlier(n: int, seed: int) -> list[Detections]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        det = _noisy(rng)
        pts = np.array(det.points_px)
        pts[k % len(pts)] += [25.0, -18.0]
        out.append(Detections(pts, det.beacon_ids, det.covariance_px2))
    return out


@pytest.mark.parametrize("method", METHODS)
def test_robust_search_stacks_the_frames_of_a_beacon_set(method, monkeypatch):
    """Frames the batch leaves to the robust search are solved together, round by round: the
    method's candidates are asked once per round and beacon set, not once per frame, and each
    record is the one the frame gets alone."""
    from deckpose.estimate import robust_search
    from deckpose.estimate.batch import estimate_batch

    frames = _frames_with_one_outlier(12, 21)
    options = EstimateOptions(sigma_px=0.5)
    alone = [run_estimator(method, d, CAMERA, DeckLayout(), options) for d in frames]
    calls: list[int] = []
    real = robust_search._answer

    def counted(kind, obs, params, frames_, solve):
        calls.append(len(frames_))
        return real(kind, obs, params, frames_, solve)

    monkeypatch.setattr(robust_search, "_answer", counted)
    together = estimate_batch(method, frames, CAMERA, DeckLayout(), options)
    assert all(e.ok and e.extras["n_outliers_removed"] == 1 for e in together)
    # a first solve, one round of trials and the solve without the outlier, each of all 12 frames
    # (the outlier's beacon differs by frame, so the last solve has one call per beacon set)
    assert calls[:2] == [12, 12]
    assert len(calls) < 2 * len(frames)
    for a, b in zip(alone, together, strict=True):
        assert (a.ok, a.reason, a.extras["outlier_id_0"]) == (b.ok, b.reason, b.extras["outlier_id_0"])
        np.testing.assert_allclose([b.roll_rad, b.pitch_rad, b.height_m], [a.roll_rad, a.pitch_rad, a.height_m],
                                   rtol=1e-9, atol=1e-12)


def test_a_numerical_error_in_one_frame_of_the_stack_fails_that_frame_only(monkeypatch):
    """A step that raises in the stacked solve is run frame by frame: the frame whose own step
    raises gets a failed record with the error, the others their own estimates."""
    from deckpose.estimate import robust_search
    from deckpose.estimate.batch import estimate_batch

    frames = _frames_with_one_outlier(6, 22)
    poisoned = frames[3].points_px[0, 0]
    real = robust_search._answer

    def flaky(kind, obs, params, frames_, solve):
        if kind == "solve" and np.any(obs.xy.shape[0] and np.isclose(
                (obs.xy[:, 0, 0] * CAMERA.K[0, 0] + CAMERA.K[0, 2]), poisoned)):
            raise np.linalg.LinAlgError("poisoned frame")
        return real(kind, obs, params, frames_, solve)

    monkeypatch.setattr(robust_search, "_answer", flaky)
    got = estimate_batch("pnp", frames, CAMERA, DeckLayout(), EstimateOptions(sigma_px=0.5))
    assert not got[3].ok and got[3].reason == "numerical failure: poisoned frame"
    assert all(e.ok for i, e in enumerate(got) if i != 3)
