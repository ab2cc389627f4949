"""Whether the training physics survives a policy's actions, on the CPU.

CPU MuJoCo steps the MJX environment's own model (load_robot: its timestep, contact and solver
settings) under an untrained policy's actions: each policy step a ~ N(0, 1) clipped to
+-EnvConfig.action_clip (PPO's initial Gaussian), turned into PD targets by the flat baseline's
velocity model at its 13.5 rad/s per unit (target += 13.5 a policy_dt, within the joint ranges):
the harshest targets an untrained policy gives, whatever action model the configuration trains
with. A robot diverges by the environment's own criterion (diverged). A proxy for MJX, which runs
the same model in float32 (benchmarks/action_stability.py --sim mjx measures both; on AOF they
agreed, benchmarks/log/2026-11-21_to_26.md).
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np

from footforge.envs.anymal import load_robot
from footforge.envs.config import EnvConfig

VELOCITY_ACTION_SCALE = 13.5
"""rad/s per unit action of OmniIsaacGymEnvs' flat Anymal (the stress of divergence_times)."""


def diverged(data: mujoco.MjData, max_speed: float) -> bool:
    """Whether a CPU MuJoCo simulation diverged, by the environment's criterion
    (EnvConfig.diverged_speed): a non-finite state or a generalised velocity past `max_speed`;
    or MuJoCo reset it because its accelerations blew up (a BADQACC warning, counted since the
    data was made or reset)."""
    return not (
        np.isfinite(data.qpos).all()
        and np.all(np.abs(data.qvel) < max_speed)
        and data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 0
    )


def divergence_times(config: EnvConfig, robots: int, seconds: float, seed: int = 0) -> list[float | None]:
    """Per robot, the time (s) at which its physics diverged, or None if it lasted `seconds`.
    Robots start from the build's stand keyframe at the default targets and are never reset
    (a fallen robot keeps being driven)."""
    config = replace(config, action="velocity", action_scale=VELOCITY_ACTION_SCALE)
    robot = load_robot(config)
    model = robot.model
    rng = np.random.default_rng(seed)
    steps = int(round(seconds / config.policy_dt))
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    times: list[float | None] = []
    for _ in range(robots):
        data = mujoco.MjData(model)
        data.qpos[:] = robot.stand_qpos
        target = robot.default_q.copy()
        data.ctrl[robot.actuator_ids] = target
        mujoco.mj_forward(model, data)
        when = None
        for k in range(steps):
            action = np.clip(rng.normal(size=len(target)), -config.action_clip, config.action_clip)
            target = np.clip(target + config.action_scale * action * config.policy_dt, lo, hi)
            data.ctrl[robot.actuator_ids] = target
            mujoco.mj_step(model, data, nstep=config.decimation)
            if diverged(data, config.diverged_speed):
                when = round((k + 1) * config.policy_dt, 4)
                break
        times.append(when)
    return times
