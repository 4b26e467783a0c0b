"""Workspace -> robot mapping (paper IV-B: 1:1, tool perpendicular to the surface)."""

from __future__ import annotations

import numpy as np
import pytest

from teleop.config import MappingConfig
from teleop.mapping import Mapping


def test_finger_to_the_users_right_moves_robot_to_its_configured_right():
    """Yaw 90 deg: the user's right (workspace +x) is the robot's +y (its configured right)."""
    m = Mapping(MappingConfig(origin_mm=(500.0, 0.0, 300.0), rpy_deg=(0.0, 0.0, 90.0)))
    d = m.to_robot([10.0, 0.0, 0.0]) - m.to_robot([0.0, 0.0, 0.0])
    np.testing.assert_allclose(d, [0.0, 10.0, 0.0], atol=1e-12)


def test_reflection_mirrors_x_only():
    m = Mapping(MappingConfig(origin_mm=(0.0, 0.0, 0.0), reflect_x=True))
    np.testing.assert_allclose(m.to_robot([10.0, 5.0, 0.0]), [-10.0, 5.0, 0.0])


def test_indentation_goes_into_the_surface_and_scale_is_one_to_one():
    m = Mapping(MappingConfig(origin_mm=(550.0, 0.0, 250.0)))
    np.testing.assert_allclose(m.to_robot([1.0, 2.0, 4.0]), [551.0, 2.0, 246.0])
    np.testing.assert_allclose(m.tool_down(), [0.0, 0.0, -1.0])


@pytest.mark.parametrize("rpy", [(0, 0, 30), (10, -20, 135), (0, 0, -90)])
def test_round_trip(rpy):
    m = Mapping(MappingConfig(rpy_deg=rpy, reflect_x=True, scale=1.5))
    p = np.array([12.0, -7.0, 3.0])
    np.testing.assert_allclose(m.to_workspace(m.to_robot(p)), p, atol=1e-9)


def test_bad_scale_is_refused():
    with pytest.raises(ValueError, match="scale"):
        Mapping(MappingConfig(scale=0.0))
