"""The paper's flat comparison (its Figure 8) at its size, 1,024 robots x 60 s per policy and feet, one pair at a time.

The paper compares the ball-feet baseline on ball feet and on AFF with a policy trained on AFF, each over
1,024 robots for 60 s (commands every 10 s, pushes). On this project's 2-core CPU one such pair is an estimated
14 minutes (`footforge evaluate` under MuJoCo's C engine; four times a 256-robot evaluation's 3.5), too long to
run every pair in one sitting; so each pair is its own `footforge evaluate` into its own folder,
`OUT/<policy>_on_<feet>/`, kept once done, and a later call with the same `--out` goes on with the pairs still
missing (`--max-minutes` stops it between pairs). Whenever every pair is there, the pairs' metrics are joined into
OUT/comparison.md, OUT/metrics.json and OUT/comparison.png (footforge.rl.evaluate's table and plot). OUT is marked
as accumulating (footforge.outputs): footforge's commands do not replace it without --force.

    python scripts/paper_comparison.py --out benchmarks/paper_comparison_1024 --max-minutes 60
    python scripts/paper_comparison.py --out /tmp/cmp --pairs flat_aff_BH:aff --num-envs 32 --seconds 20
    python scripts/paper_comparison.py --rough --out benchmarks/paper_comparison_rough --max-minutes 60

With --rough, the paper's rough comparison (its Figure 9 and Table 3): ROUGH_PAIRS by default, 17.5 s per robot
(the paper's rough evaluation) over every terrain tile, with the table per terrain kind; a default pair whose
policy has no policy/ under policies/ yet (keep_run writes it once the run reached its total steps; a run
still in training keeps a checkpoint instead) is left out and named ("not_trained" in the summary, a
line under the joined table), so the comparison grows as the policies arrive.

A pair is done when its folder's metrics.json was made by the same policy (a digest of its policy/
files), feet, robots, seconds and seed; a pair whose policy changed is evaluated again. A pair that the
policy's own evaluation already holds (`policies/<name>/evaluation/metrics.json`, a row of the same digest,
feet, robots, seconds and seed: `footforge evaluate --feet ball aff aof --num-envs 1024 --seed 0` of a rough
policy holds all three of its pairs) is taken from there instead of evaluated again ("reused"). The pairs
default to the paper's three (PAPER_PAIRS) and the AOF policy and the ball baseline on AOF beside
them. The builds are the ones `footforge build` made here (build/<feet>/); a rebuilt model is not
detected, so a comparison spread over several calls should not straddle a rebuild.

Exit codes: 0 every pair done and the table written, 1 pairs left for a later call (or one failed),
2 bad arguments or an --out folder this script did not write. Last line: a JSON summary.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
POLICIES = REPO / "policies"
clock = time.monotonic
"""The wall clock of the budget (a test sets its own)."""

PAPER_PAIRS = (
    ("flat_ball_B_cpu", "ball"),
    ("flat_ball_B_cpu", "aff"),
    ("flat_aff_B", "aff"),
    ("flat_ball_B_cpu", "aof"),
    ("flat_aof_B", "aof"),
)
"""Figure 8's three pairs (the ball baseline on its own feet and on AFF, AFF's own policy on AFF), with
AOF's own policy and the ball baseline on AOF beside them. The ball baseline is `flat_ball_B_cpu`, trained
by the same preset as the AFF and AOF policies (the paper's baseline is legged_gym's ANYmal C policy,
also trained by the recipe of the others)."""

ROUGH_PAIRS = (
    ("rough_ball_P", "ball"),
    ("rough_ball_P", "aff"),
    ("rough_ball_P", "aof"),
    ("rough_aff_P", "aff"),
    ("rough_aff_PH", "aff"),
    ("rough_aof_P", "aof"),
    ("rough_aof_PH", "aof"),
    ("rough_aof_B", "aof"),
    ("rough_aof_BH", "aof"),
)
"""The paper's rough comparison (Figure 9, Table 3): the ball-feet perceptive baseline on its own feet and
zero-shot on AFF and AOF, and the adaptive feet's own perceptive, haptic and blind policies (issue 45's order)."""
ROUGH_SECONDS = 17.5
"""The paper's rough evaluation: 1,024 robots for 17.5 s."""


def parse_pair(text: str) -> tuple[str, str]:
    """'POLICY:FEET' -> (POLICY, FEET), POLICY a folder under policies/ or a path."""
    from footforge.envs import FEET

    policy, sep, feet = text.partition(":")
    if not sep or not policy or feet not in FEET:
        raise argparse.ArgumentTypeError(f"{text!r}: give POLICY:FEET, FEET one of {', '.join(FEET)}")
    return policy, feet


