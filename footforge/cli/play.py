"""Watch a trained policy walk in CPU MuJoCo, run through its ONNX file.

    footforge play policies/flat_ball_B_cpu/policy                  # MuJoCo's viewer, keyboard commands
    footforge play policies/flat_ball_B_cpu/policy --feet full --terrain
    MUJOCO_GL=egl footforge play policy.onnx --headless --seconds 5 --command 0.5 0 0 --video walk.gif

POLICY is a policy/ folder of a training run (its ONNX graph is built in memory, as `footforge
export` writes it) or an .onnx file from footforge export. The viewer takes the command from the
keyboard (the key map is printed at the start); --headless runs without a display for --seconds
under a fixed --command, and writes what it saw as a GIF (--video, rendered offscreen: needs
MUJOCO_GL=egl or osmesa) and the robot's states as JSON (--log). A robot that falls is put back
at its start. Without --build-root the builds are build/<feet>, made on first use.
An existing --video or --log file is replaced only if play wrote it (or with --force).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

PROG = "footforge play"


def parser(prog: str = "footforge play") -> argparse.ArgumentParser:
    """The options of `footforge play`."""
    from footforge.cli.command import new_parser
    from footforge.rl.play import PlayConfig

    p = new_parser(prog, __doc__, docstring=True)
    p.add_argument(
        "policy",
        type=Path,
        metavar="POLICY",
        help="a training run's folder (its policy/, or without an "
        "intact one its newest intact checkpoint), a policy/ or checkpoints/<step>/ folder, or an .onnx file",
    )
    p.add_argument("--feet", help="ball, aff, aof or full (the 34-joint closed chain); default: the policy's own")
    p.add_argument(
        "--terrain",
        action="store_true",
        help="walk on terrain tiles (slopes, stairs down, obstacles) instead of flat ground",
    )
    p.add_argument(
        "--build-root", type=Path, help="folder holding one footforge build per feet, <root>/<feet>/ (default build/)"
    )
    p.add_argument("--seed", type=int, default=PlayConfig.seed, help="observation noise seed (default %(default)s)")
    p.add_argument("--headless", action="store_true", help="no viewer: run --seconds under --command")
    p.add_argument("--seconds", type=float, default=10.0, help="headless: simulated seconds (default %(default)g)")
    p.add_argument(
        "--command",
        type=float,
        nargs=3,
        default=[0.0, 0.0, 0.0],
        metavar=("VX", "VY", "YAW"),
        help="headless: forward and lateral velocity (m/s) and yaw rate (rad/s); default 0 0 0",
    )
    p.add_argument("--video", type=Path, metavar="FILE.gif", help="headless: write a GIF (25 fps, real time)")
    p.add_argument("--width", type=int, default=480, help="video width in pixels (default %(default)s)")
    p.add_argument("--height", type=int, default=270, help="video height in pixels (default %(default)s)")
    p.add_argument("--log", type=Path, metavar="FILE.json", help="headless: write the robot's states per policy step")
    p.add_argument("--force", action="store_true", help="replace --video or --log even if footforge did not write it")
    return p


def main(argv: list[str] | None = None, prog: str = "footforge play") -> int:
    """The `footforge play` command (also `python pipelines/play.py`)."""
    from footforge.cli.command import run_command

    return run_command(sys.modules[__name__], argv, prog, name=PROG)


def run(args: argparse.Namespace) -> int:
    """Plays the policy: the viewer, or headless with its summary, GIF and log; exit 0."""
    _check_arguments(args)
    return _run(args)


def interrupted(args: argparse.Namespace) -> str | None:
    """A headless run leaves no half-written video or log; Ctrl-C is one way to leave the viewer (exit 0)."""
    return "no video or log was written" if args.headless else None


def _check_arguments(args) -> None:
    """Everything that can be checked in a second, before the policy is loaded and compiled."""
    from footforge.envs import engine
    from footforge.errors import InputError
    from footforge.rl.play import FEET

    engine.check("mujoco")  # the robot steps on the C engine (FOOTFORGE_PHYSICS_THREADS)
    if not args.headless and (args.video or args.log):
        raise InputError("--video and --log are for --headless runs", fix="add --headless (and --seconds, --command)")
    if args.seconds <= 0 or args.width < 16 or args.height < 16:
        raise InputError(
            "--seconds must be positive, --width and --height at least 16 pixels",
            fix="e.g. --seconds 5 --width 480 --height 270",
        )
    if args.feet is not None and args.feet not in FEET:
        raise InputError(f"unknown feet '{args.feet}'", fix=f"use one of {', '.join(FEET)}")
    if not args.policy.exists():
        raise InputError(
            "no such policy folder or file",
            file=str(args.policy),
            fix="pass a training run's folder (or its policy/ folder), or an .onnx file from footforge export",
        )
    from footforge.cli.guard import policy_in_use

    args.policy = policy_in_use(args.policy, PROG)  # a run's folder: its policy/ (or its newest intact checkpoint)
    for flag, path, suffix in (("--video", args.video, ".gif"), ("--log", args.log, ".json")):
        if path is not None:
            _check_output(flag, path, suffix, args.force)
    if args.video:
        from footforge.rl.render import check_renderer

        check_renderer()  # before the policy's export and compilation
    if (
        not args.headless
        and sys.platform.startswith("linux")
        and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    ):
        raise InputError(
            "no display for MuJoCo's viewer (DISPLAY is not set)",
            fix="run on a machine with a display, or use --headless --video FILE.gif",
        )


def _check_output(flag: str, path: Path, suffix: str, force: bool) -> None:
    """A writable path with the right extension, not a file footforge did not write (unless forced)."""
    from footforge.errors import InputError
    from footforge.outputs import check_output_file

    if path.suffix.lower() != suffix:
        what = "an animated GIF" if suffix == ".gif" else "JSON"
        raise InputError(f"play writes {what} only", file=str(path), fix=f"give a {flag} file ending in {suffix}")
    check_output_file(path, flag)
    if path.exists() and not force and not _written_by_play(path):
        raise InputError(
            "exists and was not written by footforge play",
            file=str(path),
            fix=f"pass --force to replace it, or choose another {flag} path",
        )


def _written_by_play(path: Path) -> bool:
    """Whether `path` is a GIF whose comment, or a JSON log whose "tool", is footforge play's."""
    from footforge.rl.play import TOOL

    try:
        if path.suffix.lower() == ".gif":
            from PIL import Image

            with Image.open(path) as image:
                return image.info.get("comment", b"") == TOOL.encode()
        return json.loads(path.read_text()).get("tool") == TOOL
    except Exception:  # unreadable, not an image, not JSON, not an object: not ours
        return False


