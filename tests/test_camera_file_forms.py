"""Camera files in the forms other tools write: OpenCV FileStorage, ``ros2 topic echo``, ROS 1.

The OpenCV file is written by OpenCV's own ``cv2.FileStorage``; the echo forms follow the
``sensor_msgs/CameraInfo`` message layout that ``ros2 topic echo`` and ``rostopic echo``
print. Each must give the same camera as its ``camera_info`` YAML: the same pixels for the
same rays (compared through OpenCV's ``projectPoints``, not through our own model).
"""

from __future__ import annotations

import logging

import cv2
import numpy as np
import pytest

from deckpose.camera_info import read_camera_info
from deckpose.errors import CameraFileError

K = np.array([[812.5, 0.0, 319.2], [0.0, 815.1, 241.7], [0.0, 0.0, 1.0]])
DIST = np.array([-0.21, 0.07, 0.0012, -0.0008, -0.011])
RAYS = np.array([[0.0, 0.0, 1.0], [0.2, -0.1, 1.0], [-0.3, 0.25, 1.0]])


def _same_camera(cam, K_ref, dist_ref, size=(640, 480)):
    assert (cam.width_px, cam.height_px) == size
    ours = cv2.projectPoints(RAYS, np.zeros(3), np.zeros(3), cam.K, cam.dist_coeffs)[0]
    ref = cv2.projectPoints(RAYS, np.zeros(3), np.zeros(3), K_ref, dist_ref)[0]
    np.testing.assert_allclose(ours, ref, atol=1e-9)


@pytest.mark.parametrize("header", ["%YAML 1.2", "%YAML:1.0"])
def test_opencv_filestorage_written_by_opencv_reads(tmp_path, header):
    path = tmp_path / "calib.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("calibration_time", "Tue Dec  1 2026")
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", DIST.reshape(1, 5))
    fs.write("avg_reprojection_error", 0.21)
    fs.release()
    text = path.read_text()
    assert "!!opencv-matrix" in text
    path.write_text(header + "\n" + text.split("\n", 1)[1])  # OpenCV 3 wrote %YAML:1.0
    _same_camera(read_camera_info(path), K, DIST)


def test_opencv_filestorage_without_a_camera_matrix_says_what_it_looked_for(tmp_path):
    path = tmp_path / "other.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("R", np.eye(3))
    fs.release()
    with pytest.raises(CameraFileError, match="no camera matrix .*camera_matrix, cameraMatrix, K"):
        read_camera_info(path)


ROS2_ECHO = """header:
  stamp:
    sec: 1764633600
    nanosec: 500000000
  frame_id: uav_camera
height: 480
width: 640
distortion_model: plumb_bob
d:
- {d0}
- {d1}
- {d2}
- {d3}
- {d4}
k:
- {k0}
- 0.0
- {k2}
- 0.0
- {k4}
- {k5}
- 0.0
- 0.0
- 1.0
r:
- 1.0
- 0.0
- 0.0
- 0.0
- 1.0
- 0.0
- 0.0
- 0.0
- 1.0
p:
- {k0}
- 0.0
- {k2}
- 0.0
- 0.0
- {k4}
- {k5}
- 0.0
- 0.0
- 0.0
- 1.0
- 0.0
binning_x: 0
binning_y: 0
roi:
  x_offset: 0
  y_offset: 0
  height: 0
  width: 0
  do_rectify: false
---
"""


def _fmt(text: str) -> str:
    return text.format(d0=DIST[0], d1=DIST[1], d2=DIST[2], d3=DIST[3], d4=DIST[4],
                       k0=K[0, 0], k2=K[0, 2], k4=K[1, 1], k5=K[1, 2])


def test_ros2_topic_echo_of_a_camera_info_message_reads(tmp_path):
    path = tmp_path / "echo.yaml"
    path.write_text(_fmt(ROS2_ECHO) * 3)  # a few messages of the stream: the first is read
    cam = read_camera_info(path)
    _same_camera(cam, K, DIST)
    assert cam.name == "uav_camera"


def test_ros1_rostopic_echo_form_reads(tmp_path):
    path = tmp_path / "echo1.yaml"
    text = (f"header:\n  seq: 3\n  frame_id: cam\nheight: 480\nwidth: 640\ndistortion_model: plumb_bob\n"
            f"D: {DIST.tolist()}\nK: {K.ravel().tolist()}\nR: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n---\n")
    path.write_text(text)
    _same_camera(read_camera_info(path), K, DIST)


def test_plumb_bob_with_four_coefficients_loads_with_a_warning(tmp_path, caplog):
    path = tmp_path / "four.yaml"
    path.write_text(
        "image_width: 640\nimage_height: 480\n"
        f"camera_matrix: {{rows: 3, cols: 3, data: {K.ravel().tolist()}}}\n"
        "distortion_model: plumb_bob\n"
        f"distortion_coefficients: {{rows: 1, cols: 4, data: {DIST[:4].tolist()}}}\n")
    with caplog.at_level(logging.WARNING, logger="deckpose.camera_info"):
        cam = read_camera_info(path)
    _same_camera(cam, K, DIST[:4])  # OpenCV's own reading of four: k1, k2, p1, p2
    assert any("4 coefficients" in r.getMessage() and "fisheye" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("width", ['"640"', "640.5", "true", "[640]"])
def test_an_image_size_that_is_not_an_integer_is_refused(tmp_path, width):
    # a quoted "640" was read as 640 without a word; 640.5 would have been cut to 640
    path = tmp_path / "cam.yaml"
    path.write_text(f"image_width: {width}\nimage_height: 480\n"
                    "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n")
    with pytest.raises(CameraFileError, match="image_width must be an integer number of pixels"):
        read_camera_info(path)
    path.write_text(path.read_text().replace(f"image_width: {width}", "image_width: 640"))
    assert read_camera_info(path).width_px == 640


@pytest.mark.parametrize("cols", ["1e400", "three", "[3]"])
def test_a_matrix_size_that_is_not_a_whole_number_is_refused(tmp_path, cols):
    # 1e400 (YAML reads it as inf) raised OverflowError, a traceback, found by the reader fuzz test
    path = tmp_path / "cam.yaml"
    path.write_text(f"image_width: 640\nimage_height: 480\n"
                    f"camera_matrix: {{rows: 3, cols: {cols}, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}}\n")
    with pytest.raises(CameraFileError, match="'camera_matrix' has rows or cols that are not whole numbers"):
        read_camera_info(path)
