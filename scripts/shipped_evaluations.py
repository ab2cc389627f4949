"""Regenerates every shipped policy's recorded evaluation and the tables that quote it, in one command.

For each `policies/<name>/` with a `policy/`: `footforge evaluate` on its own feet and zero-shot on
the others (32 robots x 20 s, seed 0, the deterministic policy; with MUJOCO_GL set, a 3-s video per
feet) into `policies/<name>/evaluation/` (policy card, metrics, plots), then lightened as the repository
keeps it: the video on the policy's own feet alone, shrunk to at most 200 KB (footforge.rl.render's
shrink_gif), no frame strips (light()); then the table of
shipped policies between the `<!-- shipped-policies -->` markers of README.md and policies/README.md,
written from those metrics (footforge/rl/verdict.py's verdict, falls, base height, each foot's share
of the ground) and the policies' footforge.json (steps, wall time, machine).

    MUJOCO_GL=egl python scripts/shipped_evaluations.py              # every shipped policy
    python scripts/shipped_evaluations.py --policies flat_aof_B --no-video
    python scripts/shipped_evaluations.py --tables-only              # the tables from the committed metrics
    python scripts/shipped_evaluations.py --closed-chain             # also closed_chain/ and the play caption
    MUJOCO_GL=osmesa python scripts/shipped_evaluations.py --rough --policies rough_ball_P   # a rough one

With --rough, the finished rough policies instead: 1,024 robots x 17.5 s over every tile of their terrain
(the paper's rough evaluation; about 3.5 minutes per feet on 2 cores), on their own feet and, unless haptic,
zero-shot on the others (the ball baseline on AFF and AOF: the paper's Figure 9), keeping one GIF, the robot
on its own feet crossing the middle level's stairs (KEPT_VIDEO); no table is written for them.

With --closed-chain, each policy that has a `closed_chain/` record is evaluated again on the 34-joint
closed chain (`footforge evaluate-closed-chain`, 8 robots x 20 s, about 4 minutes each) and the
README's caption of the AOF policy playing on the closed chain (between `<!-- closed-chain-play -->`
markers) is measured again with `footforge play`'s own headless run.

The same policy, machine, seed and robot count give the same JSON (tests/test_shipped_policies.py); on
another machine the falls of 32 robots move by a few (docs/policies.md).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path

from footforge.rl.config import steps_before
from footforge.variants import HAPTIC

REPO = Path(__file__).resolve().parents[1]
POLICIES = REPO / "policies"
TABLES = (REPO / "README.md", POLICIES / "README.md")
START, END = "<!-- shipped-policies:start -->", "<!-- shipped-policies:end -->"
FEET_ORDER = ("ball", "aff", "aof")
FEET_NAMES = {"ball": "ball", "aff": "AFF", "aof": "AOF"}


def shipped(task: str = "flat") -> list[Path]:
    """The shipped policies' run folders of `task` (those with a policy/ whose config.json is that task), by
    name. The tables are of the flat ones; a finished rough policy keeps its rough evaluation over the terrain's
    tiles (--rough, policies/README.md)."""
    return sorted(
        p.parent
        for p in POLICIES.glob("*/policy")
        if p.is_dir() and json.loads((p.parent / "config.json").read_text())["env"]["task"] == task
    )


EVALUATION = {"flat": ("32", "20"), "rough": ("1024", "17.5")}
"""Robots and seconds of a shipped policy's recorded evaluation, per task: flat 32 x 20 s; rough the paper's
1,024 x 17.5 s, robots spread over every tile (about 17 per kind and level)."""
KEPT_VIDEO = {"flat": "video_0.gif", "rough": "video_0_stairs_up.gif"}
"""The one GIF an evaluation keeps, on the policy's own feet: flat, the robot walking its commands; rough, the
robot crossing the middle level's stairs (footforge evaluate --video on the rough task)."""


def evaluate(run: Path, video: bool, task: str = "flat") -> int:
    """`footforge evaluate` of one shipped policy on its feet and the others, into its evaluation/,
    then lightened as the repository keeps it (light())."""
    from footforge.cli.evaluate import main as evaluate_main

    meta = json.loads((run / "policy" / "footforge.json").read_text())
    own = meta["env"]["feet"]
    feet = [own] if _haptic(meta) else [own] + [f for f in FEET_ORDER if f != own]
    robots, seconds = EVALUATION[task]
    argv = [
        "--policy",
        str(run.relative_to(REPO)),
        "--feet",
        *feet,
        "--num-envs",
        robots,
        "--seconds",
        seconds,
        "--seed",
        "0",
        "--out",
        str((run / "evaluation").relative_to(REPO)),
        "--force",
    ]
    if video:
        argv += ["--video", str(VIDEO_S)]
    print("footforge evaluate " + " ".join(argv), flush=True)
    code = evaluate_main(argv)
    if code == 0:
        light(run / "evaluation", keep=KEPT_VIDEO[task])
    return code


