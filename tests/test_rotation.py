import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from deckpose import rotation as rot
from tests.tolerances import ROUNDOFF

angle = st.floats(-np.pi, np.pi, allow_nan=False)
half = st.floats(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3, allow_nan=False)


def test_elementary_rotations_match_scipy():
    a = 0.3
    for f, axis in ((rot.rot_x, "x"), (rot.rot_y, "y"), (rot.rot_z, "z")):
        np.testing.assert_allclose(f(a), Rotation.from_euler(axis, a).as_matrix(), atol=ROUNDOFF)


@given(angle, half, angle)
def test_zyx_matches_scipy_and_round_trips(roll, pitch, yaw):
    R = rot.R_from_zyx(roll, pitch, yaw)
    np.testing.assert_allclose(R, Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix(), atol=ROUNDOFF)
    np.testing.assert_allclose(rot.R_from_zyx(*rot.zyx_from_R(R)), R, atol=1e-10)


@given(angle, half, angle)
def test_thesis_matches_scipy_intrinsic_xyz_and_round_trips(roll, pitch, yaw):
    R = rot.R_from_thesis(roll, pitch, yaw)
    np.testing.assert_allclose(R, Rotation.from_euler("XYZ", [roll, pitch, yaw]).as_matrix(), atol=ROUNDOFF)
    r2, p2, y2 = rot.thesis_from_R(R)
    np.testing.assert_allclose([r2, p2, y2], [roll, pitch, yaw], atol=1e-8)


@settings(max_examples=200)
@given(angle, half, angle)
def test_thesis_zyx_conversion_preserves_the_rotation(roll, pitch, yaw):
    z = rot.zyx_from_thesis(roll, pitch, yaw)
    np.testing.assert_allclose(rot.R_from_zyx(*z), rot.R_from_thesis(roll, pitch, yaw), atol=1e-10)
    t = rot.thesis_from_zyx(*z)
    np.testing.assert_allclose(rot.R_from_thesis(*t), rot.R_from_thesis(roll, pitch, yaw), atol=1e-10)


def test_small_angles_agree_to_first_order_but_not_exactly():
    # The two conventions differ at second order: proof that the conversion matters.
    r, p, y = np.radians([5.0, 4.0, 30.0])
    zr, zp, zy = rot.zyx_from_thesis(r, p, y)
    assert abs(zy - y) < 1e-2
    assert abs(zr - r) > 1e-4 or abs(zp - p) > 1e-4


def test_vectorised_shapes():
    a = np.zeros((4, 5))
    assert rot.R_from_zyx(a, a, a).shape == (4, 5, 3, 3)
    np.testing.assert_allclose(rot.wrap_angle_rad([np.pi, -np.pi, 3 * np.pi]), [-np.pi] * 3)
