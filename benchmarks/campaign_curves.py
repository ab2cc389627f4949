"""Learning curves of training runs from their metrics.jsonl (the training episodes' logs, which
runs with --no-evaluations also have): episode length, forward-velocity tracking error and episode
return against environment steps, and for rough-terrain runs the mean terrain level, one line per
run; prints one JSON line with each run's last figures.

Usage: python benchmarks/campaign_curves.py RUN.metrics.jsonl[.gz] [...] --out curves.png

Rough-terrain runs also get <out>_levels.png: per run, the share of its robots on each terrain level
(stacked, from the training episodes' `terrain/at_level_<k>_per_step`) against environment steps, the
curriculum's progress beside its mean.
"""

import argparse
import gzip
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PANELS = (
    ("episode/length", "episode length (policy steps)"),
    ("episode/error/lin_vel_x_per_step", "forward velocity error (m/s)"),
    ("episode/sum_reward", "episode return"),
)
LEVEL = ("episode/terrain/level_per_step", "mean terrain level (rough curriculum, 0-9)")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("metrics", type=Path, nargs="+")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    runs = {}
    for path in args.metrics:
        # Records kept in the tree are gzipped (metrics.jsonl.gz): the tree's size limit, scripts/check_tree_size.py.
        text = gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else path.read_text()
        logs = [json.loads(line) for line in text.splitlines() if line.strip()]
        own = path.name in ("metrics.jsonl", "metrics.jsonl.gz")  # a run's own file
        name = path.parent.name if own else path.name.split(".")[0]
        runs[name] = [m for m in logs if "episode/length" in m]
    panels = PANELS + ((LEVEL,) if any(LEVEL[0] in m for logs in runs.values() for m in logs) else ())
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4))
    last = {}
    for name, logs in runs.items():
        for ax, (key, label) in zip(axes, panels):
            if not all(key in m for m in logs):
                continue
            # Diverged physics leaves absurd velocities in the error: clipped for the plot only.
            values = [min(m[key], 5.0) if key.startswith("episode/error") else m[key] for m in logs]
            ax.plot([m["global_step"] / 1e6 for m in logs], values, label=name)
            ax.set_xlabel("environment steps (M)")
            ax.set_title(label, fontsize=9)
        if logs:
            last[name] = {"global_step": logs[-1]["global_step"]} | {
                k.split("/")[-1]: round(logs[-1][k], 3) for k, _ in panels if k in logs[-1]
            }
    axes[1].set_ylim(0, 2.5)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    plt.close(fig)
    shares = {name: logs for name, logs in runs.items() if logs and LEVEL[0] in logs[-1]}
    if shares:
        level_shares(shares, args.out.with_name(args.out.stem + "_levels.png"))
    print(json.dumps(last))


def level_shares(runs: dict, out: Path) -> None:
    """One stacked-area panel per rough run: the share of robots on each terrain level against steps."""
    fig, axes = plt.subplots(1, len(runs), figsize=(4.6 * len(runs), 3.4), squeeze=False)
    for ax, (name, logs) in zip(axes[0], runs.items()):
        prefix = "episode/terrain/at_level_"
        levels = sorted(int(k[len(prefix) :].split("_")[0]) for k in logs[-1] if k.startswith(prefix))
        steps = [m["global_step"] / 1e6 for m in logs]
        ax.stackplot(
            steps,
            [[m.get(f"{prefix}{k}_per_step", 0.0) for m in logs] for k in levels],
            labels=[str(k) for k in levels],
            colors=plt.cm.viridis([k / max(1, len(levels) - 1) for k in levels]),
        )
        ax.set_ylim(0, 1)
        ax.set_xlabel("environment steps (M)")
        ax.set_title(f"{name}: share of robots per terrain level", fontsize=9)
    axes[0][-1].legend(title="level", fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
