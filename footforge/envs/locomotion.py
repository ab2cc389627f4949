"""ANYmal C walking on flat ground under velocity commands: an MJX environment for Brax's PPO.

One robot per environment (Brax's wrappers batch it). Actions, clipped to +-1, are joint
velocities integrated onto the previous PD target (flat task) or offsets from the default pose
(EnvConfig.action explains both), turned into torques by the model's PD actuators (kp 80, kd 2,
+-80 N m) at every physics step. An ended episode restarts inside step (footforge.envs.wrappers
explains why); footforge.envs.rough builds the rough task on the hooks marked below.

`sys` is the MJX model; Brax's DomainRandomizationVmapWrapper swaps it per robot
(footforge.envs.randomization).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jp
import mujoco
import numpy as np
from brax import math as brax_math
from brax.envs.base import Env, State
from mujoco import mjx

from footforge import constants as C
from footforge.envs import contacts, engine, observation_layout, rewards
from footforge.envs.anymal import GEOM_BASE, GEOM_THIGH, Robot, check_mjx_impl, fit_heightfield_subgrids, load_robot
from footforge.envs.config import EnvConfig, check_feet_and_policy
from footforge.envs.wrappers import policy_side
from footforge.errors import InputError

N_ACTUATED = len(C.ACTUATED_JOINTS)


class ResetKeys(NamedTuple):
    """The random keys of an episode's start, in the order they are split from the reset key."""

    rng: jax.Array
    """Carried on in info["rng"] (after the observation's key is split from it)."""
    command: jax.Array
    spawn: jax.Array
    joints: jax.Array


class StepKeys(NamedTuple):
    """The random keys of a policy step, in the order they are split from info["rng"]."""

    rng: jax.Array
    """The next step's info["rng"]."""
    push: jax.Array
    command: jax.Array
    observation: jax.Array
    spawn: jax.Array
    joints: jax.Array


def reset_keys(rng: jax.Array) -> ResetKeys:
    return ResetKeys(*jax.random.split(rng, len(ResetKeys._fields)))


def step_keys(rng: jax.Array) -> StepKeys:
    return StepKeys(*jax.random.split(rng, len(StepKeys._fields)))


def _yaw(quat):
    w, x, y, z = quat
    return jp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _wrap(angle):
    return jp.arctan2(jp.sin(angle), jp.cos(angle))


