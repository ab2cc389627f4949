"""`footforge train flat|rough`, also run as pipelines/train_flat.py and pipelines/train_rough.py."""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import footforge

footforge.headless_by_default()  # before any import of MuJoCo

from footforge.errors import EXIT_INPUT_ERROR, InputError  # noqa: E402

DESCRIPTIONS = {
    "flat": "Train an ANYmal C flat-ground policy with Brax PPO on MuJoCo (MJX on a GPU, its C engine on a CPU; "
    "the paper's flat task).",
    "rough": "Train an ANYmal C rough-terrain policy with Brax PPO on MuJoCo (MJX or its C engine), up a terrain "
    "curriculum (the paper's rough task).",
}
"""Each task's one-line description, the help's first line."""


def parser(prog: str | None = None, task: str = "flat", description: str | None = None) -> argparse.ArgumentParser:
    """The options of `footforge train TASK` (`description`: the help's first line, by default the task's)."""
    from footforge.cli.help import DefaultsHelpFormatter
    from footforge.envs import FEET, TASKS
    from footforge.envs.config import EnvConfig
    from footforge.rl.config import default_ppo

    # Defaults the help names are read from the configuration dataclasses (tests/test_cli.py checks them).
    env, ppo = EnvConfig(), default_ppo(task)
    p = argparse.ArgumentParser(
        prog=prog, description=description or DESCRIPTIONS[task], formatter_class=DefaultsHelpFormatter
    )
    p.set_defaults(task=task)
    from footforge.rl import presets

    p.add_argument(
        "--preset",
        choices=list(presets.PRESETS[task]),
        help=f"a named configuration of the {task} task (footforge/rl/presets.py; default "
        f"{presets.DEFAULT_PRESET}): " + presets.describe(task),
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.FIELD=VALUE",
        dest="overrides",
        help="override one setting of the preset, as config.json names it, e.g. --set ppo.entropy_cost=0.01 "
        "--set env.commands.resample_s=10 --set env.rewards.feet_air_time.scale=0 (repeatable, "
        "applied in order after the preset and the flags below)",
    )
    p.add_argument("--feet", choices=FEET, help=f"foot variant (default {env.feet})")
    p.add_argument("--policy", choices=TASKS[task], help=f"policy type (default {env.policy})")
    p.add_argument(
        "--num-envs", type=int, help=f"parallel robots (default: the preset's, from the task's {ppo.num_envs})"
    )
    p.add_argument(
        "--timesteps",
        type=int,
        help=f"environment steps in total (default: the preset's, from the task's "
        f"{ppo.num_timesteps:,}; with --resume it may extend "
        "the run, or with --shorten end it earlier)",
    )
    p.add_argument(
        "--shorten",
        action="store_true",
        help="with --resume and --timesteps: allow a total below the run's own (refused without it)",
    )
    p.add_argument("--seed", type=int, help=f"(default {ppo.seed})")
    p.add_argument("--out", type=Path, required=True, help="run folder")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out from its newest intact checkpoint, with the run's own settings "
        "(its config.json): other options may be left out, and any given must match them",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="start over in an --out that holds a run: removes only what footforge wrote there",
    )
    p.add_argument(
        "--max-minutes",
        type=float,
        help="wall-clock budget: stop at the last checkpoint that leaves no time for another epoch "
        "(for time-limited jobs; --resume continues)",
    )
    p.add_argument(
        "--unroll-length",
        type=int,
        help=f"policy steps per robot per iteration (the task's default {ppo.unroll_length})",
    )
    p.add_argument("--batch-size", type=int, help=f"trajectories per minibatch (the task's default {ppo.batch_size})")
    p.add_argument(
        "--minibatches", type=int, help=f"minibatches per iteration (the task's default {ppo.num_minibatches})"
    )
    p.add_argument(
        "--checkpoint-every",
        type=int,
        help=f"environment steps between checkpoints (the task's default {ppo.checkpoint_every_steps:,})",
    )
    p.add_argument(
        "--eval-envs",
        type=int,
        help=f"robots per evaluation (the task's default {ppo.num_eval_envs}, or --num-envs if fewer)",
    )
    p.add_argument(
        "--no-compile-cache",
        action="store_true",
        help="compile without JAX's persistent cache (footforge/rl/compile_cache.py: on a GPU on by default, "
        "in ~/.cache/footforge/jax or $FOOTFORGE_COMPILE_CACHE; on the CPU only where "
        "FOOTFORGE_COMPILE_CACHE names a folder)",
    )
    p.add_argument(
        "--no-evaluations",
        action="store_true",
        help="skip the deterministic evaluation at the start and at each checkpoint (on a GPU one "
        "costs as much time as about 20 PPO iterations); the curve then comes from the training "
        "episodes, and footforge evaluate evaluates the policy afterwards; a --resume keeps the "
        "run's choice",
    )
    p.add_argument(
        "--evaluations",
        action="store_true",
        help="with --resume of a run started with --no-evaluations: evaluate again from now on",
    )
    p.add_argument(
        "--contact-model",
        choices=["stance", "fast"],
        help="the MJX contact model (EnvConfig.contact_model) with the step and solver iterations it "
        f"needs (default: the preset's; default {env.contact_model}, cpu and forward fast): stance holds a "
        "standing robot "
        "(2.5 ms step); fast is 2-3x cheaper on the "
        "CPU but a robot at rest sinks and slides 150-180 mm in 10 s (5 ms step)",
    )
    p.add_argument(
        "--physics",
        choices=["auto", "mjx", "mujoco"],
        help="the engine that steps the robots (EnvConfig.physics): mujoco, MuJoCo's C engine "
        "(threaded, float64; several times faster on a CPU), or mjx, MuJoCo MJX in JAX (a GPU's); "
        "default auto: mujoco where JAX runs on the CPU, else mjx. A --resume may change it",
    )
    p.add_argument(
        "--mjx-impl",
        choices=["jax", "warp"],
        help=f"MJX's backend (EnvConfig.mjx_impl; default {env.mjx_impl}): warp needs MuJoCo Warp and an NVIDIA GPU",
    )
    p.add_argument(
        "--float64-physics",
        action="store_const",
        const=True,
        help="step MJX in float64 (EnvConfig.float64_physics; off: float32): AFF and AOF standing still "
        "sink and slide about a third as far, at 1.4-1.6x the cost per step on the CPU; the networks stay float32",
    )
    p.add_argument(
        "--build-root",
        type=Path,
        help="folder holding one footforge build per feet, <root>/<feet>/ (default build/), as in "
        "the evaluation pipelines",
    )
    p.add_argument("--build-dir", type=Path, help=argparse.SUPPRESS)  # deprecated: the feet's build itself
    p.add_argument(
        "--init-from",
        type=Path,
        metavar="RUN",
        help="start this new run from the newest intact checkpoint of an earlier run (its policy, "
        "value and normaliser) with this run's own settings: fine-tuning with other PPO settings, "
        "rewards or feet; the networks must match",
    )
    p.add_argument(
        "--coordinator",
        metavar="HOST:PORT",
        help="several machines (with --num-processes and --process-id): refused for now, exit 2: "
        "Brax 0.14.2's PPO does not train over several JAX processes on JAX 0.9 (docs/training.md); "
        "one machine's GPUs are all used without it",
    )
    p.add_argument("--num-processes", type=int, help="with --coordinator: refused for now")
    p.add_argument("--process-id", type=int, help="with --coordinator: refused for now")
    if task == "rough":
        p.add_argument(
            "--terrain",
            action="append",
            default=[],
            metavar="FIELD=VALUE",
            help="override a TerrainConfig field, e.g. --terrain seed=3 --terrain num_levels=5 "
            "(repeatable; footforge/envs/terrain.py lists the fields)",
        )
    return p


