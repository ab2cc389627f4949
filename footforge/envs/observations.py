"""The observation vector, documented in one place: what each slice holds, its unit and scale."""

from __future__ import annotations

from footforge import constants as C
from footforge.envs.config import EnvConfig

# name, width (None: one per passive foot joint; "P": one per height-scan point; "T": one per
# actuated joint where ObservationConfig.pd_targets), content
LAYOUT = (
    ("base_lin_vel", 3, "base linear velocity in the base frame, m/s x lin_vel_scale"),
    ("base_ang_vel", 3, "base angular velocity in the base frame, rad/s x ang_vel_scale"),
    ("projected_gravity", 3, "unit gravity direction in the base frame"),
    ("command", 3, "vx, vy (m/s), yaw rate (rad/s) x command_scale"),
    ("joint_pos", 12, "actuated joint angles minus the defaults, rad"),
    ("joint_vel", 12, "actuated joint velocities, rad/s x joint_vel_scale"),
    ("last_action", 12, "the previous policy output"),
    ("pd_target", "T", "with ObservationConfig.pd_targets (the flat task's velocity actions): the "
     "actuated joints' PD targets minus the defaults, rad"),
    ("height_scan", "P", "P/PH only: clip(base z - 0.5 m - terrain height, +-1 m) x 5 at the scan points, "
     "x-major (EnvConfig.height_scan)"),
    ("foot_joint_pos", None, "BH/PH only: passive foot joint angles, rad"),
    ("foot_joint_vel", None, "BH/PH only: passive foot joint velocities, rad/s x foot_joint_vel_scale"),
)


def layout(config: EnvConfig, n_passive: int) -> list[tuple[str, int]]:
    """(name, width) of each slice of the observation, in order, for this policy type."""
    out = []
    for name, width, _ in LAYOUT:
        if width is None:
            if config.haptic:
                out.append((name, n_passive))
        elif width == "P":
            if config.perceptive:
                out.append((name, config.height_scan.num_points))
        elif width == "T":
            if config.observations.pd_targets:
                out.append((name, len(C.ACTUATED_JOINTS)))
        else:
            out.append((name, width))
    return out


def size(config: EnvConfig, n_passive: int) -> int:
    return sum(w for _, w in layout(config, n_passive))


def scale(config: EnvConfig, name: str) -> float | tuple[float, ...]:
    """The factor the environment multiplies slice `name` by before it enters the observation (a
    tuple for the command: vx, vy, yaw rate). The height scan is also offset and clipped first:
    see LAYOUT."""
    o = config.observations
    return {"base_lin_vel": o.lin_vel_scale, "base_ang_vel": o.ang_vel_scale, "projected_gravity": 1.0,
            "command": tuple(o.command_scale), "joint_pos": o.joint_pos_scale, "joint_vel": o.joint_vel_scale,
            "last_action": 1.0, "pd_target": 1.0, "height_scan": o.height_scale,
            "foot_joint_pos": o.foot_joint_pos_scale,
            "foot_joint_vel": o.foot_joint_vel_scale}[name]


def passive_joints_of(config: EnvConfig, observation_size: int) -> int:
    """The number of passive foot joints a policy of `config` reads, from its observation width
    (haptic policies read each one's angle and velocity; the others none)."""
    if not config.haptic:
        return 0
    return (observation_size - size(config, 0)) // 2
