"""Evaluate trained policies as the paper does (its indices, mean and std over all policy steps).

    python pipelines/evaluate.py --policy runs/flat_aof_B/policy --feet aof
    python pipelines/evaluate.py --policy runs/flat_ball_B/policy runs/flat_aff_B/policy --feet aff  # zero-shot

Writes <out>/metrics.json, comparison.md (one row per policy and feet, like the paper's Figure 8),
comparison.png, contacts_<i>.png (feet contact schedule) and push_response_<i>.png.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    from footforge.envs import FEET

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", type=Path, nargs="+", required=True, help="policy/ folders of training runs")
    p.add_argument("--feet", nargs="+", choices=FEET, help="feet to evaluate on (default: each policy's own)")
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--build-root", type=Path,
                   help="folder holding one footforge build per feet, <root>/<feet>/ (default build/)")
    p.add_argument("--out", type=Path, default=Path("evaluation"))
    args = p.parse_args(argv)

    from footforge.atomic import atomic_directory
    from footforge.errors import FootforgeError
    from footforge.evaluate import comparison_markdown, evaluate, plot
    from footforge.train import load_policy_config

    if args.num_envs < 1 or args.seconds <= 0:
        print("evaluate: error: --num-envs and --seconds must be positive", file=sys.stderr)
        return 2
    try:
        results = []
        for policy in args.policy:
            for feet in args.feet or [None]:
                feet = feet or load_policy_config(policy).feet
                build_dir = str(args.build_root / feet) if args.build_root else None
                results.append(evaluate(policy, feet=feet, num_envs=args.num_envs, seconds=args.seconds,
                                        seed=args.seed, build_dir=build_dir))
        with atomic_directory(args.out) as tmp:
            files = plot(results, tmp)
            (tmp / "comparison.md").write_text(comparison_markdown(results))
            (tmp / "metrics.json").write_text(json.dumps(
                [{k: v for k, v in r.items() if k != "traces"} for r in results], indent=2))
    except FootforgeError as e:
        print(f"evaluate: error: {e}", file=sys.stderr)
        return e.exit_code
    print((args.out / "comparison.md").read_text())
    print(f"written to {args.out}: metrics.json, comparison.md, " + ", ".join(files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
