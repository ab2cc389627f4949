"""ANYmal C on the rough-terrain heightfield under the game-inspired curriculum: an MJX environment.

The flat environment's task (commands from a heading, pushes, the ten reward terms, termination,
time-outs as truncations) on footforge.envs.terrain's heightfield, with these differences:

- Each robot owns a terrain level and column (info 'level', 'column'); an episode starts on that
  tile's flat centre (within CurriculumConfig.spawn_radius_m, random yaw) and its end moves the
  robot up or down a level (footforge.envs.curriculum). The environment restarts its own episodes
  so that this state survives (train with footforge.envs.wrappers.wrap_for_training).
- Perceptive policies (P, PH) observe the height scan, read from the heightfield's samples on
  MuJoCo's own triangulation of it.
- The base height of the reward is measured from the terrain under the base.
- The base's and thighs' contacts are measured against the terrain's surface (their colliders
  are off in MJX on either ground; MJX could not collide their cylinders with a heightfield
  anyway, and a 0.6 m box would test ~50 prisms): LocomotionEnv.contact_flags.
"""

from __future__ import annotations

import jax
import jax.numpy as jp
from brax import math as brax_math

from footforge.envs import curriculum
from footforge.envs.anymal import load_robot
from footforge.envs.config import EnvConfig
from footforge.envs.locomotion import LocomotionEnv
from footforge.envs.terrain import KIND_LEVEL_STEPS, KINDS, generate, surface_height
from footforge.envs.wrappers import policy_side
from footforge.errors import InputError


class RoughEnv(LocomotionEnv):
    def __init__(self, config: EnvConfig):
        if config.task != "rough":
            raise InputError(f"RoughEnv needs task 'rough', got '{config.task}'", fix="use envs.make('rough', ...)")
        config.terrain.check()
        by_kind = config.curriculum.initial_level_shares_by_kind
        if by_kind is not None and (
            len(by_kind) != len(KINDS) or any(len(row) != config.terrain.num_levels or min(row) < 0 for row in by_kind)
        ):
            raise InputError(
                f"curriculum initial_level_shares_by_kind must be {len(KINDS)} rows ({', '.join(KINDS)}) of "
                f"{config.terrain.num_levels} non-negative shares (one per terrain level)",
                fix="leave it unset (a resume sets it from its checkpoint's progress.json)",
            )
        self.terrain = generate(config.terrain)
        super().__init__(config, load_robot(config, self.terrain))
        self._heights = jp.asarray(self.terrain.heights_m, jp.float32)
        self._stand_z = float(self.robot.stand_qpos[2])
        # Each column's kind as its index in KINDS (the curriculum's levels per kind).
        self._kind_of_column = jp.asarray([KINDS.index(k) for k in self.terrain.column_kinds], jp.int32)

    # Ground -------------------------------------------------------------------------------
    def terrain_height(self, xy):
        t = self.terrain
        return surface_height(self._heights, t.origin_xy, t.resolution_m, xy, jp)

    def base_height(self, data):
        return data.qpos[2] - self.terrain_height(data.qpos[:2])

    def reset_on_tile(self, rng, level, column, forward_mps: float | None = None):
        """A reset on tile (level, column) instead of the curriculum's draw (for evaluation). With
        `forward_mps`, the command is to walk straight ahead at that speed (heading kept)."""
        state = self.reset(rng)
        key = jax.random.fold_in(rng, 1)
        level, column = jp.asarray(level, jp.int32), jp.asarray(column, jp.int32)
        xy, yaw = self._spawn(level, column, key)
        info = state.info | {"level": level, "column": column, "spawn_xy": xy, "spawn_yaw": yaw}
        if forward_mps is not None:
            info |= {
                "command": jp.array([forward_mps, 0.0, 0.0]),
                "heading_target": yaw,
                "standing": jp.zeros((), bool),
            }
        data = self.physics.forward(
            self.mjx_model, self._place(state.pipeline_state, *self._start_state(info, jax.random.fold_in(rng, 2)))
        )
        info |= {"target": data.ctrl[self._ctrl_order], "command": self.heading_command(info, data)}
        return policy_side(state.replace(pipeline_state=data, obs=self.observation(data, info, key), info=info))

    # Curriculum and spawns -------------------------------------------------------------------
    def _spawn(self, level, column, key):
        """A spawn point on tile (level, column)'s platform and a yaw."""
        k_r, k_a, k_yaw = jax.random.split(key, 3)
        radius = self.config.curriculum.spawn_radius_m * jp.sqrt(jax.random.uniform(k_r))  # uniform on the disc
        angle = jax.random.uniform(k_a, minval=-jp.pi, maxval=jp.pi)
        cx, cy = self.terrain.tile_center(level, column)
        xy = jp.stack([cx + radius * jp.cos(angle), cy + radius * jp.sin(angle)])
        return xy, jax.random.uniform(k_yaw, minval=-jp.pi, maxval=jp.pi)

    def _first_spawn_info(self, key):
        k_level, k_spawn = jax.random.split(key)
        level, column = curriculum.first_levels(
            k_level, self.config.curriculum, self.config.terrain, kind_of_column=self._kind_of_column
        )
        xy, yaw = self._spawn(level, column, k_spawn)
        return {"level": level, "column": column, "spawn_xy": xy, "spawn_yaw": yaw}

    def _next_spawn_info(self, info, data, ended, key):
        cfg = self.config
        k_level, k_spawn = jax.random.split(key)
        distance = jp.linalg.norm(data.qpos[:2] - info["spawn_xy"])
        level = curriculum.next_level(
            info["level"],
            distance,
            jp.linalg.norm(info["command"][:2]),
            k_level,
            cfg.curriculum,
            cfg.terrain,
            cfg.episode_length_s,
        )
        level = jp.where(ended, level, info["level"])
        xy, yaw = self._spawn(level, info["column"], k_spawn)
        return {
            "level": level,
            "spawn_xy": jp.where(ended, xy, info["spawn_xy"]),
            "spawn_yaw": jp.where(ended, yaw, info["spawn_yaw"]),
        }

    def _spawn_qpos(self, info):
        xy, yaw = info["spawn_xy"], info["spawn_yaw"]
        turn = jp.array([jp.cos(yaw / 2), 0.0, 0.0, jp.sin(yaw / 2)])
        z = self._stand_z + self.terrain_height(xy)
        return self._stand.at[:2].set(xy).at[2].set(z).at[3:7].set(brax_math.quat_mul(turn, self._stand[3:7]))

    def _task_metrics(self, info):
        """The episode's level, and one indicator per level (their means over ended episodes are
        the distribution of robots over the levels), and one per terrain kind and level (the joint
        distribution in time, KIND_LEVEL_STEPS: what a resume restores the curriculum from; training
        keeps them out of the curve, footforge.rl.train)."""
        level = info["level"]
        kind = self._kind_of_column[info["column"]]
        levels = range(self.config.terrain.num_levels)
        return (
            {"terrain/level_per_step": level.astype(jp.float32)}
            | {f"terrain/at_level_{k}_per_step": (level == k).astype(jp.float32) for k in levels}
            | {
                KIND_LEVEL_STEPS.format(name, k): ((kind == i) & (level == k)).astype(jp.float32)
                for i, name in enumerate(KINDS)
                for k in levels
            }
        )
