"""Train an ANYmal C rough-terrain policy with Brax PPO on MuJoCo MJX (the paper's main task).

    python pipelines/train_rough.py --feet aof --policy PH --out runs/rough_aof_PH
    python pipelines/train_rough.py --feet aof --policy PH --out runs/rough_aof_PH --resume   # after a kill
    # --resume reads the run's settings (config.json); an --out holding a run needs --resume or --force
    python pipelines/train_rough.py --feet ball --policy P --num-envs 64 --timesteps 200000 \\
        --unroll-length 16 --batch-size 16 --minibatches 4 --checkpoint-every 50000 --out runs/cpu_smoke

Policy types: B blind, P perceptive (a 14 x 10 height scan), BH and PH add the feet's passive
joints. The robots walk a seeded heightfield of 10 levels x 20 columns of 8 m tiles (smooth and
rough slopes, stairs up and down, discrete obstacles, stepping stones) under the game-inspired
curriculum: each robot moves up a level when it walked over half a tile and down when it covered
less than a quarter of its command. Networks 512-256-128 and the paper's PPO settings by default.

Writes what train_flat.py writes, plus terrain.png (the terrain of the run); the distribution of
terrain levels over training episodes is logged as episode/terrain/level_per_step (mean) and
episode/terrain/at_level_<l>_per_step (share of episodes on level l).

Several accelerators: Brax's PPO splits the robots over every local JAX device (num_envs must be
a multiple of their count); on several machines start the same command on each after
jax.distributed.initialize() (see Brax's ppo.train: process_id / process_count).
"""

from __future__ import annotations

import sys

from footforge.cli.train import main

if __name__ == "__main__":
    sys.exit(main("rough", __doc__.splitlines()[0]))
