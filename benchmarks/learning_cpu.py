"""Does PPO learn to walk? One flat-ground training with a preset of commands and a variant of
the task's settings (an ablation), on whatever JAX device is present.

Presets (the commands a robot is trained and judged on):
- forward: vx fixed at 0.6 m/s, vy 0, heading 0 (no yaw), pushes off: the easiest walking task.
- full:    vx U(-1, 1), vy U(-0.5, 0.5) m/s, heading-driven yaw rate, pushes on (the task's
           heading range, gain and push schedule).

Variants: tokens joined by '+', applied in order to the flat task's defaults (envs.default_config);
each token sets absolute values, so a variant means the same whatever the defaults. The H100
ablations of 2026-11-26 ran before the defaults changed: their `position+fast` is today's
`position+paper_ppo+paper_rewards+fast`.
- today:    nothing (the defaults as they stand);
- position: position actions, target = default + 0.5 a (OmniIsaacGymEnvs' AnymalTerrain, legged_gym,
            Playground), PD targets not observed (they are a function of the last action);
- velocity: velocity actions, target += 13.5 a dt, PD targets observed (OmniIsaacGymEnvs' Anymal);
- ppo:      rsl_rl's settings as legged_gym uses them (learning rate 1e-3 with the adaptive-KL
            schedule at KL 0.01, entropy 0.01) and the policy's output layer initialised at 0.01x
            (PPOConfig's defaults since 2026-11-26);
- paper_ppo: the paper's baseline's (3e-4, KL 0.008, entropy 0.001, output layer as Brax makes it);
- bound:    the policy mean bounded to +-1.5 (Brax's softsign mean_clip_scale);
- rewards:  tracking lin_vel_xy 2, yaw_rate 1 (Playground's Go1 weighs tracking 3 and 1.5 against
            similar penalties) and base height -2 (unpublished in the paper; -10 was a guess):
            envs.FLAT_TUNED_REWARDS, the flat task's default since 2026-11-26;
- paper_rewards: the baseline's tracking 1 and 0.5 and base height -10;
- noclip:   the summed reward not clipped at zero;
- airtime:  legged_gym's feet-air-time term at its scale 1.0 (RewardConfig.feet_air_time; not among
            the paper's terms, off by default);
- stance / fast: the contact model (EnvConfig.contact_model) with its own physics step;
- airtime=X: the feet-air-time scale X (airtime=0: off, as runs from before the term trained);
- entropy=X: PPO's entropy cost alone (e.g. entropy=0.001).
- height=X: the base-height penalty's weight alone (height=10: scale -10, the paper's guess; the
            tuned flat task's is 2).
- resample=X: a new command every X > 0 seconds (CommandConfig.resample_s; the flat task's default
            is 5 s since 2026-11-27, legged_gym's 10 s before: runs from before trained at 10).

Prints one line per evaluation and per training-episode log (steps, wall s, episode length,
forward error, base height), then one JSON line: steps trained (the run's last checkpoint),
wall_s, and the final policy's walking verdict (deterministic, 32 robots x 20 s:
footforge.rl.verdict; verdict, forward_error, vx_slope, uptime (the share of robot-time up) and
time_up_s, base_height_m, stance_fraction per foot, gait, clipped_fraction), then the curve. A
figure that could not be measured is null.

    python benchmarks/learning_cpu.py --out /tmp/l --preset forward --variant position --timesteps 3000000
    python benchmarks/learning_cpu.py --out /tmp/l --timesteps 5000000 --resume   # goes on
    python benchmarks/learning_cpu.py --out /tmp/m --variant today+entropy=0.001 --init-from /tmp/l  # fine-tunes
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

from footforge.variants import FEET

PRESETS = ("forward", "full")
TOKENS = ("today", "position", "velocity", "ppo", "paper_ppo", "bound", "rewards", "paper_rewards", "noclip",
          "airtime", "airtime=X", "stance", "fast", "entropy=X", "height=X", "resample=X")


def _valued_token(token: str) -> bool:
    """A NAME=X token (airtime=X, entropy=X, ...) with a number for X: X >= 0, and X > 0 for resample."""
    name, _, value = token.partition("=")
    try:
        return f"{name}=X" in TOKENS and (float(value) > 0 if name == "resample" else float(value) >= 0)
    except ValueError:
        return False


def configure(feet: str, preset: str, variant: str, ppo_overrides: dict):
    """(EnvConfig, PPOConfig) of a preset and a '+'-joined variant (see the module's docstring)."""
    from footforge import envs
    from footforge.rl import train

    cfg = envs.default_config("flat", feet, "B")
    if preset == "forward":
        cfg = replace(cfg, commands=replace(cfg.commands, lin_vel_x_range=(0.6, 0.6), lin_vel_y_range=(0.0, 0.0),
                                            heading_range=(0.0, 0.0)),
                      pushes=replace(cfg.pushes, enabled=False))
    else:
        cfg = replace(cfg, commands=replace(cfg.commands, lin_vel_x_range=(-1.0, 1.0), lin_vel_y_range=(-0.5, 0.5)))
    ppo = train.default_ppo("flat", **ppo_overrides)
    for token in variant.split("+"):
        if token == "position":
            cfg = replace(cfg, action="position", action_scale=0.5,
                          observations=replace(cfg.observations, pd_targets=False))
        elif token == "velocity":
            cfg = replace(cfg, action="velocity", action_scale=13.5,
                          observations=replace(cfg.observations, pd_targets=True))
        elif token == "ppo":
            ppo = replace(ppo, learning_rate=1e-3, adaptive_kl=0.01, entropy_cost=0.01, policy_output_init_scale=0.01)
        elif token == "paper_ppo":
            ppo = replace(ppo, learning_rate=3e-4, adaptive_kl=0.008, entropy_cost=0.001, policy_output_init_scale=1.0)
        elif token == "bound":
            ppo = replace(ppo, policy_mean_clip=1.5)
        elif token == "rewards":
            cfg = replace(cfg, rewards=cfg.rewards.with_scales(**envs.FLAT_TUNED_REWARDS))
        elif token == "paper_rewards":
            cfg = replace(cfg, rewards=cfg.rewards.with_scales(lin_vel_xy=1.0, yaw_rate=0.5, base_height=-10.0))
        elif token == "airtime":
            cfg = replace(cfg, rewards=cfg.rewards.with_scales(feet_air_time=1.0))
        elif token == "noclip":
            cfg = replace(cfg, rewards=replace(cfg.rewards, clip_total_at_zero=False))
        elif token.startswith("airtime="):  # the feet-air-time scale, e.g. airtime=0 (off)
            cfg = replace(cfg, rewards=cfg.rewards.with_scales(feet_air_time=float(token.split("=", 1)[1])))
        elif token.startswith("height="):  # the base-height penalty's weight: height=10 is scale -10
            cfg = replace(cfg, rewards=cfg.rewards.with_scales(base_height=-float(token.split("=", 1)[1])))
        elif token.startswith("resample="):  # seconds between commands, e.g. resample=5
            cfg = replace(cfg, commands=replace(cfg.commands, resample_s=float(token.split("=", 1)[1])))
        elif token.startswith("entropy="):  # PPO's entropy cost alone, e.g. entropy=0.001
            ppo = replace(ppo, entropy_cost=float(token.split("=", 1)[1]))
        elif token in ("stance", "fast"):
            cfg = envs.with_contact_model(replace(cfg, **envs.physics(feet, token)), token)
        elif token != "today":
            raise SystemExit(f"learning_cpu: unknown variant token '{token}' (known: {', '.join(TOKENS)})")
    return cfg, ppo


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))  # the first paragraph, whole
    p.add_argument("--out", type=Path, required=True, help="run folder (a new one, or the run to --resume)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its newest checkpoint "
                   "(parameters only: Brax restarts Adam and the adaptive learning rate)")
    p.add_argument("--feet", default="ball", choices=FEET)
    p.add_argument("--preset", default="full", choices=PRESETS, help="commands (default full)")
    p.add_argument("--variant", default="today", help=f"'+'-joined tokens among {', '.join(TOKENS)} (default today)")
    p.add_argument("--timesteps", type=int, default=5_000_000)
    p.add_argument("--num-envs", type=int, default=128)
    p.add_argument("--unroll-length", type=int, default=24)
    p.add_argument("--batch-size", type=int, help="trajectories per minibatch (default num_envs / 2)")
    p.add_argument("--minibatches", type=int, default=4)
    p.add_argument("--eval-every", type=int, default=500_000, help="env steps between checkpoints (and evaluations)")
    p.add_argument("--eval-envs", type=int, default=64)
    p.add_argument("--no-evaluations", action="store_true",
                   help="no deterministic evaluations (the curve is the training episodes'; on a GPU one costs "
                        "about 20 PPO iterations)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--physics", default="auto", choices=["auto", "mjx", "mujoco"],
                   help="the engine (EnvConfig.physics; auto: MuJoCo's C engine on a CPU, MJX elsewhere); "
                        "the verdict's evaluation uses the same")
    p.add_argument("--max-minutes", type=float,
                   help="stop at the checkpoint before this wall time (train's max_wall_s)")
    p.add_argument("--init-from", type=Path, metavar="RUN",
                   help="a new run starting from RUN's newest checkpoint (train's init_from), with this "
                        "command's --variant settings: fine-tuning")
    p.add_argument("--build-dir", type=Path, help="footforge build of the feet (default build/<feet>)")
    p.add_argument("--no-verdict", action="store_true",
                   help="skip the final policy's walking verdict (pipelines/evaluate.py measures it later)")
    args = p.parse_args(argv)
    if args.out.exists() and not args.resume:
        p.error(f"--out {args.out} exists; give a new folder, or --resume")
    if args.resume and not args.out.is_dir():
        p.error(f"--resume: --out {args.out} holds no run to continue")
    if args.max_minutes is not None and args.max_minutes <= 0:
        p.error(f"--max-minutes must be positive, got {args.max_minutes:g}")
    bad = [t for t in args.variant.split("+") if t not in TOKENS and not _valued_token(t)]
    if bad:
        p.error(f"--variant: unknown token(s) {', '.join(bad)} (known: {', '.join(TOKENS)})")

    import jax

    from footforge.rl import train

    cfg, ppo = configure(args.feet, args.preset, args.variant, dict(
        num_envs=args.num_envs, num_timesteps=args.timesteps, unroll_length=args.unroll_length,
        batch_size=args.batch_size or args.num_envs // 2, num_minibatches=args.minibatches,
        checkpoint_every_steps=args.eval_every, num_eval_envs=args.eval_envs, seed=args.seed))
    if args.resume:  # the run's own settings; --feet, --preset and --variant are not read
        cfg, saved = train.load_run_config(args.out)
        ppo = replace(saved, num_timesteps=args.timesteps)
        args.feet, args.preset, args.variant = cfg.feet, "(the run's)", "(the run's)"
    if args.build_dir:  # where the feet are built is this machine's, not the run's
        cfg = replace(cfg, build_dir=str(args.build_dir))
    from footforge.envs import engine

    cfg = replace(cfg, physics=engine.resolve(args.physics))
    t0 = time.time()
    print(f"{args.feet} {args.preset} {args.variant} on {jax.default_backend()} ({jax.device_count()} device(s))",
          flush=True)
    print("env steps | wall s | episode length (policy steps) | forward error m/s | base height m | source", flush=True)

    printed = set()

    def progress(step, total, metrics, evaluation):
        if "eval/episode_reward" in metrics and evaluation:
            src, length = "eval", metrics["eval/avg_episode_length"]
            err, height = metrics["eval/episode_error/lin_vel_x_per_step"], metrics.get(
                "eval/episode_base_height_m_per_step", float("nan"))
        elif "episode/length" in metrics:
            src, length = "train", metrics["episode/length"]
            err = metrics.get("episode/error/lin_vel_x_per_step", float("nan"))
            height = metrics.get("episode/base_height_m_per_step", float("nan"))
        else:
            return
        if (step, src) in printed:  # Brax reports an epoch's end more than once
            return
        printed.add((step, src))
        print(f"{step:>9,} | {time.time() - t0:6.0f} | {length:6.1f} | {err:.3f} | {height:.3f} | {src}", flush=True)

    train.train(cfg, ppo, args.out, progress=progress, resume=args.resume, evaluate=not args.no_evaluations,
                max_wall_s=args.max_minutes * 60 if args.max_minutes else None, init_from=args.init_from)
    curve = []
    for e in map(json.loads, (args.out / "metrics.jsonl").read_text().splitlines()):
        key = "eval/" if "eval/episode_reward" in e else "episode/" if "episode/length" in e else None
        if key is None:
            continue
        curve.append({"env_steps": e["global_step"], "wall_s": round(e["wall_s"], 1), "source": key[:-1],
                      "episode_length": e.get("eval/avg_episode_length", e.get("episode/length")),
                      "forward_error_mps": e.get(f"{key}episode_error/lin_vel_x_per_step" if key == "eval/"
                                                 else "episode/error/lin_vel_x_per_step"),
                      "base_height_m": e.get(f"{key}episode_base_height_m_per_step" if key == "eval/"
                                             else "episode/base_height_m_per_step")})
    train_s = round(time.time() - t0, 1)
    result = {"benchmark": "learning_cpu", "machine": platform.platform(), "cpu_cores": os.cpu_count(),
              "backend": jax.default_backend(), "jax_devices": jax.device_count(), "feet": args.feet,
              "preset": args.preset, "variant": args.variant,
              # what was trained (the run's last checkpoint), not the curve's last row
              "steps": json.loads((args.out / "progress.json").read_text()).get("global_step", 0)
              if (args.out / "progress.json").is_file() else 0,
              "num_envs": ppo.num_envs, "wall_s": train_s, "physics": cfg.physics}
    if not args.no_verdict:  # the final policy, deterministic, 32 robots x 20 s (footforge.rl.verdict)
        from footforge.rl.evaluate import evaluate

        r = evaluate(args.out / "policy", num_envs=32, seconds=20.0, seed=args.seed, build_dir=cfg.build_dir,
                     physics=cfg.physics)
        w = r["walking"]
        result |= {"verdict": w["verdict"], "verdict_line": w["line"], "forward_error": w["forward_error_mps"],
                   "vx_slope": w["vx_slope"], "uptime": w["uptime"], "time_up_s": round(w["uptime"] * 20.0, 2),
                   "base_height_m": w["base_height_m"], "stance_fraction": w["stance_fraction"],
                   "gait": w["gait"], "pair_agreement": w["pair_agreement"],
                   "clipped_fraction": r["clipped_fraction"], "falls": r["falls"], "eval_wall_s": round(time.time() - t0 - train_s, 1)}
    print(json.dumps(_finite_or_none(result | {"curve": curve}), allow_nan=False))  # NaN is not JSON
    return 0


def _finite_or_none(value):
    """`value` with every NaN or infinite float (a figure that could not be measured) as None."""
    import math

    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    return value


if __name__ == "__main__":
    sys.exit(main())