def _haptic(meta: dict) -> bool:
    """A haptic policy (BH, PH) reads its feet's passive joints: footforge evaluate runs it on those feet only."""
    return meta["env"]["policy"] in HAPTIC


VIDEO_S = 3
"""Seconds of video recorded on the policy's own feet (the GIF the repository keeps)."""


def light(folder: Path, keep: str = KEPT_VIDEO["flat"]) -> None:
    """An evaluation folder as a policy folder keeps it: the metrics, the card, the comparison and
    the small plots, and one GIF, the policy on its own feet (`keep`, within
    footforge.rl.render.POLICY_GIF_MAX_BYTES); the frame strips and the other videos are removed
    (`footforge evaluate --video` writes them again) and the card's links to them with them."""
    from footforge.rl.render import POLICY_GIF_MAX_BYTES, shrink_gif

    removed = sorted(p.name for p in folder.glob("strip_*.png")) + sorted(
        p.name for p in folder.glob("video_*.gif") if p.name != keep
    )
    for name in removed:
        (folder / name).unlink()
    card = folder / "policy_card.md"
    lines = card.read_text().splitlines(keepends=True)
    card.write_text("".join(line for line in lines if not any(f"]({name})" in line for name in removed)))
    if (folder / keep).exists():
        width, colours, size = shrink_gif(folder / keep, max_bytes=POLICY_GIF_MAX_BYTES)
        print(f"{folder.relative_to(REPO)}/{keep}: {width} px, {colours} colours, {size / 1e3:.0f} KB")


def evaluate_closed_chain(run: Path) -> int:
    """`footforge evaluate-closed-chain` of one shipped policy into its closed_chain/ (8 robots x 20 s)."""
    from footforge.cli.evaluate_closed_chain import main as closed_chain_main

    argv = [
        "--policy",
        str(run.relative_to(REPO)),
        "--seconds",
        "20",
        "--robots",
        "8",
        "--seed",
        "0",
        "--out",
        str((run / "closed_chain").relative_to(REPO)),
        "--force",
    ]
    print("footforge evaluate-closed-chain " + " ".join(argv), flush=True)
    return closed_chain_main(argv)


PLAY_POLICY = "policies/flat_aof_B/policy"
PLAY_START, PLAY_END = "<!-- closed-chain-play:start -->", "<!-- closed-chain-play:end -->"


def play_caption() -> str:
    """The README's caption of the AOF policy on the closed chain: `footforge play`'s headless run
    (seed 0, 4 s at 0.6 m/s forward), its mean forward speed and verdict."""
    from footforge.rl.play import PlayConfig, Player, load_policy, play_headless

    player = Player(load_policy(REPO / PLAY_POLICY), PlayConfig(feet="full", seed=0))
    player.warm_up()
    result = play_headless(player, seconds=4.0, command=(0.6, 0.0, 0.0))
    vx = result["states"]["vx"]
    return (
        f"The AOF policy on the 34-joint closed chain, commanded 0.6 m/s forward (`MUJOCO_GL=egl footforge play "
        f"{PLAY_POLICY} --feet full --headless --seconds 4 --command 0.6 0 0`; the GIF: `python scripts/readme_gif.py "
        f"policies/flat_aof_B docs/images/walk_aof_closed_chain.gif --feet full`, its first 3 s): mean forward "
        f"speed {sum(vx) / len(vx):.2f} m/s over the 4 s, "
        f'{result["falls"]} falls, verdict "{result["walking"]["line"]}".'
    )


def _replace_block(path: Path, start: str, end: str, text: str) -> None:
    old = path.read_text()
    if start not in old or end not in old:
        raise SystemExit(f"{path}: no {start} ... {end} block to write into")
    new = re.sub(re.escape(start) + ".*?" + re.escape(end), lambda _: f"{start}\n{text}\n{end}", old, flags=re.S)
    if new != old:
        path.write_text(new)
        print(f"wrote {path.relative_to(REPO)}")


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _steps(n: int) -> str:
    return f"{n / 1e6:.1f} M"


def _wall(seconds: float | None) -> str:
    if not seconds:
        return "wall time not recorded"
    minutes = round(seconds / 60)
    return f"{minutes // 60} h {minutes % 60} min" if minutes >= 60 else f"{minutes} min"


