"""Does touch help? The paper's rough question (its Table 3): haptic against non-haptic policies on the
same feet, PH against P and BH against B, each arm over its seeds.

For each policy folder given (a kept run: config.json, its curve metrics.jsonl[.gz], and once evaluated
evaluation/metrics.json from `footforge evaluate` on the rough task), per run:

- the terrain level it reached: the mean of the training episodes' mean level over its last
  PLATEAU_WINDOW_STEPS of training (`episode/terrain/level_per_step`), and where it plateaued: the first
  step whose trailing window mean comes within PLATEAU_TOLERANCE_LEVELS of that final figure;
- from its evaluation on its own feet (all tiles), the share of robots that fell, that crossed their
  tile, the paper's tracking index (forward velocity error), and the walking verdict.

Runs trained for different lengths (one still in training) are also set side by side at the same step: each
run's window mean ending at the shortest run's last step ("level at the common step").

Runs are grouped into arms by (feet, policy type); each arm gets the mean and spread (sample standard
deviation) over its seeds, and each haptic arm is set against its non-haptic twin (PH-P, BH-B). The answer
is stated from the data: a difference larger than the two arms' spreads added is called one, a smaller one
"no difference beyond the spread across seeds", and with one seed in an arm there is no spread to judge by
("one seed: no answer yet").

    python benchmarks/touch_comparison.py policies/rough_aof_P policies/rough_aof_PH --out benchmarks/touch_2026-11-29

Writes OUT/touch_comparison.md (the table and the answers) and OUT/touch_comparison.png (the level curves,
one line per run, coloured by arm); prints one JSON line.
"""

from __future__ import annotations

import argparse
import bisect
import gzip
import itertools
import json
import math
import statistics
import sys
from pathlib import Path

import matplotlib

from footforge.variants import HAPTIC

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

LEVEL_KEY = "episode/terrain/level_per_step"
PLATEAU_WINDOW_STEPS = 3_000_000
"""The final stretch of training whose mean level is the level reached (about a tenth of a 30 M run)."""
PLATEAU_TOLERANCE_LEVELS = 0.25
"""A trailing-window mean within this of the final one counts as on the plateau (a quarter level: about
the swing of the window means of a run at its plateau, rough_aof_P from 20 M steps)."""
TWINS = tuple((haptic, haptic.removesuffix("H")) for haptic in HAPTIC)
"""Each haptic arm against the same policy type without touch, PH-P and BH-B (the paper's Table 3 pairs)."""


def curve(folder: Path) -> list[dict]:
    """The run's training-episode rows that logged a terrain level, in step order."""
    plain, packed = folder / "metrics.jsonl", folder / "metrics.jsonl.gz"
    if plain.is_file():
        text = plain.read_text()
    elif packed.is_file():
        text = gzip.decompress(packed.read_bytes()).decode()
    else:
        raise SystemExit(f"{folder}: no metrics.jsonl or metrics.jsonl.gz (give a training run's folder)")
    rows = []
    for line in text.splitlines():
        try:
            row = json.loads(line)
        except ValueError:  # a line cut short by a kill
            continue
        if LEVEL_KEY in row and math.isfinite(row[LEVEL_KEY]):  # a NaN would spoil every later prefix sum
            rows.append(row)
    return sorted(rows, key=lambda r: r["global_step"])


def _window_mean(rows: list[dict], end_step: int) -> float:
    """The mean level of the rows in the window ending at `end_step`; a window holding no row (logs further
    apart than the window) takes the last row at or before it."""
    inside = [r[LEVEL_KEY] for r in rows if end_step - PLATEAU_WINDOW_STEPS < r["global_step"] <= end_step]
    if inside:
        return statistics.fmean(inside)
    return [r[LEVEL_KEY] for r in rows if r["global_step"] <= end_step][-1]


def _trailing_means(rows: list[dict]) -> list[float]:
    """_window_mean at each row's own step, for all rows at once: prefix sums over the sorted steps, each
    window's bounds found by bisection (n log n; the window always holds its own row)."""
    steps = [r["global_step"] for r in rows]
    prefix = list(itertools.accumulate((r[LEVEL_KEY] for r in rows), initial=0.0))
    means = []
    for step in steps:
        lo, hi = bisect.bisect_right(steps, step - PLATEAU_WINDOW_STEPS), bisect.bisect_right(steps, step)
        means.append((prefix[hi] - prefix[lo]) / (hi - lo))
    return means