def main(task: str, description: str | None = None, argv: list[str] | None = None, prog: str | None = None) -> int:
    """`footforge train TASK` (and pipelines/train_TASK.py): one training run of `task`, flat or rough."""
    from footforge.cli.command import run_command

    name = f"footforge train {task}"  # messages name the command, whichever way it was started
    return run_command(sys.modules[__name__], argv, prog or name, name=name, task=task, description=description)


def main_with_task(argv: list[str], *, verbose: bool = False) -> int:
    """`footforge train TASK [options]` from the words after `train`: the task first."""
    from footforge.cli.command import run_command
    from footforge.envs import TASKS

    if not argv or argv[0] not in TASKS:
        usage = f"usage: footforge train {{{','.join(TASKS)}}} [options]   (footforge train flat --help lists them)"
        if argv and argv[0] in ("-h", "--help"):
            print(
                usage + "\n\nTrain a policy with Brax PPO on MuJoCo MJX: flat is the paper's flat-ground task, "
                "rough its terrain curriculum."
            )
            return 0
        print(usage, file=sys.stderr)
        print(
            f"footforge train: error: the first argument is the task, one of {', '.join(TASKS)}"
            + (f" (got '{argv[0]}')" if argv else ""),
            file=sys.stderr,
        )
        return EXIT_INPUT_ERROR
    task = argv[0]
    return run_command(sys.modules[__name__], argv[1:], f"footforge train {task}", verbose=verbose, task=task)