def row(run: Path) -> str:
    """The table row of one shipped policy, from its footforge.json, config.json and evaluation."""
    meta = json.loads((run / "policy" / "footforge.json").read_text())
    config = json.loads((run / "config.json").read_text())
    results = json.loads((run / "evaluation" / "metrics.json").read_text())
    own = next(r for r in results if r["feet"] == r["trained_on"])
    w = own["walking"]
    step = int(meta["global_step"])
    machine = meta.get("machine") or {}
    where = (
        (
            "this 2-core CPU"
            if machine.get("backend") == "cpu"
            else f"{machine.get('devices', '?')} x {machine.get('device_kind', '?')}"
        )
        if machine
        else "machine not recorded"
    )
    trained = f"{_steps(step)} steps, {where}, {_wall(meta.get('wall_s'))}"
    origin = config.get("initialised_from")
    if origin:
        trained = (
            f"{_steps(step + steps_before(origin))} steps: {_steps(steps_before(origin))} before "
            f"(`--init-from`), then {trained}"
        )
    recipe = config.get("recipe")
    recipe_cell = (
        f"`{recipe['preset']}`"
        + (f" + {_count(len(recipe['overrides']), 'override')}" if recipe.get("overrides") else "")
        if recipe
        else "not recorded"
    )
    stance = w.get("stance_fraction") or {}
    stance_cell = " / ".join(f"{100 * stance[k]:.0f} %" for k in ("LF", "RF", "LH", "RH")) if stance else "-"
    zero_shot = [r for r in results if r is not own and "walking" in r]
    others = "; ".join(f"{FEET_NAMES[r['feet']]} {r['walking']['verdict']} ({r['falls']} fell)" for r in zero_shot)
    if _haptic(meta):  # evaluate() runs it on its own feet alone
        others = "none: a haptic policy reads its own feet's passive joints"
    return (
        f"| `policies/{run.name}` | {FEET_NAMES[own['feet']]} | {trained} | {recipe_cell} | **{w['verdict']}** "
        f"({w['gait']}) | {w['forward_error_mps']:.3f} m/s | {own['falls']} | {w['base_height_m']:.3f} m | "
        f"{stance_cell} | {others or '-'} |"
    )


def table(runs: list[Path]) -> str:
    header = (
        "| policy | feet | trained | recipe (card) | verdict (gait) | forward error | falls of 32 (20 s) | base | "
        "feet on the ground LF / RF / LH / RH | zero-shot on the other feet |\n"
        "| --- | --- | --- | --- | --- | ---: | ---: | ---: | --- | --- |\n"
    )
    note = (
        "\n\n32 robots x 20 s each, seed 0, commands vx U(-1, 1), vy U(-0.5, 0.5) m/s every 10 s, pushes; "
        "written by `python scripts/shipped_evaluations.py` from each policy's `evaluation/metrics.json`."
    )
    return header + "\n".join(row(r) for r in runs) + note


def write_tables(runs: list[Path]) -> None:
    text = table(runs)
    for path in TABLES:
        _replace_block(path, START, END, text)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--policies", nargs="+", metavar="NAME", help="only these (default: every shipped policy)")
    p.add_argument("--no-video", action="store_true", help="no GIFs (also where MUJOCO_GL is unset)")
    p.add_argument("--tables-only", action="store_true", help="only rewrite the tables from the committed metrics")
    p.add_argument(
        "--rough",
        action="store_true",
        help="the finished rough policies instead (1,024 robots x 17.5 s over every tile, the GIF on stairs; "
        "no table: policies/README.md describes them)",
    )
    p.add_argument(
        "--closed-chain",
        action="store_true",
        help="also the closed-chain records (closed_chain/) and the README's closed-chain play caption",
    )
    args = p.parse_args(argv)
    if args.rough and (args.tables_only or args.closed_chain):
        p.error("--rough writes no table and no closed-chain record: leave out --tables-only and --closed-chain")
    os.chdir(REPO)  # the evaluations are recorded with paths relative to the repository
    task = "rough" if args.rough else "flat"
    runs = shipped(task)
    if args.policies:
        unknown = set(args.policies) - {r.name for r in runs}
        if unknown:
            p.error(f"not shipped policies: {', '.join(sorted(unknown))} (shipped: {', '.join(r.name for r in runs)})")
        chosen = [r for r in runs if r.name in args.policies]
    else:
        chosen = runs
    if not args.tables_only:
        video = not args.no_video and bool(os.environ.get("MUJOCO_GL"))
        for run in chosen:
            code = evaluate(run, video, task)
            if code:
                return code
            if args.closed_chain and (run / "closed_chain").is_dir():
                code = evaluate_closed_chain(run)
                if code:
                    return code
        if args.closed_chain:
            _replace_block(REPO / "README.md", PLAY_START, PLAY_END, play_caption())
    if not args.rough:
        write_tables(runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