def level_reached(rows: list[dict]) -> dict:
    """The level reached (the last window's mean) and the first step whose trailing window mean is within
    PLATEAU_TOLERANCE_LEVELS of it (None for a run shorter than one window)."""
    last = rows[-1]["global_step"]
    final = _window_mean(rows, last)
    plateau = None
    if last >= PLATEAU_WINDOW_STEPS:
        plateau = next(
            r["global_step"]
            for r, mean in zip(rows, _trailing_means(rows), strict=True)
            if r["global_step"] >= PLATEAU_WINDOW_STEPS and abs(mean - final) <= PLATEAU_TOLERANCE_LEVELS
        )
    return {"steps": last, "level": round(final, 3), "plateau_from_step": plateau}


def evaluation(folder: Path, feet: str) -> dict | None:
    """The run's rough evaluation on its own feet, or None where it has none."""
    path = folder / "evaluation" / "metrics.json"
    if not path.is_file():
        return None
    rows = [r for r in json.loads(path.read_text()) if r.get("task") == "rough" and r["feet"] == feet]
    if not rows:
        return None
    r = rows[0]
    n = r["num_envs"]
    return {
        "robots": n,
        "seconds": r["seconds"],
        "fell": round(r["falls"] / n, 3),
        "crossed": round(r["crossed"] / n, 3) if "crossed" in r else None,  # not counted before 2026-11-29
        "vx_error_mps": round(r["indices"]["lin_vel_x_error"]["mean"], 3),
        "verdict": r["walking"]["verdict"],
    }


def summarise(values: list[float]) -> dict:
    return {
        "mean": round(statistics.fmean(values), 3),
        "sd": round(statistics.stdev(values), 3) if len(values) > 1 else None,
        "n": len(values),
    }


