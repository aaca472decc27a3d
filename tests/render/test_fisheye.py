"""A fisheye (equidistant) camera through rendering, detection and estimation.

The deck raster is drawn through a wider pinhole (:func:`deckpose.render.lens.raster_camera`) and
warped by the fisheye; the beacons are splatted in the fisheye image at
``CameraModel.project``. So the tests check (1) the warp puts raster content at the fisheye
projection, (2) a rendered dataset's spots sit at its ``beacons.parquet`` truth, and (3) the
dataset's camera file, the detector and the estimator take it from there.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pandas as pd
import pytest
from deckpose.detect.frame_detection import detect_frame
from deckpose.estimate.batch import run_estimator
from deckpose.estimate.registry import EstimateOptions
from deckpose.render.config import config_from_dict
from deckpose.render.dataset import render_dataset
from deckpose.render.lens import distort, raster_camera

from deckpose.camera import CameraModel
from deckpose.camera_info import read_camera_info
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose
from deckpose.records import Frame

from .conftest import tiny_config, tiny_doc
from .test_centroid import CENTROID_PX, _centroids
from .test_scene import _white_square_image

#: 320x240 fisheye, f = 160 px: its corners see 71 deg off axis (a pinhole of that K sees 51).
FISHEYE_SPEC: dict[str, Any] = {"size": [320, 240], "K": [[160.0, 0, 159.5], [0, 160.0, 119.5], [0, 0, 1]],
                                "dist_coeffs": [0.02, -0.01, 0.003, -0.001], "distortion_model": "equidistant",
                                "name": "fisheye"}


def test_warp_puts_raster_content_at_the_fisheye_projection(egl_renderer_factory) -> None:
    """A small white square on the deck, drawn through the raster camera and warped: its centroid
    lands on the fisheye projection of its centre, 31 px from where the pinhole puts it (0.05 px
    measured).

    Tolerance: the remap's bilinear interpolation and 1/32 px table, the raster's 4x MSAA edge
    coverage, and the square's own non-affine image (a 0.6 m square 45 deg off axis, where the
    fisheye compresses it radially by about 30 percent across its width): 0.1 px.
    """
    renderer = egl_renderer_factory(tiny_config())
    K = [[200.0, 0, 201.3], [0, 200.0, 148.8], [0, 0, 1]]
    cam = CameraModel(400, 300, K, [0.02, -0.01, 0.003, -0.001], distortion_model="equidistant")
    pin = raster_camera(cam)
    assert (pin.width_px, pin.height_px) != (400, 300)  # the corners need a larger raster
    pose = CameraPose.nadir(20.0)
    centre = (-11.0, 14.0)  # about 40 deg off axis
    img = _white_square_image(renderer, pin, pose, centre, 0.2, 0.6)
    rgb = np.repeat(np.clip(img, 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    warped = distort(rgb, cam)[..., 0].astype(float)
    assert warped.shape == (300, 400)
    vv, uu = np.mgrid[0:300, 0:400]
    got = np.array([(warped * uu).sum(), (warped * vv).sum()]) / warped.sum()
    P = (pose.T_cam_from_world @ np.r_[centre, 0.0, 1.0])[None, :3]
    want, pinhole = cam.project(P)[0], CameraModel(400, 300, K).project(P)[0]
    assert np.linalg.norm(want - pinhole) > 20.0
    print(f"\nwarp centroid error {np.linalg.norm(got - want):.3f} px, pinhole offset {np.linalg.norm(want - pinhole):.1f} px")
    np.testing.assert_allclose(got, want, atol=0.1)


def _doc(**over: Any) -> dict[str, Any]:
    doc = tiny_doc(cameras=[FISHEYE_SPEC], heights_m=[15.0, 25.0], lighting=["night"])
    doc.update(over)
    return doc


@pytest.fixture(scope="module")
def fisheye_runs(tmp_path_factory: pytest.TempPathFactory, egl_renderer_factory) -> dict[str, Path]:
    """Three small fisheye datasets: noise-free with and without beacons (16-bit, unsaturated), and
    one as the tiny config renders it (8-bit, noise)."""
    egl_renderer_factory(config_from_dict(tiny_doc()))  # select EGL in this process
    root = tmp_path_factory.mktemp("fisheye")
    clean = {"bit_depth": 16, "noise": False, "beacon_peak": 0.5, "halo_fraction": 0.0}
    docs = {"on": _doc(sensor=clean), "off": _doc(sensor=clean, layout={"intensity": 1e-12}), "noisy": _doc()}
    return {k: render_dataset(config_from_dict(d), root / k, workers=0, progress=False) for k, d in docs.items()}


def test_dataset_camera_file_is_the_fisheye(fisheye_runs: dict[str, Path]) -> None:
    run = fisheye_runs["noisy"]
    man = json.loads((run / "manifest.json").read_text())
    cam = read_camera_info(run / man["cameras"][0]["file"])
    assert cam.distortion_model == "equidistant" and cam.name == "fisheye"
    np.testing.assert_array_equal(cam.dist_coeffs, FISHEYE_SPEC["dist_coeffs"])


def test_rendered_spots_sit_at_the_recorded_truth(fisheye_runs: dict[str, Path]) -> None:
    """Intensity-weighted centroid of (beacons on - beacons off) per visible beacon against
    beacons.parquet's u_px, v_px. The spots are splatted in the fisheye image itself (the warp
    only moves the background, which the difference removes), so the noise-free requirement of
    the pinhole renders applies: CENTROID_PX (point sampling of sigma >= 0.8 px Gaussians,
    16-bit quantisation; 1e-4 px measured)."""
    on, off = fisheye_runs["on"], fisheye_runs["off"]
    frames = pd.read_parquet(on / "frames.parquet")
    beacons = pd.read_parquet(on / "beacons.parquet")
    n = 0
    for row in frames.itertuples():
        a = cv2.imread(str(on / row.image), cv2.IMREAD_UNCHANGED).astype(float).sum(axis=2)
        b = cv2.imread(str(off / row.image), cv2.IMREAD_UNCHANGED).astype(float).sum(axis=2)
        truth = beacons[(beacons.frame_id == row.frame_id) & beacons.visible]
        pts = truth[["u_px", "v_px"]].to_numpy()
        c = _centroids(a - b, pts, half=8)
        ok = np.isfinite(c[:, 0])
        assert ok.sum() >= 10
        err = np.linalg.norm(c[ok] - pts[ok], axis=1)
        assert err.max() < CENTROID_PX, err.max()
        n += int(ok.sum())
    assert n >= 40


def test_detect_then_estimate_on_the_rendered_fisheye_frames(fisheye_runs: dict[str, Path]) -> None:
    """cog finds and identifies every visible beacon within 0.15 px of the truth (8-bit, read noise
    5 e; 0.04 px measured), and pnp recovers the pose within 5 of its own reported sigmas (1.5
    measured)."""
    run = fisheye_runs["noisy"]
    man = json.loads((run / "manifest.json").read_text())
    cam = read_camera_info(run / man["cameras"][0]["file"])
    frames = pd.read_parquet(run / "frames.parquet")
    beacons = pd.read_parquet(run / "beacons.parquet")
    layout = DeckLayout()
    for row in frames.itertuples():
        image = cv2.cvtColor(cv2.imread(str(run / row.image), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
        fd = detect_frame(Frame(image, cam, int(row.frame_id)), "cog", layout)
        assert fd.ok, fd.reason
        truth = beacons[(beacons.frame_id == row.frame_id) & beacons.visible].set_index("beacon_id")
        det = fd.detections
        ids = det.beacon_ids
        assert set(ids.tolist()) == set(truth.index.tolist())
        err = np.linalg.norm(det.points_px - truth.loc[ids, ["u_px", "v_px"]].to_numpy(), axis=1)
        assert err.max() < 0.15, err.max()
        R_wc = np.array([[getattr(row, f"R_world_from_cam_{i}{j}") for j in range(3)] for i in range(3)])
        est = run_estimator("pnp", det, cam, layout, EstimateOptions(R_world_from_cam=R_wc))
        assert est.ok, est.reason
        want = np.array([*np.radians([row.roll_deg, row.pitch_deg, row.yaw_deg]), row.surge_m - row.cam_x_m,
                         row.sway_m - row.cam_y_m, row.cam_z_m - row.heave_m])
        got = np.array([est.roll_rad, est.pitch_rad, est.yaw_rad, est.surge_m, est.sway_m, est.height_m])
        d = got - want
        d[:3] = (d[:3] + np.pi) % (2 * np.pi) - np.pi
        sigma = np.sqrt(np.diag(est.covariance))
        assert np.all(np.abs(d) < 5 * sigma), (d, sigma)
