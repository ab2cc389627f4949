"""Standing still: how far a built robot sinks and its feet slide at its home keyframe.

The robot starts at the `home` keyframe with its position actuators holding the keyframe's
targets and nothing else acting. It settles under gravity (the PD joints at kp 80 N m/rad give
under the 52 kg robot's weight, the adaptive feet's passive joints move to their loaded angles);
after that a correct contact model holds it still. Measured after `settle_s`: the base's
height drop (its height at settle_s minus the lowest it reaches later) and each foot's slip (the
horizontal displacement of its touchdown site), over `seconds` in all, at the model's own
timestep and solver settings.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from footforge.envs.anymal import foot_sites


@dataclass(frozen=True)
class Stance:
    base_height_start_m: float
    """Base height at the keyframe."""
    base_height_settled_m: float
    """Base height at settle_s."""
    drop_after_settle_m: float
    """Base height at settle_s minus the lowest base height after it."""
    slip_after_settle_m: float
    """Largest horizontal displacement of a foot's touchdown site between settle_s and the end."""
    finite: bool
    """No NaN, and MuJoCo never reset the simulation for bad accelerations."""


def stand(model: mujoco.MjModel, *, seconds: float = 10.0, settle_s: float = 0.5, keyframe: str = "home") -> Stance:
    """Simulates the robot standing at `keyframe` for `seconds` (see the module docstring)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(keyframe).id)
    mujoco.mj_forward(model, data)
    sites = foot_sites(model)
    z_start = float(data.qpos[2])
    settle_steps = int(round(settle_s / model.opt.timestep))
    for _ in range(settle_steps):
        mujoco.mj_step(model, data)
    z_settled, feet = float(data.qpos[2]), data.site_xpos[sites, :2].copy()
    z_min = z_settled
    for _ in range(int(round(seconds / model.opt.timestep)) - settle_steps):
        mujoco.mj_step(model, data)
        z_min = min(z_min, float(data.qpos[2]))
    finite = bool(np.isfinite(data.qpos).all() and data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 0)
    slip = float(np.linalg.norm(data.site_xpos[sites, :2] - feet, axis=1).max())
    return Stance(z_start, z_settled, z_settled - z_min, slip, finite)