def run(args: argparse.Namespace) -> int:
    """Checks the arguments in a second, then trains (or finishes a run killed after its last checkpoint)."""
    from footforge.cli.help import console as make_console
    from footforge.rl import train

    task = args.task
    console = make_console()
    name = f"footforge train {task}"  # messages name the command, whichever way it was started
    if args.build_dir and args.build_root:
        raise InputError(
            "--build-dir is the old spelling of --build-root's <root>/<feet>: give one of them",
            fix="give --build-root",
        )
    if args.build_dir:
        print(
            f"{name}: note: --build-dir is deprecated; use --build-root (the folder holding <feet>/, "
            f"e.g. --build-root {args.build_dir.parent})",
            file=sys.stderr,
        )
    if args.resume and args.force:
        raise InputError(
            "--resume and --force exclude each other: --resume continues the run in --out, --force starts it over",
            fix="pass one of them",
        )
    if args.coordinator:
        raise InputError(
            MULTI_PROCESS_UNSUPPORTED,
            fix="train on one machine (Brax splits --num-envs over all its GPUs), or leave out --coordinator",
        )
    if args.shorten and not args.resume:
        raise InputError(
            "--shorten goes with --resume (a new run's --timesteps is its total)", fix="leave out --shorten"
        )
    if args.resume and args.init_from:
        raise InputError(
            "--init-from starts a new run from another run's parameters; --resume continues the run in --out",
            fix="pass one of them",
        )
    env_config, ppo = _resumed_configs(task, args) if args.resume else _new_configs(task, args)
    # Before anything is announced, built or compiled, in the flags' own words.
    ppo.check(
        {field: flag for flag, _, (section, field) in _SETTINGS if section == "ppo"} | {"num_timesteps": "--timesteps"}
    )
    # The run folder now, before JAX compiles (train() checks again, and writes).
    train.prepare_run_dir(args.out, resume=args.resume, force=args.force, write=False)
    from footforge.cli.builds import build_defaults_if_missing

    build_defaults_if_missing(
        [env_config.feet], Path(env_config.build_dir).parent if env_config.build_dir else None, console
    )
    from footforge.envs import enable_float64_physics
    from footforge.rl import compile_cache

    enable_float64_physics(env_config)  # before any JAX array
    from footforge.envs.anymal import check_mjx_impl

    check_mjx_impl(env_config)  # before the run folder is written and JAX compiles
    from footforge.envs import engine

    engine.check(env_config.physics)
    compile_cache.enable(not args.no_compile_cache)
    done = 0
    if args.resume:
        kept = train.latest_intact_checkpoint(args.out)
        done = kept[0] if kept else 0
        if done >= ppo.num_timesteps:
            finished = train.finish_run(args.out)  # a run killed after its last checkpoint
            if finished:
                console.print(
                    f"{args.out}: {finished[1]}: wrote {args.out / 'policy'} from checkpoint {finished[0]:,}",
                    markup=False,
                    highlight=False,
                    soft_wrap=True,
                )
            console.print(
                f"{args.out}: already complete at step {done:,} (of {ppo.num_timesteps:,}); pass "
                f"--timesteps with a larger total to extend it",
                markup=False,
                highlight=False,
                soft_wrap=True,
            )
            return 0
    evaluate = _evaluations(args, name)
    _second_stage_notice(console, task, args)
    total = train.planned_steps(ppo, done)
    _announce(console, name, env_config, ppo, done, total, args.recipe)
    with _Reporter(console, task, total) as report:
        metrics = train.train(
            env_config,
            ppo,
            args.out,
            resume=args.resume,
            force=args.force,
            progress=report,
            max_wall_s=args.max_minutes * 60 if args.max_minutes is not None else None,
            evaluate=evaluate,
            init_from=args.init_from,
            recipe=args.recipe,
        )
    if metrics.get("stopped_for_time"):
        console.print(
            f"stopped at the wall-time budget ({args.max_minutes:g} min) after a checkpoint; --resume continues"
        )
    if "eval/episode_reward" in metrics:
        console.print(
            f"policy written to {args.out / 'policy'}; final evaluation return {metrics['eval/episode_reward']:.2f}"
        )
    else:
        console.print(
            f"policy written to {args.out / 'policy'} (not evaluated: footforge evaluate --policy "
            f"{args.out / 'policy'} does)"
        )
    return 0


