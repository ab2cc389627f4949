"""Regenerates every shipped policy's recorded evaluation and the tables that quote it, in one command.

For each `policies/<name>/` with a `policy/`: `footforge evaluate` on its own feet and zero-shot on
the others (32 robots x 20 s, seed 0, the deterministic policy; with MUJOCO_GL set, a 4-s video per
feet) into `policies/<name>/evaluation/` (policy card, metrics, plots), the GIFs then reduced as the
repository keeps them (every other frame, 320 x 180, one 64-colour palette); then the table of
shipped policies between the `<!-- shipped-policies -->` markers of README.md and policies/README.md,
written from those metrics (footforge/rl/verdict.py's verdict, falls, base height, each foot's share
of the ground) and the policies' footforge.json (steps, wall time, machine).

    MUJOCO_GL=egl python scripts/shipped_evaluations.py              # every shipped policy
    python scripts/shipped_evaluations.py --policies flat_aof_B --no-video
    python scripts/shipped_evaluations.py --tables-only              # the tables from the committed metrics

The same policy, machine, seed and robot count give the same JSON (tests/test_shipped_policies.py); on
another machine the falls of 32 robots move by a few (docs/policies.md).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
POLICIES = REPO / "policies"
TABLES = (REPO / "README.md", POLICIES / "README.md")
START, END = "<!-- shipped-policies:start -->", "<!-- shipped-policies:end -->"
FEET_ORDER = ("ball", "aff", "aof")
FEET_NAMES = {"ball": "ball", "aff": "AFF", "aof": "AOF"}


def shipped() -> list[Path]:
    """The shipped policies' run folders (those with a policy/), by name."""
    return sorted(p.parent for p in POLICIES.glob("*/policy") if p.is_dir())


def evaluate(run: Path, video: bool) -> int:
    """`footforge evaluate` of one shipped policy on its feet and the others, into its evaluation/."""
    from footforge.cli.evaluate import main as evaluate_main

    meta = json.loads((run / "policy" / "footforge.json").read_text())
    own = meta["env"]["feet"]
    feet = [own] + [f for f in FEET_ORDER if f != own]
    argv = ["--policy", str(run.relative_to(REPO)), "--feet", *feet, "--num-envs", "32", "--seconds", "20",
            "--seed", "0", "--out", str((run / "evaluation").relative_to(REPO)), "--force"]
    if video:
        argv += ["--video", "4"]
    print("footforge evaluate " + " ".join(argv), flush=True)
    code = evaluate_main(argv)
    if code == 0 and video:
        for gif in sorted((run / "evaluation").glob("video_*.gif")):
            reduce_gif(gif)
    return code


def reduce_gif(path: Path) -> None:
    """The GIF in place at every other frame, half size and one 64-colour palette (its comment kept)."""
    from PIL import Image, ImageSequence

    with Image.open(path) as gif:
        comment = gif.info.get("comment")
        duration = gif.info.get("duration", 40)
        frames = [f.convert("RGB") for f in ImageSequence.Iterator(gif)][::2]
    frames = [f.resize((f.width // 2, f.height // 2), Image.LANCZOS) for f in frames]
    palette = frames[len(frames) // 2].quantize(colors=64)
    frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".gif")
    os.close(fd)
    try:  # every frame of footforge's videos lasts the same (1 / fps): two of them per kept frame
        extra = {"comment": comment} if comment else {}
        frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], duration=duration * 2,
                       loop=0, optimize=True, **extra)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


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
    where = ("this 2-core CPU" if machine.get("backend") == "cpu" else
             f"{machine.get('devices', '?')} x {machine.get('device_kind', '?')}") if machine else "machine not recorded"
    trained = f"{_steps(step)} steps, {where}, {_wall(meta.get('wall_s'))}"
    origin = config.get("initialised_from")
    if origin:
        trained = (f"{_steps(step + int(origin['step']))} steps: {_steps(int(origin['step']))} of an earlier run "
                   f"(`--init-from`), then {trained}")
    recipe = config.get("recipe")
    recipe_cell = f"`{recipe['preset']}`" + (f" + {len(recipe['overrides'])} overrides" if recipe.get("overrides") else "") \
        if recipe else "not recorded"
    stance = w.get("stance_fraction") or {}
    stance_cell = " / ".join(f"{100 * stance[k]:.0f} %" for k in ("LF", "RF", "LH", "RH")) if stance else "-"
    zero_shot = [r for r in results if r is not own]
    others = "; ".join(f"{FEET_NAMES[r['feet']]} {r['walking']['verdict']} ({r['falls']} fell)" for r in zero_shot
                       if "walking" in r)
    return (f"| `policies/{run.name}` | {FEET_NAMES[own['feet']]} | {trained} | {recipe_cell} | **{w['verdict']}** "
            f"({w['gait']}) | {w['forward_error_mps']:.3f} m/s | {own['falls']} | {w['base_height_m']:.3f} m | "
            f"{stance_cell} | {others or '-'} |")


def table(runs: list[Path]) -> str:
    header = ("| policy | feet | trained | recipe (card) | verdict (gait) | forward error | falls of 32 (20 s) | base | "
              "feet on the ground LF / RF / LH / RH | zero-shot on the other feet |\n"
              "| --- | --- | --- | --- | --- | ---: | ---: | ---: | --- | --- |\n")
    note = ("\n\n32 robots x 20 s each, seed 0, commands vx U(-1, 1), vy U(-0.5, 0.5) m/s every 10 s, pushes; "
            "written by `python scripts/shipped_evaluations.py` from each policy's `evaluation/metrics.json`.")
    return header + "\n".join(row(r) for r in runs) + note


def write_tables(runs: list[Path]) -> None:
    text = table(runs)
    for path in TABLES:
        old = path.read_text()
        if START not in old or END not in old:
            raise SystemExit(f"{path}: no {START} ... {END} block to write the table into")
        new = re.sub(re.escape(START) + ".*?" + re.escape(END), lambda _: f"{START}\n{text}\n{END}", old, flags=re.S)
        if new != old:
            path.write_text(new)
            print(f"wrote the table in {path.relative_to(REPO)}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--policies", nargs="+", metavar="NAME", help="only these (default: every shipped policy)")
    p.add_argument("--no-video", action="store_true", help="no GIFs (also where MUJOCO_GL is unset)")
    p.add_argument("--tables-only", action="store_true", help="only rewrite the tables from the committed metrics")
    args = p.parse_args(argv)
    os.chdir(REPO)  # the evaluations are recorded with paths relative to the repository
    runs = shipped()
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
            code = evaluate(run, video)
            if code:
                return code
    write_tables(runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
