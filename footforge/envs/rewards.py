"""The paper's ten reward terms (and two optional terms of legged_gym's: feet air time, standing
still) as pure functions of what they penalise or reward.

Each term is declared once, as a field of RewardConfig (envs.config): its function (here), unit
and scale (a RewardTerm, envs.terms). The environment measures a step's Quantities once; each function returns its
unscaled term, which the environment multiplies by the term's scale and the policy step dt.
"""

from __future__ import annotations

from dataclasses import fields
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:
    import jax

from footforge.envs.terms import RewardParameters, RewardTerm


class Quantities(NamedTuple):
    """What the reward terms read after a policy step's physics (base frame where a vector)."""

    command: jax.Array = None
    """vx, vy (m/s), yaw rate (rad/s)."""
    lin_vel: jax.Array = None
    """Base linear velocity, m/s."""
    ang_vel: jax.Array = None
    """Base angular velocity, rad/s."""
    gravity: jax.Array = None
    """Unit gravity direction."""
    base_height: jax.Array = None
    """Base height over the ground under it, m."""
    torques: jax.Array = None
    """Actuator torques, N m."""
    joint_vel: jax.Array = None
    """Actuated joint velocities, rad/s."""
    last_joint_vel: jax.Array = None
    """The same one policy step earlier, rad/s."""
    action: jax.Array = None
    """This step's clipped action."""
    last_action: jax.Array = None
    """The previous step's."""
    haa_offset: jax.Array = None
    """Hip abduction/adduction angles minus their defaults, rad."""
    joint_offset: jax.Array = None
    """The 12 actuated joints' angles minus their defaults, rad."""
    touchdown_air_time: jax.Array = None
    """Per foot (LF, RF, LH, RH): how long it was in the air, s, on the step it touches down
    again; zero on every other step."""


def lin_vel_xy(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """exp(-|command - velocity|^2 / sigma) of the planar velocity, base frame (m/s)."""
    import jax.numpy as jp  # here, not at the top: envs.config imports this module and stays free of JAX

    error = q.command[:2] - q.lin_vel[:2]
    return jp.exp(-(error * error).sum() / cfg.tracking_sigma)


def yaw_rate(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """exp(-(command - yaw rate)^2 / sigma), rad/s."""
    import jax.numpy as jp

    return jp.exp(-((q.command[2] - q.ang_vel[2]) ** 2) / cfg.tracking_sigma)


def lin_vel_z(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """Vertical base velocity squared, (m/s)^2."""
    return q.lin_vel[2] ** 2


def ang_vel_xy(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """Roll and pitch rate squared, (rad/s)^2."""
    return (q.ang_vel[:2] ** 2).sum()


def orientation(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """|projected gravity_xy|^2: zero when the base is level (gravity along -z of the base)."""
    return (q.gravity[:2] ** 2).sum()


def base_height(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """(h - target)^2, m^2, with h the base height over the ground."""
    return (q.base_height - cfg.base_height_target_m) ** 2


def torques(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """sum tau^2, (N m)^2."""
    return (q.torques**2).sum()


def joint_acc(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """sum of squared joint-velocity changes over one policy step, (rad/s)^2: how the paper's
    baseline computes its "joint accelerations" term (the change, not divided by the step)."""
    return ((q.joint_vel - q.last_joint_vel) ** 2).sum()


def action_rate(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """sum (a - a_prev)^2."""
    return ((q.action - q.last_action) ** 2).sum()


def hip(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """sum |q_HAA - default|, rad."""
    return abs(q.haa_offset).sum()


def feet_air_time(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """sum over the feet touching down of (air time - feet_air_time_target_s), s, while the planar
    command is above 0.1 m/s (legged_gym's feet_air_time: steps of at least the target length
    pay, shorter ones cost; no reward for stepping in place under a zero command)."""
    import jax.numpy as jp

    landed = q.touchdown_air_time > 0
    moving = jp.linalg.norm(q.command[:2]) > 0.1
    return jp.where(landed, q.touchdown_air_time - cfg.feet_air_time_target_s, 0.0).sum() * moving


def stand_still(q: Quantities, cfg: RewardParameters) -> jax.Array:
    """sum |q - default| over the actuated joints, rad, while the planar command is below 0.1 m/s
    (legged_gym's stand_still: under a zero command, hold the default pose; nothing otherwise)."""
    import jax.numpy as jp

    return abs(q.joint_offset).sum() * (jp.linalg.norm(q.command[:2]) < 0.1)


def terms(cfg) -> dict[str, RewardTerm]:
    """name -> RewardTerm of every term of a RewardConfig, in declaration order."""
    return {f.name: getattr(cfg, f.name) for f in fields(cfg) if isinstance(getattr(cfg, f.name), RewardTerm)}
