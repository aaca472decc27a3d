"""The painted ring (issue 22): its config, its analytic paint, and its exact truth."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from deckpose.render.config import config_from_dict, config_to_dict, default_config
from deckpose.render.painted_ring import paint_coverage, ring_truth

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.painted_ring import BowMark, CentreMark, PaintedRing, edge_conics_px, ellipse_params
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck
from deckpose.run_folder import RunPaths, read_frames
from tests.render.conftest import tiny_doc


def _camera(distorted: bool = False) -> CameraModel:
    K = np.array([[700.0, 0.0, 322.0], [0.0, 700.0, 238.0], [0.0, 0.0, 1.0]])
    return CameraModel(640, 480, K, np.array([-0.12, 0.03, 0.0, 0.0]) if distorted else np.zeros(0))


def _edge_points_px(ring: PaintedRing, ship: ShipPose, cam_pose: CameraPose, camera: CameraModel,
                    r_m: float) -> np.ndarray:
    """Points of a deck circle projected through the camera model's own projection (independent of the conic)."""
    ang = np.linspace(0, 2 * math.pi, 97, endpoint=False)
    P = np.column_stack([r_m * np.cos(ang), r_m * np.sin(ang), np.zeros_like(ang)])
    T = T_cam_from_deck(ship, cam_pose)
    return camera.project(P @ T[:3, :3].T + T[:3, 3])


def test_config_section_parses_and_defaults_stay_unchanged():
    cfg = config_from_dict(tiny_doc(painted_ring={"radius_m": 7.0, "line_width_m": 0.4, "bow_mark": "bar",
                                                  "bar_length_m": 1.0, "centre_mark": "none"}))
    assert cfg.painted_ring == PaintedRing(radius_m=7.0, line_width_m=0.4, bow_mark=BowMark.BAR, bar_length_m=1.0,
                                           centre_mark=CentreMark.NONE)
    assert config_from_dict(config_to_dict(cfg)) == cfg  # the manifest's config reads back
    assert "painted_ring" not in config_to_dict(default_config())  # default manifests as before
    assert default_config().painted_ring is None


@pytest.mark.parametrize(("ring", "words"), [
    ({"radius_m": 5.0, "line_width_m": 5.0}, "line_width_m: must be smaller than radius_m"),
    ({"radius_m": 14.0}, "beyond the deck"),
    ({"radius_m": 9.5}, "onto the beacons"),
    ({"bow_mark": "dot"}, "bow_mark"),
    ({"colour": [1.0, 0.5]}, "colour"),
    ({"radius": 8.0}, "radius"),
    ({"contrast": 1.5}, "contrast"),
])
def test_bad_painted_ring_is_a_one_line_error(ring, words):
    with pytest.raises(ConfigError) as exc:
        config_from_dict(tiny_doc(layout={"n_ring": 12, "radius_m": 10.0}, painted_ring=ring))
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_pbr_shading_is_refused():
    with pytest.raises(ConfigError, match="shading: flat"):
        config_from_dict(tiny_doc(scene={"shading": "pbr"}, painted_ring={}))


@pytest.mark.parametrize("distorted", [False, True])
def test_truth_conics_hold_the_projected_edge_circles(distorted):
    ring = PaintedRing()
    camera = _camera(distorted)
    ship = ShipPose(math.radians(3.0), math.radians(-2.0), math.radians(25.0), 0.4, 0.6, -0.3)
    cam_pose = CameraPose.nadir(40.0, x_m=0.5)
    truth = ring_truth(ring, ship, cam_pose, camera)
    assert truth.distorted is distorted
    for k, r in enumerate(ring.edge_radii_m):
        # the conic holds in the undistorted image: undistort the camera's own projection
        pts = camera.undistort(_edge_points_px(ring, ship, cam_pose, camera, r))
        X = np.column_stack([pts, np.ones(len(pts))])
        C = truth.conics_px[k]
        f = np.einsum("ni,ij,nj->n", X, C, X)
        grad = 2 * np.hypot(*(X @ C)[:, :2].T)
        # first-order distance; 1e-6 px: the undistortion iterates to 1e-12 (normalised), f ~ 700 px
        assert np.max(np.abs(f / grad)) < 1e-6
    centre = camera.project(T_cam_from_deck(ship, cam_pose)[:3, 3][None])[0]
    np.testing.assert_allclose(truth.centre_px, centre, atol=1e-9)


