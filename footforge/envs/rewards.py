"""The paper's ten reward terms (and two optional terms of legged_gym's: feet air time, standing
still) as pure functions of what they penalise or reward.

Each term is declared once, as a field of RewardConfig (envs.config): its function (here), scale
and parameters (a RewardTerm, envs.terms), e.g.

    lin_vel_xy: RewardTerm = RewardTerm(rewards.lin_vel_xy, 1.0, sigma=0.25)

A function takes the step's Quantities and, keyword-only, its own parameters, and returns its
unscaled term. The environment measures a step's Quantities once, evaluates every declared term
(unscaled), multiplies each by its scale and the policy step dt and sums them; the metrics
(`reward/<name>`), config.json and the `--set env.rewards.<name>...` overrides all follow
RewardConfig's fields. Adding a term: its function here and its line in RewardConfig.
"""

from __future__ import annotations

from dataclasses import fields
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:
    import jax

from footforge.envs.terms import RewardTerm


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


def lin_vel_xy(q: Quantities, *, sigma: float) -> jax.Array:
    """exp(-|command - velocity|^2 / sigma) of the planar velocity, base frame (m/s); sigma, the
    kernel's width, (m/s)^2."""
    import jax.numpy as jp  # here, not at the top: envs.config imports this module and stays free of JAX

    error = q.command[:2] - q.lin_vel[:2]
    return jp.exp(-(error * error).sum() / sigma)


def yaw_rate(q: Quantities, *, sigma: float) -> jax.Array:
    """exp(-(command - yaw rate)^2 / sigma), rad/s; sigma, the kernel's width, (rad/s)^2."""
    import jax.numpy as jp

    return jp.exp(-((q.command[2] - q.ang_vel[2]) ** 2) / sigma)


def lin_vel_z(q: Quantities) -> jax.Array:
    """Vertical base velocity squared, (m/s)^2."""
    return q.lin_vel[2] ** 2


def ang_vel_xy(q: Quantities) -> jax.Array:
    """Roll and pitch rate squared, (rad/s)^2."""
    return (q.ang_vel[:2] ** 2).sum()


def orientation(q: Quantities) -> jax.Array:
    """|projected gravity_xy|^2: zero when the base is level (gravity along -z of the base)."""
    return (q.gravity[:2] ** 2).sum()


def base_height(q: Quantities, *, target_m: float) -> jax.Array:
    """(h - target_m)^2, m^2, with h the base height over the ground, m."""
    return (q.base_height - target_m) ** 2


def torques(q: Quantities) -> jax.Array:
    """sum tau^2, (N m)^2."""
    return (q.torques**2).sum()


def joint_acc(q: Quantities) -> jax.Array:
    """sum of squared joint-velocity changes over one policy step, (rad/s)^2: how the paper's
    baseline computes its "joint accelerations" term (the change, not divided by the step)."""
    return ((q.joint_vel - q.last_joint_vel) ** 2).sum()


def action_rate(q: Quantities) -> jax.Array:
    """sum (a - a_prev)^2."""
    return ((q.action - q.last_action) ** 2).sum()


def hip(q: Quantities) -> jax.Array:
    """sum |q_HAA - default|, rad."""
    return abs(q.haa_offset).sum()


def feet_air_time(q: Quantities, *, target_s: float) -> jax.Array:
    """sum over the feet touching down of (air time - target_s), s, while the planar
    command is above 0.1 m/s (legged_gym's feet_air_time: steps of at least the target length
    pay, shorter ones cost; no reward for stepping in place under a zero command)."""
    import jax.numpy as jp

    landed = q.touchdown_air_time > 0
    moving = jp.linalg.norm(q.command[:2]) > 0.1
    return jp.where(landed, q.touchdown_air_time - target_s, 0.0).sum() * moving


def stand_still(q: Quantities) -> jax.Array:
    """sum |q - default| over the actuated joints, rad, while the planar command is below 0.1 m/s
    (legged_gym's stand_still: under a zero command, hold the default pose; nothing otherwise)."""
    import jax.numpy as jp

    return abs(q.joint_offset).sum() * (jp.linalg.norm(q.command[:2]) < 0.1)


def terms(cfg) -> dict[str, RewardTerm]:
    """name -> RewardTerm of every term of a RewardConfig, in declaration order."""
    return {f.name: getattr(cfg, f.name) for f in fields(cfg) if isinstance(getattr(cfg, f.name), RewardTerm)}


def unscaled(cfg, q: Quantities) -> dict[str, jax.Array]:
    """name -> each term of a RewardConfig on a step's quantities, before its scale and dt."""
    return {name: term(q) for name, term in terms(cfg).items()}


def weighted(cfg, values: dict[str, jax.Array], dt: float) -> dict[str, jax.Array]:
    """name -> each term's unscaled value (unscaled's) times its scale and the policy step dt: the
    summands of the reward."""
    return {name: values[name] * term.scale * dt for name, term in terms(cfg).items()}
