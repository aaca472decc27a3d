"""Fisheye (equidistant) and rational-polynomial cameras: projection against the formulas written
out here, undistortion round trips, and the camera files that carry them."""

from __future__ import annotations

import logging
import re

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from deckpose.camera import CameraModel
from deckpose.camera_info import camera_to_dict, read_camera_info, write_camera_info
from deckpose.errors import CameraFileError, ConfigError
from tests.tolerances import PROJECTION_PX

K = np.array([[410.0, 0.7, 322.4], [0.0, 405.0, 238.9], [0.0, 0.0, 1.0]])  # a little skew, on purpose
FISHEYE_D = np.array([0.031, -0.012, 0.0041, -0.0007])
RATIONAL_D = np.array([-0.21, 0.07, 0.0008, -0.0005, -0.01, 0.05, -0.02, 0.004])
FISHEYE = CameraModel(640, 480, K, FISHEYE_D, "fish", "equidistant")
#: Normalised round-trip accuracy: the Newton solve stops at 1e-14 in theta.
ROUNDTRIP_NORMALISED = 1e-9


def equidistant_px(xy: np.ndarray, K: np.ndarray, k: np.ndarray) -> np.ndarray:
    """OpenCV's fisheye model written out: theta = atan(r), theta_d = theta (1 + k1 t^2 + ...)."""
    r = np.hypot(xy[:, 0], xy[:, 1])
    theta = np.arctan(r)
    theta_d = theta * (1 + k[0] * theta**2 + k[1] * theta**4 + k[2] * theta**6 + k[3] * theta**8)
    scale = np.where(r > 0, theta_d / np.where(r > 0, r, 1.0), 1.0)
    xd = xy * scale[:, None]
    return xd @ K[:2, :2].T + K[:2, 2]


def rational_px(xy: np.ndarray, K: np.ndarray, d: np.ndarray) -> np.ndarray:
    """OpenCV's standard model with k4..k6 written out (the rational_polynomial model)."""
    k1, k2, p1, p2, k3, k4, k5, k6 = d
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = (1 + k1 * r2 + k2 * r2**2 + k3 * r2**3) / (1 + k4 * r2 + k5 * r2**2 + k6 * r2**3)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.c_[xd, yd] @ K[:2, :2].T + K[:2, 2]


def _rays(rng: np.random.Generator, n: int, max_angle_rad: float) -> np.ndarray:
    """Normalised points (x/z, y/z) up to ``max_angle_rad`` off the axis."""
    theta = rng.uniform(0.0, max_angle_rad, n)
    phi = rng.uniform(-np.pi, np.pi, n)
    return np.tan(theta)[:, None] * np.c_[np.cos(phi), np.sin(phi)]


def test_fisheye_projection_is_the_equidistant_formula() -> None:
    xy = _rays(np.random.default_rng(5), 500, np.radians(85.0))
    xy[0] = 0.0  # the principal point
    z = np.random.default_rng(6).uniform(1.0, 80.0, len(xy))
    P = np.c_[xy * z[:, None], z]
    np.testing.assert_allclose(FISHEYE.project(P), equidistant_px(xy, K, FISHEYE_D), rtol=0, atol=PROJECTION_PX)


def test_fisheye_with_zero_coefficients_is_still_a_fisheye() -> None:
    cam = CameraModel(640, 480, K, np.zeros(4), distortion_model="equidistant")
    assert cam.has_distortion and cam.is_fisheye
    xy = np.array([[0.8, -0.3]])
    np.testing.assert_allclose(cam.project(np.c_[xy, [1.0]]), equidistant_px(xy, K, np.zeros(4)), atol=PROJECTION_PX)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_fisheye_project_then_undistort_returns_the_ray(seed: int) -> None:
    """Inside the field of view (here up to 80 deg) undistort inverts project to 1e-9 (normalised)."""
    xy = _rays(np.random.default_rng(seed), 64, np.radians(80.0))
    und = FISHEYE.undistort(FISHEYE.project(np.c_[xy, np.ones(len(xy))]))
    back = np.linalg.solve(K, np.c_[und, np.ones(len(und))].T).T[:, :2]
    err = np.abs(back - xy) / (1 + np.abs(xy))  # relative where tan(theta) is large (5.7 at 80 deg)
    assert err.max() < ROUNDTRIP_NORMALISED, err.max()