def answer(haptic: dict, plain: dict, what: str, higher_is_better: bool) -> str:
    """The data's answer to 'does touch help' on one figure."""
    if haptic["n"] < 2 or plain["n"] < 2:
        return f"{what}: one seed in an arm, no spread to judge by: no answer yet"
    diff = haptic["mean"] - plain["mean"]
    spread = haptic["sd"] + plain["sd"]
    if abs(diff) <= spread:
        return f"{what}: {diff:+.3f}, no difference beyond the spread across seeds ({spread:.3f})"
    better = (diff > 0) == higher_is_better
    return f"{what}: {diff:+.3f}, beyond the spread across seeds ({spread:.3f}): touch {'helps' if better else 'hurts'}"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", type=Path, nargs="+", help="policy folders (policies/<name> or a run's --out)")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    runs = []
    for folder in args.runs:
        config = folder / "config.json"
        if not config.is_file():
            print(f"{folder}: no config.json (give a training run's folder)", file=sys.stderr)
            return 2
        saved = json.loads(config.read_text())
        env, seed = saved["env"], saved["ppo"]["seed"]
        if env.get("task") != "rough":
            print(f"{folder}: a {env.get('task')} run; the touch comparison takes rough runs", file=sys.stderr)
            return 2
        if any((r["feet"], r["policy"], r["seed"]) == (env["feet"], env["policy"], seed) for r in runs):
            print(
                f"{folder}: a second {env['feet']} {env['policy']} run of seed {seed} (the same run twice?); "
                "each seed counts once",
                file=sys.stderr,
            )
            return 2
        rows = curve(folder)
        if not rows:
            print(f"{folder}: its curve has no {LEVEL_KEY} rows yet (train it past its first log)", file=sys.stderr)
            return 2
        runs.append(
            {"run": folder.name, "feet": env["feet"], "policy": env["policy"], "seed": seed, "rows": rows}
            | level_reached(rows)
            | {"evaluation": evaluation(folder, env["feet"])}
        )
    common = min(r["steps"] for r in runs)
    for r in runs:
        r["level_at_common_step"] = round(_window_mean(r["rows"], common), 3)
    arms: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        arms.setdefault((r["feet"], r["policy"]), []).append(r)
    summary = {}
    for (feet, policy), members in arms.items():
        evaluated = [m["evaluation"] for m in members if m["evaluation"]]
        summary[f"{feet}_{policy}"] = {
            "level": summarise([m["level"] for m in members]),
            "level_at_common_step": summarise([m["level_at_common_step"] for m in members]),
        } | (
            {
                k: summarise([e[k] for e in evaluated])
                for k in ("fell", "crossed", "vx_error_mps")
                if evaluated and all(e[k] is not None for e in evaluated)
            }
        )
    answers = []
    for feet in sorted({f for f, _ in arms}):
        for haptic, plain in TWINS:
            h, q = summary.get(f"{feet}_{haptic}"), summary.get(f"{feet}_{plain}")
            if h is None or q is None:
                continue
            answers.append(f"{feet.upper()} {haptic} vs {plain}, " + answer(h["level"], q["level"], "level", True))
            answers.append(
                f"{feet.upper()} {haptic} vs {plain}, "
                + answer(h["level_at_common_step"], q["level_at_common_step"], f"level at {common / 1e6:.1f} M", True)
            )
            for key, better_high in (("fell", False), ("crossed", True)):
                if key in h and key in q:
                    answers.append(f"{feet.upper()} {haptic} vs {plain}, " + answer(h[key], q[key], key, better_high))
    args.out.mkdir(parents=True, exist_ok=True)
    lines = [
        f"| run | feet | policy | seed | steps (M) | level reached | plateau from (M) | level at {common / 1e6:.1f} M "
        "| robots x s | fell | crossed | vx error (m/s) | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        e = r["evaluation"] or {}
        crossed = "-" if e.get("crossed") is None else e["crossed"]
        plateau = f"{r['plateau_from_step'] / 1e6:.1f}" if r["plateau_from_step"] is not None else "-"
        lines.append(
            f"| {r['run']} | {r['feet']} | {r['policy']} | {r['seed']} | {r['steps'] / 1e6:.2f} | {r['level']:.2f} "
            f"| {plateau} | {r['level_at_common_step']:.2f} | {e.get('robots', '-')} x {e.get('seconds', '-')} "
            f"| {e.get('fell', '-')} | {crossed} | {e.get('vx_error_mps', '-')} "
            f"| {e.get('verdict', 'not evaluated')} |"
        )
    lines += [
        "",
        f"| arm | seeds | level (mean ± sd) | level at {common / 1e6:.1f} M | fell | crossed |",
        "|---|---|---|---|---|---|",
    ]

    def cell(s: dict | None) -> str:
        if s is None:
            return "-"
        return f"{s['mean']:.3f}" + (f" ± {s['sd']:.3f}" if s["sd"] is not None else "")

    for arm, s in summary.items():
        lines.append(
            f"| {arm} | {s['level']['n']} | {cell(s['level'])} | {cell(s['level_at_common_step'])} "
            f"| {cell(s.get('fell'))} | {cell(s.get('crossed'))} |"
        )
    lines += ["", "Answers (a difference beyond the two arms' spreads added counts):", ""]
    lines += [f"- {a}" for a in answers] or ["- no haptic arm with its twin among the runs given"]
    (args.out / "touch_comparison.md").write_text("\n".join(lines) + "\n")

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    colours = {arm: f"C{i}" for i, arm in enumerate(arms)}
    for r in runs:
        ax.plot(
            [x["global_step"] / 1e6 for x in r["rows"]],
            [x[LEVEL_KEY] for x in r["rows"]],
            color=colours[(r["feet"], r["policy"])],
            lw=0.8,
            label=f"{r['feet'].upper()} {r['policy']} seed {r['seed']}",
        )
    ax.set_xlabel("environment steps (M)")
    ax.set_ylabel("mean terrain level")
    ax.set_title("terrain curriculum: haptic against non-haptic", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out / "touch_comparison.png", dpi=110)
    print(
        json.dumps(
            {
                "runs": {
                    r["run"]: {
                        k: r[k] for k in ("steps", "level", "plateau_from_step", "level_at_common_step", "evaluation")
                    }
                    for r in runs
                },
                "common_step": common,
                "arms": summary,
                "answers": answers,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
