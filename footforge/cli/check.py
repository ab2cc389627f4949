"""`footforge check`: the physical and structural defects of a URDF or xacro."""

from __future__ import annotations

import argparse
from pathlib import Path

from footforge.cli.command import new_parser
from footforge.cli.foot_options import add_package_paths
from footforge.errors import EXIT_CHECK_FAILED, EXIT_OK


def parser(prog: str = "footforge check") -> argparse.ArgumentParser:
    """The options of `footforge check`."""
    p = new_parser(
        prog,
        "Lint a URDF or xacro (inertias, masses, joints, meshes, and with --sidecar "
        "the closed chain's closures). Exit 1 when it finds an error.",
    )
    p.add_argument("path", type=Path, help="the URDF or xacro file")
    add_package_paths(p)
    p.add_argument("--arg", action="append", default=[], metavar="NAME:=VALUE", help="xacro argument; repeatable")
    p.add_argument("--sidecar", type=Path, help="also check that the sidecar's closures close")
    return p


def run(args: argparse.Namespace) -> int:
    """Prints the findings; exit 1 where one is an error."""
    from footforge.extras import require_build_extra

    require_build_extra("footforge check")
    from footforge.build.check import check_description
    from footforge.cli.help import console as make_console
    from footforge.inputs.description import parse_args
    from footforge.inputs.urdf_lint import format_findings

    console = make_console()

    result = check_description(
        args.path, package_paths=args.package_path, args=parse_args(args.arg), sidecar=args.sidecar
    )
    console.print(format_findings(result.findings), markup=False, highlight=False)
    for name, gap in result.closure_gaps_m.items():
        console.print(f"closure '{name}': gap {gap:.2e} m at the reference pose", markup=False)
    errors = sum(f.severity == "error" for f in result.findings)
    warnings = len(result.findings) - errors
    console.print(f"{args.path}: {errors} error(s), {warnings} warning(s)", markup=False)
    return EXIT_CHECK_FAILED if result.failed else EXIT_OK
