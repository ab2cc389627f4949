"""The robot at rest on flat ground: the pose the `stand` keyframe records.

A pose such as `home` is not an equilibrium: at the PD gains the legs give under the robot's weight
and an adaptive foot's passive joints turn to their loaded angles. rest_pose simulates the robot,
holding its keyframe's targets, until it stops moving. The build records the result as `stand`
(footforge.mjcf.robot); the rough task computes it again where the soles touch its heightfield
through other colliders than the build's (footforge.envs.anymal: EnvConfig.heightfield_soles),
whose rest differs.
"""

from __future__ import annotations

import mujoco
import numpy as np

from footforge import constants as C

SETTLE_MAX_S = 5.0
"""The longest the robot is given to come to rest, s."""
REST_QVEL = 1e-2
"""At rest: the base's and the 12 leg joints' velocities below this (m/s, rad/s) for REST_HOLD_S
(the closed chain's 8-16 g links keep a faint vibration of their own)."""
REST_HOLD_S = 0.2


class NoRest(Exception):
    """The robot did not come to rest within SETTLE_MAX_S: `joint` moved at `speed` at the end."""

    def __init__(self, joint: str, speed: float):
        super().__init__(f"joint '{joint}' still moving at {speed:.3g}")
        self.joint, self.speed = joint, speed


def rest_pose(model: mujoco.MjModel, *, keyframe: str = "home") -> tuple[np.ndarray, np.ndarray]:
    """(qpos, ctrl) of the robot at rest on `model`'s flat ground, simulated from `keyframe` under its
    ctrl (the PD targets) until the base and the actuated joints are still (REST_QVEL for
    REST_HOLD_S).

    Raises:
      NoRest: not still within SETTLE_MAX_S (or the state diverged).
    """
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(keyframe).id)
    still_steps, needed = 0, int(round(REST_HOLD_S / model.opt.timestep))
    watched = np.concatenate([np.arange(6), [model.joint(j).dofadr[0] for j in C.ACTUATED_JOINTS]])
    while still_steps < needed:
        if data.time > SETTLE_MAX_S or not np.isfinite(data.qvel).all():
            dof = int(watched[np.argmax(np.abs(np.nan_to_num(data.qvel[watched], nan=np.inf)))])
            raise NoRest(model.joint(model.dof_jntid[dof]).name, float(np.abs(data.qvel[dof])))
        mujoco.mj_step(model, data)
        still_steps = still_steps + 1 if np.abs(data.qvel[watched]).max() < REST_QVEL else 0
    return data.qpos.copy(), data.ctrl.copy()