def interrupted(args: argparse.Namespace) -> str:
    """What an interrupted run keeps: its complete checkpoints (with their manifest; one being written is not named)."""
    from footforge.rl import train

    kept = train.latest_intact_checkpoint(args.out) if args.out.is_dir() else None
    if kept:
        return f"{args.out} keeps its checkpoints up to step {kept[0]:,}: continue with --resume"
    return "no checkpoint was written: the same command starts the run again"


CPU_STEPS_PER_S = 3000
"""About what a 2-core CPU trains (flat task, 128 robots: 2.0-3.6 k steps/s, benchmarks/RESULTS.md)."""
CPU_ROBOTS = 512
"""Above this many robots on a CPU, training says how long an iteration will take."""


def _evaluations(args, name: str) -> bool:
    """Whether this run evaluates: --no-evaluations, or on --resume the run's own choice (its
    config.json "evaluations") unless --evaluations asks again."""
    import json

    if args.evaluations and args.no_evaluations:
        raise InputError("--evaluations and --no-evaluations exclude each other", fix="pass one of them")
    if args.no_evaluations:
        return False
    if args.resume and not args.evaluations:
        try:
            saved = json.loads((args.out / "config.json").read_text()).get("evaluations", True)
        except (OSError, ValueError, AttributeError):
            saved = True
        if saved is False:
            print(
                f"{name}: the run was started with --no-evaluations and continues without them "
                f"(--evaluations turns them on)",
                file=sys.stderr,
            )
            return False
    return True


