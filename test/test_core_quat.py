"""
Rotations, written in one place (sim_node.core.base.quat), against their definitions.

URDF's and SDF's roll, pitch and yaw are fixed-axis angles: R = Rz(yaw) Ry(pitch) Rx(roll).
"""

import math

import numpy as np
import pytest
from sim_node.core.base import quat

X, Y, Z = np.eye(3)


def test_a_yaw_turns_x_towards_y_and_a_roll_turns_y_towards_z():
    np.testing.assert_allclose(quat.rotate(quat.from_rpy(0, 0, math.pi / 2), X), Y, atol=1e-12)
    np.testing.assert_allclose(quat.rotate(quat.from_rpy(math.pi / 2, 0, 0), Y), Z, atol=1e-12)
    np.testing.assert_allclose(quat.rotate(quat.from_rpy(0, math.pi / 2, 0), Z), X, atol=1e-12)


def test_roll_is_applied_first_about_the_fixed_axes():
    """Roll 90 then yaw 90 (fixed axes): y goes to z (the roll), and z stays z (the yaw)."""
    q = quat.from_rpy(math.pi / 2, 0, math.pi / 2)
    np.testing.assert_allclose(quat.rotate(q, Y), Z, atol=1e-12)
    np.testing.assert_allclose(quat.rotate(q, X), Y, atol=1e-12)


@pytest.mark.parametrize('rpy', [(0.1, -0.4, 2.5), (-3.0, 1.2, -0.7), (0.0, 0.0, -math.pi / 3)])
def test_rpy_round_trips_and_the_matrix_is_the_same_rotation(rpy):
    q = quat.from_rpy(*rpy)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    np.testing.assert_allclose(quat.to_rpy(q), rpy, atol=1e-9)
    v = np.array([0.3, -1.2, 2.0])
    np.testing.assert_allclose(quat.to_matrix(q) @ v, quat.rotate(q, v), atol=1e-12)
    back = quat.from_matrix(quat.to_matrix(q))
    assert np.allclose(back, q) or np.allclose(back, -q)


def test_at_gimbal_lock_the_rotation_is_kept():
    q = quat.from_rpy(0.3, math.pi / 2, 0.5)
    np.testing.assert_allclose(quat.to_matrix(quat.from_rpy(*quat.to_rpy(q))), quat.to_matrix(q),
                               atol=1e-9)


def test_a_heading_and_an_axis_angle_are_the_same_turns():
    for yaw in (-3.0, -0.5, 0.0, 1.0, 3.0):
        q = quat.from_yaw(yaw)
        assert quat.yaw_of(q) == pytest.approx(yaw)
        np.testing.assert_allclose(q, quat.from_axis_angle((0, 0, 5), yaw), atol=1e-12)
        np.testing.assert_allclose(q, quat.from_rpy(0, 0, yaw), atol=1e-12)


def test_xyaxes_give_the_frame_whose_axes_they_are():
    """A MuJoCo camera (looking along -z, y up) on a Gazebo link (looking along x, z up)."""
    q = quat.from_xyaxes((0, -1, 0), (0, 0, 1))
    np.testing.assert_allclose(quat.rotate(q, X), -Y, atol=1e-12)
    np.testing.assert_allclose(quat.rotate(q, Y), Z, atol=1e-12)
    np.testing.assert_allclose(quat.rotate(q, -Z), X, atol=1e-12)  # it looks along the link's x
