"""`footforge export`: a trained policy as one ONNX file."""

from __future__ import annotations

import argparse
from pathlib import Path

from footforge.cli.command import new_parser


def parser(prog: str = "footforge export") -> argparse.ArgumentParser:
    """The options of `footforge export`."""
    p = new_parser(
        prog,
        "Write a trained policy as one ONNX file: observation normaliser and network "
        "inside, the observation layout, action scale and joint order as metadata.",
    )
    p.add_argument(
        "policy_dir",
        type=Path,
        metavar="POLICY_DIR",
        help="a training run's folder (its policy/, or without one its newest intact checkpoint), its "
        "policy/ folder, or one of its checkpoints/<step>/ folders",
    )
    p.add_argument(
        "--out",
        type=Path,
        metavar="FILE.onnx",
        help="output file (default: RUN.onnx in the current "
        "folder, named after the run; RUN_stepN.onnx for a checkpoint); an existing file is replaced only "
        "where footforge exported it",
    )
    p.add_argument("--force", action="store_true", help="replace --out even if footforge did not write it")
    return p


def run(args: argparse.Namespace) -> int:
    """Writes the ONNX file; exit 0."""
    from footforge.cli.guard import policy_in_use
    from footforge.cli.help import console as make_console
    from footforge.rl.export_onnx import export

    console = make_console()

    out = export(policy_in_use(args.policy_dir, "footforge export"), args.out, force=args.force)
    console.print(f"policy written to {out}", markup=False, highlight=False, soft_wrap=True)
    return 0