def test_fisheye_undistort_agrees_with_opencv_on_a_skew_free_camera() -> None:
    K0 = K.copy()
    K0[0, 1] = 0.0
    cam = CameraModel(640, 480, K0, FISHEYE_D, distortion_model="equidistant")
    px = np.random.default_rng(2).uniform([0, 0], [640, 480], (200, 2))
    ref = cv2.fisheye.undistortPoints(px.reshape(-1, 1, 2), K0, FISHEYE_D, R=np.eye(3), P=K0).reshape(-1, 2)
    np.testing.assert_allclose(cam.undistort(px), ref, atol=1e-6)


def test_fisheye_undistort_is_nan_where_no_ray_in_front_reaches() -> None:
    """theta_d past 90 deg of a zero-coefficient fisheye: no pinhole ray; NaN, not a mirrored point."""
    cam = CameraModel(640, 480, [[100.0, 0, 320], [0, 100.0, 240], [0, 0, 1]], np.zeros(4),
                      distortion_model="equidistant")
    got = cam.undistort(np.array([[320.0 + 100 * 1.5, 240.0], [320.0 + 100 * 1.7, 240.0], [5000.0, 240.0]]))
    assert np.isfinite(got[0]).all() and np.isnan(got[1:]).all()
    np.testing.assert_allclose(got[0], [320.0 + 100 * np.tan(1.5), 240.0], rtol=1e-9)


def test_rational_polynomial_projection_and_round_trip() -> None:
    cam = CameraModel(640, 480, K * [[1, 0, 1], [1, 1, 1], [1, 1, 1]], RATIONAL_D)  # skew-free
    assert cam.distortion_model == "rational_polynomial"
    xy = _rays(np.random.default_rng(9), 300, np.radians(35.0))
    px = cam.project(np.c_[xy, np.ones(len(xy))])
    np.testing.assert_allclose(px, rational_px(xy, cam.K, RATIONAL_D), rtol=0, atol=PROJECTION_PX)
    back = np.linalg.solve(cam.K, np.c_[cam.undistort(px), np.ones(len(px))].T).T[:, :2]
    np.testing.assert_allclose(back, xy, atol=ROUNDTRIP_NORMALISED)


def test_models_and_counts_checked_by_the_camera() -> None:
    with pytest.raises(ConfigError, match=r"equidistant takes 4 coefficients, got 5"):
        CameraModel(640, 480, K, np.zeros(5), distortion_model="equidistant")
    with pytest.raises(ConfigError, match=r"unknown distortion model 'fisheye62'"):
        CameraModel(640, 480, K, np.zeros(6), distortion_model="fisheye62")
    assert CameraModel(640, 480, K, FISHEYE_D).distortion_model == "plumb_bob"  # four unnamed: k1, k2, p1, p2
    assert CameraModel(640, 480, K, np.zeros(0), distortion_model="none").distortion_model == "plumb_bob"
    assert FISHEYE.with_size(320, 240).distortion_model == "equidistant"


@pytest.mark.parametrize("camera", [FISHEYE, CameraModel(640, 480, K, RATIONAL_D, "rational")],
                         ids=["equidistant", "rational_polynomial"])
def test_camera_info_write_then_read_gives_the_same_camera(tmp_path, camera: CameraModel) -> None:
    path = tmp_path / "cam.yaml"
    write_camera_info(camera, path)
    doc = yaml.safe_load(path.read_text())
    assert doc["distortion_model"] == camera.distortion_model
    assert doc["distortion_coefficients"]["cols"] == camera.dist_coeffs.size
    back = read_camera_info(path)
    assert back.distortion_model == camera.distortion_model
    np.testing.assert_array_equal(back.K, camera.K)
    np.testing.assert_array_equal(back.dist_coeffs, camera.dist_coeffs)
    P = np.c_[_rays(np.random.default_rng(1), 50, 1.2), np.ones(50)]
    np.testing.assert_array_equal(back.project(P), camera.project(P))


