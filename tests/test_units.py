"""The one module of unit conversions (MuJoCo radians <-> USD degrees)."""

import math

import numpy as np
import pytest

from footforge import units


def test_angles_round_trip():
    assert units.rad_to_deg(math.pi) == pytest.approx(180.0, rel=1e-15)
    assert units.deg_to_rad(90.0) == pytest.approx(math.pi / 2, rel=1e-15)
    angles = np.linspace(-3, 3, 7)
    np.testing.assert_allclose(units.deg_to_rad(units.rad_to_deg(angles)), angles, rtol=1e-15)


def test_gain_per_degree_gives_the_same_torque():
    """A 1 degree error under k per degree must give the torque of pi/180 rad under k per rad."""
    k_rad = 80.0
    k_deg = units.gain_per_deg(k_rad)
    assert k_deg * 1.0 == pytest.approx(k_rad * math.pi / 180.0, rel=1e-15)
    assert units.gain_per_rad(k_deg) == pytest.approx(k_rad, rel=1e-15)


def test_joint_quantities_convert_only_for_revolute_joints():
    assert units.joint_coordinate_to_usd(0.5, revolute=True) == pytest.approx(0.5 * 180 / math.pi)
    assert units.joint_coordinate_to_usd(0.5, revolute=False) == 0.5
    assert units.joint_gain_to_usd(2.0, revolute=True) == pytest.approx(2.0 * math.pi / 180)
    assert units.joint_gain_to_usd(2.0, revolute=False) == 2.0