def policy_dir(policy: str) -> Path:
    """The policy/ folder of a name under policies/ or of a given run or policy folder.

    A name under policies/ is `policies/<name>/policy` when the script runs from the repository, so the
    evaluations' rows, which record this path, read the same on every clone; from elsewhere it stays
    absolute."""
    path = Path(policy)
    if not path.exists():
        path = POLICIES / policy
        if Path.cwd() == POLICIES.parent:
            path = path.relative_to(POLICIES.parent)
    return path / "policy" if (path / "policy").is_dir() else path


def pair_name(policy: str, feet: str) -> str:
    """The pair's folder name: the run folder's name and the feet."""
    run = Path(policy)
    name = run.parent.name if run.name == "policy" else run.name
    return f"{name}_on_{feet}"


def settings(policy: Path, feet: str, args) -> dict:
    """What makes a pair's result reusable: the policy's digest, the feet, robots, seconds, seed."""
    from footforge.rl.policy_files import policy_digest

    return {
        "policy_sha256": policy_digest(policy),
        "feet": feet,
        "num_envs": args.num_envs,
        "seconds": args.seconds,
        "seed": args.seed,
    }


def done(folder: Path, wanted: dict) -> bool:
    """Whether `folder` holds this pair's result made with `wanted` settings."""
    try:
        return json.loads((folder / "pair.json").read_text()) == wanted and (folder / "metrics.json").is_file()
    except (OSError, ValueError):
        return False


def check_out(out: Path) -> None:
    """--out is new, empty, or a folder this script made before; anything else is the user's.

    Raises:
      InputError: a file, or a folder this script did not make.
    """
    from footforge.errors import InputError
    from footforge.outputs import ACCUMULATING, marker_kind

    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: is a file; give a folder")
    if out.is_dir() and any(out.iterdir()) and marker_kind(out) != ACCUMULATING:
        raise InputError(f"--out {out}: holds files this script did not write; give a new folder or one it made before")


def recorded_result(policy: Path, wanted: dict) -> tuple[Path, dict] | None:
    """The pair's result where the policy's own evaluation already holds it (POLICY/../evaluation/metrics.json,
    `footforge evaluate` of a kept policy): a row of the same parameters (its policy_sha256), feet, robots,
    seconds and seed, on the engine this machine's evaluations would use, with that file; None where there is
    none (evaluations made before rows carried the digest are not reused)."""
    from footforge.envs import engine

    recorded = policy.parent / "evaluation" / "metrics.json"
    try:
        rows = json.loads(recorded.read_text())
    except (OSError, ValueError):
        return None
    physics = engine.resolve("auto")  # the engine this script's own evaluations run on: one engine per table
    for row in rows if isinstance(rows, list) else []:
        if (
            isinstance(row, dict)
            and row.get("physics") == physics
            and all(row.get(key) == value for key, value in wanted.items())
        ):
            return recorded, row
    return None


def reuse_pair(recorded: Path, row: dict, folder: Path, wanted: dict) -> None:
    """The pair's folder from a recorded result (written whole or not at all), then pair.json."""
    from footforge.atomic import atomic_directory, write_json

    print(f"reusing {recorded} for {folder.name} (same policy, feet, robots, seconds and seed)", flush=True)
    with atomic_directory(folder, command=f"paper_comparison.py: reused {recorded}") as tmp:
        write_json(tmp / "metrics.json", [row])
    write_json(folder / "pair.json", wanted)


def evaluate_pair(policy: Path, feet: str, folder: Path, wanted: dict, args) -> int:
    """`footforge evaluate` of one pair into `folder` (written whole or not at all), then pair.json."""
    from footforge.atomic import write_json
    from footforge.cli.evaluate import main as evaluate_main

    argv = ["--policy", str(policy), "--feet", feet, "--num-envs", str(args.num_envs)]
    argv += ["--seconds", repr(args.seconds), "--seed", str(args.seed), "--out", str(folder)]
    print("footforge evaluate " + " ".join(argv), flush=True)
    code = evaluate_main(argv)
    if code == 0:
        write_json(folder / "pair.json", wanted)
    return code


