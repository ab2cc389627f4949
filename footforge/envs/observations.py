"""The observation's groups: what each reads from the simulation, in its own unit.

Each group is declared once, as a field of ObservationConfig (envs.config): its reading function
(here), width, unit, the policy types that read it, and its scale and noise. The field order is
the order of the slices in the observation vector. The environment adds uniform noise of
+-noise (in the group's unit) to what the function returns, then multiplies by the scale
(Isaac Lab's ObservationTermCfg: func, noise, scale).

Every reading function takes (env, data, info): the environment (its robot's index tables and
default joint angles), the MJX (or CPU, through the same fields) state, and the step's info.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import jax
    from mujoco import mjx

    from footforge.envs.terms import ObservedEnv


def base_lin_vel(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """Base linear velocity in the base frame, m/s."""
    return env.base_state(data)[0]


def base_ang_vel(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """Base angular velocity in the base frame, rad/s."""
    return env.base_state(data)[1]


def projected_gravity(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """The unit gravity direction in the base frame."""
    return env.base_state(data)[2]


def command(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """The velocity command: vx, vy (m/s), yaw rate (rad/s)."""
    return info["command"]


def joint_pos(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """Actuated joint angles minus the defaults, rad."""
    return data.qpos[env.robot.actuated_qpos] - env.default_q


def joint_vel(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """Actuated joint velocities, rad/s."""
    return data.qvel[env.robot.actuated_dof]


def last_action(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """The previous (clipped) policy output."""
    return info["last_action"]


def pd_target(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """The actuated joints' PD targets minus the defaults, rad."""
    return info["target"] - env.default_q


def height_scan(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """clip(base z - height_offset_m - terrain height, +-height_clip_m) at the scan points, m."""
    return env.height_scan(data)


def foot_joint_pos(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """Passive foot joint angles, rad."""
    return data.qpos[env.robot.passive_qpos]


def foot_joint_vel(env: ObservedEnv, data: mjx.Data, info: dict) -> jax.Array:
    """Passive foot joint velocities, rad/s."""
    return data.qvel[env.robot.passive_dof]
