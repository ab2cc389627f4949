"""The paper's ten reward terms as pure functions of the quantities they penalise or reward.

Each returns the unscaled term; the environment multiplies by its scale and the policy dt.
"""

from __future__ import annotations

import jax.numpy as jp


def lin_vel_xy(command_xy, vel_xy, sigma):
    """exp(-|command - velocity|^2 / sigma), base frame (m/s)."""
    return jp.exp(-jp.sum(jp.square(command_xy - vel_xy)) / sigma)


def yaw_rate(command_yaw, yaw_rate_now, sigma):
    return jp.exp(-jp.square(command_yaw - yaw_rate_now) / sigma)


def lin_vel_z(vel_z):
    return jp.square(vel_z)


def ang_vel_xy(ang_vel):
    return jp.sum(jp.square(ang_vel[:2]))


def orientation(projected_gravity):
    """Zero when the base is level (gravity along -z of the base)."""
    return jp.sum(jp.square(projected_gravity[:2]))


def base_height(height, target):
    return jp.square(height - target)


def torques(tau):
    return jp.sum(jp.square(tau))


def joint_acc(qvel, qvel_prev):
    """sum of squared joint-velocity changes over one policy step, (rad/s)^2: how the paper's
    baseline computes its "joint accelerations" term (the change, not divided by the step)."""
    return jp.sum(jp.square(qvel - qvel_prev))


def action_rate(action, action_prev):
    return jp.sum(jp.square(action - action_prev))


def hip(q_haa, default_haa):
    return jp.sum(jp.abs(q_haa - default_haa))


TERMS = ("lin_vel_xy", "yaw_rate", "lin_vel_z", "ang_vel_xy", "orientation", "base_height", "torques",
         "joint_acc", "action_rate", "hip")