class LocomotionEnv(Env):
    def __init__(self, config: EnvConfig, robot: Robot | None = None):
        check_feet_and_policy(config.feet, config.policy)
        if config.float64_physics and not jax.config.read("jax_enable_x64"):
            raise InputError(
                "float64_physics needs JAX's x64 mode, which is off in this process",
                fix="call footforge.envs.enable_float64_physics(config) (or set JAX_ENABLE_X64=1) "
                "before JAX makes its first array",
            )
        check_mjx_impl(config)
        self.config = config
        self.robot = robot or load_robot(config)
        r = self.robot
        # On this process's first device: MJX's default is jax.devices()[0], which on every process
        # but the first of a multi-process run (--coordinator) is another machine's device, and
        # JAX refuses to close a computation over such arrays.
        self.sys = mjx.put_model(r.model, device=jax.local_devices()[0], impl=config.mjx_impl)
        if config.mjx_impl == "jax":  # MJX Warp collides heightfields its own way
            self.sys = fit_heightfield_subgrids(self.sys, r.model)
        self._n_passive = len(r.passive_qpos)
        self._obs_size = observation_layout.size(config, self._n_passive)
        # Privileged (critic-only) observations: true base velocity (3), each foot's normal
        # force over the robot's weight (4), the noiseless height scan (points), ground friction (1).
        self._privileged_size = 3 + 4 + config.height_scan.num_points + 1
        self._weight_n = float(r.model.body_subtreemass[0] * -r.model.opt.gravity[2])
        geoms, local, category = contacts.surface_points(r.model, r.geom_category)
        self._probe_category = jp.asarray(category)
        self.physics = engine.make(config, r, geoms, local)
        """The engine that steps the robots (EnvConfig.physics; footforge.envs.engine): the only
        part of the environment that knows which one runs."""
        self._stand = jp.asarray(r.stand_qpos)
        self._ctrl_order = jp.asarray(r.actuator_ids)
        self.default_q = jp.asarray(r.default_q)
        """The actuated joints' default angles, rad (actuator order)."""
        self._q_lo, self._q_hi = jp.asarray(r.q_limits[:, 0]), jp.asarray(r.q_limits[:, 1])
        foot_geoms, foot_local, foot_radius = contacts.foot_points(r.model, r.geom_category)
        self._foot_geoms, self._foot_local = jp.asarray(foot_geoms), jp.asarray(foot_local)
        self._foot_radius = jp.asarray(foot_radius)
        stand = mujoco.MjData(r.model)
        stand.qpos[:] = r.stand_qpos
        mujoco.mj_kinematics(r.model, stand)
        lowest = (
            stand.geom_xpos[foot_geoms]
            + np.einsum("pij,pj->pi", stand.geom_xmat[foot_geoms].reshape(-1, 3, 3), foot_local)
        )[:, 2] - foot_radius
        self._stand_foot_clearance = float(lowest.min())
        """How far the stand keyframe's lowest foot collider point is above flat ground (z = 0), m:
        about minus its resting contact depth."""
        self._push_every = max(1, int(round(config.pushes.interval_s / config.policy_dt)))
        self._command_every = max(1, int(round(config.commands.resample_s / config.policy_dt)))

    @property
    def mjx_model(self):
        """The MJX model this robot steps (per robot under domain randomisation)."""
        return self.sys

    # Brax Env interface -------------------------------------------------------------------
    @property
    def observation_size(self):
        """The policy's observation width; with a privileged critic, Brax's dict of shapes."""
        if self.config.privileged_critic:
            return {"state": (self._obs_size,), "privileged_state": (self._obs_size + self._privileged_size,)}
        return self._obs_size

    @property
    def action_size(self) -> int:
        return N_ACTUATED

    @property
    def backend(self) -> str:
        return "mjx"

    def reset(self, rng: jax.Array) -> State:
        keys = reset_keys(rng)
        info = {
            "episode_step": jp.zeros((), jp.int32),
            "time_out": jp.zeros(()),
            **self._no_steps(),
        } | self._first_spawn_info(keys.spawn)
        qpos, qvel, target = self._start_state(info, keys.joints)
        data = self.physics.start(self.mjx_model, qpos, qvel, self._ctrl(target))
        info, obs = self.policy_start(data, info, keys, data.ctrl[self._ctrl_order])
        metrics = {f"reward/{t}": jp.zeros(()) for t in (*rewards.terms(self.config.rewards), "fall")}
        metrics |= {
            k: jp.zeros(())
            for k in (
                "error/lin_vel_x_per_step",
                "error/lin_vel_y_per_step",
                "error/yaw_rate_per_step",
                "base_height_m_per_step",
                "diverged",
            )
        }
        metrics |= self._task_metrics(info)
        return policy_side(State(data, self._with_privileged(obs, data), jp.zeros(()), jp.zeros(()), metrics, info))

    def _place(self, data, qpos, qvel, target, where=True):
        """The robot at (qpos, qvel) with PD targets `target` (only where `where`: the fields a
        restart sets, not the whole state, are selected)."""
        return self.physics.place(data, qpos, qvel, self._ctrl(target), where)

    def _ctrl(self, target):
        """Every actuator's control (model order) from the 12 PD targets (actuated-joint order)."""
        return jp.zeros(self.mjx_model.nu, target.dtype).at[self._ctrl_order].set(target)

    def _start_state(self, info, key) -> tuple[jax.Array, jax.Array, jax.Array]:
        """(qpos, qvel, PD targets) an episode starts from, after OmniIsaacGymEnvs' reset_idx:
        targets at default x f, f drawn per joint in EnvConfig.reset.joint_pos_factor_range, and
        joint velocities in +-joint_vel_max. The pose is the build's `stand` keyframe (at rest
        under the default targets) at the spawn point, its leg joints moved by default x (f - 1):
        with f = 1 on flat ground the robot starts at rest. The base is raised or lowered so that
        the lowest point of any foot collider is as high above the ground under it as in the stand
        on flat ground (straighter legs, tilted soles or a foot past a small platform onto a slope
        would start buried)."""
        r, cfg = self.robot, self.config.reset
        k_pos, k_vel = jax.random.split(key)
        lo, hi = cfg.joint_pos_factor_range
        factor = jax.random.uniform(k_pos, (N_ACTUATED,), minval=lo, maxval=hi)
        target = jp.clip(self.default_q * factor, self._q_lo, self._q_hi)
        qpos = self._spawn_qpos(info)
        qpos = qpos.at[r.actuated_qpos].set(
            jp.clip(qpos[r.actuated_qpos] + target - self.default_q, self._q_lo, self._q_hi)
        )
        qvel = (
            jp.zeros(self.mjx_model.nv)
            .at[r.actuated_dof]
            .set(jax.random.uniform(k_vel, (N_ACTUATED,), minval=-cfg.joint_vel_max, maxval=cfg.joint_vel_max))
        )
        # Every foot collider's lowest point, the ground under it: the base goes up or down until the
        # lowest foot is as high above its ground as in the stand on flat ground (a straighter leg,
        # a tilted sole, or a foot reaching onto a slope past a tile's platform would start buried).
        kin = mjx.kinematics(self.mjx_model, mjx.make_data(self.mjx_model).replace(qpos=qpos))
        g = self._foot_geoms
        points = kin.geom_xpos[g] + jp.einsum("pij,pj->pi", kin.geom_xmat[g], self._foot_local)
        clearance = jp.min(points[:, 2] - self._foot_radius - self.terrain_height(points[:, :2]))
        qpos = qpos.at[2].add(self._stand_foot_clearance - clearance)
        return qpos, qvel, target

    # The policy's side: what a controller on the robot computes, from the robot's state (data's
    # qpos and qvel) and its own memory (info). env.reset and env.step call these, and so does the
    # CPU runner on the closed chain (footforge.rl.evaluate_closed_chain.Controller), which gets
    # the same commands, PD targets, pushes and observations from the same random keys.
    def policy_start(self, data, info: dict, keys: ResetKeys, target, command=None):
        """(info, the policy's observation) at an episode's start: the first command, drawn with
        keys.command, its yaw rate steering to the drawn heading (`command`, vx vy yaw rate, where
        not NaN, replaces it); no previous action or joint velocity; PD targets `target`."""
        drawn, heading, standing = self.sample_command(keys.command)
        rng, key_obs = jax.random.split(keys.rng)
        info = info | {
            "rng": rng,
            "step": jp.zeros((), jp.int32),
            "target": target,
            "command": drawn,
            "heading_target": heading,
            "standing": standing,
            "last_action": jp.zeros(N_ACTUATED),
            "last_joint_vel": jp.zeros(N_ACTUATED),
        }
        info["command"] = _given(command, self.heading_command(info, data))
        return info, self.observe(data, info, key_obs)

    def policy_act(self, info: dict, action):
        """Before a policy step's physics: (the clipped action, the PD targets it sets, whether the
        step pushes the base, the planar velocity the push sets (m/s), info advanced a step, the
        step's random keys)."""
        keys = step_keys(info["rng"])
        step = info["step"] + 1
        action = self.clip_action(action)
        target = self.joint_targets(info["target"], action)
        push_now, push = self.push(step, keys.push)
        return action, target, push_now, push, info | {"rng": keys.rng, "step": step, "target": target}, keys

    def policy_command(self, info: dict, data, keys: StepKeys, command=None):
        """After the physics: (info with the command and heading target of the next step, the fresh
        draw (command, heading, standing) that episodes restarting now take). The command is redrawn every
        resample_s, its yaw rate steering to the heading; `command`, where not NaN, replaces it."""
        fresh = self.sample_command(keys.command)
        info = info | self.next_command(info, data, info["step"], *fresh)
        info["command"] = _given(command, info["command"])
        return info, fresh

    def policy_observe(self, data, info: dict, keys: StepKeys, action, ended=False, fresh=None):
        """After the physics and any restart: (info remembering this step's action and joint
        velocities, the policy's observation, non-finite values zeroed). Where `ended`, the
        episode restarted: nothing is remembered and the command is the fresh draw."""
        info = info | {
            "last_action": jp.where(ended, 0.0, action),
            "last_joint_vel": jp.where(ended, 0.0, data.qvel[self.robot.actuated_dof]),
        }
        if fresh is not None:
            info |= {
                "command": jp.where(ended, fresh[0], info["command"]),
                "heading_target": jp.where(ended, fresh[1], info["heading_target"]),
                "standing": jp.where(ended, fresh[2], info["standing"]),
            }
        obs = self.observe(data, info, keys.observation)
        return info, jp.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)

    def clip_action(self, action):
        """The policy output as the environment uses it, within +-EnvConfig.action_clip."""
        return jp.clip(action, -self.config.action_clip, self.config.action_clip)

    def joint_targets(self, previous_target, action):
        """PD targets of the 12 actuated joints (rad) for a clipped action, within the joint
        ranges: previous_target + scale a dt (velocity actions) or default + scale a (position)."""
        cfg = self.config
        if cfg.action == "velocity":
            target = previous_target + cfg.action_scale * action * cfg.policy_dt
        else:
            target = self.default_q + cfg.action_scale * action
        return jp.clip(target, self._q_lo, self._q_hi)

    def push(self, step, key):
        """(whether policy step `step` pushes, the planar base velocity it sets, m/s)."""
        p = self.config.pushes
        velocity = jax.random.uniform(key, (2,), minval=-p.max_speed, maxval=p.max_speed)
        return p.enabled & (step % self._push_every == 0), velocity

    def next_command(self, info, data, step, new_command, new_heading, new_standing):
        """info's command, heading target and standing flag after policy step `step`: redrawn
        every resample_s, the yaw-rate command steering to the heading."""
        resample = step % self._command_every == 0
        info = info | {
            "command": jp.where(resample, new_command, info["command"]),
            "heading_target": jp.where(resample, new_heading, info["heading_target"]),
            "standing": jp.where(resample, new_standing, info["standing"]),
        }
        return {
            "command": self.heading_command(info, data),
            "heading_target": info["heading_target"],
            "standing": info["standing"],
        }

    # Where episodes start: flat ground always at the home pose; RoughEnv overrides these hooks.
    def _first_spawn_info(self, key) -> dict:
        """Per-robot state that lives across episodes (the rough task's curriculum), at reset."""
        return {}

    def _next_spawn_info(self, info, data, ended, key) -> dict:
        """That state after a step in which the episode ended (where `ended`)."""
        return {}

    def _spawn_qpos(self, info):
        return self._stand

    def _task_metrics(self, info) -> dict:
        return {}

    def step(self, state: State, action: jax.Array) -> State:
        cfg = self.config
        data, info = state.pipeline_state, dict(state.info)
        action, target, push_now, push, info, keys = self.policy_act(info, action)
        # The push sets the base's planar velocity, then the physics runs.
        qvel = jp.where(push_now, data.qvel.at[:2].set(push.astype(data.qvel.dtype)), data.qvel)
        data = self.physics.step(self.mjx_model, data, data.ctrl.at[self._ctrl_order].set(target), qvel)
        info, fresh = self.policy_command(info, data, keys)

        steps = self._feet_steps(data, info)
        terms, errors = self._reward_terms(data, info, action, steps["touchdown_air_time"])
        weighted = rewards.weighted(cfg.rewards, terms, cfg.policy_dt)
        reward = sum(weighted.values())
        # A robot whose simulation diverged ends its episode as a fall with zero metrics; its
        # NaNs must reach neither the returns nor the policy's inputs. Finiteness (of the state
        # and of every reward term, raw and weighted) is checked before the clip, which would
        # turn -inf or NaN into 0 and hide the divergence; the `diverged` metric reports it.
        # Physics that blew up without reaching inf (EnvConfig.diverged_speed) counts the same.
        finite = (
            jp.isfinite(data.qpos).all()
            & (jp.abs(data.qvel) < cfg.diverged_speed).all()
            & jp.isfinite(reward)
            & jp.isfinite(data.actuator_force).all()
            & jp.all(jp.isfinite(jp.stack(list(terms.values()))))
        )
        if cfg.rewards.clip_total_at_zero:
            reward = jp.maximum(reward, 0.0)
        reward = jp.where(finite, reward, 0.0)
        weighted = {t: jp.where(finite, v, 0.0) for t, v in weighted.items()}
        errors = {k: jp.where(finite, v, 0.0) for k, v in errors.items()}
        terminated = self._terminated(data) | ~finite
        # After the clip (RewardConfig.fall). Strongly typed: a weakly typed metric would differ
        # from reset's and make every second call of a jitted step compile again.
        fall_penalty = jp.float32(cfg.rewards.fall) * terminated.astype(jp.float32)
        reward = reward + fall_penalty
        # A time-out is reported as done with info['time_out'] = 1, which PPO
        # (bootstrap_on_timeout) bootstraps instead of treating as a fall.
        episode_step = info["episode_step"] + 1
        time_out = (episode_step >= cfg.episode_steps) & ~terminated
        ended = terminated | time_out
        metrics = dict(state.metrics)  # Brax's wrappers add keys of their own: keep them
        metrics.update(
            {f"reward/{t}": v for t, v in weighted.items()}
            | errors
            | self._task_metrics(info)
            | {"reward/fall": fall_penalty, "diverged": (~finite).astype(jp.float32)}
        )
        # The environment restarts ended episodes itself (footforge.envs.wrappers): a new spawn,
        # no previous action, a new command. Brax's auto-reset would restore one fixed first
        # state and lose the curriculum's per-robot state.
        info.update(self._next_spawn_info(info, data, ended, keys.spawn))
        info.update({k: jp.where(ended, v0, steps[k]) for k, v0 in self._no_steps().items()})
        data = self._place(data, *self._start_state(info, keys.joints), where=ended)
        info.update(
            episode_step=jp.where(ended, 0, episode_step),
            time_out=time_out.astype(jp.float32),
            target=data.ctrl[self._ctrl_order],
        )  # this step's targets, or the restart's
        info, obs = self.policy_observe(data, info, keys, action, ended, fresh)
        obs = self._with_privileged(obs, data)  # policy_observe zeroed the policy's non-finite values
        return policy_side(
            state.replace(
                pipeline_state=data, obs=obs, reward=reward, done=ended.astype(jp.float32), metrics=metrics, info=info
            )
        )

    # Pieces --------------------------------------------------------------------------------
    def sample_command(self, key):
        """A command (vx, vy, 0), a target heading and whether it is a standing command (all zero,
        yaw rate too: CommandConfig.standing_fraction), drawn from CommandConfig's ranges."""
        c = self.config.commands
        kx, ky, kh = jax.random.split(key, 3)
        vx = jax.random.uniform(kx, minval=c.lin_vel_x_range[0], maxval=c.lin_vel_x_range[1])
        vy = jax.random.uniform(ky, minval=c.lin_vel_y_range[0], maxval=c.lin_vel_y_range[1])
        heading = jax.random.uniform(kh, minval=c.heading_range[0], maxval=c.heading_range[1])
        # Its own stream (fold_in), so that the other draws are those of configurations without it.
        standing = (
            (jax.random.uniform(jax.random.fold_in(key, 3)) < c.standing_fraction)
            if c.standing_fraction
            else jp.zeros((), bool)
        )
        keep = (jp.hypot(vx, vy) > c.zero_below) & ~standing
        return jp.array([vx, vy, 0.0]) * keep, heading, standing

    def heading_error(self, info, data):
        """The turn from the base's yaw to the target heading, rad in [-pi, pi)."""
        return _wrap(info["heading_target"] - _yaw(data.qpos[3:7]))

    def heading_command(self, info, data):
        """The yaw-rate command steers the base toward the target heading."""
        c = self.config.commands
        error = self.heading_error(info, data)
        yaw_rate = jp.clip(c.heading_gain * error, -c.yaw_rate_limit, c.yaw_rate_limit) * ~info["standing"]
        return info["command"].at[2].set(yaw_rate.astype(info["command"].dtype))  # float64 physics: f32 command

    def base_state(self, data):
        """(linear velocity, angular velocity, projected gravity) in the base frame."""
        quat = data.qpos[3:7]
        lin = brax_math.inv_rotate(data.qvel[:3], quat)
        ang = data.qvel[3:6]  # MuJoCo's free-joint angular velocity is already in the body frame
        gravity = brax_math.inv_rotate(jp.array([0.0, 0.0, -1.0]), quat)
        return lin, ang, gravity

    def observation(self, data, info, key):
        """What the networks read: the policy's observation, or with EnvConfig.privileged_critic
        Brax's dict {"state": the policy's, "privileged_state": the policy's + privileged}, the
        value network reading the second (an asymmetric actor-critic)."""
        return self._with_privileged(self.observe(data, info, key), data)

    def _with_privileged(self, obs, data):
        if not self.config.privileged_critic:
            return obs
        privileged = jp.nan_to_num(self.privileged(data), nan=0.0, posinf=0.0, neginf=0.0)
        return {"state": obs, "privileged_state": jp.concatenate([obs, privileged])}

    def privileged(self, data):
        """Critic-only quantities no robot measures directly: the true base linear velocity
        (x the base_lin_vel group's scale, noiseless), each foot's normal ground force over the robot's weight,
        the noiseless height scan, and the ground's friction coefficient."""
        cfg = self.config.observations
        lin, _, _ = self.base_state(data)
        return jp.concatenate(
            [
                lin * cfg.base_lin_vel.scale,
                self.foot_forces(data) / self._weight_n,
                self.height_scan(data) * cfg.height_scan.scale,
                self.mjx_model.geom_friction[self.robot.floor_geom, :1],
            ]
        )

    def foot_forces(self, data):
        """Per leg (LF, RF, LH, RH): the normal force of its foot's contacts with the ground, N."""
        return self.physics.foot_forces(self.mjx_model, data)

    def observe(self, data, info, key):
        """The policy's observation: each group this policy type reads (envs.observations), with
        uniform noise of +-noise in its unit (where ObservationConfig.noise), times its scale,
        the whole clipped to +-clip."""
        cfg = self.config.observations
        groups = observation_layout.terms(self.config)
        chunks = []
        for (_, term), k in zip(groups, jax.random.split(key, len(groups))):
            value = term.read(self, data, info)
            if cfg.noise and term.noise:
                value = value + jax.random.uniform(k, value.shape, minval=-term.noise, maxval=term.noise)
            chunks.append(value * (jp.asarray(term.scale) if isinstance(term.scale, (tuple, list)) else term.scale))
        return jp.clip(jp.concatenate(chunks), -cfg.clip, cfg.clip)

    def base_height(self, data):
        """Height of the base over the ground under it (flat ground: z)."""
        return data.qpos[2]

    def terrain_height(self, xy):
        """Ground height at world points xy (..., 2), m (flat ground: 0)."""
        return jp.zeros(xy.shape[:-1])

    def height_scan(self, data):
        """The perceptive observation before its scale: clip(base z - offset - h, +-clip) at the
        scan points (EnvConfig.height_scan), which turn with the base's yaw; x-major order, m."""
        cfg, scan = self.config.observations, self.config.height_scan
        points = jp.array([(x, y) for x in scan.x_m for y in scan.y_m])
        yaw = _yaw(data.qpos[3:7])
        c, s = jp.cos(yaw), jp.sin(yaw)
        world = data.qpos[:2] + points @ jp.array([[c, s], [-s, c]])
        relative = data.qpos[2] - cfg.height_offset_m - self.terrain_height(world)
        return jp.clip(relative, -cfg.height_clip_m, cfg.height_clip_m)

    @staticmethod
    def _no_steps() -> dict:
        """The feet's step state at an episode's start: in the air for no time, not touching."""
        return {"feet_air_time_s": jp.zeros(4), "feet_last_contact": jp.zeros(4, bool)}

    def _feet_steps(self, data, info) -> dict:
        """The feet's step state after a policy step, and each foot's air time on touching down
        (legged_gym's feet_air_time bookkeeping: a contact counts if seen this step or the last,
        which bridges a one-step flicker of the contact). Where the term is off (the rough task)
        nothing is measured: the state stays at its start."""
        if self.config.rewards.feet_air_time.scale == 0.0:  # decided when the step is traced
            return {k: info[k] for k in self._no_steps()} | {"touchdown_air_time": jp.zeros(4)}
        contact = self.foot_contacts(data)
        touching = contact | info["feet_last_contact"]
        air = info["feet_air_time_s"] + self.config.policy_dt
        touchdown = (info["feet_air_time_s"] > 0) & touching
        return {
            "feet_air_time_s": jp.where(touching, 0.0, air),
            "feet_last_contact": contact,
            "touchdown_air_time": jp.where(touchdown, air, 0.0),
        }

    def _reward_terms(self, data, info, action, touchdown_air_time):
        """(each reward term unscaled, the tracking errors and base height as metrics)."""
        r = self.robot
        lin, ang, gravity = self.base_state(data)
        q = rewards.Quantities(
            command=info["command"],
            lin_vel=lin,
            ang_vel=ang,
            gravity=gravity,
            base_height=self.base_height(data),
            torques=data.actuator_force[self._ctrl_order],
            joint_vel=data.qvel[r.actuated_dof],
            last_joint_vel=info["last_joint_vel"],
            action=action,
            last_action=info["last_action"],
            haa_offset=data.qpos[r.actuated_qpos][r.haa] - self.default_q[r.haa],
            touchdown_air_time=touchdown_air_time,
            joint_offset=data.qpos[r.actuated_qpos] - self.default_q,
        )
        terms = rewards.unscaled(self.config.rewards, q)
        command = q.command
        errors = {
            "error/lin_vel_x_per_step": jp.abs(command[0] - lin[0]),
            "error/lin_vel_y_per_step": jp.abs(command[1] - lin[1]),
            "error/yaw_rate_per_step": jp.abs(command[2] - ang[2]),
            "base_height_m_per_step": q.base_height,
        }
        return terms, errors

    def contact_flags(self, data):
        """(a base point is under the ground, number of legs with a thigh point under it).

        Geometric, on flat ground as on the heightfield: the base's and thighs' colliders are off
        in MJX (footforge.envs.anymal), since their contact only ends episodes. Sample points
        (contacts.surface_points): box corners, 8 points around each rim of a cylinder, the corners of the
        bounding box of anything else."""
        world = self.physics.probe_points(data)
        below = world[:, 2] < self.terrain_height(world[:, :2])
        base = jp.any(below & (self._probe_category == GEOM_BASE))
        knees = sum(jp.any(below & (self._probe_category == GEOM_THIGH + i)).astype(jp.int32) for i in range(4))
        return base, knees

    def foot_contacts(self, data):
        """Per leg (LF, RF, LH, RH): does its foot touch the ground."""
        return self.physics.foot_contacts(self.mjx_model, data)

    def foot_positions(self, data):
        """Per leg (LF, RF, LH, RH): its foot's touchdown site in the world, m."""
        return self.physics.foot_positions(data)

    def _terminated(self, data):
        """Base contact, or the configured number of thigh (knee) contacts (a boolean)."""
        base, knees = self.contact_flags(data)
        return base | (knees >= self.config.terminate_on_knees)


def _given(command, own):
    """`command` where given and not NaN (per component), else the environment's own."""
    return own if command is None else jp.where(jp.isnan(command), own, command)