#: As ROS's camera_calibration writes a fisheye calibration (``--fisheye``... ``equidistant``, D of 4).
ROS_FISHEYE_YAML = """\
image_width: 1280
image_height: 800
camera_name: fisheye_front
camera_matrix:
  rows: 3
  cols: 3
  data: [455.2018, 0, 641.8736, 0, 454.6607, 399.1525, 0, 0, 1]
distortion_model: equidistant
distortion_coefficients:
  rows: 1
  cols: 4
  data: [-0.01472, 0.00631, -0.00592, 0.00117]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [455.2018, 0, 641.8736, 0, 0, 454.6607, 399.1525, 0, 0, 0, 1, 0]
"""


def test_ros_fisheye_calibration_file_loads(tmp_path) -> None:
    path = tmp_path / "fisheye.yaml"
    path.write_text(ROS_FISHEYE_YAML)
    cam = read_camera_info(path)
    assert cam.distortion_model == "equidistant" and cam.name == "fisheye_front"
    assert (cam.width_px, cam.height_px) == (1280, 800)
    np.testing.assert_array_equal(cam.dist_coeffs, [-0.01472, 0.00631, -0.00592, 0.00117])
    xy = np.array([[0.5, -0.4], [1.5, 0.9]])
    np.testing.assert_allclose(cam.project(np.c_[xy, [1.0, 1.0]]), equidistant_px(xy, cam.K, cam.dist_coeffs),
                               atol=PROJECTION_PX)
    assert camera_to_dict(cam)["distortion_model"] == "equidistant"


def test_ros2_echo_of_a_fisheye_camera_info_and_the_kannala_brandt_name(tmp_path) -> None:
    path = tmp_path / "echo.yaml"
    path.write_text("header:\n  frame_id: fish\nheight: 480\nwidth: 640\ndistortion_model: equidistant\n"
                    f"d: {FISHEYE_D.tolist()}\nk: {K.ravel().tolist()}\n---\n")
    assert read_camera_info(path).distortion_model == "equidistant"
    text = ROS_FISHEYE_YAML.replace("distortion_model: equidistant", "distortion_model: kannala_brandt")
    path.write_text(text)
    assert read_camera_info(path).distortion_model == "equidistant"


def test_opencv_fisheye_calibration_output_loads(tmp_path, caplog) -> None:
    """OpenCV's calibration tutorial writes ``fisheye_model: 1`` beside a 4x1 D; without it, four
    coefficients are plumb_bob's k1, k2, p1, p2 (with the warning)."""
    path = tmp_path / "out_camera_data.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("fisheye_model", 1)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", FISHEYE_D.reshape(4, 1))
    fs.release()
    cam = read_camera_info(path)
    assert cam.distortion_model == "equidistant"
    np.testing.assert_array_equal(cam.dist_coeffs, FISHEYE_D)
    path.write_text(path.read_text().replace("fisheye_model: 1", "fisheye_model: 0"))
    with caplog.at_level(logging.WARNING, logger="deckpose.camera_info"):
        assert read_camera_info(path).distortion_model == "plumb_bob"
    assert any("write distortion_model: equidistant" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize(("model", "n", "fix"), [
    ("equidistant", 5, r"for 5 write distortion_model: plumb_bob"),
    ("equidistant", 8, r"for 8 write distortion_model: rational_polynomial"),
    ("equidistant", 0, r"has 0$"),
    ("rational_polynomial", 4, r"for 4 write distortion_model: equidistant \(a fisheye's k1..k4\) or plumb_bob"),
])
def test_a_coefficient_count_the_model_does_not_take_is_one_line_naming_file_and_fix(
        tmp_path, model: str, n: int, fix: str) -> None:
    path = tmp_path / "bad_count.yaml"
    data = [0.01 * (i + 1) for i in range(n)]
    path.write_text("image_width: 640\nimage_height: 480\n"
                    f"camera_matrix: {{rows: 3, cols: 3, data: {K.ravel().tolist()}}}\n"
                    f"distortion_model: {model}\n"
                    + (f"distortion_coefficients: {{rows: 1, cols: {n}, data: {data}}}\n" if n else ""))
    with pytest.raises(CameraFileError) as err:
        read_camera_info(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path)) and f"distortion_model {model} takes" in msg
    assert re.search(fix, msg), msg
