"""The game-inspired terrain curriculum (Rudin et al. 2022): each robot owns a level and a column
of the terrain; at the end of every episode it moves up a level when it walked far, down when it
did not cover what its command asked, and to a random level once it clears the top one.

Pure functions of arrays, so that they can be tested on constructed episodes and run inside the
jitted environment step.
"""

from __future__ import annotations

import jax
import jax.numpy as jp

from footforge.envs.config import CurriculumConfig
from footforge.envs.terrain import TerrainConfig


def first_levels(key, curriculum: CurriculumConfig, terrain: TerrainConfig, shape=(), kind_of_column=None):
    """(level, column) of robots at the start of training: a uniformly drawn column (so every kind of
    terrain gets robots) and a level in 0..initial_max_level, or drawn from initial_level_shares where given
    (a resumed run), or from the row of initial_level_shares_by_kind of the column's kind where given with
    `kind_of_column` (each column's index in terrain.KINDS) and that row is not all zero."""
    k_level, k_column = jax.random.split(key)
    if curriculum.initial_level_shares is not None:
        shares = jp.asarray(curriculum.initial_level_shares, jp.float32)
        level = jax.random.choice(k_level, terrain.num_levels, shape, p=shares / shares.sum())
    else:
        top = min(curriculum.initial_max_level, terrain.num_levels - 1)
        level = jax.random.randint(k_level, shape, 0, top + 1)
    column = jax.random.randint(k_column, shape, 0, terrain.num_columns)
    if curriculum.initial_level_shares_by_kind is not None and kind_of_column is not None:
        rows = jp.asarray(curriculum.initial_level_shares_by_kind, jp.float32)
        row = rows[jp.asarray(kind_of_column)[column]]  # (*shape, num_levels)
        logits = jp.where(row > 0, jp.log(jp.where(row > 0, row, 1.0)), -jp.inf)
        # Its own stream (fold_in): the column and the fallback level are the draws made without it.
        by_kind = jax.random.categorical(jax.random.fold_in(k_level, 1), logits, axis=-1)
        level = jp.where(row.sum(axis=-1) > 0, by_kind, level).astype(level.dtype)
    return level, column


def next_level(
    level,
    distance_m,
    command_speed_mps,
    key,
    curriculum: CurriculumConfig,
    terrain: TerrainConfig,
    episode_length_s: float,
):
    """The level after an episode in which the robot ended `distance_m` from its spawn under a
    planar command of `command_speed_mps`.

    Promoted: distance > promote_fraction_of_tile x tile side. Demoted (when not promoted):
    distance < demote_fraction_of_command x |v_cmd| x episode length, whether the episode timed
    out or ended in a fall. Levels stay >= 0; a robot promoted past the top level is sent to a
    random level, which keeps every level populated once the policy masters the terrain.
    """
    promote = distance_m > curriculum.promote_fraction_of_tile * terrain.tile_size_m
    demote = (distance_m < curriculum.demote_fraction_of_command * command_speed_mps * episode_length_s) & ~promote
    level = level + promote.astype(level.dtype) - demote.astype(level.dtype)
    random_level = jax.random.randint(key, jp.shape(level), 0, terrain.num_levels)
    return jp.where(level >= terrain.num_levels, random_level, jp.maximum(level, 0))
