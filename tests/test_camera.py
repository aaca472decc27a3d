import math

import numpy as np
import pytest

from deckpose.camera import CameraModel, PixelForm, from_focal_angle, preset, preset_names
from deckpose.camera_info import read_camera_info, write_camera_info
from deckpose.errors import CameraFileError, ConfigError


@pytest.mark.parametrize("res,size", [("4mp", (2312, 1734)), ("8mp", (3840, 2160)),
                                      ("16mp", (4624, 3468)), ("64mp", (9248, 6936))])
def test_thesis_presets_follow_eq_1_8_and_1_9(res, size):
    cam = preset(res)
    t = math.tan(math.radians(37.5))
    assert (cam.width_px, cam.height_px) == size
    assert cam.fx == pytest.approx(size[0] / 2 / t, rel=1e-15)
    assert cam.fy == pytest.approx(size[1] / 2 / t, rel=1e-15)
    sq = preset(f"{res}-square")
    assert sq.fx == sq.fy == pytest.approx(size[0] / 2 / t)


def test_published_camera():
    cam = preset("published")
    assert cam.fx == cam.fy == pytest.approx(1920 / math.tan(math.radians(50)))


def test_unknown_preset_lists_valid_names():
    with pytest.raises(ConfigError, match="8mp-thesis"):
        preset("12mp")
    assert "64mp-square" in preset_names()


def test_projection_without_distortion_is_pinhole():
    cam = from_focal_angle(640, 480, 60.0, form=PixelForm.SQUARE)
    P = np.array([[1.0, -2.0, 10.0], [0.0, 0.0, 5.0]])
    uv = cam.project(P)
    np.testing.assert_allclose(uv[1], [320, 240])
    np.testing.assert_allclose(uv[0], [320 + cam.fx * 0.1, 240 - cam.fy * 0.2])


def test_distortion_round_trip_and_against_opencv_formula():
    K = np.array([[800.0, 0, 330], [0, 790, 250], [0, 0, 1]])
    d = np.array([-0.2, 0.05, 0.001, -0.002, 0.01])
    cam = CameraModel(640, 480, K, d)
    rng = np.random.default_rng(1)
    P = np.column_stack([rng.uniform(-3, 3, 50), rng.uniform(-2, 2, 50), rng.uniform(8, 12, 50)])
    uv = cam.project(P)
    # independent plumb_bob formula
    x, y = P[:, 0] / P[:, 2], P[:, 1] / P[:, 2]
    r2 = x * x + y * y
    radial = 1 + d[0] * r2 + d[1] * r2**2 + d[4] * r2**3
    xd = x * radial + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x)
    yd = y * radial + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y
    np.testing.assert_allclose(uv, np.column_stack([800 * xd + 330, 790 * yd + 250]), atol=1e-6)
    ideal = np.column_stack([800 * x + 330, 790 * y + 250])
    np.testing.assert_allclose(cam.undistort(uv), ideal, atol=1e-6)


def test_bad_camera_values():
    with pytest.raises(ConfigError, match="positive"):
        CameraModel(0, 10, np.eye(3))
    with pytest.raises(ConfigError, match="fx and fy"):
        CameraModel(10, 10, np.diag([0.0, 1.0, 1.0]))
    with pytest.raises(ConfigError, match="coefficients"):
        CameraModel(10, 10, np.eye(3), np.zeros(3))


def test_camera_info_round_trip(tmp_path):
    K = np.array([[812.5, 0.0, 321.25], [0.0, 811.0, 239.5], [0.0, 0.0, 1.0]])
    cam = CameraModel(640, 480, K, np.array([0.1, -0.01, 0.001, 0.002, 0.0003]), "mine")
    path = tmp_path / "cam.yaml"
    write_camera_info(cam, path)
    text = path.read_text()
    for key in ("image_width", "image_height", "camera_matrix", "distortion_model",
                "distortion_coefficients", "rectification_matrix", "projection_matrix"):
        assert key in text
    back = read_camera_info(path)
    np.testing.assert_array_equal(back.K, cam.K)
    np.testing.assert_array_equal(back.dist_coeffs, cam.dist_coeffs)
    assert (back.width_px, back.height_px, back.name) == (640, 480, "mine")


def test_camera_info_reads_ros_calibration_output(tmp_path):
    # As written by ROS camera_calibration (ost.yaml).
    path = tmp_path / "ost.yaml"
    path.write_text(
        "image_width: 640\nimage_height: 480\ncamera_name: narrow_stereo\n"
        "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [500.1, 0, 320.2, 0, 501.3, 240.4, 0, 0, 1]\n"
        "distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n"
        "  data: [-0.1, 0.02, 0, 0, 0]\nrectification_matrix:\n  rows: 3\n  cols: 3\n"
        "  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nprojection_matrix:\n  rows: 3\n  cols: 4\n"
        "  data: [500.1, 0, 320.2, 0, 0, 501.3, 240.4, 0, 0, 0, 1, 0]\n"
    )
    cam = read_camera_info(path)
    assert cam.fx == 500.1 and cam.cy == 240.4 and cam.dist_coeffs[0] == -0.1


@pytest.mark.parametrize("text,match", [
    ("image_width: 640\n", "image_height"),
    ("{not yaml", "not valid YAML"),
    ("image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [1, 2]}\n", "camera_matrix"),
    ("- a\n- b\n", "mapping"),
])
def test_camera_info_errors_name_the_field(tmp_path, text, match):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(CameraFileError, match=match):
        read_camera_info(path)


def test_camera_info_missing_file(tmp_path):
    with pytest.raises(CameraFileError, match="cannot read"):
        read_camera_info(tmp_path / "nope.yaml")
