import math

import numpy as np
from deckpose.estimate import registry
from deckpose.estimate.batch import estimate_many, run_estimator
from deckpose.estimate.registry import EstimateOptions, register

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.records import PoseEstimate
from tests.estimate.synthetic import detections_for, pose_error

CAMERA = preset("8mp")
SHIP = ShipPose(0.05, -0.04, 0.3, 0.0, 0.6, -0.4)
CAM_POSE = CameraPose.nadir(30.0)


@register("test-rough")
def _rough(detections, camera, layout, options):
    """A thesis-like estimator: biased angles and height, no surge/sway, no covariance."""
    if len(detections) == 0:
        return PoseEstimate.failed("test-rough", "no detections")
    return PoseEstimate("test-rough", True, roll_rad=SHIP.roll_rad + 0.02, pitch_rad=SHIP.pitch_rad - 0.02,
                        yaw_rad=SHIP.yaw_rad + 0.03, height_m=31.0, extras={"thesis_roll_deg": 1.0})


def test_refine_any_estimator_reaches_the_ml_pose():
    rng = np.random.default_rng(2)
    dets = [detections_for(DeckLayout(), SHIP, CAM_POSE, CAMERA, sigma_px=0.5, rng=rng) for _ in range(5)]
    opts = EstimateOptions(sigma_px=0.5, refine=True)
    rough = estimate_many("test-rough", dets, CAMERA, DeckLayout(), EstimateOptions(sigma_px=0.5))
    refined = estimate_many("test-rough", dets, CAMERA, DeckLayout(), opts)
    pnp = estimate_many("pnp", dets, CAMERA, DeckLayout(), opts)
    for r0, r, p in zip(rough, refined, pnp):
        assert r0.covariance is None and math.isnan(r0.surge_m)
        assert r.ok and r.extras["refined"] == 1.0 and r.covariance is not None
        assert r.extras["thesis_roll_deg"] == 1.0 and r.extras["unrefined_height_m"] == 31.0
        # Same ML optimum as pnp, far closer to the truth than the rough start.
        np.testing.assert_allclose(pose_error(r, SHIP, CAM_POSE), pose_error(p, SHIP, CAM_POSE), atol=1e-7)
        assert abs(pose_error(r, SHIP, CAM_POSE)[0]) < 0.01


def test_run_estimator_keeps_failures_and_registry_lists_methods():
    assert {"conic", "pnp"} <= set(registry.names())
    empty = detections_for(DeckLayout(), SHIP, CAM_POSE, CAMERA, drop_ids=tuple(range(13)))
    for name in ("conic", "pnp", "test-rough"):
        e = run_estimator(name, empty, CAMERA, DeckLayout(), EstimateOptions(refine=True))
        assert not e.ok and e.reason


def test_a_relabelled_record_is_the_record_dataclasses_replace_builds():
    # The refinement relabels each refined record by a shallow copy (PoseEstimate.relabelled);
    # the reference is dataclasses.replace, which validates and freezes every field anew.
    import dataclasses

    e = PoseEstimate("", True, roll_rad=0.1, pitch_rad=-0.2, yaw_rad=0.3, height_m=30.0, surge_m=0.5,
                     sway_m=-0.4, covariance=np.diag(np.arange(1.0, 7.0)), inliers=(0, 3, 5),
                     extras={"chi2": 12.5, "refined": 1.0}, frame_id=7)
    extras = {"thesis_roll_deg": 1.0, "chi2": 12.5, "refined": 1.0}
    got = e.relabelled("thesis", extras)
    want = dataclasses.replace(e, method="thesis", extras=extras)
    for f in dataclasses.fields(PoseEstimate):
        a, b = getattr(got, f.name), getattr(want, f.name)
        assert (np.array_equal(a, b) if f.name == "covariance" else a == b), f.name
    assert dict(e.extras) == {"chi2": 12.5, "refined": 1.0} and e.method == ""  # the original is unchanged
    extras["chi2"] = 0.0  # the record keeps its own copy of the extras, read-only
    assert got.extras["chi2"] == 12.5
    with np.testing.assert_raises(TypeError):
        got.extras["chi2"] = 1.0  # type: ignore[index]
