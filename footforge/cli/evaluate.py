"""Evaluate trained policies as the paper does (its indices, mean and std over all policy steps).

    footforge evaluate --policy runs/flat_aof_B/policy --feet aof
    footforge evaluate --policy runs/flat_ball_B/policy runs/flat_aff_B/policy --feet aff  # zero-shot
    footforge evaluate --policy runs/rough_ball_P/policy --feet ball aff aof  # Figure 9's zero-shot

Writes <out>/metrics.json, comparison.md (one row per policy and feet, like the paper's Figure 8),
policy_card.md (one page per policy: its training, its indices, links to its plots; with several
policies policy_card_<k>.md, k the policy's place in --policy),
comparison.png, contacts_<i>.png (feet contact schedule) and push_response_<i>.png; with
--video SECONDS also video_<i>.gif (one robot, 25 fps) and strip_<i>.png (six of its frames),
which need an OpenGL backend: MUJOCO_GL=egl or osmesa.

Rough-terrain policies are evaluated for 17.5 s (flat: 60 s) on the terrain they trained on, robots
spread over every tile; comparison.md then adds a table per terrain kind (like the paper's
Figure 9: forward error, robots that crossed their tile, robots that fell) and metrics.json each kind's and
level's indices, falls and crossings (a robot crosses when it gets half a tile from its start while up, the
curriculum's promotion distance). Their --video adds a robot walking
straight across the middle level's stairs and stepping stones: strip_<i>_stairs_up.png,
strip_<i>_stepping_stones.png (and their GIFs).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def parser(prog: str = "footforge evaluate") -> argparse.ArgumentParser:
    """The options of `footforge evaluate`."""
    from footforge.cli.command import add_output_folder, new_parser
    from footforge.envs import FEET

    p = new_parser(prog, __doc__, docstring=True)
    p.add_argument(
        "--policy",
        type=Path,
        nargs="+",
        required=True,
        help="training runs' folders (each its policy/, or without an intact one its newest intact "
        "checkpoint), policy/ folders, or checkpoints/<step>/ folders",
    )
    p.add_argument("--feet", nargs="+", choices=FEET, help="feet to evaluate on (default: each policy's own)")
    p.add_argument("--num-envs", type=int, default=1024, help="robots evaluated at once, each for --seconds")
    p.add_argument("--seconds", type=float, help="simulated time (default 60 s flat, 17.5 s rough)")
    p.add_argument("--seed", type=int, default=0, help="seed of the commands, pushes, noise and spawn points")
    p.add_argument(
        "--physics",
        choices=["auto", "mjx", "mujoco"],
        default="auto",
        help="the engine (EnvConfig.physics): auto is MuJoCo's C engine on a CPU, MJX on a GPU",
    )
    p.add_argument(
        "--build-root", type=Path, help="folder holding one footforge build per feet, <root>/<feet>/ (default build/)"
    )
    p.add_argument(
        "--video",
        type=float,
        metavar="SECONDS",
        help="also record one robot this long: video_<i>.gif and strip_<i>.png (needs MUJOCO_GL)",
    )
    add_output_folder(p, Path("evaluation"), "output folder (default evaluation/)")
    p.add_argument(
        "--no-compile-cache",
        action="store_true",
        help="compile without JAX's persistent cache (on by default on a GPU; on the CPU only where "
        "FOOTFORGE_COMPILE_CACHE names a folder: footforge/rl/compile_cache.py)",
    )
    return p


def main(argv: list[str] | None = None, prog: str = "footforge evaluate") -> int:
    """The `footforge evaluate` command (also `python pipelines/evaluate.py`)."""
    from footforge.cli.command import run_command

    return run_command(sys.modules[__name__], argv, prog, name="footforge evaluate")


def run(args: argparse.Namespace) -> int:
    """Evaluates each policy on each feet and writes the folder; exit 0."""
    from footforge.errors import InputError

    if (
        args.num_envs < 1
        or (args.seconds is not None and args.seconds <= 0)
        or (args.video is not None and args.video <= 0)
    ):
        raise InputError("--num-envs, --seconds and --video must be positive", fix="e.g. --num-envs 32 --seconds 20")
    from footforge.rl import compile_cache

    compile_cache.enable(not args.no_compile_cache)
    return _run(args)


def _run(args) -> int:
    from footforge.atomic import atomic_directory
    from footforge.cli.builds import build_defaults_if_missing
    from footforge.cli.guard import policy_in_use
    from footforge.outputs import check_output_folder
    from footforge.rl.evaluate import comparison_markdown, evaluate, plot, record, terrain_markdown
    from footforge.rl.policy_card import card_name, policy_card
    from footforge.rl.policy_files import load_policy_config

    check_output_folder(args.out, force=args.force)  # before minutes of evaluation
    from footforge.envs import engine

    engine.check(engine.resolve(args.physics))
    args.policy = [policy_in_use(policy, "footforge evaluate") for policy in args.policy]
    if args.video:
        from footforge.rl.render import check_renderer, render_frames, write_gif, write_strip

        check_renderer()  # before minutes of evaluation
    trained_on = [load_policy_config(policy).feet for policy in args.policy]  # each a policy folder
    build_defaults_if_missing(args.feet or trained_on, args.build_root)
    results, recordings, cards = [], [], []
    for policy in args.policy:
        for feet in args.feet or [None]:
            feet = feet or load_policy_config(policy).feet
            build_dir = str(args.build_root / feet) if args.build_root else None
            # evaluate() is one compiled rollout: say what runs before its minutes, and what came out.
            started = time.perf_counter()
            print(
                f"footforge evaluate: {policy} on {feet}: {args.num_envs:,} robots"
                + (f" x {args.seconds:g} s" if args.seconds else "")
                + " (compiling, then simulating) ...",
                file=sys.stderr,
                flush=True,
            )
            results.append(
                evaluate(
                    policy,
                    feet=feet,
                    num_envs=args.num_envs,
                    seconds=args.seconds,
                    seed=args.seed,
                    build_dir=build_dir,
                    physics=args.physics,
                )
            )
            print(
                f"footforge evaluate: {policy} on {feet}: done in {time.perf_counter() - started:.0f} s, "
                f"{results[-1]['falls']} of {args.num_envs:,} fell",
                file=sys.stderr,
                flush=True,
            )
            if results[-1].get("kinds_not_covered"):
                covered, missed = results[-1]["kinds_covered"], results[-1]["kinds_not_covered"]
                print(
                    f"footforge evaluate: warning: {args.num_envs} robots cover {len(covered)} of "
                    f"{len(covered) + len(missed)} "
                    f"terrain kinds; not measured: {', '.join(missed)} (give --num-envs {len(covered) + len(missed)} "
                    f"or more)",
                    file=sys.stderr,
                )
            if results[-1]["diverged"]:
                print(
                    f"footforge evaluate: warning: {policy} on {feet}: the simulation of {results[-1]['diverged']} of "
                    f"{args.num_envs} robots diverged (counted among the falls)",
                    file=sys.stderr,
                )
            if args.video:
                i = len(results) - 1
                kinds = [None] + (["stairs_up", "stepping_stones"] if results[i]["task"] == "rough" else [])
                for kind in kinds:
                    suffix = f"{i}_{kind}" if kind else f"{i}"
                    recordings.append(
                        (
                            suffix,
                            results[i]["policy_dt_s"],
                            *record(
                                policy,
                                feet=feet,
                                seconds=args.video,
                                seed=args.seed,
                                build_dir=build_dir,
                                kind=kind,
                                physics=args.physics,
                            ),
                        )
                    )
    with atomic_directory(args.out, force=args.force) as tmp:
        files = plot(results, tmp)
        for suffix, policy_dt_s, model, qpos in recordings:
            frames = render_frames(model, qpos, every=2)  # real time at half the policy rate: 25 fps
            write_gif(frames, tmp / f"video_{suffix}.gif", fps=0.5 / policy_dt_s)
            write_strip(frames, tmp / f"strip_{suffix}.png")
            files += [f"video_{suffix}.gif", f"strip_{suffix}.png"]
        (tmp / "comparison.md").write_text(comparison_markdown(results) + "\n" + terrain_markdown(results))
        for k, policy in enumerate(args.policy):  # one card per policy, linking its own plots
            card = card_name(k, len(args.policy))
            (tmp / card).write_text(
                policy_card(policy, [(i, r) for i, r in enumerate(results) if r["policy"] == str(policy)], files)
            )
            cards.append(card)
        (tmp / "metrics.json").write_text(
            json.dumps([{k: v for k, v in r.items() if k != "traces"} for r in results], indent=2)
        )
    print((args.out / "comparison.md").read_text())
    print(f"written to {args.out}: metrics.json, comparison.md, " + ", ".join(cards + files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