def _run(args) -> int:
    import time

    from footforge.cli.builds import build_defaults_if_missing
    from footforge.rl.play import PlayConfig, Player, check_feet, key_map_text, load_policy, play_headless
    from footforge.rl.policy_files import policy_folder, steps_in_all

    started = time.perf_counter()
    policy = load_policy(args.policy)
    feet = check_feet(policy, args.feet)
    meta = policy.metadata
    steps = meta["global_step"]
    if Path(args.policy).is_dir():  # a run's policy: its steps with those of the runs it went on from
        steps = steps_in_all(policy_folder(Path(args.policy)), steps)
    print(
        f"{PROG}: {meta['policy_type']} policy trained on {meta['feet']} ({meta['task']}, "
        f"{steps / 1e6:.1f} M steps), on {feet} feet, "
        f"{'terrain tiles' if args.terrain else 'flat ground'}, "
        f"stepped by MuJoCo's C engine"
    )
    build_defaults_if_missing([meta["feet"], feet], args.build_root)
    player = Player(policy, PlayConfig(feet=feet, terrain=args.terrain, build_root=args.build_root, seed=args.seed))
    if args.headless:
        player.warm_up()  # the viewer warms up itself, before its window opens
    setup = time.perf_counter() - started
    if not args.headless:
        from footforge.rl.play import play_interactive

        print(f"{PROG}: keys (in the viewer window; commands are kept within the training ranges):\n{key_map_text()}")
        play_interactive(player)
        return 0
    result = play_headless(player, seconds=args.seconds, command=args.command)
    qpos = result.pop("qpos")
    states = result["states"]
    heights = states["base_height_m"]
    print(
        f"{PROG}: {result['steps']} policy steps ({args.seconds:g} s, {result['physics_steps_per_policy_step']} "
        f"physics steps each) under command {result['command']}: base height {min(heights):.3f} to "
        f"{max(heights):.3f} m, mean vx {sum(states['vx']) / len(heights):+.3f} m/s, falls {result['falls']}"
    )
    print(f"{PROG}: verdict: {result['walking']['line']}")
    print(
        f"{PROG}: setup {setup:.1f} s (export, build, compilation), run {result['wall_s']:.1f} s "
        f"(real-time factor {result['real_time_factor']:.2f})"
    )
    from footforge.atomic import atomic_file
    from footforge.rl.play import TOOL

    if args.video:
        from footforge.rl.render import render_frames, write_gif

        t0 = time.perf_counter()
        every = max(1, int(round(0.04 / result["policy_dt_s"])))  # 25 frames per simulated second
        frames = render_frames(player.model, qpos, width=args.width, height=args.height, every=every)
        write_gif(frames, args.video, fps=1.0 / (every * result["policy_dt_s"]), comment=TOOL)
        print(f"{PROG}: {len(frames)} frames written to {args.video} in {time.perf_counter() - t0:.1f} s")
    if args.log:
        log = {
            "tool": TOOL,
            "policy": str(args.policy),
            "policy_type": meta["policy_type"],
            "trained_on": meta["feet"],
            "feet": feet,
            "terrain": args.terrain,
            "seconds": args.seconds,
            "seed": args.seed,
        } | result
        with atomic_file(args.log) as tmp:
            tmp.write_text(json.dumps(log, indent=1))
        print(f"{PROG}: states written to {args.log}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