def _announce(console, name: str, env_config, ppo, done: int, total: int, recipe: dict | None = None) -> None:
    """What will train, on what, and for how many steps, before the minutes of compilation."""
    import jax

    from footforge.rl.config import steps_per_iteration

    devices = jax.devices()
    backend = jax.default_backend()
    iteration = steps_per_iteration(ppo)
    line = (
        f"{name}: {env_config.feet} feet, policy {env_config.policy}, {ppo.num_envs:,} robots on {backend} "
        f"({len(devices)} x {devices[0].device_kind}); steps {done:,} -> {total:,}"
    )
    if total != max(ppo.num_timesteps, done):
        line += (
            f" (--timesteps {ppo.num_timesteps:,} rounded up to whole PPO iterations of {iteration:,} steps: "
            f"{ppo.batch_size} x {ppo.num_minibatches} trajectories of {ppo.unroll_length} steps)"
        )
    console.print(line, markup=False, highlight=False, soft_wrap=True)
    if recipe is not None:
        console.print(
            f"{name}: preset {recipe['preset']}"
            + (f", overrides {' '.join(recipe['overrides'])}" if recipe["overrides"] else ""),
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
    from footforge.envs import engine

    console.print(
        f"{name}: physics {engine.describe(env_config.physics)}", markup=False, highlight=False, soft_wrap=True
    )
    if backend == "cpu" and ppo.num_envs > CPU_ROBOTS:
        minutes = iteration / CPU_STEPS_PER_S / 60
        console.print(
            f"{name}: warning: {ppo.num_envs:,} robots on a CPU: one iteration of {iteration:,} steps takes "
            f"about {minutes:.0f} min at a 2-core CPU's {CPU_STEPS_PER_S:,} steps/s (compilation first). "
            f"A CPU-sized run: --preset cpu",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )


# The options that set a saved setting: flag, attribute of args, (config, field) it sets.
_SETTINGS = (
    ("--feet", "feet", ("env", "feet")),
    ("--policy", "policy", ("env", "policy")),
    ("--seed", "seed", ("ppo", "seed")),
    ("--num-envs", "num_envs", ("ppo", "num_envs")),
    ("--unroll-length", "unroll_length", ("ppo", "unroll_length")),
    ("--batch-size", "batch_size", ("ppo", "batch_size")),
    ("--minibatches", "minibatches", ("ppo", "num_minibatches")),
    ("--checkpoint-every", "checkpoint_every", ("ppo", "checkpoint_every_steps")),
    ("--eval-envs", "eval_envs", ("ppo", "num_eval_envs")),
    ("--contact-model", "contact_model", ("env", "contact_model")),
    ("--float64-physics", "float64_physics", ("env", "float64_physics")),
    ("--mjx-impl", "mjx_impl", ("env", "mjx_impl")),
)


def _flag_overrides(task: str, args) -> list[str]:
    """The settings given as flags, in --set's form (applied after the preset, before --set)."""
    out = []
    for _flag, attr, (section, field) in _SETTINGS:
        value = getattr(args, attr)
        if value is None or section == "env" and field in ("feet", "policy"):
            continue
        out.append(f"{section}.{field}={str(value).lower() if isinstance(value, bool) else value}")
    if args.timesteps is not None:
        out.append(f"ppo.num_timesteps={args.timesteps}")
    if task == "rough":
        out += [f"env.terrain.{text.strip()}" for text in args.terrain]
    return out


def _second_stage_notice(console, task: str, args) -> None:
    """A new run of a second-stage preset (presets.Preset.after) without --init-from: said, not refused."""
    from footforge.rl import presets

    if args.resume or args.init_from or not args.preset:
        return
    first = presets.preset(task, args.preset).after
    if first:
        console.print(
            f"note: --preset {args.preset} is a second stage, for a policy that walks under --preset {first} "
            f"(--init-from RUN); from scratch it is untried",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )


def _recipe(task: str, args, feet: str, policy: str, preset_name: str | None = None) -> tuple[str, list[str]]:
    """(preset, overrides) the options give: the preset (--preset, else `preset_name`, else the
    default), its flags, then --set; evaluations no larger than --num-envs unless set."""
    from footforge import envs
    from footforge.rl import presets

    if task == "rough" and args.terrain:  # --terrain's own messages first (FIELD one of ...)
        _override(envs.default_config(task, feet, policy).terrain, args.terrain)
    name = args.preset or preset_name or presets.DEFAULT_PRESET
    overrides = _flag_overrides(task, args) + list(args.overrides)
    if (
        args.eval_envs is None
        and args.num_envs is not None
        and not any(o.startswith("ppo.num_eval_envs=") for o in args.overrides)
        and presets.resolve(task, feet, policy, name, overrides)[1].num_eval_envs > args.num_envs
    ):
        overrides.append(f"ppo.num_eval_envs={args.num_envs}")  # evaluations no larger than the training batch
    return name, overrides


def _new_configs(task: str, args):
    from footforge.envs import engine
    from footforge.envs.config import EnvConfig
    from footforge.rl import presets

    feet, policy = args.feet or EnvConfig.feet, args.policy or EnvConfig.policy  # the defaults --help names
    name, overrides = _recipe(task, args, feet, policy)
    env_config, ppo = presets.resolve(task, feet, policy, name, overrides)
    args.recipe = {"preset": name, "overrides": overrides}
    if args.build_root or args.build_dir:
        env_config = replace(env_config, build_dir=str(args.build_dir or args.build_root / env_config.feet))
    return replace(env_config, physics=engine.resolve(args.physics or "auto")), ppo


MULTI_PROCESS_UNSUPPORTED = (
    "--coordinator: training over several JAX processes does not work with the pinned Brax 0.14.2 and JAX "
    "0.9.2 (measured with two processes on one machine, 2026-11-26): Brax's PPO averages its metrics "
    "outside the compiled step on arrays that span every process's devices, which JAX 0.9's merged pmap "
    "refuses ('CopyArrays only supports destination device list of the same size'); with the legacy pmap "
    "(JAX_PMAP_SHMAP_MERGE=false, gone in JAX 0.10) both processes hang after the first checkpoint"
)
"""Why `--coordinator` is refused (train_flat.py / train_rough.py exit 2 before any work)."""


def _resumed_configs(task: str, args):
    """The run's saved configs (--timesteps may change the total); every other option given must
    equal the saved setting, or the error names it."""
    from footforge.envs.anymal import build_dir
    from footforge.rl import train

    env_config, ppo = train.load_run_config(args.out)
    if env_config.task != task:
        raise InputError(
            f"--out {args.out}: is a {env_config.task}-terrain run",
            fix=f"resume it with footforge train {env_config.task}",
        )
    args.recipe = None  # the run's own, kept by train()
    if args.preset or args.overrides:  # the whole configuration they resolve to must be the run's
        _same_configuration(task, args, env_config, ppo)
    saved = {"env": env_config, "ppo": ppo}
    for flag, attr, (section, field) in _SETTINGS:
        given, value = getattr(args, attr), getattr(saved[section], field)
        if given is not None and given != value:
            raise InputError(
                f"--resume: {flag} {given} differs from the run's {value} (its config.json)",
                file=str(args.out),
                fix=f"leave out {flag} to continue the run with its own, or start a new run with another --out",
            )
    if args.build_root or args.build_dir:
        flag, given = ("--build-dir", args.build_dir) if args.build_dir else ("--build-root", args.build_root)
        wanted = args.build_dir or args.build_root / env_config.feet
        if Path(wanted).resolve() != build_dir(env_config).resolve():
            raise InputError(
                f"--resume: {flag} {given} differs from the run's build {build_dir(env_config)} (its config.json)",
                file=str(args.out),
                fix=f"leave out {flag} to continue the run with its own build",
            )
    if task == "rough" and args.terrain:
        wanted = _override(env_config.terrain, args.terrain)
        for f in fields(wanted):
            if getattr(wanted, f.name) != getattr(env_config.terrain, f.name):
                raise InputError(
                    f"--resume: --terrain {f.name}={getattr(wanted, f.name)} differs from the run's "
                    f"{getattr(env_config.terrain, f.name)} (its config.json)",
                    file=str(args.out),
                    fix="leave out --terrain to continue the run with its own terrain",
                )
    if args.timesteps is not None:
        if args.timesteps < ppo.num_timesteps and not args.shorten:
            raise InputError(
                f"--resume --timesteps {args.timesteps:,} is below the run's total of "
                f"{ppo.num_timesteps:,} steps (its config.json)",
                file=str(args.out),
                fix=f"add --shorten to end the run at {args.timesteps:,}, or leave out --timesteps to "
                f"train it to {ppo.num_timesteps:,}",
            )
        ppo = replace(ppo, num_timesteps=args.timesteps)
    elif args.shorten:
        raise InputError("--shorten goes with --resume --timesteps N", fix="give the new total with --timesteps")
    from footforge.envs import engine

    return replace(env_config, physics=engine.resolve(args.physics or "auto")), ppo


def _same_configuration(task: str, args, env_config, ppo) -> None:
    """Raises InputError where --preset and --set (with the run's feet and policy type) resolve to
    another configuration than the run's config.json (its total of steps and run-time choices aside)."""
    import json

    from footforge.rl import presets
    from footforge.rl.config import config_differences, to_dict

    if any(o.split("=", 1)[0].strip() == "ppo.num_timesteps" for o in args.overrides):
        raise InputError(
            "--resume: a run's total is changed with --timesteps, not --set ppo.num_timesteps",
            fix="give --timesteps N (with --shorten to end it earlier)",
        )
    try:  # the run's own preset where --preset is left out
        recorded = presets.recipe_of(json.loads((args.out / "config.json").read_text()))
    except (OSError, ValueError):
        recorded = None
    name, overrides = _recipe(task, args, env_config.feet, env_config.policy, recorded[0] if recorded else None)
    wanted_env, wanted_ppo = presets.resolve(task, env_config.feet, env_config.policy, name, overrides)
    keep = {"physics": env_config.physics, "build_dir": env_config.build_dir}
    wanted = {
        "env": to_dict(replace(wanted_env, **keep)),
        "ppo": to_dict(replace(wanted_ppo, num_timesteps=ppo.num_timesteps)),
    }
    differences = config_differences({"env": to_dict(env_config), "ppo": to_dict(ppo)}, wanted)
    if differences:
        raise InputError(
            f"--resume: --preset {name} with these overrides is not the run's configuration "
            f"({len(differences)} difference{'s' if len(differences) > 1 else ''}): " + "; ".join(differences),
            file=str(args.out / "config.json"),
            fix="leave out --preset and --set to continue the run with its own settings",
        )


class _Reporter:
    """Training progress: a rich progress bar on a terminal; otherwise (a batch job's log) one
    plain line per evaluation, flushed, since rich draws nothing until the end there."""

    def __init__(self, console, task: str, total: int):
        self.console, self.task, self.total = console, task, total
        self.progress: Any = None  # a rich Progress on a terminal
        self.t0 = time.time()

    def __enter__(self):
        if self.console.is_terminal:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            self.progress = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                TextColumn("{task.completed:,.0f}/{task.total:,.0f} steps"),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=self.console,
            )
            self.progress.__enter__()
            self.bar = self.progress.add_task("compiling and training", total=self.total)
        else:
            self._line(f"compiling and training: {self.total:,} steps")
        return self

    def __exit__(self, *exc):
        if self.progress is not None:
            self.progress.__exit__(*exc)
        return False

    def _line(self, text: str) -> None:
        print(text, file=self.console.file, flush=True)

    def __call__(self, step: int, total: int, metrics: dict, evaluation: bool = True) -> None:
        if "eval/episode_reward" in metrics:
            reward = metrics["eval/episode_reward"]
            text = f"return {reward:7.2f}" + _figure(
                "  vx error", metrics.get("eval/episode_error/lin_vel_x_per_step"), "5.3f", " m/s"
            )
        elif _finite(metrics.get("episode/length")):  # no evaluations (--no-evaluations): the training episodes'
            text = f"training episodes: length {metrics['episode/length']:5.0f}" + _figure(
                "  vx error", metrics.get("episode/error/lin_vel_x_per_step"), "5.3f", " m/s"
            )
        else:
            text = "training: no episode has ended yet"
        if self.task == "rough":
            text += _figure("  terrain level", metrics.get("episode/terrain/level_per_step"), "4.2f")
        diverged = metrics.get("eval/episode_diverged", 0.0)
        if diverged:
            text += f"  diverged {diverged:g}"
        if self.progress is not None:
            self.progress.update(self.bar, completed=min(step, total), description=text)
        elif evaluation:
            elapsed = int(time.time() - self.t0)
            self._line(
                f"step {step:,}/{total:,} ({100 * step / total:.0f}%)  {text}  "
                f"elapsed {elapsed // 3600}:{elapsed // 60 % 60:02d}:{elapsed % 60:02d}"
            )


