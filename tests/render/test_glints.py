"""Glints: facets that mirror the sun into the camera, placed as Cox and Munk's glitter places them.

The checks invert the placement independently: from a glint's point, the camera and the
light, the facet that mirrors one into the other has the half vector of the two directions
as its normal (the law of reflection), and so a slope; those slopes must be the ones drawn
and must follow the slope distribution asked for.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from deckpose.render.glints import cox_munk_slope_sigma, facet_mirror_points, glint_points
from deckpose.render.scene import SUN_TRAVEL_WORLD
from deckpose.render.ship_lights import ship_lights
from deckpose.render.ship_lights_config import ShipLightsSpec
from scipy import stats

from deckpose.camera import CameraModel
from deckpose.pose import CameraPose, ShipPose

TO_SUN = -SUN_TRAVEL_WORLD
SHIP = ShipPose(math.radians(4.0), math.radians(-3.0), math.radians(20.0), 0.8, 0.6, -0.4)
#: A pinhole camera of about 170 degrees: every facet whose mirrored ray reaches it is in view.
WIDE = CameraModel(40000, 40000, [[1500.0, 0, 20000.0], [0, 1500.0, 20000.0], [0, 0, 1]])


def _slopes_from_points(X: np.ndarray, R_world_from_plane: np.ndarray, camera_centre: np.ndarray) -> np.ndarray:
    """The facet slopes (dz/dx, dz/dy in the plane's frame) that mirror the sun from X into the camera."""
    u = camera_centre[None, :] - X
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    h = u + TO_SUN[None, :]
    h = (h / np.linalg.norm(h, axis=1, keepdims=True)) @ R_world_from_plane  # in the plane's frame
    return np.column_stack([-h[:, 0] / h[:, 2], -h[:, 1] / h[:, 2]])


def test_cox_munk_slopes_are_the_papers_mean_square_slope_split_over_two_axes() -> None:
    for wind in (0.0, 5.0, 13.5):
        assert 2 * cox_munk_slope_sigma(wind) ** 2 == pytest.approx(0.003 + 5.12e-3 * wind, rel=1e-12)


def test_each_facet_lies_where_it_mirrors_the_light_into_the_camera() -> None:
    rng = np.random.default_rng(0)
    slopes = rng.normal(0.0, 0.15, (500, 2))
    R = SHIP.R_world_from_deck
    C = np.array([3.0, -2.0, 45.0])
    X = facet_mirror_points(slopes, R, SHIP.t_world_from_deck, TO_SUN, C)
    ok = np.isfinite(X).all(axis=1)
    assert ok.mean() > 0.95
    np.testing.assert_allclose((X[ok] - SHIP.t_world_from_deck) @ R[:, 2], 0.0, atol=1e-9)  # on the plane
    np.testing.assert_allclose(_slopes_from_points(X[ok], R, C), slopes[ok], atol=1e-9)


def test_sea_glints_follow_the_slope_distribution() -> None:
    """A calm sea (wind 0): the slopes of 3,000 glints seen by a very wide camera are N(0, sigma^2) per axis."""
    sigma = cox_munk_slope_sigma(0.0)
    pose = CameraPose.nadir(60.0)
    X = glint_points(3000, sigma, np.eye(3), np.array([0.0, 0.0, -6.0]), TO_SUN, pose, WIDE,
                     np.random.default_rng(1))
    assert len(X) == 3000
    np.testing.assert_allclose(X[:, 2], -6.0, atol=1e-9)
    s = _slopes_from_points(X, np.eye(3), pose.position_world_m)
    for axis in range(2):
        # a sample sd of 3,000 draws is within 1/sqrt(2n) = 1.3 % of sigma; 5 of those
        assert np.std(s[:, axis]) == pytest.approx(sigma, rel=5 / math.sqrt(2 * 3000))
        assert stats.kstest(s[:, axis] / sigma, "norm").pvalue > 1e-3
    # the glitter gathers around the sea's mirror point of the sun (the zero-slope facet)
    mirror = facet_mirror_points(np.zeros((1, 2)), np.eye(3), np.array([0.0, 0.0, -6.0]), TO_SUN,
                                 pose.position_world_m)[0]
    np.testing.assert_allclose(np.median(X[:, :2], axis=0), mirror[:2], atol=0.05 * 66.0)


def test_a_smooth_sea_far_from_its_mirror_point_shows_no_glint() -> None:
    """A narrow camera straight down over a calm sea: the sun's mirror point lies 35 degrees
    off its axis, 9 slope sigmas away, so no glint is in view (and none is made up)."""
    narrow = CameraModel(1000, 1000, [[5000.0, 0, 500.0], [0, 5000.0, 500.0], [0, 0, 1]])
    X = glint_points(5, cox_munk_slope_sigma(0.0), np.eye(3), np.array([0.0, 0.0, -6.0]), TO_SUN,
                     CameraPose.nadir(60.0), narrow, np.random.default_rng(2))
    assert X.shape == (0, 3)
    # the same sea seen wide has them all
    X = glint_points(5, cox_munk_slope_sigma(0.0), np.eye(3), np.array([0.0, 0.0, -6.0]), TO_SUN,
                     CameraPose.nadir(60.0), WIDE, np.random.default_rng(2))
    assert X.shape == (5, 3)


def test_glints_on_a_tilted_plane_follow_its_slope_distribution() -> None:
    """The wet deck's path (a plane tilted with the ship, slopes in its own frame), unbounded and
    seen wide: the slopes recovered from 3,000 glints are N(0, tan(4 deg)^2) per axis."""
    sigma = math.tan(math.radians(4.0))
    pose = CameraPose.nadir(40.0)
    X = glint_points(3000, sigma, SHIP.R_world_from_deck, SHIP.t_world_from_deck, TO_SUN, pose, WIDE,
                     np.random.default_rng(6), half_extent_m=1e6)
    assert len(X) == 3000
    np.testing.assert_allclose((X - SHIP.t_world_from_deck) @ SHIP.R_world_from_deck[:, 2], 0.0, atol=1e-9)
    s = _slopes_from_points(X, SHIP.R_world_from_deck, pose.position_world_m)
    for axis in range(2):
        assert np.std(s[:, axis]) == pytest.approx(sigma, rel=5 / math.sqrt(2 * 3000))
        assert stats.kstest(s[:, axis] / sigma, "norm").pvalue > 1e-3


def test_deck_glints_lie_on_the_plate_and_ride_with_the_deck() -> None:
    cam = CameraModel(3000, 3000, [[900.0, 0, 1500.0], [0, 900.0, 1500.0], [0, 0, 1]])
    pose = CameraPose.nadir(40.0)
    spec = ShipLightsSpec(deck_glints=40, deck_slope_deg=10.0)
    lights = ship_lights(spec, 14.0, 6.0, np.random.default_rng(3), ship=SHIP, camera_pose=pose, camera=cam,
                         to_light_world=TO_SUN)
    assert len(lights) == 40 and {lt.kind for lt in lights} == {"deck_glint"}
    p = np.array([lt.position_m for lt in lights])
    assert all(lt.on_deck for lt in lights)
    np.testing.assert_allclose(p[:, 2], 0.0, atol=1e-9)
    assert np.all(np.abs(p[:, :2]) <= 14.0 + 1e-9)
    # in the world (at this deck pose) each mirrors the sun into the camera through a facet
    # tilted as a 10-degree-RMS film allows (all within 5 sigmas, most within 2.5)
    X = p @ SHIP.R_world_from_deck.T + SHIP.t_world_from_deck
    tilt = np.degrees(np.arctan(np.hypot(*_slopes_from_points(X, SHIP.R_world_from_deck,
                                                                pose.position_world_m).T)))
    assert tilt.max() < 5 * 10.0 * math.sqrt(2) and np.median(tilt) < 2.5 * 10.0 * math.sqrt(2)


def test_glints_differ_per_frame_stream_and_repeat_per_seed() -> None:
    cam = CameraModel(3000, 3000, [[900.0, 0, 1500.0], [0, 900.0, 1500.0], [0, 0, 1]])
    spec = ShipLightsSpec(glints=4, deck_glints=2)

    def positions(seed: int) -> np.ndarray:
        return np.array([lt.position_m for lt in ship_lights(spec, 14.0, 6.0, np.random.default_rng(seed), ship=SHIP,
                                                              camera_pose=CameraPose.nadir(60.0), camera=cam,
                                                              to_light_world=TO_SUN)])

    assert positions(1).shape == (6, 3)
    np.testing.assert_array_equal(positions(1), positions(1))
    assert not np.allclose(positions(1), positions(2))


def test_no_sea_glint_is_seen_through_the_deck_plate() -> None:
    """The camera straight above the deck at 20 m: glints whose ray to the camera crosses the
    plate are hidden (checked by intersecting each segment with the plate's plane), and without
    the ship some would have been."""
    from deckpose.render.scene_config import ShipModelSpec
    from deckpose.render.ship_lights import ship_occluder

    cam = CameraModel(3000, 3000, [[700.0, 0, 1500.0], [0, 700.0, 1500.0], [0, 0, 1]])
    pose = CameraPose.nadir(20.0)
    h = 14.0
    level = ShipPose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    blocker = ship_occluder(h, 6.0, ShipModelSpec())
    blocker.apply_transform(level.T_world_from_deck)
    sigma = cox_munk_slope_sigma(25.0)  # a rough sea: glints all over the view

    def through_plate(X: np.ndarray) -> np.ndarray:
        C = pose.position_world_m
        t = (0.0 - X[:, 2]) / (C[2] - X[:, 2])  # where the segment meets the deck plane z = 0
        P = X + t[:, None] * (C - X)
        return (t > 0) & (t < 1) & np.all(np.abs(P[:, :2]) <= h, axis=1)

    seen = glint_points(400, sigma, np.eye(3), np.array([0.0, 0.0, -6.0]), TO_SUN, pose, cam,
                        np.random.default_rng(4), occluder_world=blocker)
    assert len(seen) == 400 and not through_plate(seen).any()
    bare = glint_points(400, sigma, np.eye(3), np.array([0.0, 0.0, -6.0]), TO_SUN, pose, cam,
                        np.random.default_rng(4))
    assert through_plate(bare).mean() > 0.1


def test_no_sea_glint_is_seen_through_the_hull() -> None:
    """A camera above the bow: no kept glint's segment to the camera passes inside the hull (a
    convex prism: a point is inside where it is behind every face's plane, sampled every 2 cm
    along each segment); without the ship some would."""
    from deckpose.render.scene_config import ShipModelSpec
    from deckpose.render.ship_lights import ship_occluder
    from deckpose.render.ship_model import hull_mesh

    level = ShipPose()
    pose = CameraPose.nadir(30.0, x_m=40.0, y_m=-10.0)
    cam = CameraModel(3000, 3000, [[700.0, 0, 1500.0], [0, 700.0, 1500.0], [0, 0, 1]])
    sea = (np.eye(3), np.array([0.0, 0.0, -6.0]), TO_SUN, pose, cam)
    hull = hull_mesh(14.0, 6.0)
    normals, corners = hull.face_normals, hull.triangles[:, 0]

    def through_hull(X: np.ndarray) -> np.ndarray:
        C = pose.position_world_m
        t = np.linspace(0.0, 1.0, 3000)[1:-1]
        pts = X[:, None, :] + t[None, :, None] * (C - X)[:, None, :]  # (N, S, 3), spacing < 2 cm
        depth = np.einsum("nsk,fk->nsf", pts, normals) - np.einsum("fk,fk->f", corners, normals)
        return np.any(np.all(depth < -1e-6, axis=2), axis=1)

    blocker = ship_occluder(14.0, 6.0, ShipModelSpec(hull=True))
    blocker.apply_transform(level.T_world_from_deck)
    sigma = cox_munk_slope_sigma(25.0)
    seen = glint_points(200, sigma, *sea, np.random.default_rng(5), occluder_world=blocker)
    bare = glint_points(200, sigma, *sea, np.random.default_rng(5))
    assert len(seen) == 200 and not through_hull(seen).any()
    assert through_hull(bare).mean() > 0.05
