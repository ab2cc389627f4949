"""Standing still: how far a built robot sinks and its feet slide at its home keyframe.

The robot starts at the `home` keyframe with its position actuators holding the keyframe's
targets and nothing else acting. It settles under gravity (the PD joints at kp 80 N m/rad give
under the 52 kg robot's weight, the adaptive feet's passive joints move to their loaded angles);
after that a correct contact model holds it still. Measured after `settle_s`: the base's
height drop (its height at settle_s minus the lowest it reaches later) and each foot's slip (the
horizontal displacement of its touchdown site), over `seconds` in all, at the model's own
timestep and solver settings.

env_stance measures the same in a training environment (MJX, its contact model and precision)
from a reset state, the episode's own start; env_stance_start sets up issue 12's measurement
(benchmarks/stance_env.py and the tests).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

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


@dataclass(frozen=True)
class FootLoads:
    """Ground forces on each foot (LF, RF, LH, RH), world frame, N."""

    forces_n: np.ndarray
    """(4, 3): the sum of each foot's contact forces."""

    @property
    def sideways_ratio(self) -> np.ndarray:
        """Per foot, horizontal over vertical force: the friction coefficient the stance needs
        (PhysX-like static friction holds it only where the ground's coefficient is higher)."""
        return np.hypot(self.forces_n[:, 0], self.forces_n[:, 1]) / np.abs(self.forces_n[:, 2])


def foot_loads(model: mujoco.MjModel, *, keyframe: str = "stand", settle_s: float = 0.5) -> FootLoads:
    """The ground forces on each foot after standing `settle_s` at `keyframe` with the actuators at
    its targets (contact forces from mj_contactForce, rotated out of each contact frame)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(keyframe).id)
    mujoco.mj_step(model, data, nstep=int(round(settle_s / model.opt.timestep)))
    legs = [model.body(model.site_bodyid[s]).name.split("_")[0] for s in foot_sites(model)]
    forces = np.zeros((len(legs), 3))
    wrench = np.zeros(6)
    for i in range(data.ncon):
        contact = data.contact[i]
        robot_geom = (
            contact.geom2 if model.geom_bodyid[contact.geom1] == 0 else contact.geom1
        )  # the world's is the ground
        leg = model.body(model.geom_bodyid[robot_geom]).name.split("_")[0]
        if leg not in legs:
            continue
        mujoco.mj_contactForce(model, data, i, wrench)
        force = contact.frame.reshape(3, 3).T @ wrench[:3]  # force on geom2, world frame
        forces[legs.index(leg)] += force if robot_geom == contact.geom2 else -force
    return FootLoads(forces)


def frictionless_rest(model: mujoco.MjModel, *, seconds: float = 5.0, keyframe: str = "stand") -> tuple[float, float]:
    """Where the robot comes to rest on frictionless ground (every geom's condim 1) from
    `keyframe` with the actuators at its targets: (base height m, largest horizontal displacement
    of a foot's touchdown site m). Soft friction creeps towards this pose."""
    m = copy.copy(model)
    m.geom_condim[:] = 1
    data = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, data, m.key(keyframe).id)
    mujoco.mj_forward(m, data)
    sites = foot_sites(m)
    start = data.site_xpos[sites, :2].copy()
    mujoco.mj_step(m, data, nstep=int(round(seconds / m.opt.timestep)))
    return float(data.qpos[2]), float(np.linalg.norm(data.site_xpos[sites, :2] - start, axis=1).max())


@dataclass(frozen=True)
class EnvStance:
    """A robot of a training environment (MJX) under zero actions: figures after settle_s."""

    drop_after_settle_m: float
    """Base height over the ground at settle_s minus the lowest it reaches later."""
    slip_after_settle_m: float
    """Largest horizontal displacement of a foot's touchdown site after settle_s."""
    base_height_min_m: float
    """Lowest base height over the ground in the whole run."""
    fell: bool
    """The episode ended (a fall or a diverged simulation) before the end."""


STANCE_TERRAIN_FIELDS: dict[str, Any] = {
    "num_levels": 3,
    "num_columns": 6,
    "tile_size_m": 4.0,
    "border_m": 2.0,
    "platform_m": 1.5,
}
"""The rough terrain of the stance measurement (TerrainConfig fields): level 0's spawn platform is
the same as in the full field, which compiles far slower."""


def env_stance_start(
    task: str,
    feet: str,
    build_dir: str,
    *,
    contact_model: str | None = None,
    float64_physics: bool = False,
    seed: int = 0,
    physics: str | None = None,
    **overrides,
):
    """(environment, start state) of issue 12's stance measurement: the task's default
    configuration (or `contact_model`), pushes off; flat: the task's own reset (the `stand`
    keyframe, joint velocities U(+-0.1) rad/s); rough: level 0 of a small field
    (STANCE_TERRAIN_FIELDS) from the `stand` keyframe (the rough reset's randomised joint angles
    off: the issue measures at the keyframe, with the actuators at its targets). float64_physics
    switches JAX's x64 mode for the whole process (envs.enable_float64_physics). `physics`:
    the engine (EnvConfig.physics), the configuration's own if None. `overrides`: other EnvConfig
    fields (e.g. heightfield_soles)."""
    from dataclasses import replace

    import jax

    from footforge import envs
    from footforge.envs.config import ResetConfig
    from footforge.envs.terrain import TerrainConfig

    config = envs.default_config(task, feet, "B", contact_model)
    config = replace(
        envs.with_float64_physics(config, float64_physics),
        build_dir=str(build_dir),
        pushes=replace(config.pushes, enabled=False),
    )
    if physics is not None:
        config = replace(config, physics=physics)
    config = replace(config, **overrides)
    if task == "rough":
        config = replace(
            config, reset=ResetConfig(joint_pos_factor_range=(1.0, 1.0)), terrain=TerrainConfig(**STANCE_TERRAIN_FIELDS)
        )
    envs.enable_float64_physics(config)
    env = envs.from_config(config)
    key = jax.random.PRNGKey(seed)
    return env, (jax.jit(env.reset)(key) if task == "flat" else env.reset_on_tile(key, 0, 0))


def env_stance(env, state, *, seconds: float, settle_s: float = 0.5, step=None) -> EnvStance:
    """Issue 12's stance measure in a footforge environment: one robot from `state` (a reset
    state, unbatched) given zero actions for `seconds`, at the environment's own physics (its
    contact model, step and precision). `step`: the environment's jitted step, if already
    compiled."""
    import jax
    import jax.numpy as jp

    policy_steps = int(round(seconds / env.config.policy_dt))
    settle = int(round(settle_s / env.config.policy_dt))
    if policy_steps <= settle:
        raise ValueError(f"seconds ({seconds}) must exceed settle_s ({settle_s})")
    step = step or jax.jit(env.step)
    heights, feet_xy, fell = [], [], False
    for _ in range(policy_steps):
        state = step(state, jp.zeros(env.action_size))
        if float(state.done) != 0.0:
            fell = True
            break
        heights.append(float(env.base_height(state.pipeline_state)))
        feet_xy.append(np.asarray(env.foot_positions(state.pipeline_state)[:, :2]))
    if fell:
        return EnvStance(float("nan"), float("nan"), min(heights, default=float("nan")), True)
    settled, xy = np.array(heights[settle:]), np.array(feet_xy[settle:])
    return EnvStance(
        float(settled[0] - settled.min()), float(np.linalg.norm(xy - xy[0], axis=-1).max()), float(min(heights)), False
    )