def _finite(value) -> bool:
    import math

    return value is not None and math.isfinite(float(value))


def _figure(label: str, value, spec: str, unit: str = "") -> str:
    """' label value unit', or nothing where the value is absent or not a number (no episode yet)."""
    return f"{label} {float(value):{spec}}{unit}" if _finite(value) else ""


def _override(config, assignments: list[str]):
    """`config` with FIELD=VALUE assignments applied, each value read as its field's type."""
    known = {f.name: getattr(config, f.name) for f in fields(config)}
    changes = {}
    for text in assignments:
        name, sep, value = text.partition("=")
        if not sep or name not in known:
            raise InputError(
                f"--terrain {text}: expected FIELD=VALUE with FIELD one of {', '.join(known)}",
                fix="e.g. --terrain num_levels=5",
            )
        default = known[name]
        try:
            if isinstance(default, tuple):
                changes[name] = tuple(float(v) for v in value.split(","))
            else:
                changes[name] = type(default)(value)
        except ValueError:
            expected = "comma-separated list of numbers" if isinstance(default, tuple) else type(default).__name__
            raise InputError(
                f"--terrain {text}: '{value}' is not a {expected}",
                fix=f"e.g. --terrain {name}={','.join(map(str, default)) if isinstance(default, tuple) else default}",
            ) from None
    config = replace(config, **changes)
    config.check()
    return config
