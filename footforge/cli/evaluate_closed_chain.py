"""Run trained policies on the 34-joint closed-chain feet (CPU MuJoCo) beside the feet they were trained on.

    footforge evaluate-closed-chain --policy runs/flat_aof_B/policy
    footforge evaluate-closed-chain --policy runs/flat_ball_B/policy runs/flat_aof_B/policy \\
        --seconds 20 --robots 8 --terrain --out closed_chain_eval

Any policy type: haptic ones (BH, PH) read the closed chain's passive joints as estimated from the
foot's IMUs. The closed chain steps at its own 0.25 ms (80 physics
steps per policy step), its robots on every thread (FOOTFORGE_PHYSICS_THREADS): about 0.3 simulated
seconds per second per thread, so 8 robots x 20 s take 4-5 minutes on 2 cores: keep --robots small.
Without --build-root the builds are build/<feet> (build/full for the closed chain), made on first use.
Writes <out>/metrics.json, closed_chain.md (tracking errors, falls, closure drift and real-time
factor per policy and feet) and closed_chain_<i>.png (forward velocity against the command on
both feet, closure drift over time), all at once.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def parser(prog: str = "footforge evaluate-closed-chain") -> argparse.ArgumentParser:
    """The options of `footforge evaluate-closed-chain`."""
    from footforge.cli.command import add_output_folder, new_parser

    p = new_parser(prog, __doc__, docstring=True)
    p.add_argument(
        "--policy",
        type=Path,
        nargs="+",
        required=True,
        help="training runs' folders (each its policy/, or without an intact one its newest intact "
        "checkpoint), policy/ folders, or checkpoints/<step>/ folders",
    )
    p.add_argument("--seconds", type=float, default=10.0, help="simulated time per robot (default %(default)g)")
    p.add_argument("--robots", type=int, default=4, help="robots per feet (default %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the commands and observation noise")
    p.add_argument(
        "--terrain",
        action="store_true",
        help="walk on a few terrain tiles (slopes, stairs, obstacles) instead of flat ground",
    )
    p.add_argument(
        "--build-root", type=Path, help="folder holding one footforge build per feet, <root>/<feet>/ (default build/)"
    )
    add_output_folder(p, Path("closed_chain_evaluation"), "output folder (default closed_chain_evaluation/)")
    return p


def main(argv: list[str] | None = None, prog: str = "footforge evaluate-closed-chain") -> int:
    """The `footforge evaluate-closed-chain` command (also `python pipelines/evaluate_closed_chain.py`)."""
    from footforge.cli.command import run_command

    return run_command(sys.modules[__name__], argv, prog, name="footforge evaluate-closed-chain")


def run(args: argparse.Namespace) -> int:
    """Runs each policy on the closed chain and writes the folder; exit 0."""
    from footforge.atomic import atomic_directory
    from footforge.cli.builds import build_defaults_if_missing
    from footforge.cli.guard import policy_in_use
    from footforge.cli.help import console as make_console, counted_progress
    from footforge.envs import engine
    from footforge.outputs import check_output_folder
    from footforge.rl.evaluate_closed_chain import TERRAIN_TILES, comparison_markdown, evaluate_closed_chain, plot
    from footforge.rl.policy_files import load_policy_config

    console = make_console()
    engine.check("mujoco")  # its robots step on the C engine's threads (FOOTFORGE_PHYSICS_THREADS)
    check_output_folder(args.out, force=args.force)  # before minutes of simulation
    args.policy = [policy_in_use(policy, "footforge evaluate-closed-chain") for policy in args.policy]
    trained_on = [load_policy_config(policy).feet for policy in args.policy]  # each a policy folder
    build_defaults_if_missing([*trained_on, "full"], args.build_root, console)
    results = []
    with counted_progress(console) as progress:
        for policy in args.policy:
            tasks: dict = {}

            def report(feet, done, total, policy=policy, tasks=tasks):
                if feet not in tasks:
                    tasks[feet] = progress.add_task(f"{policy.parent.name or policy} on {feet}", total=total)
                progress.update(tasks[feet], completed=done)

            results.append(
                evaluate_closed_chain(
                    policy,
                    seconds=args.seconds,
                    num_robots=args.robots,
                    seed=args.seed,
                    build_root=args.build_root,
                    terrain_tiles=TERRAIN_TILES if args.terrain else None,
                    progress=report,
                )
            )
    with atomic_directory(args.out, force=args.force) as tmp:
        files = []
        for i, r in enumerate(results):
            plot(r, tmp / f"closed_chain_{i}.png")
            files.append(f"closed_chain_{i}.png")
        (tmp / "closed_chain.md").write_text(comparison_markdown(results))
        (tmp / "metrics.json").write_text(
            json.dumps(
                [
                    r | {"feet": {f: {k: v for k, v in c.items() if k != "traces"} for f, c in r["feet"].items()}}
                    for r in results
                ],
                indent=2,
            )
        )
    print((args.out / "closed_chain.md").read_text())
    print(f"written to {args.out}: metrics.json, closed_chain.md, " + ", ".join(files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
