"""Unit conventions between MuJoCo (SI, radians) and USD Physics (degrees for angles).

Every conversion footforge makes lives here, so that no exporter multiplies by 180/pi inline.
MuJoCo stores angles in radians and angular gains per radian. UsdPhysics stores revolute limits
and drive targets in degrees, and angular drive stiffness and damping per degree: a torque
k * dq with dq in radians is (k * pi/180) * dq with dq in degrees. Linear (prismatic) quantities
are SI on both sides.
"""

from __future__ import annotations

import math

import numpy as np

DEG_PER_RAD = 180.0 / math.pi
RAD_PER_DEG = math.pi / 180.0


def rad_to_deg(angle_rad):
    """Radians -> degrees (a float or an array)."""
    return np.multiply(angle_rad, DEG_PER_RAD) if np.ndim(angle_rad) else float(angle_rad) * DEG_PER_RAD


def deg_to_rad(angle_deg):
    """Degrees -> radians (a float or an array)."""
    return np.multiply(angle_deg, RAD_PER_DEG) if np.ndim(angle_deg) else float(angle_deg) * RAD_PER_DEG


def gain_per_deg(gain_per_rad: float) -> float:
    """Angular stiffness N m/rad (or damping N m s/rad) -> per degree."""
    return float(gain_per_rad) * RAD_PER_DEG


def gain_per_rad(gain_per_deg_value: float) -> float:
    """Angular stiffness N m/deg (or damping N m s/deg) -> per radian."""
    return float(gain_per_deg_value) * DEG_PER_RAD


def joint_coordinate_to_usd(value: float, *, revolute: bool) -> float:
    """A joint position (limit, drive target): degrees for revolute joints, metres otherwise."""
    return rad_to_deg(value) if revolute else float(value)


def joint_gain_to_usd(value: float, *, revolute: bool) -> float:
    """A drive stiffness or damping: per degree for revolute joints, per metre otherwise."""
    return gain_per_deg(value) if revolute else float(value)