def join(out: Path, folders: list[Path], not_trained: list[str]) -> None:
    """OUT/comparison.md, metrics.json and comparison.png from the pairs' metrics, in the pairs' order;
    `not_trained` (pairs left out for want of a policy) named under the table."""
    from footforge.atomic import atomic_file, write_json
    from footforge.rl.evaluate import comparison_markdown, plot_indices, terrain_markdown

    results = [r for f in folders for r in json.loads((f / "metrics.json").read_text())]
    write_json(out / "metrics.json", results)
    with atomic_file(out / "comparison.md") as tmp:
        missing = f"\nNot trained yet, left out: {', '.join(not_trained)}.\n" if not_trained else ""
        # Rough results: also Figure 9's table, per terrain kind, and each kind's verdict.
        rough = terrain_markdown(results)
        tmp.write_text(comparison_markdown(results) + (f"\n{rough}" if rough else "") + missing)
    plot_indices(results, out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="the comparison's folder (new, or one this script made)")
    p.add_argument(
        "--rough",
        action="store_true",
        help="the paper's rough comparison: ROUGH_PAIRS by default (those trained so far), --seconds 17.5",
    )
    p.add_argument(
        "--pairs",
        type=parse_pair,
        nargs="+",
        metavar="POLICY:FEET",
        help="policy (a folder under policies/, or a run or policy folder) and the feet to walk it on "
        "(default: " + " ".join(f"{p}:{f}" for p, f in PAPER_PAIRS) + "; with --rough ROUGH_PAIRS)",
    )
    p.add_argument("--num-envs", type=int, default=1024, help="robots per pair (default the paper's 1,024)")
    p.add_argument(
        "--seconds",
        type=float,
        help=f"simulated time per robot (default the paper's 60 s; with --rough {ROUGH_SECONDS})",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--max-minutes",
        type=float,
        help="start no pair after this wall time, nor one the longest pair so far says would end after it",
    )
    args = p.parse_args(argv)
    if args.seconds is None:
        args.seconds = ROUGH_SECONDS if args.rough else 60.0
    not_trained = []
    if args.pairs is None and args.rough:
        not_trained = [
            f"{policy}:{feet}" for policy, feet in ROUGH_PAIRS if not (POLICIES / policy / "policy").is_dir()
        ]
        args.pairs = [(policy, feet) for policy, feet in ROUGH_PAIRS if (POLICIES / policy / "policy").is_dir()]
    elif args.pairs is None:
        args.pairs = list(PAPER_PAIRS)

    from footforge.errors import InputError
    from footforge.outputs import ACCUMULATING, write_marker

    started = clock()
    try:
        if args.num_envs < 1 or args.seconds <= 0 or (args.max_minutes is not None and args.max_minutes <= 0):
            raise InputError("--num-envs, --seconds and --max-minutes must be positive")
        if not args.pairs:
            raise InputError(f"--rough: none of the rough policies is trained yet ({', '.join(not_trained)})")
        check_out(args.out)
        pairs = []
        for policy, feet in args.pairs:
            folder = policy_dir(policy)
            if not (folder / "footforge.json").is_file():
                raise InputError(f"--pairs {policy}:{feet}: {folder} is not a policy folder (no footforge.json)")
            pairs.append((folder, feet, args.out / pair_name(str(folder), feet)))
        names = [f.name for _, _, f in pairs]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise InputError(
                f"--pairs: {', '.join(twice)} named twice (two policies from run folders of one name, or a pair "
                "given twice); each pair needs its own folder: compare such policies in separate --out folders"
            )
    except InputError as e:
        print(f"paper_comparison: error: {e}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    write_marker(args.out, kind=ACCUMULATING)  # footforge's commands then refuse to replace it

    budget_s = None if args.max_minutes is None else 60.0 * args.max_minutes
    longest_s, evaluated, reused, failed = 0.0, [], [], []
    # Each pair's settings once: a digest reads every file of its policy.
    wanted_of = {folder: settings(policy, feet, args) for policy, feet, folder in pairs}
    for policy, feet, folder in pairs:
        wanted = wanted_of[folder]
        if done(folder, wanted):
            continue
        recorded = recorded_result(policy, wanted)
        if recorded is not None:
            try:
                reuse_pair(*recorded, folder, wanted)
            except InputError as e:  # the pair's folder is not this script's (as evaluate_pair's failure)
                print(f"paper_comparison: {folder.name}: {e}", file=sys.stderr)
                failed.append(folder.name)
            else:
                reused.append(folder.name)
            continue
        elapsed = clock() - started
        if budget_s is not None and elapsed + longest_s > budget_s:
            break
        t0 = clock()
        if evaluate_pair(policy, feet, folder, wanted, args) != 0:
            failed.append(folder.name)  # a quick failure says nothing of a pair's time
        else:
            evaluated.append(folder.name)
            longest_s = max(longest_s, clock() - t0)
    left = [f.name for _, _, f in pairs if not done(f, wanted_of[f])]
    if not left:
        join(args.out, [f for _, _, f in pairs], not_trained)
    summary = {
        "paper_comparison": "done" if not left else "pairs left",
        "evaluated": evaluated,
        "reused": reused,
        "failed": failed,
        "left": left,
        "not_trained": not_trained,
        "wall_s": round(clock() - started, 1),
    }
    print(json.dumps(summary))
    return 0 if not left else 1


if __name__ == "__main__":
    sys.exit(main())
