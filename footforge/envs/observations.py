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
    from footforge.envs.config import EnvConfig, ObservationTerm


def base_lin_vel(env, data, info):
    """Base linear velocity in the base frame, m/s."""
    return env.base_state(data)[0]


def base_ang_vel(env, data, info):
    """Base angular velocity in the base frame, rad/s."""
    return env.base_state(data)[1]


def projected_gravity(env, data, info):
    """The unit gravity direction in the base frame."""
    return env.base_state(data)[2]


def command(env, data, info):
    """The velocity command: vx, vy (m/s), yaw rate (rad/s)."""
    return info["command"]


def joint_pos(env, data, info):
    """Actuated joint angles minus the defaults, rad."""
    return data.qpos[env.robot.actuated_qpos] - env.default_q


def joint_vel(env, data, info):
    """Actuated joint velocities, rad/s."""
    return data.qvel[env.robot.actuated_dof]


def last_action(env, data, info):
    """The previous (clipped) policy output."""
    return info["last_action"]


def pd_target(env, data, info):
    """The actuated joints' PD targets minus the defaults, rad."""
    return info["target"] - env.default_q


def height_scan(env, data, info):
    """clip(base z - height_offset_m - terrain height, +-height_clip_m) at the scan points, m."""
    return env.height_scan(data)


def foot_joint_pos(env, data, info):
    """Passive foot joint angles, rad."""
    return data.qpos[env.robot.passive_qpos]


def foot_joint_vel(env, data, info):
    """Passive foot joint velocities, rad/s."""
    return data.qvel[env.robot.passive_dof]


def terms(config: EnvConfig) -> list[tuple[str, ObservationTerm]]:
    """(name, term) of every group this policy type reads, in observation order."""
    from dataclasses import fields

    from footforge.envs.config import ObservationTerm

    o = config.observations
    reads = {"always": True, "haptic": config.haptic, "perceptive": config.perceptive, "pd_targets": o.pd_targets}
    out = []
    for f in fields(o):
        term = getattr(o, f.name)
        if isinstance(term, ObservationTerm) and reads[term.read_by]:
            out.append((f.name, term))
    return out


def width(config: EnvConfig, term: ObservationTerm, n_passive: int) -> int:
    """The number of values of `term`: its width, or one per passive foot joint or scan point."""
    return {"passive_joints": n_passive, "scan_points": config.height_scan.num_points}.get(term.width, term.width)


def layout(config: EnvConfig, n_passive: int) -> list[tuple[str, int]]:
    """(name, width) of each slice of the observation, in order, for this policy type."""
    return [(name, width(config, term, n_passive)) for name, term in terms(config)]


def size(config: EnvConfig, n_passive: int) -> int:
    return sum(w for _, w in layout(config, n_passive))


def scale(config: EnvConfig, name: str) -> float | tuple[float, ...]:
    """The factor the environment multiplies group `name` by (a tuple for the command: vx, vy,
    yaw rate)."""
    return getattr(config.observations, name).scale


def description(config: EnvConfig, name: str) -> str:
    """What group `name` holds and in which unit (its reading function's docstring)."""
    return getattr(config.observations, name).read.__doc__.strip()


def passive_joints_of(config: EnvConfig, observation_size: int) -> int:
    """The number of passive foot joints a policy of `config` reads, from its observation width
    (haptic policies read each one's angle and velocity; the others none)."""
    if not config.haptic:
        return 0
    return (observation_size - size(config, 0)) // 2

