"""Train an ANYmal C flat-terrain policy with Brax PPO on MuJoCo MJX (the paper's flat task).

    python pipelines/train_flat.py --feet aof --policy B --out runs/flat_aof_B
    python pipelines/train_flat.py --feet aof --policy B --out runs/flat_aof_B --resume   # after a kill
    # --resume reads the run's settings (config.json); an --out holding a run needs --resume or --force
    python pipelines/train_flat.py --feet ball --num-envs 64 --timesteps 200000 --unroll-length 16 \\
        --batch-size 16 --minibatches 4 --checkpoint-every 50000 --out runs/cpu_smoke     # a CPU run

Writes <out>/config.json, checkpoints/<step>/, progress.json, metrics.jsonl, tensorboard/ (every
reward term and tracking error, of evaluations and of training episodes) and policy/ (the final
policy, with the environment and PPO configs in footforge.json; load it with
footforge.rl.train.load_policy).
"""

from __future__ import annotations

import sys

from footforge.cli.train import main

if __name__ == "__main__":
    sys.exit(main("flat", __doc__.splitlines()[0]))
