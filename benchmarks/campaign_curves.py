"""Learning curves of training runs from their metrics.jsonl (the training episodes' logs, which
runs with --no-evaluations also have): episode length, forward-velocity tracking error and episode
return against environment steps, and for rough-terrain runs the mean terrain level, one line per
run; prints one JSON line with each run's last figures.

Usage: python benchmarks/campaign_curves.py RUN.metrics.jsonl [...] --out curves.png
"""

import argparse
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
        logs = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
        name = path.parent.name if path.name == "metrics.jsonl" else path.name.split(".")[0]  # a run's own file
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
    print(json.dumps(last))


if __name__ == "__main__":
    main()
