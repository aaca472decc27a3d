"""Two-ring identification: above the outer ring, below it (inner ring alone), bow hidden, aliases refused;
and identification by a prior pose (partial ring, no bow in view)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from deckpose.detect.identify import identify_beacons
from deckpose.detect.prior_identify import PriorIdentifyOptions, identify_with_prior
from deckpose.estimate.pose_model import relative_from_params

from deckpose.errors import ConfigError
from tests.two_ring_frames import LAYOUT, camera, shuffled_noisy, true_frame

#: Centroid noise of the tests, px: bright spots' Cramér-Rao level is 0.1-0.3 px.
SIGMA_PX = 0.3


@pytest.mark.parametrize(("height_m", "x_m"), [(40.0, 0.0), (12.0, 0.0), (6.0, 0.3), (3.0, 0.0), (2.0, 0.2)])
def test_every_visible_beacon_gets_its_true_id(height_m: float, x_m: float) -> None:
    f = true_frame(height_m, x_m=x_m)
    pts, rgb, truth = shuffled_noisy(f, SIGMA_PX, np.random.default_rng(int(10 * height_m)))
    got = identify_beacons(pts, LAYOUT, camera(), rgb_flux=rgb)
    assert got.ok, got.reason
    np.testing.assert_array_equal(got.beacon_ids, truth)


def test_below_the_outer_ring_only_the_inner_ring_and_centre_are_seen() -> None:
    f = true_frame(3.0)
    assert set(f.ids.tolist()) == {12, *range(13, 19)}  # the premise: no outer beacon in view
    pts, rgb, truth = shuffled_noisy(f, SIGMA_PX, np.random.default_rng(1))
    got = identify_beacons(pts, LAYOUT, camera(), rgb_flux=rgb)
    assert got.ok
    np.testing.assert_array_equal(got.beacon_ids, truth)
    # the same frame without colour: the bow cannot be told, so no ring id is given
    mono = identify_beacons(pts, LAYOUT, camera(), rgb_flux=None)
    assert not mono.ok and "mono frame" in mono.reason


def test_an_inner_ring_that_may_be_every_other_outer_beacon_is_refused() -> None:
    # From 30 m the whole deck is in view. Keep the outer beacons 0, 2, ..., 10 (the outer bow
    # among them) and 1: 7 outer beacons, too few for the outer ring (8), while the even six
    # plus the centre look exactly like the inner ring and its centre, ten times larger.
    f = true_frame(30.0)
    keep = np.isin(f.ids, [0, 1, 2, 4, 6, 8, 10, 12, *range(13, 19)])
    pts, rgb = f.points_px[keep], f.rgb[keep]
    got = identify_beacons(pts, LAYOUT, camera(), rgb_flux=rgb)
    assert not got.ok
    assert "every other beacon of the outer ring" in got.reason
    assert np.all(got.beacon_ids == -1)


def test_bow_less_frame_is_not_identified_alone() -> None:
    f = true_frame(1.5, x_m=-0.5)  # inner bow (13) and beacon 18 out of view, no outer beacon
    assert 13 not in f.ids and f.ids.size >= 5
    pts, rgb, _ = shuffled_noisy(f, SIGMA_PX, np.random.default_rng(2))
    got = identify_beacons(pts, LAYOUT, camera(), rgb_flux=rgb)
    assert not got.ok and "outer ring:" in got.reason and "inner ring:" in got.reason


def _prior(f_params: np.ndarray, R_wc: np.ndarray, delta: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    return relative_from_params(f_params + np.asarray(delta), R_wc)


def test_partial_ring_identified_by_a_prior_pose() -> None:
    f = true_frame(1.5, x_m=-0.5)
    pts, _rgb, truth = shuffled_noisy(f, SIGMA_PX, np.random.default_rng(3))
    # the previous frame's pose, a tenth of a second older: a little off in every parameter
    R, t = _prior(f.params, f.R_world_from_cam, (0.01, -0.01, 0.03, 0.03, -0.02, 0.05))
    got = identify_with_prior(pts, LAYOUT, camera(), R, t)
    assert got.ok, got.reason
    np.testing.assert_array_equal(got.beacon_ids, truth)


def test_a_prior_off_by_more_than_the_gate_matches_nothing_wrong() -> None:
    f = true_frame(1.5, x_m=-0.5)
    pts, _rgb, truth = shuffled_noisy(f, SIGMA_PX, np.random.default_rng(4))
    # yaw off by 25 deg: inner beacons predicted 0.44 m (about 120 px) from where they are,
    # beyond the gate (0.3 of their ~280 px spacing) and short of their neighbours (60 deg away)
    R, t = _prior(f.params, f.R_world_from_cam, (0.0, 0.0, np.radians(25.0), 0.0, 0.0, 0.0))
    got = identify_with_prior(pts, LAYOUT, camera(), R, t)
    assert not got.ok and "match the beacons the prior pose predicts" in got.reason
    given = got.beacon_ids >= 0
    np.testing.assert_array_equal(got.beacon_ids[given], truth[given])  # only the centre, rightly


def test_two_blobs_in_one_gate_leave_that_beacon_unassigned() -> None:
    f = true_frame(3.0)
    pts, _rgb, truth = shuffled_noisy(f, SIGMA_PX, np.random.default_rng(5))
    glint = pts[0] + np.array([4.0, -3.0])  # a reflection 5 px from a beacon
    R, t = _prior(f.params, f.R_world_from_cam, (0.0,) * 6)
    got = identify_with_prior(np.vstack([pts, glint]), LAYOUT, camera(), R, t)
    assert got.ok
    assert got.beacon_ids[0] == -1 and got.beacon_ids[-1] == -1  # which one is the beacon is not known
    np.testing.assert_array_equal(got.beacon_ids[1:-1], truth[1:])


def test_prior_options_are_validated() -> None:
    with pytest.raises(ConfigError, match="gate_frac"):
        PriorIdentifyOptions(gate_frac=0.5)
    with pytest.raises(ConfigError, match="min_beacons"):
        PriorIdentifyOptions(min_beacons=3)


def test_one_ring_layouts_take_the_one_ring_path() -> None:
    one = dataclasses.replace(LAYOUT, inner_n_ring=0)
    f = true_frame(40.0, layout=one)
    pts, rgb, truth = shuffled_noisy(f, SIGMA_PX, np.random.default_rng(6))
    got = identify_beacons(pts, one, camera(), rgb_flux=rgb)
    assert got.ok
    np.testing.assert_array_equal(got.beacon_ids, truth)
