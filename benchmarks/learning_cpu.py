"""Does PPO learn to walk? One flat-ground training of a footforge preset with a variant of its
settings (an ablation), on whatever JAX device is present, then the final policy's walking verdict.

A thin benchmark over `footforge train`'s configurations (footforge/rl/presets.py): --preset is
this benchmark's `full` (default) or `forward`, kept as they were so that recorded commands mean
what they meant (LEGACY_PRESETS: footforge presets with overrides), or footforge's flat `default`,
`cpu` (128 robots x 24 steps, the `fast` contact, commands vx U(-1, 1), vy U(-0.5, 0.5) m/s, no
feet-air-time term, entropy 0.001) or `paper`.
The variant's tokens, joined by '+', are shorthands for overrides applied after the
preset, each an absolute setting, and --set gives any other (`--set ppo.learning_rate=3e-4`); the
run's config.json records the whole recipe. The H100 ablations of 2026-11-26 ran before the
defaults changed: their `position+fast` is today's `position+paper_ppo+paper_rewards+fast`.

Tokens (TOKENS below gives each one's overrides):
- today:    nothing (the preset as it stands);
- position: position actions, target = default + 0.5 a (OmniIsaacGymEnvs' AnymalTerrain, legged_gym,
            Playground), PD targets not observed (they are a function of the last action);
- velocity: velocity actions, target += 13.5 a dt, PD targets observed (OmniIsaacGymEnvs' Anymal);
- ppo:      rsl_rl's settings as legged_gym uses them (learning rate 1e-3 with the adaptive-KL
            schedule at KL 0.01, entropy 0.01) and the policy's output layer initialised at 0.01x;
- paper_ppo: the paper's baseline's (3e-4, KL 0.008, entropy 0.001, output layer as Brax makes it);
- bound:    the policy mean bounded to +-1.5 (Brax's softsign mean_clip_scale);
- rewards:  tracking lin_vel_xy 2, yaw_rate 1 and base height -2 (envs.FLAT_TUNED_REWARDS);
- paper_rewards: the baseline's tracking 1 and 0.5 and base height -10;
- noclip:   the summed reward not clipped at zero;
- airtime:  legged_gym's feet-air-time term at its scale 1.0;
- stance / fast: the contact model (EnvConfig.contact_model) with its own physics step;
- airtime=X: the feet-air-time scale X (airtime=0: off);
- entropy=X: PPO's entropy cost alone (e.g. entropy=0.001);
- height=X: the base-height penalty's weight alone (height=10: scale -10);
- resample=X: a new command every X > 0 seconds (CommandConfig.resample_s).

Prints one line per evaluation and per training-episode log (steps, wall s, episode length,
forward error, base height), then one JSON line: steps trained (the run's last checkpoint),
wall_s, the recipe, and the final policy's walking verdict (deterministic, 32 robots x 20 s:
footforge.rl.verdict; verdict, forward_error, vx_slope, uptime (the share of robot-time up) and
time_up_s, base_height_m, stance_fraction per foot, gait, clipped_fraction), then the curve. A
figure that could not be measured is null.

    python benchmarks/learning_cpu.py --out /tmp/l --feet aof --preset cpu --max-minutes 60
    python benchmarks/learning_cpu.py --out /tmp/l --timesteps 12000000 --resume   # goes on
    python benchmarks/learning_cpu.py --out /tmp/m --variant entropy=0.0005 --init-from /tmp/l  # fine-tunes
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

_LEGACY_SIZE = (
    "ppo.num_envs=128",
    "ppo.unroll_length=24",
    "ppo.batch_size=64",
    "ppo.num_minibatches=4",
    "ppo.num_eval_envs=64",
    "ppo.checkpoint_every_steps=500000",
    "ppo.num_timesteps=5000000",
)
LEGACY_PRESETS = {
    "full": ("default", _LEGACY_SIZE + ("env.commands.lin_vel_x_range=-1,1", "env.commands.lin_vel_y_range=-0.5,0.5")),
    "forward": ("forward", ("env.contact_model=stance",) + _LEGACY_SIZE),
}
"""This benchmark's own presets from before footforge's, as (footforge preset, overrides), so that
the commands recorded in RESULTS.md mean what they meant: `full`, the task's defaults with commands
vx U(-1, 1), vy U(-0.5, 0.5) m/s; `forward`, one command 0.6 m/s ahead, no pushes, the `stance`
contact unless the variant names another; both 128 robots x 24 steps, batch 64 x 4, a checkpoint
every 500,000 steps, 5 M steps."""

TOKENS = {
    "today": (),
    "position": ("env.action=position", "env.action_scale=0.5", "env.observations.pd_targets=false"),
    "velocity": ("env.action=velocity", "env.action_scale=13.5", "env.observations.pd_targets=true"),
    "ppo": (
        "ppo.learning_rate=0.001",
        "ppo.adaptive_kl=0.01",
        "ppo.entropy_cost=0.01",
        "ppo.policy_output_init_scale=0.01",
    ),
    "paper_ppo": (
        "ppo.learning_rate=0.0003",
        "ppo.adaptive_kl=0.008",
        "ppo.entropy_cost=0.001",
        "ppo.policy_output_init_scale=1.0",
    ),
    "bound": ("ppo.policy_mean_clip=1.5",),
    "rewards": (
        "env.rewards.lin_vel_xy.scale=2.0",
        "env.rewards.yaw_rate.scale=1.0",
        "env.rewards.base_height.scale=-2.0",
    ),
    "paper_rewards": (
        "env.rewards.lin_vel_xy.scale=1.0",
        "env.rewards.yaw_rate.scale=0.5",
        "env.rewards.base_height.scale=-10.0",
    ),
    "noclip": ("env.rewards.clip_total_at_zero=false",),
    "airtime": ("env.rewards.feet_air_time.scale=1.0",),
    "stance": ("env.contact_model=stance",),
    "fast": ("env.contact_model=fast",),
}
"""Each variant token's overrides (footforge.rl.presets' form)."""
VALUED = {
    "airtime": lambda x: f"env.rewards.feet_air_time.scale={x}",
    "entropy": lambda x: f"ppo.entropy_cost={x}",
    "height": lambda x: f"env.rewards.base_height.scale={-x}",
    "resample": lambda x: f"env.commands.resample_s={x}",
}
"""NAME=X tokens: the override of X (X >= 0; X > 0 for resample)."""


def _valued_token(token: str) -> bool:
    """A NAME=X token (airtime=X, entropy=X, ...) with a number for X: X >= 0, and X > 0 for resample."""
    name, _, value = token.partition("=")
    try:
        return name in VALUED and (float(value) > 0 if name == "resample" else float(value) >= 0)
    except ValueError:
        return False


def variant_overrides(variant: str) -> list[str]:
    """The overrides of a '+'-joined variant, in order."""
    out = []
    for token in variant.split("+"):
        name, _, value = token.partition("=")
        out += [VALUED[name](float(value))] if value and name in VALUED else list(TOKENS[token])
    return out


def configure(feet: str, preset: str, variant: str, flags: list[str], sets: list[str] = ()):
    """(EnvConfig, PPOConfig, recipe) of a preset, this benchmark's flags (as overrides), a variant
    and --set overrides, in that order; recipe = {"preset", "overrides"} as config.json records it."""
    from footforge.rl import presets

    name, base = LEGACY_PRESETS.get(preset, (preset, ()))
    overrides = list(base) + list(flags) + variant_overrides(variant) + list(sets)
    env, ppo = presets.resolve("flat", feet, "B", name, overrides)
    return env, ppo, {"preset": name, "overrides": overrides}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))  # the first paragraph, whole
    p.add_argument("--out", type=Path, required=True, help="run folder (a new one, or the run to --resume)")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out from its newest checkpoint "
        "(parameters only: Brax restarts Adam and the adaptive learning rate)",
    )
    p.add_argument("--feet", default="ball", choices=FEET)
    from footforge.rl.presets import PRESETS

    p.add_argument(
        "--preset",
        default="full",
        choices=sorted(set(PRESETS["flat"]) | set(LEGACY_PRESETS)),
        help="this benchmark's full or forward (LEGACY_PRESETS; default full), or footforge's flat "
        "preset default, cpu or paper",
    )
    p.add_argument(
        "--variant",
        default="today",
        help=f"'+'-joined tokens among {', '.join(TOKENS)}, {', '.join(f'{k}=X' for k in VALUED)} (default today)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        dest="overrides",
        metavar="SECTION.FIELD=VALUE",
        help="any other override, after the variant (footforge train's --set)",
    )
    p.add_argument("--timesteps", type=int, help="(default: the preset's; full and forward: 5,000,000)")
    p.add_argument("--num-envs", type=int, help="(default: the preset's, 128 for cpu)")
    p.add_argument("--unroll-length", type=int)
    p.add_argument("--batch-size", type=int, help="trajectories per minibatch (default: the preset's)")
    p.add_argument("--minibatches", type=int)
    p.add_argument(
        "--eval-every", type=int, help="env steps between checkpoints (and evaluations; default: the preset's)"
    )
    p.add_argument("--eval-envs", type=int)
    p.add_argument(
        "--no-evaluations",
        action="store_true",
        help="no deterministic evaluations (the curve is the training episodes'; on a GPU one costs "
        "about 20 PPO iterations)",
    )
    p.add_argument("--seed", type=int, help="(default: the preset's, 0)")
    p.add_argument(
        "--physics",
        default="auto",
        choices=["auto", "mjx", "mujoco"],
        help="the engine (EnvConfig.physics; auto: MuJoCo's C engine on a CPU, MJX elsewhere); "
        "the verdict's evaluation uses the same",
    )
    p.add_argument(
        "--max-minutes", type=float, help="stop at the checkpoint before this wall time (train's max_wall_s)"
    )
    p.add_argument(
        "--init-from",
        type=Path,
        metavar="RUN",
        help="a new run starting from RUN's newest checkpoint (train's init_from), with this "
        "command's --variant settings: fine-tuning",
    )
    p.add_argument("--build-dir", type=Path, help="footforge build of the feet (default build/<feet>)")
    p.add_argument(
        "--no-verdict",
        action="store_true",
        help="skip the final policy's walking verdict (pipelines/evaluate.py measures it later)",
    )
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

    flags = [
        f"ppo.{field}={value}"
        for field, value in (
            ("num_timesteps", args.timesteps),
            ("num_envs", args.num_envs),
            ("unroll_length", args.unroll_length),
            # As before presets: half the robots per minibatch where --num-envs is given alone.
            (
                "batch_size",
                args.batch_size if args.batch_size is not None or args.num_envs is None else args.num_envs // 2,
            ),
            ("num_minibatches", args.minibatches),
            ("checkpoint_every_steps", args.eval_every),
            ("num_eval_envs", args.eval_envs),
            ("seed", args.seed),
        )
        if value is not None
    ]
    from footforge.errors import InputError

    try:
        cfg, ppo, recipe = configure(args.feet, args.preset, args.variant, flags, args.overrides)
        ppo.check()
    except InputError as e:
        p.error(str(e))
    if args.resume:  # the run's own settings; --feet, --preset, --variant and --set are not read
        cfg, saved = train.load_run_config(args.out)
        ppo = replace(saved, num_timesteps=args.timesteps or saved.num_timesteps)
        args.feet, args.preset, args.variant, recipe = cfg.feet, "(the run's)", "(the run's)", None
    if args.build_dir:  # where the feet are built is this machine's, not the run's
        cfg = replace(cfg, build_dir=str(args.build_dir))
    from footforge.envs import engine

    cfg = replace(cfg, physics=engine.resolve(args.physics))
    t0 = time.time()
    print(
        f"{args.feet} {args.preset} {args.variant} on {jax.default_backend()} ({jax.device_count()} device(s))",
        flush=True,
    )
    print("env steps | wall s | episode length (policy steps) | forward error m/s | base height m | source", flush=True)

    printed = set()

    def progress(step, total, metrics, evaluation):
        if "eval/episode_reward" in metrics and evaluation:
            src, length = "eval", metrics["eval/avg_episode_length"]
            err, height = (
                metrics["eval/episode_error/lin_vel_x_per_step"],
                metrics.get("eval/episode_base_height_m_per_step", float("nan")),
            )
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

    train.train(
        cfg,
        ppo,
        args.out,
        progress=progress,
        resume=args.resume,
        evaluate=not args.no_evaluations,
        max_wall_s=args.max_minutes * 60 if args.max_minutes else None,
        init_from=args.init_from,
        recipe=recipe,
    )
    curve = []
    for e in map(json.loads, (args.out / "metrics.jsonl").read_text().splitlines()):
        key = "eval/" if "eval/episode_reward" in e else "episode/" if "episode/length" in e else None
        if key is None:
            continue
        curve.append(
            {
                "env_steps": e["global_step"],
                "wall_s": round(e["wall_s"], 1),
                "source": key[:-1],
                "episode_length": e.get("eval/avg_episode_length", e.get("episode/length")),
                "forward_error_mps": e.get(
                    f"{key}episode_error/lin_vel_x_per_step" if key == "eval/" else "episode/error/lin_vel_x_per_step"
                ),
                "base_height_m": e.get(
                    f"{key}episode_base_height_m_per_step" if key == "eval/" else "episode/base_height_m_per_step"
                ),
            }
        )
    train_s = round(time.time() - t0, 1)
    result = {
        "benchmark": "learning_cpu",
        "machine": platform.platform(),
        "cpu_cores": os.cpu_count(),
        "backend": jax.default_backend(),
        "jax_devices": jax.device_count(),
        "feet": args.feet,
        "preset": args.preset,
        "variant": args.variant,
        "recipe": json.loads((args.out / "config.json").read_text()).get("recipe"),
        # what was trained (the run's last checkpoint), not the curve's last row
        "steps": json.loads((args.out / "progress.json").read_text()).get("global_step", 0)
        if (args.out / "progress.json").is_file()
        else 0,
        "num_envs": ppo.num_envs,
        "wall_s": train_s,
        "physics": cfg.physics,
    }
    if not args.no_verdict:  # the final policy, deterministic, 32 robots x 20 s (footforge.rl.verdict)
        from footforge.rl.evaluate import evaluate

        r = evaluate(
            args.out / "policy", num_envs=32, seconds=20.0, seed=ppo.seed, build_dir=cfg.build_dir, physics=cfg.physics
        )
        w = r["walking"]
        result |= {
            "verdict": w["verdict"],
            "verdict_line": w["line"],
            "forward_error": w["forward_error_mps"],
            "vx_slope": w["vx_slope"],
            "uptime": w["uptime"],
            "time_up_s": round(w["uptime"] * 20.0, 2),
            "base_height_m": w["base_height_m"],
            "stance_fraction": w["stance_fraction"],
            "gait": w["gait"],
            "pair_agreement": w["pair_agreement"],
            "clipped_fraction": r["clipped_fraction"],
            "falls": r["falls"],
            "eval_wall_s": round(time.time() - t0 - train_s, 1),
        }
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
