"""The foot description's options, the same for `footforge build` and `footforge validate`: a foot
that builds with some flags validates with the same flags."""

from __future__ import annotations

import argparse
from pathlib import Path

from footforge.models.mesh_simplify import DEFAULT_FACE_BUDGET


def add_package_paths(p: argparse.ArgumentParser) -> None:
    """--package-path: where xacro's $(find pkg) and package:// URIs look (build, validate, check)."""
    p.add_argument(
        "--package-path",
        type=Path,
        action="append",
        default=[],
        metavar="DIR",
        help="folder searched for ROS packages ($(find pkg), package://); repeatable",
    )


def add_description_options(p: argparse.ArgumentParser, params_help: str | None = None) -> None:
    """The foot description and its derivation, the same for build and validate (a foot that builds
    with some flags validates with the same flags)."""
    p.add_argument("--description", type=Path, help="foot xacro/URDF (default: the project's SoftFoot-Q)")
    p.add_argument("--sidecar", type=Path, help="foot sidecar YAML (default: <stem>.sidecar.yaml beside it)")
    p.add_argument("--params", type=Path, help=params_help or "variant parameter file (default: the SoftFoot-Q's)")
    add_package_paths(p)
    p.add_argument(
        "--arg",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="xacro argument for the foot description; repeatable",
    )
    p.add_argument(
        "--repair", action="store_true", help="repair repairable description defects (reported in build_report.json)"
    )
    # DecompositionConfig's defaults (footforge.models.collision, whose trimesh import would slow every
    # command's start), checked against it by tests/test_cli.py.
    p.add_argument("--max-hull-vertices", type=int, default=64, help="vertex cap per convex hull (default %(default)s)")
    p.add_argument(
        "--coacd-timeout",
        type=float,
        default=900.0,
        help="seconds before CoACD is stopped, per mesh: a guard against a decomposition that never ends "
        "(it takes minutes on a busy machine)",
    )
    p.add_argument(
        "--face-budget",
        type=int,
        default=DEFAULT_FACE_BUDGET,
        help="simplify collision meshes above this many faces before CoACD (default %(default)s; 0: never)",
    )
    p.add_argument("--cache-dir", type=Path, help="CoACD cache folder (default ~/.cache/footforge/coacd)")


def description_options(args) -> dict:
    """FootInputs fields (also BuildOptions's) from _add_description_options' flags, checked before any work.

    Raises:
      InputError: a hull vertex cap below 4, a non-positive CoACD timeout, a negative face budget.
    """
    from footforge.errors import InputError
    from footforge.inputs.description import parse_args
    from footforge.models.collision import DecompositionConfig

    if args.max_hull_vertices < 4:
        raise InputError(
            f"--max-hull-vertices {args.max_hull_vertices} is below 4",
            fix="a convex hull needs at least 4 vertices; the default is 64",
        )
    if args.coacd_timeout <= 0:
        raise InputError("--coacd-timeout must be positive", fix="give seconds, e.g. 900")
    if args.face_budget < 0:
        raise InputError(
            f"--face-budget {args.face_budget} is negative",
            fix=f"give a face count (default {DEFAULT_FACE_BUDGET}), or 0 to keep every face",
        )

    return dict(
        foot_description=args.description,
        sidecar=args.sidecar,
        params=args.params,
        package_paths=tuple(args.package_path),
        foot_args=parse_args(args.arg),
        repair=args.repair,
        cache_dir=args.cache_dir,
        decomposition=DecompositionConfig(
            max_hull_vertices=args.max_hull_vertices, timeout_s=args.coacd_timeout, face_budget=args.face_budget
        ),
    )
