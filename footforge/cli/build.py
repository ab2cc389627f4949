"""`footforge build`: ANYmal C with a foot variant, as MJCF and USD."""

from __future__ import annotations

import argparse
from pathlib import Path

from footforge.cli.command import add_output_folder, new_parser
from footforge.cli.foot_options import add_description_options, description_options


def parser(prog: str = "footforge build") -> argparse.ArgumentParser:
    """The options of `footforge build`."""
    from footforge.variants import VARIANTS, foot_variant

    p = new_parser(
        prog,
        "Build ANYmal C with a foot variant: MuJoCo MJCF (robot.xml, scene.xml with "
        "keyframes home and stand, foot_rig.xml) and USD for Isaac Sim, from the "
        "SoftFoot-Q description or yours; mass properties checked against the closed "
        "chain with Pinocchio; collision hulls by CoACD (cached). About a minute on 2 cores.",
    )
    p.add_argument(
        "--variant",
        required=True,
        choices=VARIANTS,
        help="; ".join(f"{v}: {foot_variant(v).summary}" for v in VARIANTS),
    )
    p.add_argument("--foot-only", action="store_true", help="write the foot alone (foot.xml) and its rig")
    add_description_options(p)
    p.add_argument("--robot", type=Path, help="robot xacro/URDF with a foot:=ball|none argument (default: ANYmal C)")
    p.add_argument(
        "--format",
        default="mjcf,usd",
        metavar="FORMATS",
        help="comma-separated outputs: mjcf (MuJoCo XML), usd (robot.usda/.usd for Isaac Sim); default mjcf,usd",
    )
    add_output_folder(p, None, "output folder (default build/<variant>)")
    return p


def run(args: argparse.Namespace) -> int:
    """Builds the variant and prints its summary; exit 0."""
    from footforge.extras import require_build_extra

    require_build_extra("footforge build")
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from footforge.build import BuildOptions, build
    from footforge.cli.help import console as make_console

    console = make_console()
    options = BuildOptions(
        variant=args.variant,
        out_dir=args.out or Path("build") / args.variant,
        foot_only=args.foot_only,
        robot_description=args.robot,
        force=args.force,
        formats=tuple(f.strip() for f in args.format.split(",") if f.strip()),
        **description_options(args),
    )
    with Progress(
        SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), console=console, transient=True
    ) as progress:
        task = progress.add_task("building", total=None)
        report = build(options, progress=lambda stage: progress.update(task, description=stage))
    _print_summary(report, options.out_dir, console)
    return 0


def _print_summary(report: dict, out_dir: Path, console) -> None:
    from rich.table import Table

    m = report["model"]
    table = Table(title=f"footforge build --variant {report['variant']} -> {out_dir}", show_header=False)
    table.add_row("bodies", str(m["bodies"]))
    table.add_row("joints", ", ".join(f"{v} {k}" for k, v in m["joints_by_kind"].items()))
    table.add_row("DOF", str(m["dof"]))
    table.add_row("equality constraints", ", ".join(f"{v} {k}" for k, v in m["equality_constraints"].items()) or "none")
    table.add_row("total mass", f"{m['total_mass_kg']:.5f} kg")
    table.add_row("timestep", f"{m['timestep_s'] * 1e3:g} ms")
    if "home_base_height_m" in m:
        table.add_row("home base height", f"{m['home_base_height_m']:.4f} m")
    if "closure_residual_at_home_m" in report:
        table.add_row("closure residual (home)", f"{report['closure_residual_at_home_m']:.2e} m")
    mp = report.get("mass_properties_vs_full")
    if mp:
        worst_inertia = max(f["centroidal_inertia_relative_error"] for f in mp["feet"].values())
        table.add_row(
            "vs full: mass, COM, foot inertia",
            f"{mp['total_mass']['relative_error']:.1e}, {mp['com']['relative_error']:.1e}, "
            f"{worst_inertia:.1e} (tol {mp['total_mass']['tolerance']:g}) "
            + ("[green]pass[/green]" if mp["passed"] else "[red]FAIL[/red]"),
        )
    for mesh in report.get("collision", {}).get("meshes", []):
        table.add_row(
            f"hulls {Path(mesh['mesh']).name}",
            f"{mesh['hulls']} (max {max(mesh['vertices'])} vertices{', cached' if mesh['cached'] else ''})",
        )
    for stem, u in report.get("usd", {}).items():
        c = u["vs_mjcf"]
        table.add_row(
            f"USD {stem}",
            f"valid; vs MJCF: mass {c['mass_rel']:.1e}, anchors {c['anchor_m']:.1e} m, "
            f"axes {c['axis_rad']:.1e} rad; {len(u['unsupported'])} item(s) not carried "
            "(build_report.json: usd.unsupported)",
        )
    for note in report.get("repairs", []):
        table.add_row("[yellow]repaired[/yellow]", note)
    table.add_row("time", f"{sum(report['timings_s'].values()):.2f} s")
    console.print(table)