def test_ellipse_params_round_trip_a_drawn_ellipse():
    # an ellipse written out: centre (300, 200), semi-axes 120 and 70, major axis at 30 deg
    c, a, b, th = np.array([300.0, 200.0]), 120.0, 70.0, math.radians(30.0)
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    A = R @ np.diag([1 / a**2, 1 / b**2]) @ R.T
    C = np.block([[A, (-A @ c)[:, None]], [(-A @ c)[None, :], np.array([[c @ A @ c - 1]])]])
    e = ellipse_params(C)
    assert e is not None
    np.testing.assert_allclose([e.centre_u_px, e.centre_v_px, e.semi_major_px, e.semi_minor_px, e.angle_rad],
                               [300.0, 200.0, 120.0, 70.0, th], rtol=1e-12, atol=1e-9)


def test_paint_coverage_area_is_the_annulus_area_seen_from_nadir():
    # Fronto-parallel deck (nadir camera, level deck, fx = fy): the image is the deck scaled by
    # f / h, so the painted area in px^2 is the painted deck area times (f / h)^2, written out.
    ring = PaintedRing(bow_mark=BowMark.GAP, gap_deg=20.0, centre_mark=CentreMark.DISC, centre_radius_m=0.6)
    camera = _camera()
    h = 40.0
    got = paint_coverage(ring, ShipPose(), CameraPose.nadir(h), camera, samples=8)
    assert got is not None
    cov = got[2]
    ri, ro = ring.edge_radii_m
    area_m2 = math.pi * (ro**2 - ri**2) * (1 - 20.0 / 360.0) + math.pi * 0.6**2
    expected = area_m2 * (camera.fx / h) ** 2
    # each boundary pixel's coverage is quantised to 1/64; the errors along ~2 x 2 pi x 150 px
    # of edge average out, so 1 % of the area (~24 px^2) is a loose, safe bound
    boundary = np.count_nonzero((cov > 0) & (cov < 1))
    assert abs(float(cov.sum()) - expected) < max(0.01 * expected, boundary / 64.0)
    assert 0.0 <= cov.min() and cov.max() <= 1.0


def test_dataset_writes_the_painted_ring_truth(tmp_path, egl_renderer_factory):
    from deckpose.render.dataset import render_dataset

    doc = tiny_doc(cameras=[{"preset": "4mp-square", "size": [640, 480]}], heights_m=[40.0], lighting=["day", "night"],
                   layout={"n_ring": 12, "radius_m": 10.0}, painted_ring={"radius_m": 8.0})
    out = render_dataset(config_from_dict(doc), tmp_path / "ds", workers=0, progress=False)
    truth = pd.read_parquet(out / "painted_ring.parquet")
    frames = read_frames(RunPaths(out))
    assert len(truth) == 2 * len(frames) and set(truth["edge"]) == {"inner", "outer"}
    cam = config_from_dict(doc).cameras[0].model()
    ring = PaintedRing()
    for f in frames.itertuples():
        R = np.array([[getattr(f, f"R_world_from_cam_{i}{j}") for j in range(3)] for i in range(3)])
        cp = CameraPose(R, np.array([f.cam_x_m, f.cam_y_m, f.cam_z_m]))
        ship = ShipPose(*np.radians([f.roll_deg, f.pitch_deg, f.yaw_deg]), f.heave_m, f.surge_m, f.sway_m)
        C = edge_conics_px(ring, T_cam_from_deck(ship, cp), cam.K)
        for k, edge in enumerate(("inner", "outer")):
            row = truth[(truth.frame_id == f.frame_id) & (truth.edge == edge)]
            got = row[[f"conic_px_{i}{j}" for i in range(3) for j in range(3)]].to_numpy().reshape(3, 3)
            np.testing.assert_allclose(got, C[k], atol=1e-12)  # the table's conic is the pose's
            pts = _edge_points_px(ring, ship, cp, cam, ring.edge_radii_m[k])
            e = ellipse_params(got)
            assert e is not None
            # the projected circle's points lie within the table's ellipse's bounding radius
            d = np.hypot(pts[:, 0] - e.centre_u_px, pts[:, 1] - e.centre_v_px)
            assert d.max() <= e.semi_major_px + 1e-6 and d.min() >= e.semi_minor_px - 1e-6
